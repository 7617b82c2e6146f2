"""Analytic references the HF solves are checked against: 2D plane-strain Hertz and
Cattaneo-Mindlin (:mod:`.hertz`), 3D Hertz (:mod:`.hertz3d`) and the Cattaneo-Mindlin check
of a friction solve (:mod:`.mindlin`)."""

from rbbench.hf.references.hertz import (
    Hertz2D,
    Mindlin2D,
    effective_modulus,
    effective_radius,
    hertz_2d,
    hertz_of_bodies,
    mindlin_2d,
    mindlin_from_hertz,
)
from rbbench.hf.references.hertz3d import (
    Hertz3D,
    hertz3d_of_bodies,
    hertz_3d,
    hertz_3d_at_approach,
    hertz_3d_load,
)

__all__ = ["Hertz3D", "hertz3d_of_bodies", "hertz_3d", "hertz_3d_at_approach", "hertz_3d_load",
           "Hertz2D", "Mindlin2D", "effective_modulus", "effective_radius", "hertz_2d",
           "hertz_of_bodies", "mindlin_2d", "mindlin_from_hertz"]

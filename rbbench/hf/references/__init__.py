"""Analytic references the HF solves are checked against: 2D plane-strain Hertz and
Cattaneo-Mindlin (:mod:`.hertz`) and the Cattaneo-Mindlin check of a friction solve
(:mod:`.mindlin`)."""

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

__all__ = ["Hertz2D", "Mindlin2D", "effective_modulus", "effective_radius", "hertz_2d",
           "hertz_of_bodies", "mindlin_2d", "mindlin_from_hertz"]

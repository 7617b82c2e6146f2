"""3D Hertz theory of two elastic spheres, or a sphere on a flat (an external reference;
science.md section 7; Johnson, *Contact Mechanics*, 1985, section 4.2).

For a force ``P`` between spheres of radii ``R1``, ``R2``:
``1/R* = 1/R1 + 1/R2``, ``1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2``, contact radius
``a = (3 P R* / (4 E*))^(1/3)`` (Johnson eq. 4.22), peak pressure ``p0 = 3 P / (2 pi a^2)``
(eq. 4.21), profile ``p(r) = p0 sqrt(1 - r^2/a^2)`` and approach of distant points
``delta = a^2 / R*`` (eq. 4.23). A rigid flat has ``R2 = inf`` (``None``), a rigid body
``E2 = inf`` (``None``). Unlike 2D, the approach-load law ``P = 4/3 E* sqrt(R*) delta^(3/2)``
is unique, so an imposed approach gives the force as a second check.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from rbbench.hf.references.hertz import effective_modulus, effective_radius

__all__ = ["Hertz3D", "hertz3d_of_bodies", "hertz_3d", "hertz_3d_at_approach",
           "hertz_3d_load"]


@dataclass
class Hertz3D:
    """Hertz contact of two spheres at force ``P`` (N): effective radius ``R_star`` (m) and
    modulus ``E_star`` (Pa), contact radius ``a`` (m), peak pressure ``p0`` (Pa), approach
    ``delta`` (m)."""

    P: float
    R_star: float
    E_star: float
    a: float
    p0: float
    delta: float

    def pressure(self, r: np.ndarray) -> np.ndarray:
        """``p0 sqrt(1 - r^2/a^2)`` on ``r <= a``, 0 outside (r: distance to the axis, m)."""
        r = np.asarray(r, dtype=float)
        return self.p0 * np.sqrt(np.clip(1.0 - (r / self.a) ** 2, 0.0, None))

    def as_dict(self) -> dict:
        return asdict(self)


def _positive(name: str, value: float) -> None:
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"hertz_3d: {name} = {value!r} must be finite and > 0")


def _effective(R1: float, R2: float | None, E1: float, nu1: float, E2: float | None,
               nu2: float | None) -> tuple[float, float]:
    _positive("R1", R1)
    _positive("E1", E1)
    if not -1.0 < nu1 < 0.5:
        raise ValueError(f"hertz_3d: nu1 = {nu1!r} must lie in (-1, 0.5)")
    if R2 is not None and math.isfinite(R2):
        _positive("R2", R2)
    if E2 is not None and math.isfinite(E2):
        _positive("E2", E2)
        if nu2 is None or not -1.0 < nu2 < 0.5:
            raise ValueError(f"hertz_3d: nu2 = {nu2!r} must lie in (-1, 0.5) with E2")
    return effective_radius(R1, R2), effective_modulus(E1, nu1, E2, nu2)


def _from_radius(P: float, Rs: float, Es: float, a: float) -> Hertz3D:
    return Hertz3D(P=P, R_star=Rs, E_star=Es, a=a, p0=3.0 * P / (2.0 * math.pi * a * a),
                   delta=a * a / Rs)


def hertz_3d(P: float, R1: float, R2: float | None, E1: float, nu1: float,
             E2: float | None = None, nu2: float | None = None) -> Hertz3D:
    """Hertz contact radius, peak pressure and approach at force ``P`` (module docstring);
    ``R2``/``E2`` ``None`` (or ``inf``): a flat / rigid second body."""
    _positive("P", P)
    Rs, Es = _effective(R1, R2, E1, nu1, E2, nu2)
    return _from_radius(P, Rs, Es, (3.0 * P * Rs / (4.0 * Es)) ** (1.0 / 3.0))


def hertz_3d_load(delta: float, R_star: float, E_star: float) -> float:
    """The force (N) at approach ``delta`` (m): ``P = 4/3 E* sqrt(R*) delta^(3/2)``."""
    _positive("delta", delta)
    return 4.0 / 3.0 * E_star * math.sqrt(R_star) * delta**1.5


def hertz_3d_at_approach(delta: float, R1: float, R2: float | None, E1: float, nu1: float,
                         E2: float | None = None, nu2: float | None = None) -> Hertz3D:
    """:func:`hertz_3d` at the force that approach ``delta`` gives (``a = sqrt(R* delta)``)."""
    _positive("delta", delta)
    Rs, Es = _effective(R1, R2, E1, nu1, E2, nu2)
    return _from_radius(hertz_3d_load(delta, Rs, Es), Rs, Es, math.sqrt(Rs * delta))


def hertz3d_of_bodies(P: float, geometry: dict, bodies: list) -> Hertz3D:
    """:func:`hertz_3d` at ``P`` for the radii ``geometry["R1"]``, ``geometry["R2"]`` and
    the materials (``.E``, ``.nu``) of the upper body and, if any, the lower one."""
    upper, lower = bodies[0], bodies[1] if len(bodies) > 1 else None
    return hertz_3d(P, geometry["R1"], geometry["R2"], upper.E, upper.nu,
                    lower.E if lower else None, lower.nu if lower else None)

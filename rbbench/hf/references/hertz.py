"""2D plane-strain Hertz theory (an external reference; science.md section 5).

For a load P per unit length between cylinders of radii R1, R2:
``1/R* = 1/R1 + 1/R2``, ``1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2``,
half-width ``a = sqrt(4 P R* / (pi E*))``, peak pressure ``p0 = 2 P / (pi a)``,
profile ``p(x) = p0 sqrt(1 - x^2/a^2)``. A rigid flat has ``R2 = inf`` and
``E2 = inf``. 2D Hertz gives no unique approach-load law, so the comparison is
made at the force the solver itself reports.

Cattaneo-Mindlin (science.md section 6; Johnson, *Contact Mechanics*, 1985, section 7.1):
elastically similar bodies pressed by ``P`` then sheared by ``Q < F P`` stick on
``|x| < c = a sqrt(1 - Q / (F P))`` and slip on ``c <= |x| <= a``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np


def _half_ellipse(x: np.ndarray, a: float, peak: float) -> np.ndarray:
    """``peak sqrt(1 - x^2/a^2)`` on ``|x| <= a``, 0 outside."""
    x = np.asarray(x, dtype=float)
    return peak * np.sqrt(np.clip(1.0 - (x / a) ** 2, 0.0, None))


@dataclass
class Hertz2D:
    P: float  # load per unit thickness (N/m)
    R_star: float
    E_star: float
    a: float
    p0: float

    def pressure(self, x: np.ndarray) -> np.ndarray:
        return _half_ellipse(x, self.a, self.p0)

    def as_dict(self) -> dict:
        return asdict(self)


def effective_modulus(E1: float, nu1: float, E2: float | None, nu2: float | None) -> float:
    inv = (1 - nu1**2) / E1
    if E2 is not None and math.isfinite(E2):
        inv += (1 - nu2**2) / E2
    return 1.0 / inv


def effective_radius(R1: float, R2: float | None) -> float:
    if R2 is None or not math.isfinite(R2):
        return R1
    return R1 * R2 / (R1 + R2)


def hertz_2d(P: float, R1: float, R2: float | None, E1: float, nu1: float,
             E2: float | None = None, nu2: float | None = None) -> Hertz2D:
    """Hertz half-width and peak pressure at load ``P`` (plane strain)."""
    Rs = effective_radius(R1, R2)
    Es = effective_modulus(E1, nu1, E2, nu2)
    a = math.sqrt(4.0 * P * Rs / (math.pi * Es))
    p0 = 2.0 * P / (math.pi * a)
    return Hertz2D(P=P, R_star=Rs, E_star=Es, a=a, p0=p0)


@dataclass
class Mindlin2D:
    """Cattaneo-Mindlin partial slip for a 2D Hertz contact (plane strain).

    ``c``: stick half-width; :meth:`shear_traction` ``q(x) = F p0 sqrt(1 - x^2/a^2)
    - F p0 (c/a) sqrt(1 - x^2/c^2)`` for ``|x| < c``, ``F p(x)`` for ``c <= |x| <= a``,
    0 outside; its integral over ``[-a, a]`` is ``Q``.
    """

    P: float
    Q: float
    F: float
    a: float
    p0: float
    c: float

    def shear_traction(self, x: np.ndarray) -> np.ndarray:
        full = _half_ellipse(x, self.a, self.F * self.p0)
        if self.c <= 0.0:
            return full
        return full - _half_ellipse(x, self.c, self.F * self.p0 * (self.c / self.a))

    def as_dict(self) -> dict:
        return asdict(self)


def hertz_of_bodies(P: float, geometry: dict, bodies: list) -> Hertz2D:
    """:func:`hertz_2d` at ``P`` for the radii ``geometry["R1"]``, ``geometry["R2"]`` and
    the materials (``.E``, ``.nu``) of the upper body and, if any, the lower one."""
    upper, lower = bodies[0], bodies[1] if len(bodies) > 1 else None
    return hertz_2d(P, geometry["R1"], geometry["R2"], upper.E, upper.nu,
                    lower.E if lower else None, lower.nu if lower else None)


def mindlin_2d(P: float, Q: float, F: float, a: float, p0: float) -> Mindlin2D:
    """Cattaneo-Mindlin stick half-width and shear traction at loads ``P``, ``Q``.

    ``a``, ``p0`` are the Hertz half-width and peak pressure at ``P`` (e.g. from
    :func:`hertz_2d`); they must satisfy ``p0 = 2 P / (pi a)`` (relative 1e-6) so that the
    traction integrates to ``Q``. Raises ``ValueError`` naming the quantity unless all are
    finite, ``P, a, p0 > 0``, ``F >= 0`` and ``0 <= Q < F P``.
    """
    vals = {"P": P, "Q": Q, "F": F, "a": a, "p0": p0}
    for name, v in vals.items():
        if not math.isfinite(v):
            raise ValueError(f"mindlin_2d: {name} = {v!r} is not finite")
    for name in ("P", "a", "p0"):
        if vals[name] <= 0:
            raise ValueError(f"mindlin_2d: {name} = {vals[name]!r} must be > 0")
    if F < 0 or Q < 0:
        raise ValueError(f"mindlin_2d: F = {F!r} and Q = {Q!r} must be >= 0")
    if not Q < F * P:
        raise ValueError(f"mindlin_2d: the tangential load Q = {Q!r} must be below "
                         f"F P = {F * P!r} (F = {F!r}, P = {P!r}): full sliding otherwise")
    if abs(p0 - 2.0 * P / (math.pi * a)) > 1e-6 * p0:
        raise ValueError(f"mindlin_2d: p0 = {p0!r} and a = {a!r} are not the Hertz values "
                         f"at P = {P!r} (p0 = 2 P / (pi a) = {2.0 * P / (math.pi * a)!r})")
    c = a * math.sqrt(1.0 - Q / (F * P))
    return Mindlin2D(P=P, Q=Q, F=F, a=a, p0=p0, c=c)


def mindlin_from_hertz(hertz: Hertz2D, Q: float, F: float) -> Mindlin2D:
    """:func:`mindlin_2d` at the load, half-width and peak pressure of ``hertz``."""
    return mindlin_2d(hertz.P, Q, F, hertz.a, hertz.p0)

"""2D plane-strain Hertz theory (an external reference; science.md section 5).

For a load P per unit length between cylinders of radii R1, R2:
``1/R* = 1/R1 + 1/R2``, ``1/E* = (1 - nu1^2)/E1 + (1 - nu2^2)/E2``,
half-width ``a = sqrt(4 P R* / (pi E*))``, peak pressure ``p0 = 2 P / (pi a)``,
profile ``p(x) = p0 sqrt(1 - x^2/a^2)``. A rigid flat has ``R2 = inf`` and
``E2 = inf``. 2D Hertz gives no unique approach-load law, so the comparison is
made at the force the solver itself reports.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np


@dataclass
class Hertz2D:
    P: float  # load per unit thickness (N/m)
    R_star: float
    E_star: float
    a: float
    p0: float

    def pressure(self, x: np.ndarray) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        return self.p0 * np.sqrt(np.clip(1.0 - (x / self.a) ** 2, 0.0, None))

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

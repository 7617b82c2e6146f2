"""The feasible set of the design: a polyhedron ``{x : lb <= x <= ub, cl <= C x <= cu}``
(the admissible shapes of the talk "On coupling of complementarity with friction in contact
shape optimization": box bounds, slope bounds and the area, affine in the design)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

_GROUPS = {"lb": "x >= lb", "ub": "x <= ub", "cl": "C x >= cl", "cu": "C x <= cu"}


@dataclass
class Polyhedron:
    """The set ``{x : lb <= x <= ub, cl <= C x <= cu}`` (infinite bounds allowed)."""

    lb: np.ndarray
    ub: np.ndarray
    C: np.ndarray
    cl: np.ndarray
    cu: np.ndarray

    def __post_init__(self) -> None:
        for key in ("lb", "ub", "cl", "cu"):
            setattr(self, key, np.asarray(getattr(self, key), dtype=float).ravel())
        n = self.lb.size
        self.C = np.asarray(self.C, dtype=float).reshape(-1, n)
        sizes = {"ub": n, "cl": self.C.shape[0], "cu": self.C.shape[0]}
        for key, size in sizes.items():
            if (got := getattr(self, key).size) != size:
                raise ValueError(f"Polyhedron.{key}: {got} entries, need {size}")
        for lo, hi in (("lb", "ub"), ("cl", "cu")):
            bad = np.flatnonzero(getattr(self, lo) > getattr(self, hi))
            if bad.size:
                raise ValueError(f"Polyhedron: {lo} > {hi} at index {int(bad[0])}")
        if not np.isfinite(self.C).all():
            raise ValueError("Polyhedron.C: non-finite entries")

    @classmethod
    def box(cls, lb: np.ndarray, ub: np.ndarray) -> Polyhedron:
        """A box ``lb <= x <= ub`` without general constraints."""
        lb = np.asarray(lb, dtype=float).ravel()
        return cls(lb, ub, np.zeros((0, lb.size)), np.zeros(0), np.zeros(0))

    @property
    def n(self) -> int:
        return self.lb.size

    def residuals(self, x: np.ndarray) -> dict[str, float]:
        """Largest violation per group ``lb, ub, cl, cu`` (raw: > 0 violated, -inf if the
        group has no finite bound)."""
        x = np.asarray(x, dtype=float).ravel()
        Cx = self.C @ x
        parts = {"lb": self.lb - x, "ub": x - self.ub, "cl": self.cl - Cx, "cu": Cx - self.cu}
        return {k: float(np.max(v, initial=-math.inf)) for k, v in parts.items()}

    def is_feasible(self, x: np.ndarray, tol: float = 1e-8) -> bool:
        return all(r <= tol for r in self.residuals(x).values())

    def project(self, z: np.ndarray) -> np.ndarray:
        """The Euclidean projection ``argmin |x - z|`` over the polyhedron (a strictly convex
        QP, by daqp: Arnstrom, Bemporad, Axehill 2022), clipped to the bounds so that they
        hold exactly; ValueError if daqp fails (an empty polyhedron) or its answer violates
        the polyhedron by more than 1e-9."""
        import daqp

        z = np.asarray(z, dtype=float).ravel()
        if z.size != self.n or not np.isfinite(z).all():
            raise ValueError(f"project: need {self.n} finite entries, got {z.size}")
        big = 1e30  # daqp's infinity
        up = np.minimum(np.r_[self.ub, self.cu], big)
        lo = np.maximum(np.r_[self.lb, self.cl], -big)
        x, _, flag, _ = daqp.solve(np.eye(self.n), -z, np.ascontiguousarray(self.C), up, lo,
                                   np.zeros(up.size, dtype=np.int32), primal_tol=1e-12)
        x = np.clip(np.asarray(x, dtype=float), self.lb, self.ub)  # bounds exactly
        if int(flag) != 1 or not self.is_feasible(x, 1e-9):
            raise ValueError(f"project: daqp exit flag {int(flag)} (empty polyhedron?)")
        return x

    def check(self, x: np.ndarray, name: str = "x0", tol: float = 1e-8) -> None:
        """Raise ValueError naming every violated group and by how much."""
        x = np.asarray(x, dtype=float).ravel()
        if x.size != self.n:
            raise ValueError(f"{name}: {x.size} entries, the polyhedron has {self.n}")
        if not np.isfinite(x).all():
            raise ValueError(f"{name}: non-finite entries")
        res = self.residuals(x)
        bad = [f"{k} ({_GROUPS[k]}) violated by {v:.3g}" for k, v in res.items() if v > tol]
        if bad:
            raise ValueError(f"{name} is infeasible: " + "; ".join(bad))

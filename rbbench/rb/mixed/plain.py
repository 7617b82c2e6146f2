"""The mixed reduced model without hyper-reduction (``hyper = "none"``): its online stage
assembles the HF operators at mu, projects them on the bases and solves the small saddle
point (:func:`rbbench.rb.mixed.model.solve_reduced`). Its online cost grows with the HF size;
it is the reference the hyper-reduced models are measured against, and the only mixed model
with an online stabiliser (supremizers ``X^{-1} B(mu)^T V``, which need the HF ``B(mu)``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rbbench.interfaces import HFVectors
from rbbench.rb.algorithms import infsup as inf
from rbbench.rb.mixed.model import OnlineResult, solve_reduced
from rbbench.rb.online import PlainArrays, ReducedBasis, require_basis
from rbbench.scene.parameters import ParameterSpace

__all__ = ["PlainProjection", "PlainReducedModel"]


class PlainProjection:
    """``problem -> ((A_N, F_N, B_N, G_N), Z)``: the Galerkin projection of an HF contact
    problem on ``Z_off`` (with an online ``stabilizer``: on ``Z_off`` and the supremizers of
    the cone generators ``V`` at this problem's ``B``, X-orthonormalised) and ``V``.

    Picklable: the factorisation of ``X`` the supremizers need is rebuilt after unpickling.
    """

    def __init__(self, Z_off: np.ndarray, V: np.ndarray, stabilizer: Any = None,
                 X: Any = None, x_solve: Any = None) -> None:
        self.Z_off, self.V, self.stabilizer, self.X = Z_off, V, stabilizer, X
        self._x_solve = x_solve

    def __call__(self, p: Any) -> tuple[tuple[np.ndarray, ...], np.ndarray]:
        Z, V = self.Z_off, self.V
        if self.stabilizer is not None and self.stabilizer.online:
            if self._x_solve is None:
                self._x_solve = inf.make_solver(self.X)
            Z = self.stabilizer.online_basis(self.Z_off, V, self.X, self._x_solve, p.B)
        return (Z.T @ (p.A @ Z), Z.T @ p.F, V.T @ (p.B @ Z), V.T @ p.G), Z

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_x_solve"] = None
        return state


@dataclass
class PlainReducedModel:
    """The plain mixed model (module docstring).

    Attributes
    ----------
    arrays_at : PlainArrays
        ``mu -> (((A_N, F_N, B_N, G_N), Z), assembly time)`` (:class:`PlainProjection` of a
        freshly assembled HF problem; the assembly at a mu is timed once and counted in the
        online time of every solve at that mu).
    parameters : ParameterSpace or None
        The domain D that :meth:`solve` checks mu against.
    online_method : str
        The reduced solver (:data:`rbbench.rb.mixed.model.ONLINE_METHODS`).
    basis : ReducedBasis or None
        The cone generators ``V`` for :meth:`reconstruct` (``Z`` is the online one).
    """

    arrays_at: PlainArrays
    parameters: ParameterSpace | None = None
    online_method: str = "auto"
    basis: ReducedBasis | None = None
    info: dict = field(default_factory=dict)

    def solve(self, mu: Any, method: str | None = None) -> OnlineResult:
        """Assemble and project at mu (:attr:`arrays_at`), then solve the reduced saddle
        point; ``time_s`` = the assembly and projection + the reduced solve."""
        if self.parameters is not None:
            mu = self.parameters.check(mu)
        (arrays, _), t_asm = self.arrays_at(mu)
        method = self.online_method if method is None else method
        res = solve_reduced(*arrays, method=method)
        res.time_s += t_asm
        res.assembly_s, res.mu, res.method = t_asm, mu, method
        return res

    def reconstruct(self, solution: OnlineResult) -> HFVectors:
        """``Z c`` with the online basis at the solution's mu, ``V alpha``."""
        (_, Z), _ = self.arrays_at(solution.mu)
        return require_basis(self).vectors(solution.c, solution.alpha, Z=Z)

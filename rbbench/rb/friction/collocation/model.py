"""The reduced friction model: small dense arrays, the online Coulomb solve, picklable.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slides "Plain RBM", "Preliminaries" (4: "Large collocation
sets"). With a primal basis ``Z`` (n x N), the normal cone ``W_R^n = Span+(Vn)`` (Vn: m x R,
mCPG) and the tangential space ``X_S = span(Vt)`` (Vt: m x S, POD of lam_t), ``u_N = Z a``,
``lam_n = Vn c_n``, ``lam_t = Vt theta``, the reduced problem of one load step is::

    A_N a + Bn_N^T c_n + Bt_N^T theta = F_N,   c_n >= 0,   Vn^T (Gn - Bn Z a) in (R_+^R)^*
    |(Qt theta)_r| <= s_r  at the collocation nodes r in C  (Tresca, s given)

``A_N = Z^T A Z``, ``Bn_N = Vn^T Bn Z``, ``Bt_N = Vt^T Bt Z``, ``Gn_N = Vn^T Gn``,
``gt_N = -Vt^T ut_lift`` (the tangential jump of the lifting), ``Qn = Vn[C]``,
``Qt = Vt[C]`` (the rows of the nodal bases at the selected nodes). As the HF
condensation (:mod:`rbbench.hf.algebra.friction`), ``a = a0 - A_N^{-1} B_N^T x`` with
``x = (c_n, theta)``, ``B_N = [Bn_N; Bt_N]``, ``D_N = B_N A_N^{-1} B_N^T``,
``q_N = [Gn_N - Bn_N a0; gt_N - Bt_N a0]``, and Tresca is the QP
``min 1/2 x^T D_N x + q_N^T x`` over ``c_n >= 0``, ``-s <= Qt theta <= s``, solved by daqp
(Arnstrom et al. 2022; ``D_N`` may be singular when ``R + S > N``: daqp's proximal
regularisation, ``u_N`` is unique, the multipliers need not be). Coulomb is Benaceur et al.'s
fixed point on Tresca, ``s_r = nu_F (Qn c_n)_r`` of the previous iterate, warm-started from
the nearest training mu.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rbbench.interfaces import HFVectors
from rbbench.rb.algorithms.saddle import condense_dense
from rbbench.rb.friction.qp import (
    check_reducible,
    increment_stop,
    nearest_training,
    tresca_qp,
)
from rbbench.rb.online import ReducedBasis, require_basis
from rbbench.scene.parameters import ParameterSpace

__all__ = ["FrictionArrays", "FrictionOnlineResult", "FrictionReducedModel",
           "ReducedCondensed", "condense_reduced", "project_friction", "solve_coulomb"]


@dataclass
class FrictionArrays:
    """The reduced arrays of one load step at one mu (shapes: N, R normal, S tangential;
    ``law_values``: the Coulomb coefficient or the Tresca threshold per HF node)."""

    A: np.ndarray  # (N, N)
    F: np.ndarray  # (N,)
    Bn: np.ndarray  # (R, N)
    Gn: np.ndarray  # (R,)
    Bt: np.ndarray  # (S, N)
    gt: np.ndarray  # (S,)
    law_values: np.ndarray  # (m,)


def project_friction(problem: Any, Z: np.ndarray, Vn: np.ndarray, Vt: np.ndarray
                     ) -> FrictionArrays:
    """Galerkin projection of a one-step :class:`~rbbench.interfaces.FrictionProblem` on
    ``(Z, Vn, Vt)`` (the plain model's online assembly: its cost grows with the HF size)."""
    step = check_reducible(problem)
    law = problem.threshold if problem.law == "tresca" else problem.coefficient
    return FrictionArrays(A=Z.T @ (problem.A @ Z), F=Z.T @ step.F, Bn=Vn.T @ (problem.Bn @ Z),
                          Gn=Vn.T @ step.Gn, Bt=Vt.T @ (problem.Bt @ Z),
                          gt=-(Vt.T @ np.asarray(step.ut_lift, float)),
                          law_values=np.asarray(law, float))


@dataclass
class ReducedCondensed:
    """``a0 = A_N^{-1} F_N``, ``K = A_N^{-1} B_N^T``, ``D = B_N K``, ``q`` (module docstring)."""

    a0: np.ndarray
    K: np.ndarray
    D: np.ndarray
    q: np.ndarray
    R: int


def condense_reduced(arr: FrictionArrays) -> ReducedCondensed:
    """Condense the reduced arrays on ``x = (c_n, theta)`` (one dense Cholesky of A_N)."""
    a0, K, D, q = condense_dense(arr.A, arr.F, np.vstack([arr.Bn, arr.Bt]),
                                 np.concatenate([arr.Gn, arr.gt]))
    return ReducedCondensed(a0, K, D, q, arr.Bn.shape[0])


@dataclass
class FrictionOnlineResult:
    """One online friction solve: ``a`` (N), ``c_n`` (R), ``theta`` (S); fixed-point
    ``iterations``, daqp ``inner_iterations``, ``stop_reason``, ``history`` (relative
    increments ``||x^{k+1} - x^k||_inf / ||x^{k+1}||_inf``), wall time (s). A
    :class:`rbbench.interfaces.Solution`: ``u = a``, ``lam = (c_n, theta)``."""

    a: np.ndarray
    c_n: np.ndarray
    theta: np.ndarray
    iterations: int
    inner_iterations: int
    stop_reason: str
    time_s: float = 0.0
    history: list[float] = field(default_factory=list)
    #: the parameter of the solve
    mu: np.ndarray | None = None
    #: the time of the reduced arrays at mu (s): the HF assembly and projection of the plain
    #: model, included in ``time_s``
    assembly_s: float = 0.0

    @property
    def c(self) -> np.ndarray:
        """The primal coordinates (the name of :class:`rbbench.rb.mixed.model.OnlineResult`)."""
        return self.a

    @property
    def u(self) -> np.ndarray:
        return self.a

    @property
    def lam(self) -> np.ndarray:
        """The dual coordinates ``(c_n, theta)`` (:class:`rbbench.interfaces.Solution`)."""
        return self.x

    @property
    def x(self) -> np.ndarray:
        return np.concatenate([self.c_n, self.theta])


def solve_coulomb(cond: ReducedCondensed, Qn: np.ndarray, Qt: np.ndarray,
                  values: np.ndarray, law: str = "coulomb", x0: np.ndarray | None = None,
                  tol: float = 1e-10, max_iter: int = 200) -> FrictionOnlineResult:
    """Tresca (one QP, ``s = values``) or Coulomb by Benaceur et al.'s fixed point on Tresca
    (``s = values * (Qn c_n)`` of the previous iterate, clipped at 0) until the relative
    increment is ``<= tol`` (relative to ``max(||x||_inf, 1e-12 ||q|| / ||D||_2)``: a
    zero solution, all nodes open, converges too). Stops ``"converged"``,
    ``"max_iterations"``, ``"diverged"`` (increments grew 1e6-fold) or
    ``"qp failed (daqp flag k)"``."""
    R, n = cond.R, cond.q.size
    x = np.zeros(n) if x0 is None else np.asarray(x0, float).copy()
    hist: list[float] = []
    inner, reason, it = 0, "max_iterations", 0
    floor = 1e-12 * float(np.linalg.norm(cond.q)) / max(float(np.linalg.norm(cond.D, 2)),
                                                         np.finfo(float).tiny)
    while it < (1 if law == "tresca" else max_iter):
        it += 1
        s = values if law == "tresca" else values * np.maximum(Qn @ x[:R], 0.0)
        new, k, flag = tresca_qp(cond.D, cond.q, R, Qt, s, x0=x)
        inner += k
        if new is None:
            reason = f"qp failed (daqp flag {flag})"
            break
        stop = increment_stop(hist, new, x, tol, floor)
        x = new
        if law == "tresca" or stop is not None:
            reason = "converged" if law == "tresca" else stop
            break
    a = cond.a0 - cond.K @ x
    return FrictionOnlineResult(a, x[:R].copy(), x[R:].copy(), it, inner, reason, 0.0, hist)


@dataclass
class FrictionReducedModel:
    """The reduced friction model with collocated Coulomb (or Tresca) constraints: small dense
    arrays, picklable.

    ``Qn``, ``Qt``: the rows of ``Vn``, ``Vt`` at the collocation nodes ``nodes`` (HF node
    indices, chosen by GCNS); ``law``: ``"coulomb"`` or ``"tresca"``; ``mus_train`` and
    ``x_train``: the reduced solutions ``(c_n, theta)`` of the training set (the warm start
    from the nearest training mu). ``arrays_at``: ``mu -> (FrictionArrays, seconds)``, the
    reduced arrays at mu and the time they took; without hyper-reduction a
    :class:`rbbench.rb.online.PlainArrays` (the HF problem at mu projected by
    :func:`project_friction`). ``parameters``: the domain D checked by :meth:`solve`;
    ``basis``: ``Z``, ``Vn``, ``Vt`` (HF size) for :meth:`reconstruct`.
    """

    Qn: np.ndarray
    Qt: np.ndarray
    nodes: np.ndarray
    law: str
    mus_train: np.ndarray
    x_train: np.ndarray
    arrays_at: Callable[[np.ndarray], tuple[FrictionArrays, float]] | None = None
    parameters: ParameterSpace | None = None
    tol: float = 1e-10
    max_iter: int = 200
    info: dict = field(default_factory=dict)
    basis: ReducedBasis | None = None

    @property
    def R(self) -> int:
        return int(self.Qn.shape[1])

    @property
    def S(self) -> int:
        return int(self.Qt.shape[1])

    def warm_start(self, mu: np.ndarray) -> np.ndarray | None:
        """``(c_n, theta)`` of the nearest training mu (:func:`nearest_training`)."""
        return nearest_training(self.mus_train, self.x_train, mu)

    def solve_arrays(self, mu: np.ndarray, arr: FrictionArrays,
                     x0: np.ndarray | None = None) -> FrictionOnlineResult:
        """Condense ``arr`` and solve (:func:`solve_coulomb`), warm-started at ``x0``
        (default: :meth:`warm_start`); ``time_s`` covers condensation and solve."""
        t0 = time.perf_counter()
        mu = np.atleast_1d(np.asarray(mu, float))
        x0 = self.warm_start(mu) if x0 is None else x0
        values = np.asarray(arr.law_values, float)[self.nodes]
        res = solve_coulomb(condense_reduced(arr), self.Qn, self.Qt, values, self.law, x0,
                            self.tol, self.max_iter)
        res.time_s = time.perf_counter() - t0
        return res

    def solve(self, mu: np.ndarray) -> FrictionOnlineResult:
        """Online solve: mu checked against D, the arrays at mu (:attr:`arrays_at`), then
        :meth:`solve_arrays`; ``time_s`` = the arrays' time + condensation and solve."""
        if self.arrays_at is None:
            raise ValueError("reduced friction model without arrays_at: give the reduced "
                             "arrays (solve_arrays) or a PlainArrays of the HF problem")
        mu = self.parameters.check(mu) if self.parameters is not None else mu
        arr, t_arrays = self.arrays_at(mu)
        res = self.solve_arrays(mu, arr)
        res.time_s += t_arrays
        res.assembly_s, res.mu = t_arrays, mu
        return res

    def reconstruct(self, solution: FrictionOnlineResult) -> HFVectors:
        """``Z a`` on the free dofs, ``Vn c_n`` and ``Vt theta`` at the friction nodes."""
        return require_basis(self).vectors(solution.a, solution.c_n, solution.theta)

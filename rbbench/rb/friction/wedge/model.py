"""Coulomb wedge cones and De Saxce's modified gap: a reduced friction model whose friction
cone holds at EVERY HF node by construction (our alternative to the ``X_S`` + collocation
model of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), :mod:`rbbench.rb.friction.collocation.model`).

In 2D the Coulomb cone ``K = {|lam_t| <= F lam_n}`` is a wedge, the image of the
non-negative orthant under ``w+ = F lam_n + lam_t``, ``w- = F lam_n - lam_t``: every HF
snapshot has ``w+ >= 0`` and ``w- >= 0`` at every node. A cone compressor (mCPG, ...) of the
``w+`` and ``w-`` snapshots gives non-negative generators ``V+`` (m x R+), ``V-`` (m x R-)
and the reduced multipliers (per node, ``F`` the coefficient there)::

    lam_n = (V+ c+ + V- c-) / (2 F),   lam_t = (V+ c+ - V- c-) / 2,   c = (c+, c-) >= 0

i.e. ``lam_n = Ln c``, ``lam_t = Lt c`` (:class:`WedgeBasis`): the cone holds at all nodes
for any ``c >= 0``, with no collocation. The law is Coulomb's (non-associated), recovered
by De Saxce and Feng's bipotential (De Saxce & Feng 1991; De Saxce 1992): Coulomb is the
associated law of ``K`` on the modified velocity ``(w_n + F |w_t|, w_t)``, ``w_n`` the gap,
``w_t = -v`` (:mod:`rbbench.hf.algebra.friction`: ``w = q + D x``, slip ``v = -w_t``,
``lam_t = +F lam_n sign(v)``): at a slipping node ``lam . w~ = lam_n w_n``, and
``w~ in K*`` iff ``w_n >= 0``. The fixed point (:func:`desaxce_coulomb`)::

    c^{k+1} = argmin_{c >= 0} 1/2 c^T D_c c + (q_c + P |t0 + T c^k|)^T c

is one bound-constrained QP per iteration (daqp), ``P = Ln^T diag(F) = [V+, V-]^T / 2`` and
``w_t = t0 + T c`` the HF nodal tangential gap of the iterate. Measured on 30 random 2D
problems per F with identity bases (the full nodal wedge, :func:`identity_wedge`; tol 1e-13),
against :func:`rbbench.hf.solvers.friction.coulomb_direct`: agreement to 1e-8 in 30/30 for
F = 0.1 ... 3; iterations (median / max) 9 / 12 at F = 0.1, 12 / 16 at 0.2, 42 / 95 at 1,
127 / 441 at 3; contraction factor (median) 0.04, 0.09, 0.50, 0.80: about ``F / 2`` for
small F, approaching 1 for large F. At F = 5, 29/30: the other converged to a different
Coulomb solution (residual 8e-13; Coulomb friction is not unique for large F).
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
    nonneg_qp,
)
from rbbench.rb.online import ReducedBasis, require_basis
from rbbench.scene.parameters import ParameterSpace

__all__ = ["WedgeArrays", "WedgeBasis", "WedgeCondensed", "WedgeOnlineResult",
           "WedgeReducedModel", "condense_wedge", "desaxce_coulomb", "identity_wedge",
           "project_wedge", "wedge_basis", "wedge_condensed", "wedge_snapshots"]

#: negative w+- entries above ``-WEDGE_RTOL * max(w)`` are the HF solver's rounding of the
#: cone (clipped, counted); larger ones are an error
WEDGE_RTOL = 1e-8


def wedge_snapshots(LAM_N: np.ndarray, LAM_T: np.ndarray, F: np.ndarray
                    ) -> tuple[np.ndarray, np.ndarray, dict[str, float]]:
    """``(w+, w-, info)``: ``F lam_n +- lam_t`` per node and snapshot, round-off negatives
    clipped (``info``: raw minimum relative to ``max w``, number clipped)."""
    F = np.asarray(F, float).reshape(-1, 1)
    WP, WM = F * LAM_N + LAM_T, F * LAM_N - LAM_T
    big = max(float(np.abs(WP).max(initial=0.0)), float(np.abs(WM).max(initial=0.0)), 1e-300)
    low = min(float(WP.min(initial=0.0)), float(WM.min(initial=0.0)))
    if low < -WEDGE_RTOL * big:
        raise ValueError(f"friction snapshots outside the Coulomb cone: min(F lam_n +- lam_t)"
                         f" = {low:.3e} (max {big:.3e}); the wedge model needs them inside")
    info = {"raw_min_rel": low / big, "clipped": int((WP < 0).sum() + (WM < 0).sum())}
    return np.maximum(WP, 0.0), np.maximum(WM, 0.0), info


@dataclass
class WedgeBasis:
    """Generators ``V+`` (m x R+), ``V-`` (m x R-) of the compressed ``w+``, ``w-`` cones and
    the coefficient ``F`` (m,) per node (module docstring)."""

    Vp: np.ndarray
    Vm: np.ndarray
    F: np.ndarray
    history: dict[str, Any] = field(default_factory=dict)

    @property
    def R(self) -> int:
        """Dual unknowns ``R+ + R-``."""
        return int(self.Vp.shape[1] + self.Vm.shape[1])

    @property
    def Ln(self) -> np.ndarray:
        """``lam_n = Ln c``: ``[V+, V-] / (2 F)`` (m x R)."""
        return np.hstack([self.Vp, self.Vm]) / (2.0 * self.F[:, None])

    @property
    def Lt(self) -> np.ndarray:
        """``lam_t = Lt c``: ``[V+, -V-] / 2`` (m x R)."""
        return np.hstack([self.Vp, -self.Vm]) / 2.0

    @property
    def P(self) -> np.ndarray:
        """``Ln^T diag(F) = [V+, V-]^T / 2`` (R x m): the modified gap's coupling."""
        return np.hstack([self.Vp, self.Vm]).T / 2.0

    @property
    def generators(self) -> np.ndarray:
        """``[Ln; Lt]`` (2m x R): the combined dual generators of ``b^n + b^tau``."""
        return np.vstack([self.Ln, self.Lt])


def identity_wedge(F: np.ndarray) -> WedgeBasis:
    """The full nodal wedge ``V+ = V- = I``: the reduced problem is the HF one."""
    F = np.asarray(F, float)
    return WedgeBasis(np.eye(F.size), np.eye(F.size), F)


def wedge_basis(compress: Callable[..., Any], LAM_N: np.ndarray, LAM_T: np.ndarray,
                F: np.ndarray, W: Any, tol: float = 1e-3, r_plus: int | None = None,
                r_minus: int | None = None) -> WedgeBasis:
    """Compress ``w+`` and ``w-`` (:func:`wedge_snapshots`) with a dual compressor
    ``compress(LAM, W, tol=, r_max=) -> DualBasis`` (mCPG etc.); history: both ``e_proj``."""
    F = np.asarray(F, float)
    if F.min(initial=1.0) <= 0:
        raise ValueError("wedge model: the friction coefficient must be > 0 at every node")
    WP, WM, info = wedge_snapshots(LAM_N, LAM_T, F)
    bp = compress(WP, W, tol=tol, r_max=r_plus)
    bm = compress(WM, W, tol=tol, r_max=r_minus)
    for b in (bp, bm):
        if np.asarray(b.generators).min(initial=0.0) < 0 or not getattr(b, "is_cone", True):
            raise ValueError("wedge model: the dual compressor must return a cone of "
                             "non-negative generators (mcpg, cpg, eng, nnmf; not pod)")
    hist = {"e_proj_plus": list(bp.e_proj), "e_proj_minus": list(bm.e_proj), **info}
    return WedgeBasis(np.asarray(bp.generators, float), np.asarray(bm.generators, float), F,
                      hist)


@dataclass
class WedgeArrays:
    """The reduced arrays of one mu: ``A`` (N x N), ``F`` (N), ``B = Ln^T Bn Z + Lt^T Bt Z``
    (R x N), ``g = Ln^T Gn - Lt^T ut_lift`` (R), ``BtZ`` (m x N) and ``wt0 = -ut_lift`` (m)
    for the nodal tangential gap ``w_t = wt0 - BtZ a``."""

    A: np.ndarray
    F: np.ndarray
    B: np.ndarray
    g: np.ndarray
    BtZ: np.ndarray
    wt0: np.ndarray


def project_wedge(problem: Any, Z: np.ndarray, basis: WedgeBasis) -> WedgeArrays:
    """Galerkin projection of a one-step Coulomb FrictionProblem (the plain online stage)."""
    step = check_reducible(problem)
    BtZ = np.asarray(problem.Bt @ Z)
    Ln, Lt = basis.Ln, basis.Lt
    wt0 = -np.asarray(step.ut_lift, float)
    return WedgeArrays(A=Z.T @ (problem.A @ Z), F=Z.T @ step.F,
                       B=Ln.T @ np.asarray(problem.Bn @ Z) + Lt.T @ BtZ,
                       g=Ln.T @ step.Gn + Lt.T @ wt0, BtZ=BtZ, wt0=wt0)


@dataclass
class WedgeCondensed:
    """``min 1/2 c^T D c + (q + P |t0 + T c'|)^T c``, ``c >= 0``; ``u = a0 - K c`` (``a0``,
    ``K``: None for a problem condensed at the HF level, :func:`wedge_condensed`)."""

    D: np.ndarray
    q: np.ndarray
    P: np.ndarray
    t0: np.ndarray
    T: np.ndarray
    a0: np.ndarray | None = None
    K: np.ndarray | None = None


def condense_wedge(arr: WedgeArrays, P: np.ndarray) -> WedgeCondensed:
    """Condense on ``c`` (one dense Cholesky of ``A_N``): ``a = a0 - K c``, so
    ``w_t = (wt0 - BtZ a0) + (BtZ K) c``."""
    a0, K, D, q = condense_dense(arr.A, arr.F, arr.B, arr.g)
    return WedgeCondensed(D, q, P, arr.wt0 - arr.BtZ @ a0, arr.BtZ @ K, a0, K)


def wedge_condensed(D: np.ndarray, q: np.ndarray, basis: WedgeBasis) -> WedgeCondensed:
    """An HF condensed friction problem (``w = q + D x``, ``x = [lam_n; lam_t]``) restricted
    to ``x = [Ln; Lt] c`` (:func:`identity_wedge`: the HF problem itself)."""
    m = q.size // 2
    L = basis.generators
    Dc = L.T @ D @ L
    return WedgeCondensed(0.5 * (Dc + Dc.T), L.T @ q, basis.P, q[m:], D[m:] @ L)


@dataclass
class WedgeOnlineResult:
    """One wedge solve: ``a`` (N; empty at the HF level), ``c`` (R), fixed-point
    ``iterations``, ``inner_iterations`` of the QPs (daqp's on the Python path, passive-set
    solves on the compiled one), ``stop_reason``, ``history`` (relative
    increments), ``rate`` (geometric mean of the increment ratios), wall time (s)."""

    a: np.ndarray
    c: np.ndarray
    iterations: int
    inner_iterations: int
    stop_reason: str
    time_s: float = 0.0
    history: list[float] = field(default_factory=list)
    #: the parameter of the solve
    mu: np.ndarray | None = None
    #: the time of the reduced arrays at mu (s): the HF assembly and projection of the plain
    #: model, the EIM evaluation of the hyper-reduced one; included in ``time_s``
    assembly_s: float = 0.0
    #: which online path ran: "python" (the reference) or "compiled"
    #: (:mod:`rbbench.rb.friction.wedge.compiled`: one kernel, no split into arrays and solve)
    path: str = "python"

    @property
    def x(self) -> np.ndarray:
        return self.c

    @property
    def u(self) -> np.ndarray:
        return self.a

    @property
    def lam(self) -> np.ndarray:
        """The wedge coefficients ``c`` (:class:`rbbench.interfaces.Solution`)."""
        return self.c

    @property
    def rate(self) -> float:
        h = np.asarray([v for v in self.history if v > 0])
        return float(np.exp(np.mean(np.diff(np.log(h))))) if h.size > 2 else 0.0


def desaxce_coulomb(cond: WedgeCondensed, x0: np.ndarray | None = None, tol: float = 1e-10,
                    max_iter: int = 500, record: list | None = None) -> WedgeOnlineResult:
    """De Saxce's fixed point (module docstring): daqp on ``c >= 0`` with the gap modified
    by ``F |w_t|`` of the previous iterate (daqp's bound round-off projected: ``c >= 0``
    exactly, so the cone holds exactly), iterated on the linear term
    ``g = q + P |t0 + T c|`` (a function of ``u``: unique even when ``c`` is not) until
    ``||g^{k+1} - g^k||_inf <= tol ||g^{k+1}||_inf`` (``history``). Stops ``"converged"``,
    ``"max_iterations"``, ``"diverged"`` (increments grew 1e6-fold) or
    ``"qp failed (daqp flag k)"``. ``record``: a list that receives the slip ``|t0 + T c|``
    of every iterate (the snapshots of the slip DEIM, :mod:`rbbench.rb.friction.wedge.hyper`)."""
    c = np.zeros(cond.q.size) if x0 is None else np.maximum(np.asarray(x0, float), 0.0)
    hist: list[float] = []
    inner, reason, it = 0, "max_iterations", 0
    g = cond.q + cond.P @ np.abs(cond.t0 + cond.T @ c)
    while it < max_iter:
        it += 1
        new, k, flag = nonneg_qp(cond.D, g, c if (x0 is not None or it > 1) else None)
        inner += k
        if new is None:
            reason = f"qp failed (daqp flag {flag})"
            break
        c = np.maximum(new, 0.0)
        slip = np.abs(cond.t0 + cond.T @ c)
        if record is not None:
            record.append(slip)
        g_new = cond.q + cond.P @ slip
        stop = increment_stop(hist, g_new, g, tol)
        g = g_new
        if stop is not None:
            reason = stop
            break
    a = np.zeros(0) if cond.a0 is None else cond.a0 - cond.K @ c
    return WedgeOnlineResult(a, c, it, inner, reason, 0.0, hist)


@dataclass
class WedgeReducedModel:
    """The reduced wedge model: ``P`` (R x m), the training solutions for the warm start
    (nearest training mu), ``parameters`` (domain D), ``arrays_at``: ``mu -> (WedgeArrays,
    seconds)`` (without hyper-reduction a :class:`rbbench.rb.online.PlainArrays`: the HF
    problem at mu projected by :func:`project_wedge`), ``basis``: ``Z``, ``Ln``, ``Lt`` (HF
    size) for :meth:`reconstruct`."""

    P: np.ndarray
    mus_train: np.ndarray
    x_train: np.ndarray
    parameters: ParameterSpace | None = None
    tol: float = 1e-10
    max_iter: int = 500
    info: dict = field(default_factory=dict)
    arrays_at: Callable[[np.ndarray], tuple[WedgeArrays, float]] | None = None
    basis: ReducedBasis | None = None

    @property
    def R(self) -> int:
        return int(self.P.shape[0])

    def warm_start(self, mu: np.ndarray) -> np.ndarray | None:
        """``c`` of the nearest training mu (:func:`nearest_training`)."""
        return nearest_training(self.mus_train, self.x_train, mu)

    def solve_arrays(self, mu: np.ndarray, arr: WedgeArrays,
                     x0: np.ndarray | None = None) -> WedgeOnlineResult:
        """Condense and solve (:func:`desaxce_coulomb`); ``time_s`` covers both."""
        t0 = time.perf_counter()
        x0 = self.warm_start(np.atleast_1d(np.asarray(mu, float))) if x0 is None else x0
        res = desaxce_coulomb(condense_wedge(arr, self.P), x0, self.tol, self.max_iter)
        res.time_s = time.perf_counter() - t0
        return res

    def timed_arrays(self, mu: np.ndarray) -> tuple[WedgeArrays, float]:
        """The reduced arrays at mu and the time they took (:attr:`arrays_at`)."""
        if self.arrays_at is None:
            raise ValueError("wedge model without arrays_at: give the reduced arrays "
                             "(solve_arrays) or a PlainArrays of the HF problem")
        return self.arrays_at(mu)

    def solve(self, mu: np.ndarray, x0: np.ndarray | None = None) -> WedgeOnlineResult:
        """Online solve: mu checked against D, the arrays at mu (:meth:`timed_arrays`), then
        De Saxce's fixed point; ``time_s`` = the arrays' time + condensation and solve."""
        mu = self.parameters.check(mu) if self.parameters is not None else mu
        arr, t_arrays = self.timed_arrays(mu)
        res = self.solve_arrays(mu, arr, x0)
        res.time_s += t_arrays
        res.assembly_s, res.mu = t_arrays, mu
        return res

    def reconstruct(self, solution: WedgeOnlineResult) -> HFVectors:
        """``Z a`` on the free dofs, ``Ln c`` and ``Lt c`` at the friction nodes."""
        return require_basis(self).vectors(solution.a, solution.c, solution.c)

"""Dual compressors: reduced positive cones ``W_R^+`` from multiplier snapshots.

Setting (``science.md`` section 2, step 2; seed 000, slides "CPG algorithm" and
"mCPG algorithm (1/4)" to "(4/4)"): the multiplier snapshots ``theta_q``
(``q = 1..Q``) are the columns of a dense ``Theta`` (``n x Q``) with
non-negative entries (the HF positive cone ``W^+`` is the non-negative orthant
of the coefficients). ``W`` is the SPD Gram matrix of the multiplier space and
``||x||_W = sqrt(x^T W x)``. A *dual compressor* returns a :class:`DualBasis`
whose generators ``v_1..v_R`` span the reduced cone
``W_R^+ = Span^+{v_r} = {V alpha, alpha >= 0}`` (or, for the POD baseline, a
linear space).

Error measures (seed, slide "mCPG algorithm (4/4)"):

* ``e_proj(R) = max_q ||(I - Pi_{W_R^+}) theta_q||_W / max_q ||theta_q||_W``,
  with ``Pi_{W_R^+}`` the W-orthogonal projection onto the closed convex cone
  (computed exactly by :func:`cone_projection`).
* ``e_orth(r)``: the seed writes ``||(I - Pi_{W_R^+}) nu_r||_W``, which is zero
  for every generator of ``W_R^+`` if read literally. We read it as the
  *aperture of the new generator*: its normalised distance from the previous
  cone, ``e_orth(r) = ||(I - Pi_{W_{r-1}^+}) nu_r||_W / ||nu_r||_W`` in
  ``[0, 1]`` (``1``: ``nu_r`` is W-orthogonal to, or points away from, the
  previous cone; ``0``: it adds nothing). ``e_orth(1) = 1``.

Functions work on plain arrays. ``W`` may be a dense or scipy sparse
``(n, n)`` matrix, a 1-D array of diagonal weights, or a prebuilt
:class:`WMetric` (pass one to avoid refactorising a non-diagonal ``W``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.optimize import lsq_linear, nnls

__all__ = [
    "DUAL_COMPRESSORS",
    "ConeGram",
    "DualBasis",
    "WMetric",
    "as_metric",
    "cone_gram",
    "cone_projection",
    "cpg",
    "eng",
    "mcpg",
    "mcpg_split",
    "nnmf",
    "nnmf_compressor",
    "pod_dual",
    "span_projection",
]

#: A snapshot whose projection error is below this fraction of the largest
#: snapshot norm is considered exactly represented (greedy loops stop there).
EXHAUSTED_RTOL = 1e-11
#: Negative snapshot entries above ``-NEG_RTOL * max|Theta|`` are rounding noise
#: (clipped to 0); larger ones are an error for the cone methods.
NEG_RTOL = 1e-12
_INF = 1e30  # daqp's "no bound"
#: Relative size (w.r.t. max(theta)) below which an mCPG residual entry is
#: cancellation noise: set to 0 so that generators keep clean supports.
_CRUMB = 1e-13


# --------------------------------------------------------------------------- metric
@dataclass(frozen=True)
class WMetric:
    """The multiplier-space metric ``W = C^T C`` and its factor ``C``.

    Diagonal ``W`` (the common case: lumped boundary mass, P0 multipliers):
    ``C = diag(sqrt(w))``. Any other SPD ``W``: a dense Cholesky factor
    ``W = L L^T``, ``C = L^T`` (``O(n^3)`` once; fine for ``n`` up to a few
    thousand, which covers contact boundaries).
    """

    n: int
    sqrt_diag: np.ndarray | None  # sqrt(w) when W is diagonal
    chol: np.ndarray | None  # lower Cholesky factor L otherwise

    @property
    def is_diagonal(self) -> bool:
        return self.sqrt_diag is not None

    @property
    def diagonal(self) -> np.ndarray:
        """``diag(W)`` (exact for a diagonal ``W``)."""
        if self.sqrt_diag is not None:
            return self.sqrt_diag**2
        return np.einsum("ij,ij->i", self.chol, self.chol)

    def factor(self, X: np.ndarray) -> np.ndarray:
        """``C X`` with ``C^T C = W`` (so that ``||x||_W = ||C x||_2``)."""
        X = np.asarray(X, dtype=float)
        if self.sqrt_diag is not None:
            return self.sqrt_diag[:, None] * X if X.ndim == 2 else self.sqrt_diag * X
        return self.chol.T @ X

    def unfactor(self, Y: np.ndarray) -> np.ndarray:
        """``C^{-1} Y``."""
        Y = np.asarray(Y, dtype=float)
        if self.sqrt_diag is not None:
            return Y / self.sqrt_diag[:, None] if Y.ndim == 2 else Y / self.sqrt_diag
        return sla.solve_triangular(self.chol.T, Y, lower=False)

    def norm(self, X: np.ndarray) -> np.ndarray | float:
        """``||x||_W`` of a vector, or of each column of a matrix."""
        Y = self.factor(X)
        return np.linalg.norm(Y, axis=0) if Y.ndim == 2 else float(np.linalg.norm(Y))

    def inner(self, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """``X^T W Y``."""
        return self.factor(X).T @ self.factor(Y)


def as_metric(W: Any) -> WMetric:
    """Build a :class:`WMetric` from a dense/sparse SPD matrix or diagonal weights.

    Parameters
    ----------
    W : WMetric, (n,) array, (n, n) ndarray or scipy sparse matrix
        The multiplier-space Gram matrix (a 1-D array means ``diag(W)``).

    Returns
    -------
    WMetric
    """
    if isinstance(W, WMetric):
        return W
    if sp.issparse(W):
        W = sp.csr_matrix(W, dtype=float)
        d = W.diagonal()
        if (W - sp.diags(d)).count_nonzero() == 0:
            return _diag_metric(d)
        dense = W.toarray()
    else:
        dense = np.asarray(W, dtype=float)
        if dense.ndim == 1:
            return _diag_metric(dense)
        if dense.ndim != 2 or dense.shape[0] != dense.shape[1]:
            raise ValueError(f"W must be square, got shape {dense.shape}")
        d = np.diag(dense).copy()
        if np.count_nonzero(dense - np.diag(d)) == 0:
            return _diag_metric(d)
    sym = 0.5 * (dense + dense.T)
    try:
        L = np.linalg.cholesky(sym)
    except np.linalg.LinAlgError as exc:
        raise ValueError("W is not symmetric positive definite") from exc
    return WMetric(n=sym.shape[0], sqrt_diag=None, chol=L)


def _diag_metric(d: np.ndarray) -> WMetric:
    d = np.asarray(d, dtype=float)
    if not np.all(d > 0):
        raise ValueError("diagonal W must have positive entries")
    return WMetric(n=d.size, sqrt_diag=np.sqrt(d), chol=None)


# ------------------------------------------------------------------ cone projection
@dataclass(frozen=True)
class ConeGram:
    """Precomputed data for projecting onto ``Span^+(columns of V)`` in ``W``.

    ``CV = C V = Qf Rf`` (thin QR), so that for any ``theta``
    ``||theta - V alpha||_W^2 = ||Qf^T C theta - Rf alpha||^2 + const``: the cone
    projection is an ``R x R`` NNLS with the triangular ``Rf``, whose
    conditioning is that of ``C V`` (not squared, as with the normal equations
    ``G = V^T W V = Rf^T Rf``).
    """

    V: np.ndarray
    metric: WMetric
    CV: np.ndarray
    Qf: np.ndarray
    Rf: np.ndarray

    @property
    def R(self) -> int:
        return int(self.V.shape[1])

    @property
    def G(self) -> np.ndarray:
        """W-Gram matrix of the generators, ``V^T W V``."""
        return self.CV.T @ self.CV

    def cond(self) -> float:
        """2-norm condition number of the W-Gram matrix ``G`` (``= cond(C V)^2``)."""
        if self.R == 0:
            return 1.0
        s = np.linalg.svd(self.Rf, compute_uv=False)
        return float((s[0] / s[-1]) ** 2) if s[-1] > 0 else float("inf")


def cone_gram(V: np.ndarray, W: Any) -> ConeGram:
    """Precompute ``C V`` and its thin QR for repeated :func:`cone_projection` calls.

    Parameters
    ----------
    V : (n, R) array
        Cone generators (columns); ``R = 0`` is the trivial cone ``{0}``.
    W : metric (see :func:`as_metric`)

    Returns
    -------
    ConeGram
    """
    M = as_metric(W)
    V = np.asarray(V, dtype=float)
    if V.ndim == 1:
        V = V[:, None]
    if V.shape[0] != M.n:
        raise ValueError(f"V has {V.shape[0]} rows, W is {M.n} x {M.n}")
    CV = M.factor(V)
    if V.shape[1] == 0:
        Qf = np.zeros((M.n, 0))
        Rf = np.zeros((0, 0))
    else:
        Qf, Rf = np.linalg.qr(CV, mode="reduced")
    return ConeGram(V=V, metric=M, CV=CV, Qf=Qf, Rf=np.ascontiguousarray(Rf))


def _nnls_exact(Rf: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``argmin_{a >= 0} ||Rf a - rhs||``: Lawson-Hanson (scipy), KKT-checked.

    Falls back on the bounded-variable active set (``lsq_linear(method="bvls")``)
    if the C Lawson-Hanson hits its iteration limit or its output fails the KKT
    test. Both are finite active-set methods: exact up to rounding at termination.
    """
    R = Rf.shape[1]
    try:
        a, _ = nnls(Rf, rhs, maxiter=max(50, 20 * R))
    except RuntimeError:
        a = None
    if a is not None:
        g = Rf.T @ (Rf @ a - rhs)  # gradient = G a - b
        scale = 1e-9 * max(np.linalg.norm(Rf) * np.linalg.norm(rhs), 1e-300)
        free = a > 0
        if np.all(g[~free] >= -scale) and np.all(np.abs(g[free]) <= scale):
            return a
    return lsq_linear(Rf, rhs, bounds=(0.0, np.inf), method="bvls", tol=1e-14).x


def cone_projection(
    theta: np.ndarray,
    V: np.ndarray | None = None,
    W: Any = None,
    gram: ConeGram | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | float]:
    """W-orthogonal projection onto the cone ``Span^+(columns of V)``.

    Implements ``Pi^W_{W_R^+}`` of the seed (slides "CPG algorithm" and
    "mCPG algorithm (4/4)"): ``alpha = argmin_{alpha >= 0} ||theta - V alpha||_W``.
    Solved as an exact active-set NNLS (Lawson-Hanson) on the ``R x R``
    triangular factor of ``C V`` (see :class:`ConeGram`), one small solve per
    column; the ``n``-sized work (``C theta``, ``Qf^T C theta``, residuals) is
    done once for the whole batch.

    Parameters
    ----------
    theta : (n,) or (n, k) array
        Vector(s) to project.
    V : (n, R) array, optional
        Generators (ignored when ``gram`` is given).
    W : metric, optional
        See :func:`as_metric` (ignored when ``gram`` is given).
    gram : ConeGram, optional
        ``cone_gram(V, W)``, precomputed once for repeated calls.

    Returns
    -------
    alpha : (R,) or (R, k) array
        Non-negative coefficients.
    proj : (n,) or (n, k) array
        ``V alpha``.
    err : float or (k,) array
        ``||theta - V alpha||_W``, computed from the explicit residual.
    """
    if gram is None:
        if V is None or W is None:
            raise ValueError("give V and W, or gram")
        gram = cone_gram(V, W)
    th = np.asarray(theta, dtype=float)
    single = th.ndim == 1
    T = th[:, None] if single else th
    X = gram.metric.factor(T)
    k = T.shape[1]
    if gram.R == 0:
        alpha = np.zeros((0, k))
        proj = np.zeros_like(T)
        err = np.linalg.norm(X, axis=0)
    else:
        rhs = gram.Qf.T @ X
        alpha = np.empty((gram.R, k))
        for j in range(k):
            alpha[:, j] = _nnls_exact(gram.Rf, rhs[:, j])
        proj = gram.V @ alpha
        err = np.linalg.norm(X - gram.CV @ alpha, axis=0)
    if single:
        return alpha[:, 0], proj[:, 0], float(err[0])
    return alpha, proj, err


def span_projection(
    theta: np.ndarray, V: np.ndarray, W: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray | float]:
    """W-orthogonal projection onto the linear span of the columns of ``V``.

    Returns ``(coeffs, proj, err)`` shaped as in :func:`cone_projection`
    (least squares in ``C V``; used for the non-cone POD baseline).
    """
    M = as_metric(W)
    V = np.asarray(V, dtype=float)
    th = np.asarray(theta, dtype=float)
    single = th.ndim == 1
    T = th[:, None] if single else th
    X = M.factor(T)
    CV = M.factor(V)
    if V.shape[1] == 0:
        c = np.zeros((0, T.shape[1]))
    else:
        c = np.linalg.lstsq(CV, X, rcond=None)[0]
    proj = V @ c
    err = np.linalg.norm(X - CV @ c, axis=0)
    if single:
        return c[:, 0], proj[:, 0], float(err[0])
    return c, proj, err


# ----------------------------------------------------------------- mCPG sub-problem
def _mcpg_qp(CV: np.ndarray, Ct: np.ndarray, A: np.ndarray, b: np.ndarray,
             status: dict[str, Any]) -> np.ndarray | None:
    """``min ||Ct - CV x||^2, x >= 0, A x <= b`` (b > 0, A >= 0) by daqp, then made feasible.

    Attempts: tight primal tolerance ``1e-12``; the same with the Hessian
    shifted by ``1e-12`` then ``1e-9`` times its largest diagonal entry (rank
    deficient ``CV``); finally primal tolerance ``1e-10``. A solution is
    accepted if daqp reports optimality and the feasibility scaling
    (``min b_i / (A x)_i`` over the violated rows) is at least ``1 - 1e-6``.
    Returns None if no attempt is accepted.
    """
    import daqp  # compiled dense QP solver (see module notes)

    R = CV.shape[1]
    m = b.size
    H = np.ascontiguousarray(CV.T @ CV)
    f = -(CV.T @ Ct)
    A = np.ascontiguousarray(A)
    bupper = np.concatenate([np.full(R, _INF), b])
    blower = np.concatenate([np.zeros(R), np.full(m, -_INF)])
    sense = np.zeros(R + m, dtype=np.int32)
    hmax = float(np.max(np.diag(H)))
    tries = ((0.0, 1e-12), (1e-12 * hmax, 1e-12), (1e-9 * hmax, 1e-12), (0.0, 1e-10))
    bmax = float(b.max()) if m else 1.0
    for attempt, (shift, ptol) in enumerate(tries):
        Hs = H + shift * np.eye(R) if shift else H
        xa, _, flag, _ = daqp.solve(Hs, f, A, bupper, blower, sense, primal_tol=ptol)
        status.update(flag=int(flag), attempt=attempt)
        if int(flag) != 1 or not np.all(np.isfinite(xa)):
            continue
        x = np.maximum(np.asarray(xa, dtype=float), 0.0)
        # scaled problem (||theta||_W = ||v_r||_W = 1): x = O(1) at most
        x[x <= max(1e-12, 1e-10 * x.max())] = 0.0
        Ax = A @ x
        over = Ax - b > _CRUMB * bmax  # rounding-level excesses are clipped in nu
        shrink = float(np.min(b[over] / Ax[over])) if np.any(over) else 1.0
        if shrink >= 1.0 - 1e-6:
            status["shrink"] = shrink
            return x * shrink
    return None


def mcpg_split(
    theta: np.ndarray,
    V: np.ndarray | None = None,
    W: Any = None,
    gram: ConeGram | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
    """The mCPG split ``theta = theta_tilde + nu`` (seed, slide "mCPG algorithm (2/4)").

    ``theta_tilde = V alpha`` solves ::

        min_{alpha >= 0} ||theta - V alpha||_W   s.t.   theta - V alpha >= 0  (componentwise)

    i.e. the element of the current cone closest to ``theta`` that leaves a
    residual ``nu = theta - theta_tilde`` in ``W^+``. It is a QP in ``R``
    unknowns with ``R`` bounds and ``n`` general inequalities. Requires
    ``theta >= 0`` (so ``alpha = 0`` is feasible) and ``V >= 0``.

    Solution: an exact presolve first fixes ``alpha_j = 0`` for every generator
    that is positive where ``theta`` vanishes, and drops the rows where the
    remaining generators vanish (these degenerate ``0 <= 0`` constraints made
    daqp report infeasibility at tight tolerance). The reduced QP, scaled to
    ``||theta||_W = 1``, is solved by the dual active-set solver ``daqp``
    (exact on its final active set) with primal tolerance ``1e-12``;
    ``theta_tilde`` is unique but ``alpha`` is not when ``C V`` is rank
    deficient (e.g. more generators than ``n``), so on failure the Hessian is
    retried with the shifts ``1e-12`` and ``1e-9`` times ``max diag(G)``
    (Tikhonov: the min-norm ``alpha``, ``theta_tilde`` moves by ``O(shift)``),
    then with primal tolerance ``1e-10``.

    Exact feasibility is then restored: ``alpha`` is clipped at 0, entries
    below ``max(1e-12, 1e-10 max(alpha))`` in the scaled problem are zeroed,
    and ``alpha`` is scaled by ``min_i theta_i / (V alpha)_i`` over the rows
    where ``V alpha`` exceeds ``theta`` by more than ``1e-13 max(theta)``
    (feasible because ``V >= 0``); a solve needing a scaling below ``1 - 1e-6``
    is rejected as inexact. The residual ``nu = theta - V alpha`` has its
    entries below ``1e-13 max(theta)`` (rounding excesses and cancellation
    crumbs) set to 0, so ``nu >= 0`` exactly and equals
    ``theta - theta_tilde`` to ``1e-13`` relative. If every attempt fails,
    the feasible point ``alpha = 0`` (``nu = theta``: the CPG choice) is
    returned with ``status["ok"] = False``.

    Parameters
    ----------
    theta : (n,) array, non-negative
    V : (n, R) array, non-negative (ignored when ``gram`` is given)
    W : metric (ignored when ``gram`` is given)
    gram : ConeGram, optional

    Returns
    -------
    alpha : (R,) array, >= 0
    theta_tilde : (n,) array, ``V alpha``
    nu : (n,) array, >= 0
    status : dict
        ``ok`` (False: fallback ``alpha = 0``), ``flag`` (daqp's exit flag of
        the last solve, 1: optimal), ``attempt`` (0: tight solve; 1, 2:
        shifted Hessian; 3: primal tolerance ``1e-10``), ``shrink`` (the
        feasibility scaling factor).
    """
    if gram is None:
        if V is None or W is None:
            raise ValueError("give V and W, or gram")
        gram = cone_gram(V, W)
    th = np.asarray(theta, dtype=float)
    R = gram.R
    s = gram.metric.norm(th)
    status: dict[str, Any] = {"ok": True, "flag": 1, "attempt": 0, "shrink": 1.0}
    if R == 0 or s == 0.0:
        return np.zeros(R), np.zeros_like(th), th.copy(), status
    t = th / s
    Vm = gram.V
    # Exact presolve. A generator with v_ij > 0 where theta_i = 0 must have
    # alpha_j = 0 (V >= 0); rows where the kept generators all vanish are
    # 0 <= theta_i, always true. Both are degenerate constraints that made daqp
    # report infeasibility at tight tolerance.
    cols = np.flatnonzero(~np.any(Vm[t <= 0.0] > 0.0, axis=0))
    x = np.zeros(R)
    if cols.size:
        rows = np.flatnonzero(np.any(Vm[:, cols] > 0.0, axis=1))
        xs = _mcpg_qp(gram.CV[:, cols], gram.metric.factor(t), Vm[np.ix_(rows, cols)],
                      t[rows], status)
        if xs is None:
            status["ok"] = False  # feasible fallback: nu = theta (the CPG choice)
        else:
            x[cols] = xs
    alpha = s * x
    theta_tilde = Vm @ alpha
    nu = th - theta_tilde
    nu[nu <= _CRUMB * th.max()] = 0.0  # cancellation crumbs: keep supports clean
    return alpha, theta_tilde, nu, status


# -------------------------------------------------------------------- result object
@dataclass
class DualBasis:
    """Output of a dual compressor.

    Attributes
    ----------
    generators : (n, R) array
        Generators ``v_r``, each of unit W-norm; non-negative for cone methods.
    name : str
        Compressor name (key of :data:`DUAL_COMPRESSORS`).
    is_cone : bool
        True: the reduced set is ``Span^+(generators)``; False: a linear span.
    selected : list of int
        Snapshot index ``q_r`` picked at each greedy iteration (empty if none).
    e_proj : list of float
        ``e_proj(r)``, ``r = 1..R`` (seed, "mCPG algorithm (4/4)"); NaN where
        not computed (non-nested NNMF, see ``info``).
    e_orth : list of float
        Aperture ``||(I - Pi_{W_{r-1}^+}) v_r||_W / ||v_r||_W`` of each new
        generator (module docstring).
    info : dict
        ``stop`` (why the loop ended), timings, Gram condition numbers, ...
    """

    generators: np.ndarray
    name: str
    is_cone: bool
    selected: list[int] = field(default_factory=list)
    e_proj: list[float] = field(default_factory=list)
    e_orth: list[float] = field(default_factory=list)
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def R(self) -> int:
        return int(self.generators.shape[1])

    def project(self, theta: np.ndarray, W: Any):
        """Project ``theta`` onto the reduced cone (or span): ``(coeffs, proj, err)``."""
        if self.is_cone:
            return cone_projection(theta, self.generators, W)
        return span_projection(theta, self.generators, W)


# ------------------------------------------------------------------------- helpers
def _check_snapshots(Theta: np.ndarray, nonneg: bool = True) -> tuple[np.ndarray, int]:
    T = np.array(Theta, dtype=float, copy=True)
    if T.ndim == 1:
        T = T[:, None]
    if T.ndim != 2:
        raise ValueError(f"Theta must be (n, Q), got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise ValueError("Theta has non-finite entries")
    n_clipped = 0
    if nonneg and T.size:
        big = np.abs(T).max()
        if T.min() < -NEG_RTOL * big:
            raise ValueError(
                f"Theta has negative entries (min {T.min():.3e}, max |.| {big:.3e}): "
                "cone compressors need snapshots in W+ (the non-negative orthant)")
        neg = T < 0
        n_clipped = int(neg.sum())
        T[neg] = 0.0
    return T, n_clipped


def _normalise(v: np.ndarray, M: WMetric) -> np.ndarray:
    return v / M.norm(v)


def _greedy(
    Theta: np.ndarray,
    W: Any,
    tol: float,
    r_max: int | None,
    name: str,
    make_generator: Callable[[np.ndarray, ConeGram, dict], np.ndarray],
    post_add: Callable[[np.ndarray, WMetric, dict], np.ndarray] | None = None,
) -> DualBasis:
    """Shared loop of CPG / mCPG / ENG (selection of the seed's "CPG algorithm")."""
    t0 = time.perf_counter()
    M = as_metric(W)
    T, n_clipped = _check_snapshots(Theta)
    n, Q = T.shape
    if n != M.n:
        raise ValueError(f"Theta has {n} rows, W is {M.n} x {M.n}")
    norms = M.norm(T)
    scale = float(norms.max()) if Q else 0.0
    r_max = Q if r_max is None else int(r_max)
    info: dict[str, Any] = {"n": n, "Q": Q, "tol": tol, "r_max": r_max,
                            "clipped_negative": n_clipped, "cond_G": []}
    V = np.zeros((n, 0))
    gram = cone_gram(V, M)
    selected: list[int] = []
    e_proj: list[float] = []
    e_orth: list[float] = []
    if scale == 0.0:
        info["stop"] = "zero_snapshots"
        return DualBasis(V, name, True, selected, e_proj, e_orth, info)
    errs = np.asarray(norms, dtype=float).copy()  # projection errors on {0}
    ep = 1.0
    while True:
        if ep <= tol:
            info["stop"] = "tol"
            break
        if len(selected) >= r_max:
            info["stop"] = "r_max"
            break
        q = int(np.argmax(errs))
        if errs[q] <= EXHAUSTED_RTOL * scale:
            info["stop"] = "exhausted"  # every snapshot is in the cone
            break
        if q in selected:
            info["stop"] = "no_progress"  # numerical: a selected snapshot left the cone
            break
        nu = make_generator(T[:, q], gram, info)
        nrm = M.norm(nu)
        if not nrm > 0:
            info["stop"] = "no_progress"
            break
        nu = nu / nrm
        e_orth.append(float(np.clip(cone_projection(nu, gram=gram)[2], 0.0, 1.0)))
        V = np.column_stack([V, nu])
        if post_add is not None:
            V = post_add(V, M, info)
        gram = cone_gram(V, M)
        _, _, errs = cone_projection(T, gram=gram)
        errs = np.asarray(errs)
        selected.append(q)
        ep = float(errs.max() / scale)
        e_proj.append(ep)
        info["cond_G"].append(gram.cond())
    info["time"] = time.perf_counter() - t0
    return DualBasis(V, name, True, selected, e_proj, e_orth, info)


# ----------------------------------------------------------------------- greedies
def cpg(Theta: np.ndarray, W: Any, tol: float = 1e-3, r_max: int | None = None,
        **options: Any) -> DualBasis:
    """Cone Projected Greedy (seed 000, slide "CPG algorithm" [Benaceur, Ern, Ehrlacher 2020]).

    Iteration ``r``: select ``q_r = argmax_q ||(I - Pi_{W_{r-1}^+}) theta_q||_W``
    and set ``W_r^+ = Span^+{theta_{q_1}, ..., theta_{q_r}}``; each generator is
    the selected snapshot normalised in ``W`` (no Gram-Schmidt: it would destroy
    positivity). The cones are nested, so ``e_proj`` is non-increasing and every
    selected snapshot is reproduced exactly.

    Parameters
    ----------
    Theta : (n, Q) array, non-negative
        Multiplier snapshots (columns).
    W : metric (see :func:`as_metric`)
    tol : float
        Stop when ``e_proj(r) <= tol`` (``delta_CPG``).
    r_max : int, optional
        At most ``r_max`` generators (default ``Q``).

    Returns
    -------
    DualBasis
        ``info["stop"]`` is ``"tol"``, ``"r_max"``, ``"exhausted"`` (all
        snapshots in the cone to rounding) or ``"no_progress"``.
    """
    if options:
        raise TypeError(f"cpg: unexpected options {sorted(options)}")
    return _greedy(Theta, W, tol, r_max, "cpg", lambda th, gram, info: th)


def _init_qp_counters(info: dict) -> None:
    """The mCPG QP tallies of ``info``, at zero unless already counting."""
    for key, val in (("qp_retries", 0), ("qp_fallbacks", 0), ("qp_min_shrink", 1.0)):
        info.setdefault(key, val)


def _count_qp(status: dict, info: dict) -> bool:
    """Tally QP retries / failures in ``info``; True if the QP was solved."""
    _init_qp_counters(info)
    ok = bool(status["ok"])
    if not ok:
        info["qp_fallbacks"] += 1
    elif status["attempt"] > 0:
        info["qp_retries"] += 1
    info["qp_min_shrink"] = min(info["qp_min_shrink"], status["shrink"])
    return ok


def _mcpg_generator(th: np.ndarray, gram: ConeGram, info: dict) -> np.ndarray:
    _, _, nu, status = mcpg_split(th, gram=gram)
    _count_qp(status, info)
    if nu.min() < 0:
        raise AssertionError("mCPG generator left W+")
    return nu


def mcpg(Theta: np.ndarray, W: Any, tol: float = 1e-3, r_max: int | None = None,
         **options: Any) -> DualBasis:
    """Modified Cone Projected Greedy (seed 000, slide "mCPG algorithm (2/4)").

    Same selection as :func:`cpg`; the new generator is
    ``nu_r = theta_{q_r} - theta_tilde_{r-1}`` (normalised in ``W``), where
    ``theta_tilde_{r-1}`` is the element of ``W_{r-1}^+`` closest to
    ``theta_{q_r}`` such that ``nu_r`` stays in ``W^+`` (:func:`mcpg_split`, an
    exact QP). Since ``theta_{q_r} = nu_r + theta_tilde`` with
    ``theta_tilde in W_{r-1}^+``, the cones are nested and contain the selected
    snapshots, as for CPG, but the generators are "peeled" of what the previous
    cone already explains. The seed (slides "(3/4)", "(4/4)") reports a wider
    aperture (larger ``e_orth``), better accuracy and a better conditioned
    Gram matrix than CPG; this is an empirical claim, not a theorem (the
    selections of the two greedies differ after the first step).

    Parameters and returns as :func:`cpg`; ``info["qp_fallbacks"]`` counts QP
    solves that failed (then ``nu_r = theta_{q_r}``, the CPG step; none seen
    in our tests, including ``r > n``), ``info["qp_retries"]`` those solved
    only by a retry (shifted Hessian or looser tolerance), and
    ``info["qp_min_shrink"]`` the smallest feasibility scaling (see
    :func:`mcpg_split`).
    Requires the ``daqp`` package.
    """
    if options:
        raise TypeError(f"mcpg: unexpected options {sorted(options)}")
    basis = _greedy(Theta, W, tol, r_max, "mcpg", _mcpg_generator)
    _init_qp_counters(basis.info)
    return basis


def _peel_all(V: np.ndarray, M: WMetric, info: dict, sweeps: int,
              min_gain: float) -> np.ndarray:
    """ENG enlargement: replace each generator by its mCPG residual against the others."""
    V = V.copy()
    R = V.shape[1]
    n_rep = 0
    for _ in range(sweeps):
        changed = 0
        for i in range(R):
            others = np.delete(V, i, axis=1)
            _, tt, nu, status = mcpg_split(V[:, i], gram=cone_gram(others, M))
            if not _count_qp(status, info):
                continue
            # v_i = nu + tt, tt in Span+(others): replacing v_i by nu can only
            # enlarge the cone. Skip negligible peels, and near-total ones
            # (v_i almost inside the others' cone: nu would be rounding noise).
            if M.norm(tt) <= min_gain or M.norm(nu) <= 1e-8:
                continue
            V[:, i] = _normalise(nu, M)
            changed += 1
        n_rep += changed
        if not changed:
            break
    info["peel_replacements"] = info.get("peel_replacements", 0) + n_rep
    return V


def eng(Theta: np.ndarray, W: Any, tol: float = 1e-3, r_max: int | None = None,
        *, sweeps: int = 1, min_gain: float = 1e-10, **options: Any) -> DualBasis:
    """Enlarged Nonnegative Greedy: CPG selection + mCPG peeling of *all* generators.

    The seed (slide "mCPG algorithm (3/4)") only names ENG [Bakhta, Boiveau,
    Maday & Mula 2020] as the idea of building progressively a cone of wider
    aperture inside ``W^+``; the paper's algorithm was not available to us.
    What is implemented here is our design, built on one elementary fact:

        if ``v_i = nu + theta_tilde`` with ``nu >= 0`` and
        ``theta_tilde in Span^+(other generators)``, then replacing ``v_i`` by
        ``nu`` gives a cone that contains the old one (``v_i`` is still in it)
        and stays in ``W^+``.

    Iteration ``r``:

    1. select ``q_r`` as in CPG/mCPG (worst projected snapshot);
    2. add ``nu_r`` = mCPG residual of ``theta_{q_r}`` against the current cone
       (exactly the mCPG step; ``e_orth(r)`` is measured on this ``nu_r``);
    3. *enlarge*: for ``i = 1..r`` (``sweeps`` passes), replace ``v_i`` by its
       mCPG residual against the cone of the other ``r - 1`` generators
       (:func:`mcpg_split`), normalised. By the fact above each replacement
       enlarges the cone, so the cones remain nested across iterations
       (``e_proj`` non-increasing), keep every selected snapshot exactly, and
       keep non-negative generators.

    Difference from CPG / mCPG: CPG keeps raw snapshots (narrowest cone, Gram
    matrix close to singular for similar snapshots); mCPG peels only the new
    generator against the *previous* cone, so early generators stay raw
    snapshots and the cone is never revisited; ENG peels every generator
    against all the others each time one is added, so older generators also
    shed what newer ones explain. For the same selected snapshots the ENG
    cone contains the mCPG cone; generators become closer to extreme rays
    (more localised, less correlated: better-conditioned Gram matrix). The
    price: ``r`` extra small QPs per iteration, and a cone that may contain
    directions far from the snapshots (to be checked against the inf-sup
    stability of the reduced problem).

    Parameters
    ----------
    Theta, W, tol, r_max : as :func:`cpg`
    sweeps : int
        Enlargement passes over all generators per iteration (default 1).
    min_gain : float
        Skip a replacement when the peeled part ``||theta_tilde||_W`` (of a
        unit generator) is below this.

    Returns
    -------
    DualBasis
        ``info["peel_replacements"]`` counts generator replacements.
    """
    if options:
        raise TypeError(f"eng: unexpected options {sorted(options)}")

    def post(V: np.ndarray, M: WMetric, info: dict) -> np.ndarray:
        return _peel_all(V, M, info, sweeps, min_gain) if V.shape[1] > 1 else V

    basis = _greedy(Theta, W, tol, r_max, "eng", _mcpg_generator, post)
    _init_qp_counters(basis.info)
    basis.info.setdefault("peel_replacements", 0)
    basis.info["sweeps"] = sweeps
    return basis


# --------------------------------------------------------------------- POD baseline
def pod_dual(Theta: np.ndarray, W: Any, tol: float = 1e-3, r_max: int | None = None,
             **options: Any) -> DualBasis:
    """POD of the multiplier snapshots in ``W`` (baseline, not a cone).

    ``science.md`` section 2: "plain POD of lam (not a cone: shows why cones
    matter)". SVD of ``C Theta`` (``C^T C = W``); the modes ``C^{-1} U_r`` are
    W-orthonormal but not non-negative, so ``Span`` (not ``Span^+``) is meant.
    ``R`` is the smallest ``r`` with linear ``e_proj(r) <= tol`` (the same
    relative max error as the cone methods, with the W-orthogonal projection
    on the span), capped by ``r_max`` and the numerical rank. ``e_orth(r) = 1``
    (each mode is W-orthogonal to the previous ones). Mode signs are fixed so
    that each mode has a non-negative sum.

    Returns
    -------
    DualBasis
        ``is_cone=False``; ``info["singular_values"]`` (of ``C Theta``).
    """
    if options:
        raise TypeError(f"pod_dual: unexpected options {sorted(options)}")
    t0 = time.perf_counter()
    M = as_metric(W)
    T, _ = _check_snapshots(Theta, nonneg=False)
    n, Q = T.shape
    X = M.factor(T)
    norms = np.linalg.norm(X, axis=0)
    scale = float(norms.max()) if Q else 0.0
    info: dict[str, Any] = {"n": n, "Q": Q, "tol": tol}
    if scale == 0.0:
        info.update(stop="zero_snapshots", singular_values=[], time=time.perf_counter() - t0)
        return DualBasis(np.zeros((n, 0)), "pod", False, [], [], [], info)
    U, S, _ = np.linalg.svd(X, full_matrices=False)
    rank = int(np.sum(S > S[0] * max(n, Q) * np.finfo(float).eps))
    cap = rank if r_max is None else min(rank, int(r_max))
    e_proj: list[float] = []
    R = 0
    info["stop"] = "r_max" if r_max is not None and cap == int(r_max) else "rank"
    for r in range(1, cap + 1):
        Ur = U[:, :r]
        ep = float(np.linalg.norm(X - Ur @ (Ur.T @ X), axis=0).max() / scale)
        e_proj.append(ep)
        R = r
        if ep <= tol:
            info["stop"] = "tol"
            break
    modes = M.unfactor(U[:, :R])
    signs = np.where(modes.sum(axis=0) < 0, -1.0, 1.0)
    modes = modes * signs
    info["singular_values"] = S.tolist()
    info["time"] = time.perf_counter() - t0
    return DualBasis(modes, "pod", False, [], e_proj, [1.0] * R, info)


# -------------------------------------------------------------------- NNMF baseline
def _nndsvda(X: np.ndarray, r: int) -> tuple[np.ndarray, np.ndarray]:
    """NNDSVD initialisation [Boutsidis & Gallopoulos 2008], zeros filled with mean(X)."""
    U, S, Vt = np.linalg.svd(X, full_matrices=False)
    n, Q = X.shape
    A = np.zeros((n, r))
    B = np.zeros((r, Q))
    A[:, 0] = np.sqrt(S[0]) * np.abs(U[:, 0])
    B[0] = np.sqrt(S[0]) * np.abs(Vt[0])
    for k in range(1, min(r, S.size)):
        x, y = U[:, k], Vt[k]
        xp, xn = np.maximum(x, 0), np.maximum(-x, 0)
        yp, yn = np.maximum(y, 0), np.maximum(-y, 0)
        mp = np.linalg.norm(xp) * np.linalg.norm(yp)
        mn = np.linalg.norm(xn) * np.linalg.norm(yn)
        if mp >= mn and mp > 0:
            u, v, m = xp / np.linalg.norm(xp), yp / np.linalg.norm(yp), mp
        elif mn > 0:
            u, v, m = xn / np.linalg.norm(xn), yn / np.linalg.norm(yn), mn
        else:
            continue
        A[:, k] = np.sqrt(S[k] * m) * u
        B[k] = np.sqrt(S[k] * m) * v
    avg = X.mean()
    A[A == 0] = avg
    B[B == 0] = avg
    return A, B


def _hals(X: np.ndarray, r: int, *, init: str, seed: int, max_iter: int,
          fit_tol: float) -> tuple[np.ndarray, np.ndarray, int, float]:
    """HALS for ``min ||X - A B||_F``, ``A, B >= 0`` [Cichocki & Phan 2009, Gillis 2014]."""
    n, Q = X.shape
    if init == "nndsvda":
        A, B = _nndsvda(X, r)
    elif init == "random":
        rng = np.random.default_rng(seed)
        s = np.sqrt(max(X.mean(), 1e-300) / r)
        A = s * rng.random((n, r))
        B = s * rng.random((r, Q))
    else:
        raise ValueError(f"unknown init {init!r}")
    eps = 1e-16 * max(X.max(), 1e-300)
    nx = np.linalg.norm(X)
    prev = np.inf
    it = 0
    fit = np.inf
    while it < max_iter:
        it += 1
        AtX, AtA = A.T @ X, A.T @ A
        for k in range(r):
            if AtA[k, k] > 0:
                B[k] = np.maximum(eps, B[k] + (AtX[k] - AtA[k] @ B) / AtA[k, k])
        XBt, BBt = X @ B.T, B @ B.T
        for k in range(r):
            if BBt[k, k] > 0:
                A[:, k] = np.maximum(eps, A[:, k] + (XBt[:, k] - A @ BBt[:, k]) / BBt[k, k])
        fit = np.linalg.norm(X - A @ B) / nx
        if prev - fit <= fit_tol * max(fit, 1e-12):
            break
        prev = fit
    return A, B, it, float(fit)


def _nnmf_once(T: np.ndarray, M: WMetric, r: int, *, init: str, seed: int, max_iter: int,
               fit_tol: float) -> tuple[np.ndarray, float, dict]:
    s = np.sqrt(M.diagonal)  # exact C for diagonal W, lumped otherwise
    A, B, it, fit = _hals(s[:, None] * T, r, init=init, seed=seed, max_iter=max_iter,
                          fit_tol=fit_tol)
    V = A / s[:, None]
    weight = np.linalg.norm(A, axis=0) * np.linalg.norm(B, axis=1)
    V = V[:, np.argsort(-weight, kind="stable")]
    V = V / M.norm(V)
    _, _, errs = cone_projection(T, gram=cone_gram(V, M))
    return V, float(np.max(errs)), {"iterations": it, "fit": fit}


def nnmf(Theta: np.ndarray, W: Any, r: int, *, seed: int = 0, max_iter: int = 500,
         fit_tol: float = 1e-7, init: str = "nndsvda", history: bool | None = None,
         **options: Any) -> DualBasis:
    """Non-negative matrix factorisation baseline [Balajewicz, Amsallem & Farhat 2016].

    Factorise ``C Theta ~ A B`` with ``A, B >= 0`` by HALS (hierarchical
    alternating least squares), NNDSVDa initialisation (deterministic; ``seed``
    is used only by ``init="random"``). For a diagonal ``W``, ``C = sqrt(W)``
    maps ``A >= 0`` to ``V = C^{-1} A >= 0`` and the fit is exactly the W-metric
    one. For a non-diagonal ``W`` positivity of ``C^{-1} A`` would not be
    preserved, so the factorisation uses the lumped metric ``diag(W)`` instead
    (``info["metric"]`` says which); ``e_proj`` is always evaluated exactly in
    ``W`` by projecting the snapshots on ``Span^+(V)`` (:func:`cone_projection`),
    which is never worse than the factorisation's own coefficients ``B``.

    NNMF is not nested: ``e_proj(r')`` for ``r' < r`` needs a refit per rank.
    ``history=True`` refits for ``r' = 1..r``; ``history=False`` reports only
    ``e_proj(r)`` (earlier entries NaN); ``None`` (default) refits when the
    estimated cost ``max_iter * r * (r + 1)`` is at most ``5e5`` HALS column
    updates. ``info["e_proj_history"]`` records the choice. Generators are
    ordered by decreasing weight ``||a_k|| ||b_k||``; ``e_orth`` is measured in
    that order.

    Returns
    -------
    DualBasis
        ``is_cone=True``, ``selected=[]``, ``info["stop"] = "rank"``.
    """
    if options:
        raise TypeError(f"nnmf: unexpected options {sorted(options)}")
    t0 = time.perf_counter()
    M = as_metric(W)
    T, n_clipped = _check_snapshots(Theta)
    n, Q = T.shape
    r = int(r)
    if r < 1:
        raise ValueError("r must be >= 1")
    if history is None:
        history = max_iter * r * (r + 1) <= 5e5
    scale = float(M.norm(T).max())
    kw = dict(init=init, seed=seed, max_iter=max_iter, fit_tol=fit_tol)
    e_proj = [float("nan")] * r
    ranks = range(1, r + 1) if history else [r]
    fits = {}
    V = np.zeros((n, 0))
    for rr in ranks:
        V, emax, fi = _nnmf_once(T, M, rr, **kw)
        e_proj[rr - 1] = emax / scale if scale > 0 else 0.0
        fits[rr] = fi
    e_orth = []
    for k in range(V.shape[1]):
        e = cone_projection(V[:, k], V[:, :k], M)[2]
        e_orth.append(float(np.clip(e, 0.0, 1.0)))
    info = {"n": n, "Q": Q, "stop": "rank", "seed": seed, "init": init,
            "metric": "W diagonal (exact)" if M.is_diagonal
            else "factorised in lumped diag(W); e_proj in full W",
            "e_proj_history": "refit per rank" if history else "final rank only",
            "hals": fits, "clipped_negative": n_clipped, "time": time.perf_counter() - t0}
    return DualBasis(V, "nnmf", True, [], e_proj, e_orth, info)


def nnmf_compressor(Theta: np.ndarray, W: Any, tol: float = 1e-3, r_max: int | None = None,
                    *, r: int | None = None, **options: Any) -> DualBasis:
    """NNMF with the common compressor signature.

    With ``r`` given: :func:`nnmf` at that rank. Otherwise refit for
    ``r = 1, 2, ...`` until ``e_proj(r) <= tol`` or ``r = r_max`` (default
    ``min(n, Q)``); the returned ``e_proj`` is the per-rank history.
    """
    if r is not None:
        return nnmf(Theta, W, r, **options)
    t0 = time.perf_counter()
    M = as_metric(W)
    T, _ = _check_snapshots(Theta)
    n, Q = T.shape
    cap = min(n, Q) if r_max is None else int(r_max)
    hist: list[float] = []
    basis = None
    for rr in range(1, cap + 1):
        basis = nnmf(T, M, rr, history=False, **options)
        hist.append(basis.e_proj[-1])
        if hist[-1] <= tol:
            break
    if basis is None:
        return DualBasis(np.zeros((n, 0)), "nnmf", True, [], [], [], {"stop": "r_max"})
    basis.e_proj = hist
    basis.info["stop"] = "tol" if hist[-1] <= tol else "r_max"
    basis.info["e_proj_history"] = "refit per rank"
    basis.info["time"] = time.perf_counter() - t0
    return basis


#: Common signature ``f(Theta, W, tol, r_max, **options) -> DualBasis``.
DUAL_COMPRESSORS: dict[str, Callable[..., DualBasis]] = {
    "pod": pod_dual,
    "cpg": cpg,
    "mcpg": mcpg,
    "eng": eng,
    "nnmf": nnmf_compressor,
}

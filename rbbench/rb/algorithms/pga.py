"""Supremizers and the Projected Greedy Algorithm (PGA) for an offline inf-sup stable primal space.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slides "Parameter-dependent context", "Approximation of
S_R", "Main result", "Projected Greedy Algorithm (PGA)" and "Some details". Notation as in
:mod:`rbbench.rb.algorithms.infsup`: ``X`` (n x n, SPD) is the primal Gram matrix, all norms and
projections below are in the X-inner product ``(u, v)_X = u^T X v``.

* ``T(mu) = X^{-1} B(mu)^T Vg`` (n x R): the supremizers (Riesz representers of
  ``b(mu; ., v_r)`` for each cone generator ``v_r``); ``S_R(mu) = span T(mu)``.
  ``V_N + S_R(mu)`` is the online-enriched space of ``beta_on(mu)``.
* ``sigma_S(mu) = ||(I - Pi_{V_N + S})|_{S_R(mu)}||_{L(V)}`` in ``[0, 1]``: how badly the
  offline space ``V_N + S`` misses the supremizers of ``mu``.
* :func:`pga` builds ``S`` greedily over a training set until ``max sigma_S <= delta``;
  ``V_off = V_N + S``, and :func:`theorem_lower_bound` is Benaceur et al.'s "Main result".
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.linalg.blas import dger as _dger

__all__ = [
    "PGAResult",
    "pga",
    "projection_defect",
    "supremizers",
    "riesz_lower_bound",
    "theorem_lower_bound",
    "x_orthonormalize",
]

#: Relative X-norm below which a direction counts as linearly dependent.
RANK_RTOL = 1e-12
#: ``sigma`` at or below this counts as 0 (S_R(mu) numerically inside V_N + S).
SIGMA_ZERO = 1e-10


def supremizers(B, X_solve: Callable[[np.ndarray], np.ndarray], Vg: np.ndarray) -> np.ndarray:
    """Supremizers ``T(mu) = X^{-1} B(mu)^T Vg`` (n x R).

    Column ``r`` is the X-Riesz representer of ``v -> b(mu; v, Vg[:, r]) = Vg[:, r]^T B v``,
    i.e. the maximiser of ``b(mu; v, eta) / ||v||_X`` for ``eta = Vg[:, r]``; for any
    ``eta = Vg y`` the supremizer is ``T y``. ``S_R(mu) = span T(mu)``.

    Parameters
    ----------
    B : (m, n) sparse or dense
    X_solve : callable
        Solves ``X y = rhs`` for ``rhs`` of shape (n, R) (e.g. ``splu(X).solve``, or
        :func:`rbbench.rb.algorithms.infsup.make_solver`).
    Vg : (m, R) ndarray
        Cone generators.
    """
    Vg = np.asarray(Vg, dtype=float)
    rhs = np.asfortranarray(B.T @ Vg, dtype=float)  # SuperLU's layout
    n = B.shape[1]
    return np.asarray(X_solve(rhs), dtype=float).reshape(n, Vg.shape[1])


def _xmul(X, V: np.ndarray) -> np.ndarray:
    return np.asarray(X @ V, dtype=float)


def x_orthonormalize(V: np.ndarray, X, U: np.ndarray | None = None,
                     XU: np.ndarray | None = None, *, rtol: float = RANK_RTOL,
                     ) -> tuple[np.ndarray, np.ndarray]:
    """X-orthonormal basis of ``(I - Pi_U) span(V)``, rank-revealing.

    Columns are scaled to unit X-norm and projected out of ``U`` (twice). If they are then
    well conditioned (smallest Gram eigenvalue ``>= 1e-8``) a blocked CholeskyQR2 is used.
    Otherwise: column-pivoted modified Gram-Schmidt in the X-inner product, every accepted
    vector re-orthogonalised once more against ``U`` and the previous ones ("twice is
    enough"); a direction is dropped when its residual X-norm, relative to the (unit) norm
    of its column, is ``<= rtol``. Residual norms are computed from the vectors themselves
    (not from a Gram matrix), so ``rtol = 1e-12`` is meaningful down to about
    ``eps * sqrt(cond X)``.

    Parameters
    ----------
    V : (n, k) ndarray
    X : (n, n) matrix (anything with ``X @ ndarray``)
    U, XU : (n, j) ndarray, optional
        An X-orthonormal basis to orthogonalise against, and ``X @ U`` (computed if absent).

    Returns
    -------
    Q, XQ : (n, r) ndarray
        ``Q^T X Q = I``, ``U^T X Q = 0`` (to rounding), ``XQ = X @ Q``; ``r <= k``.
    """
    V = np.array(V, dtype=float, order="F", copy=True)
    n = V.shape[0]
    if V.ndim != 2 or V.shape[1] == 0:
        return np.zeros((n, 0)), np.zeros((n, 0))
    if U is not None and U.shape[1] == 0:
        U = None
    if U is not None and XU is None:
        XU = _xmul(X, U)
    XV = np.asfortranarray(_xmul(X, V))
    norms = np.sqrt(np.clip(np.einsum("ij,ij->j", V, XV), 0.0, None))
    nz = norms > 0
    V, XV = np.asfortranarray(V[:, nz] / norms[nz]), np.asfortranarray(XV[:, nz] / norms[nz])
    k = V.shape[1]
    if k == 0:
        return np.zeros((n, 0)), np.zeros((n, 0))
    if U is not None:
        for _ in range(2):
            coef = XU.T @ V
            V -= U @ coef
            XV -= XU @ coef
    fast = _chol_qr2(V, XV, X)
    if fast is not None:
        return fast
    Q = np.zeros((n, k), order="F")
    XQ = np.zeros((n, k), order="F")
    r = 0
    active = np.ones(k, dtype=bool)
    while active.any():
        res2 = np.where(active, np.einsum("ij,ij->j", V, XV), -np.inf)
        j = int(np.argmax(res2))
        if res2[j] <= rtol**2:
            break
        active[j] = False
        q = V[:, j].copy()
        if U is not None:
            q -= U @ (XU.T @ q)
        if r:
            q -= Q[:, :r] @ (XQ[:, :r].T @ q)
        xq = _xmul(X, q)
        nq = float(np.sqrt(max(q @ xq, 0.0)))
        if nq <= rtol:
            continue
        Q[:, r] = q / nq
        XQ[:, r] = xq / nq
        coef = XQ[:, r] @ V
        V = _ger(-1.0, Q[:, r], coef, V)
        XV = _ger(-1.0, XQ[:, r], coef, XV)
        r += 1
    return Q[:, :r], XQ[:, :r]


def _chol_qr2(V: np.ndarray, XV: np.ndarray, X):
    """Blocked fast path of :func:`x_orthonormalize`: CholeskyQR2 in the X-inner product.

    Only used when the unit-norm columns are well conditioned (smallest Gram eigenvalue
    ``>= 1e-8``, i.e. ``cond <= 1e4``), where two Cholesky passes give X-orthonormality to
    rounding and no direction can fall below the rank threshold; returns None otherwise (the
    pivoted Gram-Schmidt then decides the rank). All BLAS-3, no per-column loop.
    """
    G = 0.5 * (V.T @ XV + XV.T @ V)
    if np.linalg.eigvalsh(G)[0] < 1e-8:
        return None
    L = np.linalg.cholesky(G)
    Q = np.asfortranarray(sla.solve_triangular(L, V.T, lower=True).T)
    XQ = np.asfortranarray(sla.solve_triangular(L, XV.T, lower=True).T)
    L2 = np.linalg.cholesky(0.5 * (Q.T @ XQ + XQ.T @ Q))
    Q = np.asfortranarray(sla.solve_triangular(L2, Q.T, lower=True).T)
    return Q, np.asfortranarray(_xmul(X, Q))


def _ger(alpha: float, x: np.ndarray, y: np.ndarray, A: np.ndarray) -> np.ndarray:
    """``A += alpha x y^T`` in place for a Fortran-ordered ``A`` (BLAS dger: 0.05-0.09 ms at
    (35k, 20) against 0.9 ms for a numpy broadcast update, which allocates)."""
    if A.flags.f_contiguous and A.dtype == np.float64:
        return _dger(alpha, x, y, a=A, overwrite_a=1)
    A += alpha * np.multiply.outer(x, y)
    return A


def _residual(Q: np.ndarray, U: np.ndarray, XU: np.ndarray) -> np.ndarray:
    """``(I - Pi_U) Q`` by classical Gram-Schmidt applied twice (U X-orthonormal)."""
    E = np.array(Q, dtype=float, order="F")
    if U.shape[1]:
        for _ in range(2):
            E -= U @ (XU.T @ E)
    return E


def _top_eig(G: np.ndarray) -> tuple[float, np.ndarray]:
    """Largest eigenvalue (clipped at 0) and its eigenvector of a symmetric matrix."""
    if G.size == 0:
        return 0.0, np.zeros(G.shape[0])
    w, V = np.linalg.eigh(0.5 * (G + G.T))
    return max(float(w[-1]), 0.0), V[:, -1]


def projection_defect(T: np.ndarray, Z: np.ndarray, S: np.ndarray | None, X, *,
                      rtol: float = RANK_RTOL) -> float:
    """``sigma_S(mu) = ||(I - Pi_{V_N + S})|_{S_R(mu)}||_{L(V)}`` for one ``mu``.

    The largest X-singular value of ``(I - Pi) Q`` with ``Q`` an X-orthonormal basis of
    ``S_R(mu) = span T``: the largest X-norm of the residual of a unit vector of
    ``S_R(mu)``. In ``[0, 1]``; 0 iff ``S_R(mu)`` is inside ``V_N + S``.

    Parameters
    ----------
    T : (n, R) ndarray
        Supremizers of ``mu`` (:func:`supremizers`).
    Z, S : (n, N), (n, K) ndarray
        Bases of ``V_N`` and ``S`` (any, need not be orthonormal; ``S`` may be None).
    X : (n, n) matrix
    """
    parts = [np.asarray(Z, dtype=float)] + ([np.asarray(S, dtype=float)] if S is not None else [])
    U, XU = x_orthonormalize(np.column_stack(parts), X, rtol=rtol)
    Q, _ = x_orthonormalize(T, X, rtol=rtol)
    if Q.shape[1] == 0:
        return 0.0
    E = _residual(Q, U, XU)
    return float(np.sqrt(_top_eig(E.T @ _xmul(X, E))[0]))


@dataclass
class PGAResult:
    """Output of :func:`pga`.

    Attributes
    ----------
    basis : (n, K) ndarray
        Basis of ``S = S_R^red``: X-orthonormal, and X-orthogonal to ``V_N``. The offline
        primal space is ``V_off = span([Z, basis])`` (``dim = N + K``).
    sigma_max : (K + 1,) ndarray
        ``sigma_max[i] = max_{mu in train} sigma_{S^i}(mu)`` with ``S^i`` the span of the
        first ``i`` basis vectors: the value before each addition (``i < K``) and the final
        one (``i = K``). Non-increasing (Benaceur et al., slide "Some details", "Monotonicity").
    picks : list of int
        ``picks[i]`` = index into ``T_list`` of the parameter whose supremizer residual gave
        basis vector ``i`` (``mu_{i+1}`` of Benaceur et al.).
    stop_reason : str
        ``"tolerance"`` (``sigma_max[-1] <= delta``), ``"exhausted"`` (``sigma_max[-1] <=
        sigma_zero``: ``V_N + S`` contains every training ``S_R(mu)``, the finite termination
        of Benaceur et al.), or ``"max_dim"`` (``K = max_dim``, tolerance not reached).
    sigma : (P,) ndarray
        Final ``sigma_S(mu)`` for every training parameter.
    """

    basis: np.ndarray
    sigma_max: np.ndarray
    picks: list[int]
    stop_reason: str
    sigma: np.ndarray = field(repr=False)

    @property
    def dim(self) -> int:
        """``K = dim S``."""
        return int(self.basis.shape[1])


def pga(T_list: Sequence[np.ndarray], Z: np.ndarray, X, delta: float,
        max_dim: int | None = None, *, rtol: float = RANK_RTOL,
        sigma_zero: float = SIGMA_ZERO) -> PGAResult:
    """Projected Greedy Algorithm (Benaceur et al., slide "Some details").

    ``S^0 = {}``; while ``e_n = max_mu sigma_{S^n}(mu) > delta``: pick
    ``mu_n = argmax_mu sigma_{S^n}(mu)``; ``v^(1)`` = the unit-X-norm element of
    ``S_R(mu_n)`` with the largest residual ``||(I - Pi_{V_N + S^n}) v||_X`` (top right
    X-singular vector of ``(I - Pi) Q_mu``); add ``v_n = (I - Pi_{V_N + S^n}) v^(1)``
    (X-normalised, re-orthogonalised) to ``S``.

    ``sigma_S(mu)`` is the largest X-singular value of ``E_mu = (I - Pi_{V_N + S}) Q_mu``,
    ``Q_mu`` an X-orthonormal basis of ``S_R(mu)`` (rank-revealing, :func:`x_orthonormalize`).
    ``E_mu`` and its Gram matrix ``G_mu = E_mu^T X E_mu`` are downdated after each addition
    ``s`` (``c = E_mu^T X s``; ``E -= s c^T``; ``G -= c c^T``): all ``E_mu`` live side by side
    in one (n, sum R_p) Fortran array (8 n sum R_p bytes, 117 MB for n = 35k, 21 x 20), so an
    iteration costs one GEMV and one rank-one update, no sparse product. ``G_mu`` is
    recomputed exactly (``X @ E_mu``) for the picked parameter and whenever its top eigenvalue
    fell by 1e4 since the last exact computation, so small ``sigma`` keep full relative
    accuracy. Parameters with ``sigma <= sigma_zero`` are frozen (``sigma`` only decreases).

    Parameters
    ----------
    T_list : sequence of (n, R_p) ndarray
        Supremizers ``T(mu_p)`` of the training parameters (:func:`supremizers`).
    Z : (n, N) ndarray
        Basis of ``V_N`` (any; X-orthonormalised internally, dependent columns dropped).
    X : (n, n) matrix
        Primal Gram matrix (sparse or dense).
    delta : float
        Tolerance ``delta_PGA`` on ``max sigma``. Benaceur et al. use ``sup_train beta_HF / c_HF``;
        the "Main result" condition holds on every training ``mu`` only for
        ``delta < min_train beta_on / c_HF``, while :func:`riesz_lower_bound` gives
        ``beta_off >= sqrt(1 - delta^2) beta_on > 0`` on the training set for any
        ``delta < 1``.
    max_dim : int, optional
        Maximum ``K = dim S`` (default: ``n - dim V_N``).
    rtol : float
        Rank threshold of :func:`x_orthonormalize` (bases of ``V_N`` and ``S_R(mu)``).
    sigma_zero : float
        ``sigma`` at or below it is zero (``"exhausted"``; no division by it).

    Returns
    -------
    PGAResult
    """
    Z = np.asarray(Z, dtype=float)
    if sp.issparse(X):
        X = sp.csr_matrix(X)
    Zo, XZo = x_orthonormalize(Z, X, rtol=rtol)
    if max_dim is None:
        max_dim = Z.shape[0] - Zo.shape[1]
    res = _Residuals(T_list, Zo, XZo, X, rtol=rtol, sigma_zero=sigma_zero)
    space = _Space(Zo, XZo, max_dim)
    history: list[float] = []
    picks: list[int] = []
    while True:
        if res.P == 0:
            history.append(0.0)
            reason = "exhausted"
            break
        p = res.pick()
        smax = float(np.sqrt(res.sig2[p]))
        history.append(smax)
        reason = _stop_reason(smax, delta, sigma_zero, space.dim >= max_dim)
        if reason:
            break
        v = _residual(res.direction(p)[:, None], space.U[:, :space.k],
                      space.XU[:, :space.k])[:, 0]
        xv = _xmul(X, v)
        nv = float(np.sqrt(max(v @ xv, 0.0)))
        if nv <= sigma_zero:  # pragma: no cover - guarded by smax > sigma_zero
            reason = "exhausted"
            break
        s, xs = space.append(v, xv, nv)
        picks.append(p)
        res.downdate(s, xs)
    return PGAResult(basis=space.basis(), sigma_max=np.array(history), picks=picks,
                     stop_reason=reason, sigma=np.sqrt(res.sig2))


def _stop_reason(smax: float, delta: float, sigma_zero: float, full: bool) -> str:
    """Why :func:`pga` stops at ``max sigma = smax`` (``""``: go on)."""
    if smax <= sigma_zero:
        return "exhausted"
    if smax <= delta:
        return "tolerance"
    if full:
        return "max_dim"
    return ""


class _Residuals:
    """The residuals ``E_mu = (I - Pi_{V_N + S}) Q_mu`` of :func:`pga` and their Gram matrices.

    All ``E_mu`` live side by side in one Fortran-ordered array ``E_all`` (``E[p]`` are
    views), downdated by one BLAS rank-one update per added basis vector; ``G[p]`` is
    downdated alongside and recomputed exactly when needed (see :func:`pga`).
    """

    def __init__(self, T_list: Sequence[np.ndarray], Zo: np.ndarray, XZo: np.ndarray, X, *,
                 rtol: float, sigma_zero: float) -> None:
        self.X = X
        self.sigma_zero = sigma_zero
        Qs = [x_orthonormalize(np.asarray(T, dtype=float), X, rtol=rtol)[0] for T in T_list]
        self.P = len(Qs)
        self.bounds = np.cumsum([0] + [Q.shape[1] for Q in Qs])
        self.E_all = np.zeros((Zo.shape[0], self.bounds[-1]), order="F")
        for p, Q in enumerate(Qs):
            self.E_all[:, self.bounds[p]:self.bounds[p + 1]] = _residual(Q, Zo, XZo)
        del Qs
        self.E = [self.E_all[:, self.bounds[p]:self.bounds[p + 1]]
                  for p in range(self.P)]  # views
        self.G = [Ep.T @ _xmul(X, Ep) for Ep in self.E]
        self.sig2 = np.array([_top_eig(g)[0] for g in self.G])
        self.ref = self.sig2.copy()  # top eigenvalue at the last exact computation of G
        self.frozen = self.sig2 <= sigma_zero**2

    def refresh(self, p: int) -> None:
        """Recompute ``G[p]`` exactly from ``E[p]``."""
        self.G[p] = self.E[p].T @ _xmul(self.X, self.E[p])
        self.sig2[p] = self.ref[p] = _top_eig(self.G[p])[0]
        self.frozen[p] = self.sig2[p] <= self.sigma_zero**2

    def pick(self) -> int:
        """``argmax_p sigma(mu_p)``, taken on an exactly recomputed ``G`` (downdates are only
        screening)."""
        p, exact = int(np.argmax(self.sig2)), set()
        while not self.frozen[p] and p not in exact:
            self.refresh(p)
            exact.add(p)
            p = int(np.argmax(self.sig2))
        return p

    def direction(self, p: int) -> np.ndarray:
        """``E[p] c``, ``c`` the top eigenvector of ``G[p]`` (before orthogonalisation)."""
        _, c = _top_eig(self.G[p])
        return self.E[p] @ c

    def downdate(self, s: np.ndarray, xs: np.ndarray) -> None:
        """Project the new X-unit basis vector ``s`` (``xs = X s``) out of every residual."""
        coef_all = xs @ self.E_all
        self.E_all = _ger(-1.0, s, coef_all, self.E_all)  # in place: the views E[q] follow
        for q in range(self.P):
            if self.frozen[q] or self.E[q].shape[1] == 0:
                continue
            coef = coef_all[self.bounds[q]:self.bounds[q + 1]]
            self.G[q] -= np.outer(coef, coef)
            self.sig2[q] = _top_eig(self.G[q])[0]
            if self.sig2[q] < 1e-4 * self.ref[q]:
                self.refresh(q)


class _Space:
    """``U = [Zo, S basis]`` and ``X U`` of :func:`pga`, in Fortran-ordered buffers grown by
    doubling; ``k`` columns are in use."""

    def __init__(self, Zo: np.ndarray, XZo: np.ndarray, max_dim: int) -> None:
        n, self.n0 = Zo.shape
        cap = self.n0 + min(max_dim, 32)
        self.U = np.zeros((n, cap), order="F")
        self.XU = np.zeros((n, cap), order="F")
        self.U[:, :self.n0], self.XU[:, :self.n0] = Zo, XZo
        self.k = self.n0

    @property
    def dim(self) -> int:
        """``K = dim S`` so far."""
        return self.k - self.n0

    def append(self, v: np.ndarray, xv: np.ndarray, nv: float) -> tuple[np.ndarray, np.ndarray]:
        """Add ``v / nv`` (``xv = X v``); return the stored column and its ``X`` image."""
        if self.k == self.U.shape[1]:
            self.U = np.asfortranarray(np.hstack([self.U, np.zeros_like(self.U)]))
            self.XU = np.asfortranarray(np.hstack([self.XU, np.zeros_like(self.XU)]))
        self.U[:, self.k], self.XU[:, self.k] = v / nv, xv / nv
        s, xs = self.U[:, self.k], self.XU[:, self.k]
        self.k += 1
        return s, xs

    def basis(self) -> np.ndarray:
        """A copy of the basis of ``S``."""
        return np.array(self.U[:, self.n0:self.k])


def theorem_lower_bound(beta_on, c_hf, sigma):
    """``beta*_S(mu) = (beta_on - c_HF sigma_S) / (1 + sigma_S)`` (Benaceur et al., slide
    "Main result").

    If ``sigma_S(mu) < beta_on(mu) / c_HF(mu)`` then ``beta_off(mu) >= beta*_S(mu) > 0``,
    where ``beta_off`` is the inf-sup over ``W_R^+`` (cone, or its span: the proof works for
    any multiplier set inside ``span Vg``) and ``V_N + S``, ``beta_on`` the same over
    ``V_N + S_R(mu)`` (:mod:`rbbench.rb.algorithms.infsup`), and ``c_HF`` a continuity constant of
    ``b(mu)`` on ``V x span(Vg)`` (:func:`rbbench.rb.algorithms.infsup.boundedness_constant`; the HF
    constant on ``V x W`` is larger, hence also valid). Outside that condition the value is
    ``<= 0`` and guarantees nothing. Works elementwise on arrays. :func:`riesz_lower_bound`
    is sharper and needs no condition.
    """
    beta_on, c_hf, sigma = (np.asarray(a, dtype=float) for a in (beta_on, c_hf, sigma))
    out = (beta_on - c_hf * sigma) / (1.0 + sigma)
    return float(out) if out.ndim == 0 else out


def riesz_lower_bound(beta_on, sigma):
    """Sharper bound ``beta_off(mu) >= sqrt(1 - sigma_S(mu)^2) beta_on(mu)`` (no ``c_HF``).

    Not in Benaceur et al.'s talk; follows from the X-Riesz structure of ``b``. For
    ``eta = Vg y`` let
    ``s = T(mu) y = X^{-1} B^T eta``, the supremizer, which lies in ``S_R(mu)``. Then
    ``b(v, eta) = (s, v)_X``, so ``sup_{v in Y} b(v, eta) / ||v||_X = ||Pi_Y s||_X`` for any
    ``Y``; ``beta_on`` uses ``Y = V_N + S_R(mu)`` (``Pi_Y s = s``) and ``beta_off`` uses
    ``Y = V_N + S``, where ``||Pi_Y s||^2 = ||s||^2 - ||(I - Pi_Y) s||^2 >=
    (1 - sigma_S^2) ||s||^2``. Dividing by ``||eta||_W`` and taking the inf over any set of
    multipliers (cone or span, the same on both sides) gives the bound. It dominates
    :func:`theorem_lower_bound` (since ``c_HF >= beta_on``) and is positive whenever
    ``sigma_S(mu) < 1``. Works elementwise on arrays.
    """
    beta_on, sigma = (np.asarray(a, dtype=float) for a in (beta_on, sigma))
    out = np.sqrt(np.clip(1.0 - sigma**2, 0.0, None)) * beta_on
    return float(out) if out.ndim == 0 else out

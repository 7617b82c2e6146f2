"""A posteriori error bounds of reduced saddle-point variational inequalities.

Setting (Haasdonk, Salomon & Wohlmuth, "A reduced basis method for parametrized variational
inequalities", SIAM J. Numer. Anal. 50 (2012) 2656-2676, the a posteriori analysis of their
Section 4), algebraically on the free dofs: the HF solution ``(u, lam)`` of::

    A u + B^T lam = F,   lam in M = {lam >= 0},   (eta - lam)^T B u <= (eta - lam)^T G  (eta in M)

and any reduced pair ``u_N``, ``lam_N in M`` (a non-negative combination of non-negative
multiplier snapshots: the reduced cone lies in M). Residuals::

    r_u = F - A u_N - B^T lam_N  (in X'),     d = B u_N - G  (the constraint residual)

Norms: ``||.||_X`` the scene's inner product ``X``; on multipliers the *natural* norm of
``b``, ``||eta||_* = ||B^T eta||_{X'} = sup_v eta^T B v / ||v||_X`` (a norm when ``B^T`` is
injective, the HF inf-sup condition), whose dual norm is ``||d||_*' = (d^T D^{-1} d)^(1/2)``,
``D = B X^{-1} B^T``. In this norm the inf-sup and continuity constants of ``b`` are both 1,
so no inf-sup constant enters (the HF inf-sup in another multiplier norm, ``beta_W``, only
converts ``Delta_lam`` into that norm: ``||e_lam||_W <= Delta_lam / beta_W``).

**Theorem** (HSW's bound, re-derived in the natural multiplier norm, with one
Cauchy-Schwarz step left out). Let ``alpha_LB <= inf_v v^T A v / ||v||_X^2`` and ``gamma_UB
>= sup_{v,w} w^T A v / (||w||_X ||v||_X)``, and::

    rho   = ||r_u||_X'                                   (1) primal residual
    sigma = ||[d]_+||_*'                                 (2) violated part of the constraint
    kappa = lam_N^T [G - B u_N]_+  (>= 0)                (3) complementarity defect
    l_N   = ||lam_N||_* = ||B^T lam_N||_X'               (4) (reported; not in (5))

Then ``||u - u_N||_X <= Delta_u = delta_1 + (delta_1^2 + delta_2)^(1/2)`` with::

    delta_1 = (rho + gamma_UB sigma) / (2 alpha_LB),
    delta_2 = (sigma rho + kappa) / alpha_LB                                  (5)

and ``||lam - lam_N||_* <= Delta_lam = rho + gamma_UB Delta_u``                (6).

*Proof.* With ``e = u - u_N``, ``e_lam = lam - lam_N``: ``A e + B^T e_lam = r_u``, so
``e^T A e = r_u(e) - e_lam^T B e``. The HF inequality at ``eta = lam_N in M`` gives
``-e_lam^T B u <= -e_lam^T G``, hence ``-e_lam^T B e <= lam^T d - lam_N^T d``. As ``lam >=
0``, ``lam^T d <= lam^T [d]_+ = lam_N^T [d]_+ + e_lam^T [d]_+ <= lam_N^T [d]_+ +
||e_lam||_* sigma``, and ``lam_N^T ([d]_+ - d) = kappa``. Further ``||e_lam||_* = ||r_u - A
e||_X' <= rho + gamma_UB ||e||_X`` (6), so ``alpha_LB ||e||^2 <= rho ||e|| + sigma (rho +
gamma_UB ||e||) + kappa``: a quadratic inequality whose larger root is (5). HSW bound
``lam^T [d]_+ <= ||lam|| sigma`` instead, which gives ``sigma (l_N + rho) + max(0,
lam_N^T (G - B u_N))`` in place of ``sigma rho + kappa``: an upper bound of it (``lam_N^T
[d]_+ <= l_N sigma``), so (5) is never larger. When ``u_N = u`` and ``lam_N = lam``:
``rho = sigma = 0`` and ``kappa = 0`` (complementarity), so ``Delta_u = 0``. ``[d]_+`` may
be replaced by any ``d - p`` with ``p <= 0`` (the polar cone of M): the positive part is the
simplest such choice, not the smallest dual norm (a QP), so (2) is an upper bound of HSW's
projected residual.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

__all__ = ["BoundTerms", "VIBound", "coercivity_constants", "delassus", "hf_bound_terms",
           "lanczos_start",
           "natural_dual", "riesz_factor", "vi_bound"]

#: Relative safety margin on the computed extreme eigenvalues of ``(A, X)`` (Lanczos /
#: dense eigensolvers resolve them to round-off, far below this)
EIG_MARGIN = 1e-8


@dataclass
class BoundTerms:
    """The computable pieces (1)-(4) of the bound (module docstring)."""

    rho: float  # ||r_u||_X'
    sigma: float  # ||[B u_N - G]_+||_*'
    kappa: float  # lam_N . [G - B u_N]_+
    lam_norm: float  # ||B^T lam_N||_X'


@dataclass
class VIBound:
    """``Delta_u`` (5), ``Delta_lam`` (6, natural norm) and the terms and constants used."""

    delta_u: float
    delta_lam: float
    terms: BoundTerms
    alpha: float
    gamma: float


def lanczos_start(n: int) -> np.ndarray:
    """A fixed start vector for ARPACK's Lanczos (``eigsh(..., v0=)``): seeded normal
    draws. Without one ARPACK draws its own, so two runs may differ, and on a small pencil
    an unlucky draw stops it ("No shifts could be applied", error 3)."""
    return np.random.default_rng(0).standard_normal(n)


def vi_bound(terms: BoundTerms, alpha: float, gamma: float) -> VIBound:
    """The bound (5)-(6) from its terms, a coercivity lower bound ``alpha`` and a continuity
    upper bound ``gamma`` of ``a`` in X (module docstring's theorem)."""
    if not alpha > 0:
        raise ValueError(f"coercivity lower bound alpha = {alpha}: must be > 0")
    t = terms
    d1 = (t.rho + gamma * t.sigma) / (2.0 * alpha)
    d2 = (t.sigma * t.rho + t.kappa) / alpha
    du = float(d1 + math.sqrt(d1 * d1 + d2))
    return VIBound(du, t.rho + gamma * du, terms, alpha, gamma)


def coercivity_constants(A: Any, X: Any) -> tuple[float, float]:
    """``(alpha, gamma)``: the smallest and the largest generalised eigenvalue of the
    symmetric pencil ``(A, X)`` (coercivity and continuity constants of ``a`` in X), with a
    relative margin :data:`EIG_MARGIN` towards safety (alpha down, gamma up).

    Exact for a mu-independent ``A`` (shift-invert Lanczos at 0 for alpha, Lanczos for gamma;
    dense below 400 dofs)."""
    n = A.shape[0]
    if n < 400:
        Ad = A.toarray() if sp.issparse(A) else np.asarray(A)
        Xd = X.toarray() if sp.issparse(X) else np.asarray(X)
        w = sla.eigh(0.5 * (Ad + Ad.T), Xd, eigvals_only=True)
        lo, hi = float(w[0]), float(w[-1])
    else:
        lo = float(spla.eigsh(A, k=1, M=X, sigma=0.0, which="LM", v0=lanczos_start(n),
                              return_eigenvectors=False)[0])
        hi = float(spla.eigsh(A, k=1, M=X, which="LA", v0=lanczos_start(n),
                              return_eigenvectors=False)[0])
    return lo * (1.0 - EIG_MARGIN), hi * (1.0 + EIG_MARGIN)


def natural_dual(B: Any, x_solve: Callable[[np.ndarray], np.ndarray]
                 ) -> Callable[[np.ndarray], float]:
    """``d -> ||d||_*' = (d^T D^{-1} d)^(1/2)``, ``D = B X^{-1} B^T`` (m solves with X, a
    dense Cholesky of D). A ValueError when D is not positive definite (``B^T`` not
    injective: the natural norm is no norm, the HF inf-sup fails)."""
    D = delassus(B, x_solve)
    try:
        cho = sla.cho_factor(D, lower=True)
    except np.linalg.LinAlgError:
        raise ValueError("B X^-1 B^T is not positive definite: B^T is not injective (the HF "
                         "inf-sup condition fails), the natural multiplier norm is no norm"
                         ) from None

    def dual_norm(d: np.ndarray) -> float:
        y = sla.solve_triangular(cho[0], d, lower=True)
        return float(np.linalg.norm(y))

    return dual_norm


def delassus(B: Any, x_solve: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """``D = B X^{-1} B^T`` (m x m dense, symmetrised): m solves with X, B kept sparse."""
    Bt = B.T.toarray() if sp.issparse(B) else np.asarray(B, dtype=float).T
    Y = np.asarray(x_solve(np.asfortranarray(Bt)), dtype=float).reshape(Bt.shape)
    D = np.asarray(B @ Y)
    return 0.5 * (D + D.T)


def hf_bound_terms(A: Any, F: np.ndarray, B: Any, G: np.ndarray,
                   x_solve: Callable[[np.ndarray], np.ndarray],
                   dual_norm: Callable[[np.ndarray], float], u_N: np.ndarray,
                   lam_N: np.ndarray) -> BoundTerms:
    """The terms (1)-(4) evaluated with the HF operators (the reference of the offline-online
    evaluation; rigorous whatever produced ``u_N``, ``lam_N >= 0``)."""
    if lam_N.size and lam_N.min() < 0:
        raise ValueError(f"lam_N has a negative entry ({lam_N.min():.3g}): the bound needs "
                         "lam_N in the multiplier cone M")
    Btl = B.T @ lam_N
    r = F - A @ u_N - Btl
    d = B @ u_N - G
    return BoundTerms(rho=_xdual(r, x_solve), sigma=dual_norm(np.maximum(d, 0.0)),
                      kappa=float(lam_N @ np.maximum(-d, 0.0)), lam_norm=_xdual(Btl, x_solve))


def _xdual(r: np.ndarray, x_solve: Callable[[np.ndarray], np.ndarray]) -> float:
    return float(np.sqrt(max(float(r @ np.asarray(x_solve(r)).ravel()), 0.0)))


def riesz_factor(pieces: np.ndarray, X: Any, x_solve: Callable[[np.ndarray], np.ndarray],
                 rtol: float = 1e-13, return_ranks: bool = False, block: int = 64
                 ) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """``T`` (k x q) with ``||pieces @ w||_X' = ||T w||_2`` for every ``w``: the Riesz
    representers ``X^{-1} pieces`` orthonormalised in X (Gram-Schmidt, twice), ``T`` their
    coordinates. Unlike the Gram form ``w^T G w`` this does not square the residual, so a
    residual 1e-8 of the load is still resolved (Buhr, Engwer, Ohlberger & Rave 2014).
    Directions below ``rtol`` of the largest are dropped (dependent pieces).

    By blocks of ``block`` pieces: each block projected twice against the directions of the
    blocks before it (matrix products), then column by column (twice) within the block
    (``block = 1``: column by column throughout).

    ``return_ranks``: also, per piece, the rows of ``T`` its column needs: the number of
    directions after it when it added one (``T[i, j]`` is round-off below: ``T`` is upper
    trapezoidal), all ``k`` when it was dropped (its remainder below ``rtol``, not zero,
    has components on later directions, which a large coefficient can make matter)."""
    V = np.asarray(x_solve(np.asfortranarray(pieces)), dtype=float).reshape(pieces.shape)
    n, q = V.shape
    Q, XQ = np.zeros_like(V), np.zeros_like(V)  # the directions and X times them
    ranks = np.zeros(q, dtype=np.int64)
    k = 0
    scale = 0.0
    for j0 in range(0, q, max(1, int(block))):
        Vb = V[:, j0:j0 + max(1, int(block))]
        W = Vb.copy()
        for _ in range(2):
            if k:
                W -= Q[:, :k] @ (XQ[:, :k].T @ W)
        XVb = np.asarray(X @ Vb)
        k0 = k
        for jj in range(W.shape[1]):
            scale = max(scale, float(np.sqrt(max(Vb[:, jj] @ XVb[:, jj], 0.0))))
            v = W[:, jj].copy()
            for _ in range(2):
                if k > k0:
                    v -= Q[:, k0:k] @ (XQ[:, k0:k].T @ v)
            Xv = np.asarray(X @ v).ravel()
            nv = float(np.sqrt(max(v @ Xv, 0.0)))
            if nv > rtol * max(scale, np.finfo(float).tiny) and nv > 0:
                Q[:, k], XQ[:, k] = v / nv, Xv / nv
                k += 1
                ranks[j0 + jj] = k
            else:
                ranks[j0 + jj] = -1
    ranks[ranks < 0] = k
    T = XQ[:, :k].T @ V
    return (T, ranks) if return_ranks else T

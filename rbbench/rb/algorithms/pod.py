"""Primal compressors: POD and the (ideal / weak) greedy algorithm.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slides "Method 1: Proper Orthogonal Decomposition" and
"Method 2: (Ideal) Greedy algorithms" / "Quasi-optimality of greedy algorithms" (DeVore,
Petrova, Wojtaszczyk). Both return an X-orthonormal basis ``Z`` (``Z^T X Z = I``) of the span
of selected snapshots, with ``X`` the V inner product matrix.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

__all__ = ["GreedyResult", "PODResult", "gram_schmidt_add", "pod", "projection_errors",
           "weak_greedy"]

#: Eigenvalues of the correlation matrix below this fraction of the largest are dropped.
EIG_DROP = 1e-12


def _matvec(X, V: np.ndarray) -> np.ndarray:
    return X @ V if X is not None else V


def _xnorms(X, V: np.ndarray) -> np.ndarray:
    return np.sqrt(np.maximum(np.einsum("ij,ij->j", V, _matvec(X, V)), 0.0))


@dataclass
class PODResult:
    """Output of :func:`pod`.

    Attributes
    ----------
    Z : (n, N)
        X-orthonormal POD modes (``Z^T X Z = I``).
    s : (r,)
        Singular values (decreasing) of all ``r`` kept modes (eigenvalues of the
        correlation matrix above ``EIG_DROP`` relative).
    N : int
        Selected size.
    total_energy : float
        ``sum_p ||u_p||_X^2`` (the trace of the correlation matrix).
    tail : (r + 1,)
        ``tail[k] = sum_{j > k} s_j^2 / total_energy``: the relative squared
        projection error of the snapshot set onto the first ``k`` modes.
    modes : (n, r)
        All kept modes (``Z = modes[:, :N]``).
    """

    Z: np.ndarray
    s: np.ndarray
    N: int
    total_energy: float
    tail: np.ndarray
    modes: np.ndarray
    tol: float | None = None

    @property
    def rank(self) -> int:
        return int(self.s.size)


def pod(U: np.ndarray, X=None, tol: float | None = None, n: int | None = None) -> PODResult:
    """POD of the snapshot columns ``U`` in the X inner product (method of snapshots).

    Parameters
    ----------
    U : (n, P)
        Snapshots.
    X : (n, n) sparse or dense SPD, optional
        Inner product matrix (identity if None).
    tol : float, optional
        Energy tolerance: ``N`` is the smallest integer with
        ``sum_{k > N} s_k^2 <= tol^2 sum_k s_k^2``, i.e. the relative X-norm
        projection error of the snapshot matrix (Frobenius sense) is at most ``tol``.
    n : int, optional
        Cap on ``N``. Without ``tol`` and ``n``, ``N`` is the numerical rank.

    Notes
    -----
    The correlation matrix ``C = U^T X U`` (P x P) is diagonalised (``eigh``);
    eigenvalues below ``EIG_DROP * lambda_max`` are dropped (their modes are noise).
    ``Z = U V S^{-1}`` is then re-orthonormalised in X and the singular values
    refined by an SVD of the small matrix ``Z^T X U``, which keeps
    ``Z^T X Z = I`` to machine precision even for the small modes.
    """
    U = np.asarray(U, dtype=float)
    if U.ndim != 2:
        raise ValueError(f"U must be 2-D (n x P), got shape {U.shape}")
    XU = _matvec(X, U)
    C = U.T @ XU
    C = 0.5 * (C + C.T)
    total = float(np.trace(C))
    if U.shape[1] == 0 or total <= 0.0:
        empty = np.zeros((U.shape[0], 0))
        return PODResult(empty, np.zeros(0), 0, max(total, 0.0), np.zeros(1), empty, tol)
    lam, V = np.linalg.eigh(C)
    order = np.argsort(lam)[::-1]
    lam, V = lam[order], V[:, order]
    keep = lam > EIG_DROP * lam[0]
    lam, V = lam[keep], V[:, keep]
    Z = U @ (V / np.sqrt(lam))
    Z = _orthonormalise(Z, X)
    # refine: U ~ Z (Z^T X U); the SVD of the small factor rotates Z onto the POD modes
    Wm, s, _ = np.linalg.svd(Z.T @ XU, full_matrices=False)
    Z = Z @ Wm
    beyond = max(total - float(np.sum(s**2)), 0.0)  # energy of the dropped modes
    tail = (np.concatenate((np.cumsum((s**2)[::-1])[::-1], [0.0])) + beyond) / total
    r = s.size
    N = r
    if tol is not None:
        N = int(np.argmax(tail <= tol**2)) if np.any(tail <= tol**2) else r
    if n is not None:
        N = min(N, int(n))
    return PODResult(Z[:, :N].copy(), s, N, total, tail, Z, tol)


def _orthonormalise(Z: np.ndarray, X) -> np.ndarray:
    """X-orthonormalise the columns of ``Z`` (Cholesky QR, two passes)."""
    for _ in range(2):
        G = Z.T @ _matvec(X, Z)
        R = np.linalg.cholesky(0.5 * (G + G.T)).T
        Z = sla.solve_triangular(R, Z.T, trans="T", lower=False).T
    return Z


def gram_schmidt_add(Z: np.ndarray, v: np.ndarray, X=None,
                     drop: float = 1e-12) -> tuple[np.ndarray, float]:
    """Append ``v`` to the X-orthonormal ``Z`` by Gram-Schmidt with one reorthogonalisation.

    Returns the new basis and the X-norm of ``v`` minus its projection (relative to
    ``||v||_X``); when that is below ``drop``, ``Z`` is returned unchanged.
    """
    v = np.asarray(v, dtype=float).copy()
    nv = float(np.sqrt(max(v @ _matvec(X, v), 0.0)))
    if nv == 0.0:
        return Z, 0.0
    for _ in range(2):  # "twice is enough" (Kahan, Parlett)
        if Z.shape[1]:
            v -= Z @ (Z.T @ _matvec(X, v))
    nr = float(np.sqrt(max(v @ _matvec(X, v), 0.0)))
    if nr <= drop * nv:
        return Z, nr / nv
    return np.column_stack([Z, v / nr]), nr / nv


def projection_errors(U: np.ndarray, Z: np.ndarray, X=None) -> np.ndarray:
    """``||u_p - Pi_Z u_p||_X`` for each column (``Z`` X-orthonormal)."""
    R = U - Z @ (Z.T @ _matvec(X, U)) if Z.shape[1] else U
    return _xnorms(X, R)


@dataclass
class GreedyResult:
    """Output of :func:`weak_greedy`.

    Attributes
    ----------
    Z : (n, N)
        X-orthonormal basis; ``Z[:, k]`` comes from snapshot ``picks[k]``.
    picks : list of int
        Selected snapshot columns, in order.
    sigma : (N + 1,)
        ``sigma[k]`` is the largest error (true or indicated) over the training set
        with the first ``k`` basis vectors: ``sigma[0] = max_p ||u_p||_X`` for the ideal
        greedy, and each entry is the max *before* adding ``Z[:, k]``. (Benaceur et
        al.'s ``sigma_N`` is our ``sigma[N - 1]``.)
    d_pod : (r + 1,)
        Proxy for the Kolmogorov width of the *training set*: ``d_pod[k] = max_p
        ||u_p - Pi_{POD_k} u_p||_X``, an upper bound of the training-set width ``d_k``.
    dpw_bound : (r + 1,)
        DeVore-Petrova-Wojtaszczyk check value ``sqrt(2 sigma[0] d_pod[k])``, to compare
        with ``sigma[2k]``. The theorem (ideal greedy, set in the unit ball) reads
        ``sigma_{2k} <= sqrt(2 d_k)``; scaling the set by ``1 / sigma[0]`` gives this
        form. Only a proxy: ``d_pod`` is computed on the training snapshots.
    """

    Z: np.ndarray
    picks: list[int]
    sigma: np.ndarray
    d_pod: np.ndarray
    dpw_bound: np.ndarray
    tol: float
    ideal: bool

    @property
    def N(self) -> int:
        return int(self.Z.shape[1])


def weak_greedy(U: np.ndarray, X=None,
                indicator: Callable[[np.ndarray, int], float] | None = None,
                tol: float = 1e-8, n_max: int | None = None) -> GreedyResult:
    """Greedy selection of snapshots (Benaceur et al., "Method 2: (Ideal) Greedy algorithms").

    Parameters
    ----------
    U : (n, P)
        Training snapshots.
    X : sparse or dense (n, n), optional
        Inner product (identity if None).
    indicator : callable ``(basis, index) -> float``, optional
        Error indicator of snapshot ``index`` for the current X-orthonormal basis
        (n x k). None: the true projection error ``||u - Pi u||_X`` (ideal greedy on the
        snapshot set; then ``sigma`` is non-increasing, a theorem).
    tol : float
        Stop when ``sigma[k] <= tol * sigma[0]`` (relative to the largest initial error).
    n_max : int, optional
        Largest basis size (default ``P``).

    Returns
    -------
    GreedyResult
        The basis is built by Gram-Schmidt with reorthogonalisation; the greedy also stops
        when the chosen snapshot already lies in the span (numerically).
    """
    U = np.asarray(U, dtype=float)
    n, P = U.shape
    n_max = P if n_max is None else min(int(n_max), P)
    ideal = indicator is None
    Z = np.zeros((n, 0))
    picks: list[int] = []
    sigma: list[float] = []
    if ideal:
        R = U.copy()
        XR = np.asarray(_matvec(X, R))  # sparse @ ndarray is an ndarray
    while True:
        if ideal:
            err = np.sqrt(np.maximum(np.einsum("ij,ij->j", R, XR), 0.0))
        else:
            err = np.array([-np.inf if i in picks else float(indicator(Z, i))  # type: ignore[misc]
                            for i in range(P)])
        i = int(np.argmax(err))
        sigma.append(float(err[i]))
        if Z.shape[1] >= n_max or sigma[-1] <= tol * sigma[0] or not np.isfinite(err[i]):
            break
        Znew, rel = gram_schmidt_add(Z, U[:, i], X)
        if Znew.shape[1] == Z.shape[1]:  # the pick is already in the span
            break
        Z = Znew
        picks.append(i)
        if ideal:
            z = Z[:, -1]
            Xz = _matvec(X, z)
            c = Xz @ R
            R -= np.outer(z, c)
            XR -= np.outer(Xz, c)
    sig = np.asarray(sigma)
    d_pod = _pod_width_proxy(U, X)
    dpw = np.sqrt(2.0 * (sig[0] if sig.size else 0.0) * d_pod)
    return GreedyResult(Z, picks, sig, d_pod, dpw, tol, ideal)


def _pod_width_proxy(U: np.ndarray, X) -> np.ndarray:
    """``max_p ||u_p - Pi_{POD_k} u_p||_X`` for ``k = 0 .. rank``, without cancellation:
    the squared error is the tail sum of the squared POD coefficients plus the residual
    beyond the kept modes."""
    if U.shape[1] == 0:
        return np.zeros(1)
    pr = pod(U, X)
    C = pr.modes.T @ _matvec(X, U)  # (r, P) coefficients
    beyond = projection_errors(U, pr.modes, X) ** 2
    tails = np.cumsum((C**2)[::-1], axis=0)[::-1]  # tails[k] = sum_{j >= k} C_j^2
    sq = np.vstack([tails, np.zeros((1, U.shape[1]))]) + beyond
    return np.sqrt(sq.max(axis=1))

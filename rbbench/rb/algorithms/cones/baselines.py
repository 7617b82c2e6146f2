"""Baseline dual compressors: POD of the multipliers (a span, not a cone) and NNMF.

Setting and error measures: :mod:`rbbench.rb.algorithms.cones`; both return a
:class:`rbbench.rb.algorithms.cones.greedy.DualBasis`.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from rbbench.rb.algorithms.cones.greedy import DualBasis, _check_snapshots
from rbbench.rb.algorithms.cones.metric import WMetric, as_metric, cone_gram, cone_projection

__all__ = ["nnmf", "nnmf_compressor", "pod_dual"]


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


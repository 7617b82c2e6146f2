"""Lemke's complementary pivoting for the 2D collocated Coulomb problem (an exact fallback).

Conventions of :mod:`rbbench.hf.algebra.friction` (``w = q + D x``, slip ``v = -w_t``,
``lam_t = +F lam_n sign(v)``). With ``lam_t = b1 - b2`` and a slip magnitude ``sigma``
(Stewart-Trinkle 1996, written for the quasi-static step; Klarbring 1986) the problem is
the LCP ``W = M z + r >= 0``, ``z = (lam_n, b1, b2, sigma) >= 0``, ``z . W = 0``::

    W_n     = q_n + D_nn lam_n + D_nt (b1 - b2)       (gap)
    W_b1    = sigma - v                              (b1 > 0 => v = sigma >= 0)
    W_b2    = sigma + v                              (b2 > 0 => v = -sigma <= 0)
    W_sigma = F lam_n - b1 - b2                      (sigma > 0 => on the wedge)

``M`` is copositive (``z^T M z = x^T D x + sigma F lam_n >= 0`` for ``z >= 0``)
but not copositive-plus, so Lemke's method (Cottle-Pang-Stone, 1992, section 4.4) is not
guaranteed to avoid a secondary ray; it ends either with a solution or with that ray,
reported as ``"stagnation"``.
"""

from __future__ import annotations

import numpy as np

from rbbench.hf.algebra.friction import (
    FrictionResult,
    check_problem,
    delassus_scale,
    finish,
    node_array,
)


def coulomb_lcp(D: np.ndarray, q: np.ndarray, F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The LCP data ``(M, r)`` of the module docstring (size ``4m``; unscaled: dividing the
    ``W_sigma`` rows by ``F`` made Lemke reach secondary rays more often)."""
    m = F.size
    Dnn, Dnt, Dtn, Dtt = D[:m, :m], D[:m, m:], D[m:, :m], D[m:, m:]
    Z, eye = np.zeros((m, m)), np.eye(m)
    M = np.block([[Dnn, Dnt, -Dnt, Z],
                  [Dtn, Dtt, -Dtt, eye],
                  [-Dtn, -Dtt, Dtt, eye],
                  [np.diag(F), -eye, -eye, Z]])
    r = np.concatenate([q[:m], q[m:], -q[m:], np.zeros(m)])
    return M, r


def lemke(M: np.ndarray, r: np.ndarray, max_pivots: int | None = None,
          piv_tol: float = 1e-12) -> tuple[np.ndarray | None, int, str]:
    """Lemke's method with covering vector ``e`` on LCP(r, M).

    Returns ``(z, pivots, status)`` with status ``"solution"``, ``"ray"`` (secondary ray)
    or ``"max_pivots"``; ``z`` is ``None`` unless a solution was found.
    """
    n = r.size
    if n == 0 or r.min() >= 0:
        return np.zeros(n), 0, "solution"
    max_pivots = max_pivots or 50 * n
    T = np.hstack([np.eye(n), -M, -np.ones((n, 1)), r[:, None]]).astype(float)
    basis = np.arange(n)
    entering, row = 2 * n, int(np.argmin(r))
    for pivots in range(1, max_pivots + 1):
        T[row] /= T[row, entering]
        col = T[:, entering].copy()
        col[row] = 0.0
        T -= np.outer(col, T[row])
        leaving, basis[row] = basis[row], entering
        if leaving == 2 * n:
            z = np.zeros(n)
            isz = (basis >= n) & (basis < 2 * n)
            z[basis[isz] - n] = T[isz, -1]
            return z, pivots, "solution"
        entering = leaving + n if leaving < n else leaving - n
        col = T[:, entering]
        ok = col > piv_tol
        if not ok.any():
            return None, pivots, "ray"
        ratios = np.where(ok, T[:, -1] / np.where(ok, col, 1.0), np.inf)
        best = ratios.min()
        ties = np.flatnonzero(ratios <= best + 1e-12 * max(1.0, abs(best)))
        z0_row = np.flatnonzero(basis[ties] == 2 * n)
        row = int(ties[z0_row[0]]) if z0_row.size else int(ties[0])
    return None, max_pivots, "max_pivots"


def coulomb_lemke(D: np.ndarray, q: np.ndarray, F: float | np.ndarray,
                  tol: float = 1e-10) -> FrictionResult:
    """Solve the 2D Coulomb problem by :func:`lemke` on :func:`coulomb_lcp`.

    ``iterations`` counts pivots. Converged when every residual is ``<= tol max(1, F)``;
    a secondary ray or the pivot cap stop with ``"stagnation"`` / ``"max_iterations"``.
    The tableau mixes ``D`` with identity blocks under an absolute pivot tolerance: a ``D``
    far from order one (mean diagonal outside ``[1e-6, 1e6]``, e.g. physical, ~1e-13
    m^2 / Pa) is divided by its mean diagonal (:func:`delassus_scale`); an order-one ``D``
    is taken as given (the pivot path, hence a secondary ray, depends on that scaling).
    """
    m = check_problem(D, q)
    F = node_array(F, m, "F")
    k = delassus_scale(D)
    k = k if not 1e-6 <= k <= 1e6 else 1.0  # see the docstring
    M, r = coulomb_lcp(D / k, q, F)
    z, pivots, status = lemke(M, r)
    if z is None:
        reason = "stagnation" if status == "ray" else "max_iterations"
        return finish(D, q, np.zeros(2 * m), np.zeros(m), pivots, reason, [],
                      {"why": f"lemke: {status}"})
    x = np.concatenate([z[:m], z[m:2 * m] - z[2 * m:3 * m]]) / k
    res = finish(D, q, x, F * x[:m], pivots, "converged", [], {"lemke": status})
    if res.residuals["max"] > tol * max(1.0, float(F.max(initial=0.0))):
        res.stop_reason = "stagnation"
        res.info["why"] = f"lemke solution residual {res.residuals['max']:.3g} above tol"
    res.history.append(res.residuals["max"])
    return res

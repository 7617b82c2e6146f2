"""The linear complementarity problem of the condensed contact problem and its solvers
(plain functions on arrays): LCP(q, D), ``s = q + D lam``, ``lam >= 0``, ``s >= 0``,
``lam . s = 0``, with the Delassus operator ``D = B A^{-1} B^T`` of
:mod:`rbbench.hf.condensation` (the HF mixed problem of Benaceur, Drouet, Ehrlacher, Ern &
Niakh, "Model order reduction methods: parametric variational inequalities" (talk), slide
"Mixed formulation", condensed on the contact unknowns; the optimality system of the dual QP
``min_{lam >= 0} 1/2 lam^T D lam + q^T lam``): the primal-dual active set (PDAS), Lawson-
Hanson's NNLS on a Cholesky factor, Uzawa, and the natural residual that checks them.
"""

from __future__ import annotations

import warnings

import numpy as np
import scipy.linalg as sla
from scipy.optimize import nnls

from rbbench.hf.condensation.dense import delassus_scaling


def natural_residual(D: np.ndarray, q: np.ndarray, lam: np.ndarray, c: float) -> float:
    """Relative natural residual ``||min(lam, c s)||_2 / ||c q||_2`` of LCP(q, D).

    Zero exactly at the solution; ``c = 1 / mean(diag D)`` puts ``c s`` in the
    units of ``lam``.
    """
    s = q + D @ lam
    scale = max(np.linalg.norm(c * q), np.finfo(float).tiny)
    return float(np.linalg.norm(np.minimum(lam, c * s)) / scale)


def _solve_active(D: np.ndarray, q: np.ndarray, active: np.ndarray) -> np.ndarray:
    lam = np.zeros_like(q)
    if active.any():
        Daa = D[np.ix_(active, active)]
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("error", sla.LinAlgWarning)
                lam[active] = sla.solve(Daa, -q[active], assume_a="pos")
        except (sla.LinAlgError, sla.LinAlgWarning, ValueError):
            lam[active] = np.linalg.lstsq(Daa, -q[active], rcond=None)[0]
    return lam


def nnls_dual(D: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Solution of LCP(q, D) for SPD ``D`` by Lawson-Hanson NNLS.

    ``min_{lam>=0} ||L^T lam + L^{-1} q||^2`` with ``D = L L^T``: the same
    minimiser as the dual QP. A ``D`` that Cholesky finds singular (redundant
    constraints) is shifted by ``1e-14 trace(D)/m``; callers check the natural residual.
    Raises ``numpy.linalg.LinAlgError`` if even the shifted ``D`` is not SPD.
    """
    try:
        L = np.linalg.cholesky(D)
    except np.linalg.LinAlgError:
        m = max(q.size, 1)
        shift = 1e-14 * max(float(np.trace(D)) / m, np.finfo(float).tiny)
        L = np.linalg.cholesky(D + shift * np.eye(q.size))
    rhs = -sla.solve_triangular(L, q, lower=True)
    lam, _ = nnls(L.T, rhs, maxiter=50 * max(q.size, 1))
    return lam


def pdas(D: np.ndarray, q: np.ndarray, lam0: np.ndarray | None = None, max_iter: int = 100,
         tol: float = 1e-10) -> tuple[np.ndarray, int, str, list[float], dict]:
    """Primal-dual active set = semismooth Newton on ``min(lam, c s) = 0``.

    Hintermueller-Ito-Kunisch (2002). Active set ``{lam - c s > 0}``; on the
    active set ``s = 0``, elsewhere ``lam = 0``. Stops when the active set
    repeats the previous one (then the KKT conditions hold exactly, checked
    against ``tol``). A cycle (an older set coming back) switches to the
    exact NNLS solve (:func:`nnls_dual`) and says so in ``info``.

    Returns ``(lam, iterations, stop_reason, residuals, info)``.
    """
    c = delassus_scaling(D)
    m = q.size
    info: dict = {}
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(D))):
        return np.full(m, np.nan), 0, "nan", [float("nan")], {"why": "non-finite data"}
    lam = np.zeros(m) if lam0 is None else np.maximum(np.asarray(lam0, float), 0.0)
    s = q + D @ lam
    active = (lam - c * s) > 0
    seen = {active.tobytes()}
    residuals = [natural_residual(D, q, lam, c)]
    for it in range(1, max_iter + 1):
        lam = _solve_active(D, q, active)
        s = q + D @ lam
        res = natural_residual(D, q, lam, c)
        residuals.append(res)
        if not (np.all(np.isfinite(lam)) and np.isfinite(res)):
            return lam, it, "nan", residuals, info
        new = (lam - c * s) > 0
        if np.array_equal(new, active):
            reason = "converged" if res <= tol else "stagnation"
            return lam, it, reason, residuals, info
        key = new.tobytes()
        if key in seen:
            info["fallback"] = "nnls (active-set cycle)"
            try:
                lam = nnls_dual(D, q)
            except (np.linalg.LinAlgError, RuntimeError) as exc:
                info["why"] = f"nnls fallback failed: {exc}"
                return lam, it, "stagnation", residuals, info
            res = natural_residual(D, q, lam, c)
            residuals.append(res)
            return lam, it, "converged" if res <= tol else "stagnation", residuals, info
        seen.add(key)
        active = new
    return lam, max_iter, "max_iterations", residuals, info


def uzawa(D: np.ndarray, q: np.ndarray, lam0: np.ndarray | None = None, omega: float = 1.0,
          tol: float = 1e-9, max_iter: int = 200_000,
          stall_window: int = 5000) -> tuple[np.ndarray, int, str, list[float], dict]:
    """Uzawa projected iteration (Benaceur et al., slide "Uzawa"), on the condensed problem.

    ``lam_{k+1} = max(0, lam_k - rho (G - B u_{k+1}))`` with
    ``A u_{k+1} = F - B^T lam_k``; condensed, ``G - B u_{k+1} = q + D lam_k``,
    so every iterate equals that of Benaceur et al.'s Uzawa. ``rho = omega / lambda_max(D)``
    (convergent for 0 < omega < 2). Stops on the natural residual ``<= tol``,
    on ``max_iter``, on NaN, or on stagnation (no decrease of the best residual
    over ``stall_window`` iterations).
    """
    if not 0.0 < omega < 2.0:
        raise ValueError(f"uzawa: omega = {omega!r} must lie in (0, 2)")
    c = delassus_scaling(D)
    m = q.size
    lmax = float(sla.eigvalsh(D, subset_by_index=[m - 1, m - 1])[0]) if m else 1.0
    rho = omega / lmax
    lam = np.zeros(m) if lam0 is None else np.maximum(np.asarray(lam0, float), 0.0)
    residuals: list[float] = []
    best, best_it = np.inf, 0
    info = {"rho": rho}
    scale = max(np.linalg.norm(c * q), np.finfo(float).tiny)
    for it in range(1, max_iter + 1):
        s = q + D @ lam
        res = float(np.linalg.norm(np.minimum(lam, c * s)) / scale)
        if it == 1 or it % 50 == 0:
            residuals.append(res)
        if not np.isfinite(res):
            return lam, it, "nan", residuals, info
        if res <= tol:
            residuals.append(res)
            return lam, it, "converged", residuals, info
        if res < best * (1 - 1e-12):
            best, best_it = res, it
        elif it - best_it > stall_window:
            return lam, it, "stagnation", residuals, info
        lam = np.maximum(lam - rho * s, 0.0)
    return lam, max_iter, "max_iterations", residuals, info

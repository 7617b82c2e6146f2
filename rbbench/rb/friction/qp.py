"""Small dense problems shared by the reduced friction models: the Tresca box QP and the
bound-constrained QP by daqp (Arnstrom et al. 2022), the stopping rule of their online
fixed points, the nearest-training warm start, and the one-load-step check."""

from __future__ import annotations

from typing import Any

import numpy as np
import scipy.linalg as sla

__all__ = ["check_reducible", "increment_stop", "nearest_training", "nonneg_qp", "tresca_qp"]


def check_reducible(problem: Any) -> Any:
    """The single load step of a FrictionProblem the reduced models solve (ValueError for
    several steps or a slip-dependent coefficient)."""
    if len(problem.steps) != 1:
        raise ValueError(f"reduced friction: {len(problem.steps)} load steps; the reduced "
                         "model solves one load step (the snapshots hold the last one)")
    if problem.coefficient_law is not None:
        raise ValueError("reduced friction: a slip-dependent coefficient (model B) is not "
                         "reduced; Tresca or constant-coefficient Coulomb only")
    return problem.steps[0]


def tresca_qp(D: np.ndarray, q: np.ndarray, R: int, Qt: np.ndarray, s: np.ndarray,
              x0: np.ndarray | None = None) -> tuple[np.ndarray | None, int, int]:
    """The reduced Tresca QP ``min 1/2 x^T D x + q^T x``, ``x[:R] >= 0``,
    ``|Qt x[R:]| <= s``: ``(x or None, daqp iterations, daqp exit flag)``.

    Nodes with ``s = 0`` (open nodes of the Coulomb fixed point: ``s <= 1e-10 s_ref``,
    ``s_ref = max|Qt| ||q|| / ||D||_2`` the scale of ``Qt theta``) pin ``Qt theta`` to 0:
    ``theta = N0 phi`` with ``N0`` an orthonormal basis of the null space of those rows, so
    that daqp never sees rows with (nearly) equal bounds (two of them, on nearly parallel
    rows, already overdetermine its working set: exit flag -6, measured on hertz_friction).
    The rest is :func:`_daqp_qp`.
    """
    s = np.asarray(s, float)
    n = q.size
    s_ref = float(np.abs(Qt).max(initial=0.0)) * float(np.linalg.norm(q)) / max(
        float(np.linalg.norm(D, 2)), np.finfo(float).tiny)
    zero = s <= 1e-10 * s_ref
    T = np.eye(n)
    if np.any(zero):
        _, sv, Vh = np.linalg.svd(Qt[zero], full_matrices=True)
        rank = int(np.sum(sv > 1e-10 * sv.max(initial=0.0))) if sv.size else 0
        T = sla.block_diag(np.eye(R), Vh[rank:].T)
    y0 = None if x0 is None else T.T @ np.asarray(x0, float)
    y, it, flag = _daqp_qp(T.T @ D @ T, T.T @ q, R, Qt[~zero] @ T[R:, R:], s[~zero], y0)
    return (None if y is None else T @ y), it, flag


def nonneg_qp(D: np.ndarray, q: np.ndarray, x0: np.ndarray | None = None
              ) -> tuple[np.ndarray | None, int, int]:
    """``min 1/2 x^T D x + q^T x`` over ``x >= 0`` (bounds only) by :func:`_daqp_qp`."""
    return _daqp_qp(D, q, q.size, np.zeros((0, 0)), np.zeros(0), x0)


def _daqp_qp(D: np.ndarray, q: np.ndarray, R: int, Qt: np.ndarray, s: np.ndarray,
             x0: np.ndarray | None) -> tuple[np.ndarray | None, int, int]:
    """:func:`tresca_qp` with ``s > 0`` by daqp (Arnstrom et al. 2022).

    daqp's tolerances are absolute: ``x = fs diag(sc) y`` with ``sc = diag(D)^{-1/2}``
    (unit-diagonal Hessian) and ``fs = ||sc q||`` (unit load), constraint rows scaled to
    unit norm (rows of ``Qt`` that vanish are dropped: ``0 <= s``); ``primal_tol =
    dual_tol = 1e-12``. ``x0``: warm start (primal), a cold start if daqp refuses it.
    """
    import daqp

    n = q.size
    d = np.diag(D).copy()
    sc = 1.0 / np.sqrt(np.maximum(d, 1e-14 * max(float(d.max(initial=0.0)), 1e-300)))
    g = sc * q
    fs = float(np.linalg.norm(g)) or 1.0
    rows = np.zeros((Qt.shape[0], n))
    rows[:, R:] = Qt * sc[None, R:]
    rn = np.linalg.norm(rows, axis=1)
    keep = rn > 1e-14 * max(float(rn.max(initial=0.0)), 1e-300)
    bound = s[keep] / (fs * rn[keep])
    args = (np.ascontiguousarray(sc[:, None] * D * sc[None, :]), g / fs,
            np.ascontiguousarray(rows[keep] / rn[keep, None]),
            np.concatenate([np.full(R, 1e30), bound]), np.concatenate([np.zeros(R), -bound]),
            np.zeros(R + bound.size, dtype=np.int32))
    it, flag = 0, 0
    starts = ([{"primal_start": np.asarray(x0, float) / (fs * sc)}] if x0 is not None
              else []) + [{}]
    for kw in starts:
        y, _, flag, info = daqp.solve(*args, primal_tol=1e-12, dual_tol=1e-12, **kw)
        it += int(info["iterations"])
        if int(flag) == 1 and np.all(np.isfinite(y)):
            return fs * sc * np.asarray(y, float), it, 1
    return None, it, int(flag)


def increment_stop(hist: list[float], new: np.ndarray, old: np.ndarray, tol: float,
                   floor: float = 0.0) -> str | None:
    """The stopping rule of the online fixed points: append the relative increment
    ``||new - old||_inf / max(||new||_inf, floor)`` to ``hist``; ``"converged"`` when it is
    ``<= tol``, ``"diverged"`` when it grew 1e6-fold over the smallest so far, else None."""
    hist.append(float(np.abs(new - old).max(initial=0.0))
                / max(float(np.abs(new).max(initial=0.0)), floor, np.finfo(float).tiny))
    if hist[-1] <= tol:
        return "converged"
    return "diverged" if hist[-1] > 1e6 * min(hist) else None


def nearest_training(mus_train: np.ndarray, x_train: np.ndarray,
                     mu: np.ndarray) -> np.ndarray | None:
    """The online warm start: the training solution ``x_train[j]`` of the training mu
    nearest to ``mu`` (Euclidean), or None without training solutions."""
    if x_train.size == 0:
        return None
    d = np.linalg.norm(mus_train - np.asarray(mu, float)[None, :], axis=1)
    return x_train[int(np.argmin(d))]

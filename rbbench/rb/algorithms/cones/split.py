"""The mCPG split ``theta = theta_tilde + nu``.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slide "mCPG algorithm (2/4)".

A QP in the cone coefficients, solved by ``daqp`` after an exact presolve and made exactly
feasible afterwards (see :func:`mcpg_split`). Used by the mCPG and ENG greedies of
:mod:`rbbench.rb.algorithms.cones.greedy`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rbbench.rb.algorithms.cones.metric import ConeGram, cone_gram

__all__ = ["mcpg_split"]

_INF = 1e30  # daqp's "no bound"
#: Relative size (w.r.t. max(theta)) below which an mCPG residual entry is
#: cancellation noise: set to 0 so that generators keep clean supports.
_CRUMB = 1e-13


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
        status["alpha_raw_min"] = float(np.min(xa)) if len(xa) else 0.0  # before the clip
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


def _presolved_qp(gram: ConeGram, t: np.ndarray, status: dict[str, Any]) -> np.ndarray:
    """The scaled mCPG QP (``||t||_W = 1``) after an exact presolve; ``x = 0`` on failure.

    A generator with ``v_ij > 0`` where ``t_i = 0`` must have ``x_j = 0`` (``V >= 0``);
    rows where the kept generators all vanish are ``0 <= t_i``, always true. Both are
    degenerate constraints that made daqp report infeasibility at tight tolerance.
    """
    Vm = gram.V
    cols = np.flatnonzero(~np.any(Vm[t <= 0.0] > 0.0, axis=0))
    x = np.zeros(gram.R)
    if cols.size:
        rows = np.flatnonzero(np.any(Vm[:, cols] > 0.0, axis=1))
        xs = _mcpg_qp(gram.CV[:, cols], gram.metric.factor(t), Vm[np.ix_(rows, cols)],
                      t[rows], status)
        if xs is None:
            status["ok"] = False  # feasible fallback: nu = theta (the CPG choice)
        else:
            x[cols] = xs
    return x


def mcpg_split(
    theta: np.ndarray,
    V: np.ndarray | None = None,
    W: Any = None,
    gram: ConeGram | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
    """The mCPG split ``theta = theta_tilde + nu`` (Benaceur et al., slide "mCPG algorithm (2/4)").

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
        feasibility scaling factor), ``alpha_raw_min`` (the smallest coefficient
        daqp returned, scaled problem, before the clip at 0), ``nu_raw_min``
        (``min(theta - V alpha) / max(theta)`` before the crumbs are zeroed).
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
    alpha = s * _presolved_qp(gram, th / s, status)
    theta_tilde = gram.V @ alpha
    nu = th - theta_tilde
    status["nu_raw_min"] = float(nu.min()) / float(th.max())  # relative, before the crumbs
    # cancellation crumbs of either sign: keep supports clean; a larger negative entry stays
    # (and fails the W+ checks: the shrink above makes it impossible)
    nu[np.abs(nu) <= _CRUMB * th.max()] = 0.0
    return alpha, theta_tilde, nu, status


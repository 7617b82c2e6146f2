"""Active-set / semismooth Newton and fixed-point solvers for 2D collocated friction.

The condensed problem, its unknowns ``x = [lam_n; lam_t]``, ``w = q + D x`` and the sign
convention (slip ``v = -w_t``, ``lam_t = +s sign(v)``, the traction on the body ``-lam_t``
opposing the slip) are those of :mod:`rbbench.hf.algebra.friction`.

* :func:`pdas_tresca`: primal-dual active set (Hintermueller-Ito-Kunisch 2002) on the box
  ``lam_n >= 0``, ``|lam_t| <= s`` jointly with Signorini;
* :func:`coulomb_fixed_point`: the fixed point on Tresca with ``s = F lam_n`` of Benaceur,
  Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric variational
  inequalities" (talk);
* :func:`coulomb_direct`: active set on the 2D wedge ``|lam_t| <= F lam_n`` (the collocated
  2D Coulomb problem is a non-symmetric LCP; Alart-Curnier 1991 predictor);
* :func:`coulomb_model_b`: model B of the talk "On coupling of complementarity with friction
  in contact shape optimization", ``F = f(|u_t|)``, by a fixed point on the coefficient.

Anti-cycling (pitfalls.md, "Contact algebra"): a tangential dof never jumps from one bound
to the other (it becomes free / stick first), the PDAS constant is ``1 / D_ii`` per dof,
every pattern is remembered and a repeated one stops the iteration (``"stagnation"``, or
the exact fallback for Tresca).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable

import numpy as np
import scipy.linalg as sla

from rbbench.hf.algebra.friction import (
    MODEL_B,
    CoefficientLaw,
    FrictionResult,
    box_bounds,
    check_problem,
    delassus_scale,
    finish,
    friction_residuals,
    node_array,
    slip,
    tresca_bvls,
)
from rbbench.hf.solvers.lemke import coulomb_lemke

OPEN, STICK, SLIP_PLUS, SLIP_MINUS = 0, 1, 2, 3
#: per-node states of :func:`coulomb_direct` (``info["pattern"]``)
COULOMB_STATES = {OPEN: "open", STICK: "stick", SLIP_PLUS: "slip+", SLIP_MINUS: "slip-"}


def _dof_constants(D: np.ndarray) -> np.ndarray:
    """The per-dof PDAS constant ``1 / D_ii`` (``1 / mean diag`` where ``D_ii <= 0``)."""
    d = np.diag(D).astype(float)
    mean = float(np.mean(d[d > 0])) if np.any(d > 0) else 1.0
    return 1.0 / np.where(d > 0, d, mean)


def _solve(M: np.ndarray, r: np.ndarray, sym: bool, info: dict) -> np.ndarray:
    """Solve one pattern system; a singular one falls back to least squares (noted)."""
    if r.size == 0:
        return r.copy()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", sla.LinAlgWarning)
            return sla.solve(M, r, assume_a="pos" if sym else "gen")
    except (sla.LinAlgError, sla.LinAlgWarning, ValueError):
        info["singular_patterns"] = info.get("singular_patterns", 0) + 1
        return np.linalg.lstsq(M, r, rcond=None)[0]


# --------------------------------------------------------------------------- Tresca

def _tresca_pattern(D: np.ndarray, q: np.ndarray, s: np.ndarray, state: np.ndarray,
                    info: dict) -> np.ndarray:
    """Solve ``w_I = 0`` on the free dofs, the others at their value (0 or +-s)."""
    m = s.size
    x = np.zeros(2 * m)
    x[m:] = s * state[m:]  # tangential: -1 lower, 0 free, +1 upper
    free = np.concatenate([state[:m] == 1, state[m:] == 0])
    if free.any():
        rhs = -(q[free] + D[np.ix_(free, ~free)] @ x[~free])
        x[free] = _solve(D[np.ix_(free, free)], rhs, True, info)
    return x


def _tresca_predict(x: np.ndarray, w: np.ndarray, c: np.ndarray, s: np.ndarray,
                    prev: np.ndarray | None) -> np.ndarray:
    """Active sets from ``y = x - c w``: contact ``y_n > 0``; ``lam_t`` at ``+-s`` beyond it.

    A tangential dof never jumps bound to bound: it becomes free first.
    """
    m = s.size
    y = x - c * w
    normal = (y[:m] > 0).astype(np.int8)
    tang = (y[m:] > s).astype(np.int8) - (y[m:] < -s).astype(np.int8)
    if prev is not None:
        tang[tang * prev[m:] < 0] = 0
    return np.concatenate([normal, tang])


def pdas_tresca(D: np.ndarray, q: np.ndarray, s: float | np.ndarray,
                lam0: np.ndarray | None = None, max_iter: int = 100, tol: float = 1e-10,
                fallback: bool = True) -> FrictionResult:
    """Primal-dual active set for Tresca friction with Signorini (the box QP of the module).

    Semismooth Newton on ``x = P_box(x - c w)`` with ``c = 1 / D_ii`` per dof: contact
    ``{y_n > 0}``, tangential bounds ``{y_t > s}``, ``{y_t < -s}`` (``y = x - c w``); each
    iteration solves ``D_II x_I = -(q_I + D_IF x_F)`` on the free dofs. Converged when every
    residual of :func:`friction_residuals` is ``<= tol``. Never hangs: a repeated pattern
    (cycle) switches to the exact :func:`tresca_bvls` if ``fallback`` (noted in
    ``info["fallback"]``) or stops with ``"stagnation"``; ``max_iter`` caps the loop.
    """
    m = check_problem(D, q)
    s = node_array(s, m, "s")
    info: dict = {}
    if not (np.all(np.isfinite(D)) and np.all(np.isfinite(q))):
        return finish(D, q, np.full(2 * m, np.nan), s, 0, "nan", [], {"why": "non-finite data"})
    c = _dof_constants(D)
    x = np.zeros(2 * m) if lam0 is None else np.clip(lam0, *box_bounds(s))
    state = _tresca_predict(x, q + D @ x, c, s, None)
    seen = {state.tobytes()}
    history: list[float] = []
    for it in range(1, max_iter + 1):
        x = _tresca_pattern(D, q, s, state, info)
        res = friction_residuals(D, q, x[:m], x[m:], s)["max"]
        history.append(res)
        if not np.isfinite(res):
            return finish(D, q, x, s, it, "nan", history, info)
        if res <= tol:
            return finish(D, q, x, s, it, "converged", history, info)
        new = _tresca_predict(x, q + D @ x, c, s, state)
        if np.array_equal(new, state) or new.tobytes() in seen:
            info["why"] = "active-set cycle" if not np.array_equal(new, state) \
                else "pattern repeats with residual above tol"
            if not fallback:
                return finish(D, q, x, s, it, "stagnation", history, info)
            info["fallback"] = f"bvls ({info['why']})"
            x = tresca_bvls(D, q, s)
            res = friction_residuals(D, q, x[:m], x[m:], s)["max"]
            history.append(res)
            return finish(D, q, x, s, it, "converged" if res <= tol else "stagnation",
                          history, info)
        seen.add(new.tobytes())
        state = new
    return finish(D, q, x, s, max_iter, "max_iterations", history, info)


# --------------------------------------------------------------------------- Coulomb

def _increment_monitor(increments: list[float], window: int, what: str,
                       info: dict) -> str | None:
    """``"diverged"`` if increments grew 1e6-fold, ``"stagnation"`` if no progress over
    ``window`` iterations (``info["why"]`` names the ``what`` increments), else ``None``."""
    bad = None
    if not math.isfinite(increments[-1]):
        bad = "nan"
    elif len(increments) > 2 and increments[-1] > 1e6 * max(increments[0], 1e-300):
        bad = "diverged"
    elif len(increments) > window and min(increments[-window:]) >= min(increments[:-window]):
        bad = "stagnation"
    if bad:
        info["why"] = f"{what} increments: {bad} (no contraction)"
    return bad


def _record_contraction(info: dict, increments: list[float]) -> None:
    """``info["ratios"]`` of successive increments, ``info["contraction"]`` the last one."""
    info["ratios"] = [b / a if a > 0 else 0.0
                      for a, b in zip(increments[:-1], increments[1:], strict=True)]
    info["contraction"] = info["ratios"][-1] if info["ratios"] else 0.0


def coulomb_fixed_point(D: np.ndarray, q: np.ndarray, F: float | np.ndarray,
                        lam0: np.ndarray | None = None, max_iter: int = 200,
                        tol: float = 1e-10, window: int = 20,
                        tresca: Callable[..., FrictionResult] = pdas_tresca) -> FrictionResult:
    """Benaceur et al.'s fixed point: Tresca with ``s = F lam_n^k`` until
    ``||x^{k+1} - x^k||_inf <= tol * fscale`` and the Coulomb residuals are ``<= 10 tol``.

    ``tresca(D, q, s, lam0=x)`` solves each Tresca problem (:func:`pdas_tresca`, or any
    solver of the box QP, e.g. PETSc's SNES VI).

    ``info["ratios"]`` holds the ratios of successive increments (the contraction;
    ``info["contraction"]`` is the last one), ``info["inner_iterations"]`` the PDAS total.
    Stops ``"diverged"`` when increments grow 1e6-fold, ``"stagnation"`` when they do not
    decrease over ``window`` iterations, or passes on an inner failure (``info["why"]``).
    """
    m = check_problem(D, q)
    F = node_array(F, m, "F")
    x = np.zeros(2 * m) if lam0 is None else np.asarray(lam0, float).copy()
    increments: list[float] = []
    info: dict = {"inner_iterations": 0}
    reason, it = "max_iterations", 0
    while it < max_iter:
        it += 1
        inner = tresca(D, q, F * np.maximum(x[:m], 0.0), lam0=x)
        info["inner_iterations"] += inner.iterations
        if inner.stop_reason != "converged":
            reason, info["why"] = inner.stop_reason, f"inner Tresca solve: {inner.stop_reason}"
            x = inner.x
            break
        fscale = max(float(np.abs(inner.x).max(initial=0.0)), np.finfo(float).tiny)
        increments.append(float(np.abs(inner.x - x).max(initial=0.0)) / fscale)
        x = inner.x
        res = friction_residuals(D, q, x[:m], x[m:], F * x[:m])["max"]
        if increments[-1] <= tol and res <= 10 * tol:
            reason = "converged"
            break
        bad = _increment_monitor(increments, window, "iterate", info)
        if bad:
            reason = bad
            break
    _record_contraction(info, increments)
    return finish(D, q, x, F * x[:m], it, reason, increments, info)


def _coulomb_system(D: np.ndarray, q: np.ndarray, F: np.ndarray,
                    pattern: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The linear system of one node pattern (non-symmetric on slipping nodes).

    open: ``lam_n = lam_t = 0``; stick: ``w_n = w_t = 0``; slip+-: ``w_n = 0``,
    ``lam_t -+ F lam_n = 0``; the rows on multipliers times :func:`delassus_scale`, of the
    order of the rows of ``D`` (a physical ``D`` made the system look singular).
    """
    m = F.size
    idx = np.arange(m)
    k = delassus_scale(D)
    M, r = np.zeros((2 * m, 2 * m)), np.zeros(2 * m)
    contact = pattern != OPEN
    M[idx[~contact], idx[~contact]] = k
    M[m + idx[~contact], m + idx[~contact]] = k
    M[idx[contact]] = D[idx[contact]]
    r[idx[contact]] = -q[idx[contact]]
    st = idx[pattern == STICK]
    M[m + st] = D[m + st]
    r[m + st] = -q[m + st]
    for code, sign in ((SLIP_PLUS, 1.0), (SLIP_MINUS, -1.0)):
        sl = idx[pattern == code]
        M[m + sl, m + sl] = k
        M[m + sl, sl] = -sign * F[sl] * k
    return M, r


def coulomb_pattern(D: np.ndarray, q: np.ndarray, F: np.ndarray, pattern: np.ndarray,
                    info: dict | None = None) -> np.ndarray:
    """The multipliers ``x`` of one node pattern (codes :data:`COULOMB_STATES`)."""
    M, r = _coulomb_system(D, q, F, pattern)
    return _solve(M, r, False, {} if info is None else info)


def _coulomb_predict(x: np.ndarray, w: np.ndarray, c: np.ndarray, F: np.ndarray,
                     prev: np.ndarray | None) -> np.ndarray:
    """Alart-Curnier predictor: contact ``y_n > 0``; slip+- where ``|y_t| > F y_n``.

    A slip+ node never becomes slip- in one step (nor the reverse): it sticks first.
    """
    m = F.size
    y = x - c * w
    thr = F * np.maximum(y[:m], 0.0)
    pattern = np.full(m, STICK, dtype=np.int8)
    pattern[y[m:] > thr] = SLIP_PLUS
    pattern[y[m:] < -thr] = SLIP_MINUS
    pattern[y[:m] <= 0] = OPEN
    if prev is not None:
        flip = ((prev == SLIP_PLUS) & (pattern == SLIP_MINUS)) | \
               ((prev == SLIP_MINUS) & (pattern == SLIP_PLUS))
        pattern[flip] = STICK
    return pattern


def _next_pattern(pattern: np.ndarray, predicted: np.ndarray, seen: set, single: set | None,
                  info: dict) -> tuple[np.ndarray | None, set | None]:
    """The next Coulomb pattern; on the first repeat switch to one change per iteration.

    Single-change mode (Murty's least-index rule, finite for P-matrix LCPs): only the
    first node whose predicted state differs changes. ``None`` when that repeats too.
    """
    if single is None and predicted.tobytes() not in seen:
        seen.add(predicted.tobytes())
        return predicted, None
    if single is None:
        single, info["single_change_from"] = {pattern.tobytes()}, len(seen)
    diff = np.flatnonzero(predicted != pattern)
    if diff.size == 0:
        return None, single
    new = pattern.copy()
    new[diff[0]] = predicted[diff[0]]
    if new.tobytes() in single:
        return None, single
    single.add(new.tobytes())
    return new, single


def coulomb_direct(D: np.ndarray, q: np.ndarray, F: float | np.ndarray,
                   lam0: np.ndarray | None = None, max_iter: int = 200,
                   tol: float = 1e-10, fallback: bool = True) -> FrictionResult:
    """Active set / semismooth Newton directly on the 2D Coulomb wedge.

    Per-node states open / stick / slip+ / slip- (:data:`COULOMB_STATES`) predicted from
    ``y = x - c w`` (``c = 1 / D_ii`` per dof, threshold ``F [y_n]_+``); each iteration solves
    the non-symmetric system of the pattern (:func:`coulomb_pattern`). Converged when every
    residual (``s = F lam_n``) is ``<= tol max(1, F)`` (the cone residual carries the
    rounding of ``lam_n`` times ``F``). Without a convexity argument there is no global
    guarantee: the first repeated pattern switches to single changes (:func:`_next_pattern`,
    ``info["single_change_from"]``), a repeat there stops with ``"stagnation"``
    (``info["why"]``), or with ``fallback`` hands over to Lemke's method
    (:func:`rbbench.hf.solvers.lemke.coulomb_lemke`, ``info["fallback"]``); ``max_iter``
    caps the loop. ``info["pattern"]``: final node states.
    """
    m = check_problem(D, q)
    F = node_array(F, m, "F")
    info: dict = {}
    if not (np.all(np.isfinite(D)) and np.all(np.isfinite(q))):
        return finish(D, q, np.full(2 * m, np.nan), F * 0, 0, "nan", [], {"why": "non-finite"})
    c = _dof_constants(D)
    tol_eff = tol * max(1.0, float(F.max(initial=0.0)))
    x = np.zeros(2 * m) if lam0 is None else np.asarray(lam0, float).copy()
    pattern = _coulomb_predict(x, q + D @ x, c, F, None)
    seen, single = {pattern.tobytes()}, None
    history: list[float] = []
    reason, it = "max_iterations", 0
    while it < max_iter:
        it += 1
        x = coulomb_pattern(D, q, F, pattern, info)
        res = friction_residuals(D, q, x[:m], x[m:], F * x[:m])["max"]
        history.append(res)
        if not np.isfinite(res) or res <= tol_eff:
            reason = "converged" if np.isfinite(res) else "nan"
            break
        predicted = _coulomb_predict(x, q + D @ x, c, F, pattern)
        new, single = _next_pattern(pattern, predicted, seen, single, info)
        if new is None:
            reason, info["why"] = "stagnation", "active-set cycle (also with single changes)"
            break
        pattern = new
    info["pattern"] = [COULOMB_STATES[int(p)] for p in pattern]
    if reason == "stagnation" and fallback:
        lem = coulomb_lemke(D, q, F, tol=tol)
        lem.info.update(info, fallback=f"lemke ({info['why']})", pivots=lem.iterations)
        lem.iterations, lem.history = it, history + lem.history
        return lem
    return finish(D, q, x, F * x[:m], it, reason, history, info)


# --------------------------------------------------------------------------- model B

def coulomb_model_b(D: np.ndarray, q: np.ndarray, law: CoefficientLaw = MODEL_B,
                    ut_prev: np.ndarray | None = None, max_iter: int = 100,
                    tol: float = 1e-10, window: int = 20,
                    inner: Callable[..., FrictionResult] = coulomb_direct) -> FrictionResult:
    """Model B (shape-optimisation talk): Coulomb with ``F_i = f(|u_t,i|)``, fixed point on ``F``.

    ``u_t = ut_prev + v`` (the relative tangential displacement at the end of the step).
    ``F^0 = f(|ut_prev|)``; iterate ``F^{k+1} = f(|u_t(x(F^k))|)`` with the ``inner``
    Coulomb solve (warm-started) until ``||F^{k+1} - F^k||_inf <= tol max(F)``.
    ``info["ratios"]`` / ``info["contraction"]``: ratios of successive coefficient
    increments; ``info["coefficient"]`` the final ``F``; ``info["max_abs_dcoef"]``
    ``max |f'(|u_t|)|`` when the law has a derivative. Failure: the inner stop reason
    (``info["why"]``), ``"diverged"`` / ``"stagnation"`` as in :func:`coulomb_fixed_point`.
    """
    m = check_problem(D, q)
    ut_prev = np.zeros(m) if ut_prev is None else np.asarray(ut_prev, float).ravel()
    Fk = node_array(law.f(np.abs(ut_prev)), m, f"coefficient law {law.name!r}")
    x: np.ndarray | None = None
    increments: list[float] = []
    info: dict = {"inner_iterations": 0, "law": law.name}
    reason, it = "max_iterations", 0
    while it < max_iter:
        it += 1
        r = inner(D, q, Fk, lam0=x)
        info["inner_iterations"] += r.iterations
        x = r.x
        if r.stop_reason != "converged":
            reason, info["why"] = r.stop_reason, f"inner Coulomb solve: {r.stop_reason}"
            break
        ut = ut_prev + slip(D, q, r.lam_n, r.lam_t)
        F_new = node_array(law.f(np.abs(ut)), m, f"coefficient law {law.name!r}")
        increments.append(float(np.abs(F_new - Fk).max(initial=0.0))
                          / max(float(F_new.max(initial=0.0)), np.finfo(float).tiny))
        Fk = F_new if increments[-1] > tol else Fk
        if increments[-1] <= tol:
            reason = "converged"
            break
        bad = _increment_monitor(increments, window, "coefficient", info)
        if bad:
            reason = bad
            break
    _record_contraction(info, increments)
    info["coefficient"] = Fk
    if law.df is not None and x is not None:
        ut = ut_prev + slip(D, q, x[:m], x[m:])
        info["max_abs_dcoef"] = float(np.abs(law.df(np.abs(ut))).max(initial=0.0))
    return finish(D, q, x, Fk * x[:m], it, reason, increments, info)


def _model_b_newton_system(D: np.ndarray, q: np.ndarray, law: CoefficientLaw,
                           ut_prev: np.ndarray, x: np.ndarray,
                           pattern: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Newton system of one node pattern of model B at ``x``, and ``F(x)``.

    As :func:`_coulomb_system` with ``F = f(|u_t(x)|)``; a slipping row
    ``g = k (lam_t -+ f(|u_t|) lam_n)`` is linearised with ``u_t = ut_prev - q_t - D_t x``:
    ``dg/dx = k (e_t -+ f e_n -+ lam_n f'(|u_t|) sign(u_t) (-D_t))``, so row and right-hand
    side gain ``+- k lam_n f' sign(u_t) D_t`` times ``x_new`` and ``x`` (Newton's
    ``J x_new = J x - g(x)``; the rest of the row is linear).
    """
    m = pattern.size
    ut = ut_prev + slip(D, q, x[:m], x[m:])
    F = node_array(law.f(np.abs(ut)), m, f"coefficient law {law.name!r}")
    M, r = _coulomb_system(D, q, F, pattern)
    k = delassus_scale(D)
    dF = k * x[:m] * np.asarray(law.df(np.abs(ut)), float) * np.sign(ut)  # per node
    for code, sign in ((SLIP_PLUS, 1.0), (SLIP_MINUS, -1.0)):
        sl = np.flatnonzero(pattern == code)
        g = sign * dF[sl]
        M[m + sl] += g[:, None] * D[m + sl]
        r[m + sl] += g * (D[m + sl] @ x)
    return M, r, F


def _model_b_state(D: np.ndarray, q: np.ndarray, law: CoefficientLaw, ut_prev: np.ndarray,
                   x: np.ndarray) -> tuple[np.ndarray, float]:
    """``(F(x), max residual)`` of model B at ``x``: the Coulomb residuals with
    ``s = f(|u_t(x)|) lam_n`` (:func:`friction_residuals`)."""
    m = x.size // 2
    F = law.f(np.abs(ut_prev + slip(D, q, x[:m], x[m:])))
    return F, friction_residuals(D, q, x[:m], x[m:], F * x[:m])["max"]


def model_b_newton(D: np.ndarray, q: np.ndarray, law: CoefficientLaw = MODEL_B,
                   ut_prev: np.ndarray | None = None, lam0: np.ndarray | None = None,
                   max_iter: int = 100, tol: float = 1e-10, window: int = 8,
                   fallback: bool = True) -> FrictionResult:
    """Model B (shape-optimisation talk) by a semismooth Newton with the law's derivative ``f'``.

    Active set on the Coulomb wedge (Alart-Curnier predictor of :func:`coulomb_direct` with
    ``F = f(|u_t(x)|)``); each iteration solves the pattern's system linearised in ``x``,
    the ``f'`` term included (:func:`_model_b_newton_system`). Converged when every residual
    with ``s = f(|u_t|) lam_n`` is ``<= tol max(1, F)``. Newton fails when the residual does
    not reach a new minimum over ``window`` iterations, is not finite, or ``max_iter`` is
    reached (``info["newton_why"]``); then, with ``fallback``, the fixed point
    :func:`coulomb_model_b` runs from the start and its result is returned. ``info``:
    ``"method"`` (``"newton"`` or ``"fixed_point"``: which one produced ``x``),
    ``"newton_iterations"``, ``"newton_history"`` (residual per Newton iteration).
    """
    m = check_problem(D, q)
    if law.df is None:
        raise ValueError(f"model_b_newton: coefficient law {law.name!r} has no derivative")
    ut_prev = np.zeros(m) if ut_prev is None else np.asarray(ut_prev, float).ravel()
    c = _dof_constants(D)
    x = np.zeros(2 * m) if lam0 is None else np.asarray(lam0, float).copy()
    F, _ = _model_b_state(D, q, law, ut_prev, x)
    pattern = _coulomb_predict(x, q + D @ x, c, F, None)
    info: dict = {"law": law.name}
    history: list[float] = []
    best, best_it, why = math.inf, 0, f"max_iter = {max_iter} reached"
    for it in range(1, max_iter + 1):
        M, r, _ = _model_b_newton_system(D, q, law, ut_prev, x, pattern)
        x = _solve(M, r, False, info)
        F, res = _model_b_state(D, q, law, ut_prev, x)
        history.append(res)
        if res <= tol * max(1.0, float(F.max(initial=0.0))):
            info.update(method="newton", newton_iterations=it, newton_history=history,
                        pattern=[COULOMB_STATES[int(p)] for p in pattern], coefficient=F)
            return finish(D, q, x, F * x[:m], it, "converged", history, info)
        if not math.isfinite(res) or it - best_it > window:
            why = "residual not finite" if not math.isfinite(res) else \
                f"residual did not decrease over {window} iterations (best {best:.3e})"
            break
        if res < best:
            best, best_it = res, it
        pattern = _coulomb_predict(x, q + D @ x, c, F, pattern)
    info.update(newton_iterations=len(history), newton_history=history, newton_why=why)
    if not fallback:
        info["method"] = "newton"
        reason = "nan" if not math.isfinite(history[-1]) else \
            "max_iterations" if len(history) == max_iter else "stagnation"
        return finish(D, q, x, F * x[:m], len(history), reason, history, info)
    fp = coulomb_model_b(D, q, law, ut_prev=ut_prev, max_iter=max_iter, tol=tol)
    fp.info.update(info, method="fixed_point", fallback=f"fixed point ({why})")
    return fp

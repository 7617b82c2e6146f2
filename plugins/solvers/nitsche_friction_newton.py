"""Generalised Newton for Nitsche friction over the load steps (Renard 2013).

:class:`~rbbench.interfaces.NitscheFrictionProblem`, algebra in
:mod:`rbbench.hf.algebra.nitsche_friction`: ``K(u_k) d = -R(u_k)`` with ``K`` an element of the
generalised Jacobian (stick / slip / open sets of the points; non-symmetric for Coulomb,
so SuperLU; Tresca with ``theta = 1`` is symmetric and may use the backend's solver).

* Load steps in order: each warm-started from the previous step's ``u``; the slip of a
  step is measured from the full tangential jump at the end of the previous one
  (``ut_prev``). A step that does not converge stops the sequence (its stop reason is
  the result's).
* Globalisation: backtracking on ``||R||`` (:func:`_backtrack`: ``t = 1, 1/2, ...``, at
  most :data:`BACKTRACKS` halvings, so ``t >= 1e-3``); a step that no ``t`` improves is
  taken in full (``R`` is piecewise smooth: a full step may reach the right sets; with
  30 halvings the search crawled along a kink with ``t ~ 1e-9`` on a full-stick case),
  :data:`MAX_FAILURES` in a row stop with ``stagnation``.
* Stop tests and the rounding floor: :meth:`rbbench_plugins.solvers.newton.NewtonSolver._stop`
  (the "settled" sets are the normal active set and the stick set).

``SolveResult.info``: ``reason``, ``load_steps`` (per step: iterations, stop reason, final
relative Newton residual, the residual ratios of its last iterations), and the per-point
arrays (:data:`POINT_INFO`, not in ``summary.json``): ``lam_n_points = -[P_n]_-``,
``lam_t_points = -[P_t]_S`` (the mixed multipliers' signs), ``slip_points`` (``u_t -
ut_prev``, m), ``states_points`` (open / stick / slip), ``ut_prev_points``, ``S_points``
(the radius) and, for Coulomb, ``coefficient_points``; ``friction_residuals``
(:func:`rbbench.hf.algebra.nitsche_friction.condition_residuals`: the consistency of the weak
conditions, not the algebraic convergence).
"""

from __future__ import annotations

import dataclasses
import time
from typing import Any

import numpy as np
import scipy.sparse.linalg as spla

from rbbench.hf.algebra import nitsche as nt
from rbbench.hf.algebra import nitsche_friction as nf
from rbbench.interfaces import NitscheFrictionProblem, NitscheStep, SolveResult

#: largest number of step halvings of the backtracking line search
BACKTRACKS = 10
#: the line search compares with the largest of this many last residual norms (1: monotone;
#: measured: a non-monotone 5 cycled on full steps on mindlin_cylinders, Coulomb 0.2)
MEMORY = 1
#: successive steps without decrease (taken in full) before ``stagnation``
MAX_FAILURES = 5
#: the per-point arrays of ``SolveResult.info`` (left out of ``summary.json``)
POINT_INFO = ("lam_n_points", "lam_t_points", "slip_points", "states_points",
              "ut_prev_points", "S_points", "coefficient_points")


def at_step(prob: NitscheFrictionProblem, step: NitscheStep, ut_prev: np.ndarray
            ) -> NitscheFrictionProblem:
    """``prob`` with the data of load step ``step`` and the reference jump ``ut_prev``."""
    return dataclasses.replace(prob, F=step.F, gap=step.gap, snn_lift=step.snn_lift,
                               snt_lift=step.snt_lift, ut_lift=step.ut_lift,
                               u_lift=step.u_lift, ut_prev=ut_prev)


def _finite(prob: NitscheFrictionProblem) -> bool:
    arrays = [prob.A.data, prob.Un.data, prob.Snn.data, prob.Ut.data, prob.Snt.data,
              prob.weights, prob.gamma, np.atleast_1d(prob.theta)]
    for st in prob.steps:
        arrays += [st.F, st.gap, st.snn_lift, st.snt_lift, st.ut_lift]
    for a in (prob.threshold, prob.coefficient):
        if a is not None:
            arrays.append(a)
    return all(np.all(np.isfinite(a)) for a in arrays)


def _direction(solver: Any, prob: NitscheFrictionProblem, fs: nf.FrictionState,
               u: np.ndarray, R: np.ndarray) -> tuple[np.ndarray | None, str]:
    """``(d, "")`` or ``(None, why)`` for a singular tangent."""
    K = nf.tangent(prob, u, fs)
    symmetric = prob.law == "tresca" and prob.theta == 1.0
    try:
        d = solver._direction(prob, K, R, symmetric=symmetric) if symmetric \
            else spla.splu(K.tocsc()).solve(-R)
    except RuntimeError as exc:  # SuperLU: exactly singular
        return None, f"singular tangent ({exc})"
    if not np.all(np.isfinite(d)):
        return None, "singular tangent (non-finite Newton direction)"
    return d, ""


def _backtrack(prob: NitscheFrictionProblem, u: np.ndarray, d: np.ndarray, ref: float
               ) -> tuple[float | None, nf.FrictionState, np.ndarray]:
    """``(t, state, residual)`` at ``u + t d``: the first ``t = 2^-k`` (``k <=``
    :data:`BACKTRACKS`) with Armijo's decrease ``||R(u + t d)|| <= (1 - 1e-4 t) ref``
    (``ref``: the largest of the last :data:`MEMORY` residual norms; Grippo, Lampariello &
    Lucidi 1986 when > 1); ``t = None`` (and the full step's values) when none does."""
    t, first = 1.0, None
    for _ in range(BACKTRACKS + 1):
        fs = nf.state(prob, u + t * d)
        Rt = nf.residual(prob, u + t * d, fs)
        first = first or (fs, Rt)
        if np.all(np.isfinite(Rt)) and np.linalg.norm(Rt) <= (1.0 - 1e-4 * t) * ref:
            return t, fs, Rt
        t *= 0.5
    return None, *first


def newton_step_solve(solver: Any, prob: NitscheFrictionProblem, u: np.ndarray
                      ) -> tuple[np.ndarray, int, tuple[str, str], list[float],
                                 nf.FrictionState]:
    """Generalised Newton on one load step from ``u``: ``(u, iterations, (reason, why),
    relative residuals, final state)``."""
    residuals: list[float] = []
    steps: list[float] = []
    norms: list[float] = []
    fs = nf.state(prob, u)
    R = nf.residual(prob, u, fs)
    best, it, failures, prev, settled = np.inf, 0, 0, None, 0
    while True:
        rel = solver._relative(prob, u, R)
        residuals.append(rel)
        sets = np.concatenate([fs.normal.active, fs.stick])
        same = prev is not None and np.array_equal(prev, sets)
        settled = settled + 1 if same and steps and steps[-1] == 1.0 else 0
        prev, best = sets, min(best, rel)
        stop = solver._stop(prob, rel, residuals, settled, best, it)
        if stop is not None:
            return u, it, stop, residuals, fs
        d, why = _direction(solver, prob, fs, u, R)
        if d is None:
            return u, it, ("diverged", why), residuals, fs
        it += 1
        near = rel <= solver.FLOOR_TOL  # near the solution: the full (piecewise exact) step
        norms.append(float(np.linalg.norm(R)))
        t, fs_new, R_new = (None, None, None) if near else \
            _backtrack(prob, u, d, max(norms[-MEMORY:]))
        if t is None:
            failures = 0 if near else failures + 1
            if failures >= MAX_FAILURES:
                return u, it, ("stagnation", f"the line search found no decrease in "
                               f"{MAX_FAILURES} successive steps (relative residual "
                               f"{rel:.2e})"), residuals, fs
            t = 1.0
            fs_new = nf.state(prob, u + d)
            R_new = nf.residual(prob, u + d, fs_new)
        else:
            failures = 0
        steps.append(t)
        u = u + t * d
        fs, R = fs_new, R_new


def _ratios(residuals: list[float], k: int = 3) -> list[float]:
    """The last ``k`` ratios ``r_{j+1} / r_j`` of a residual history (superlinear: -> 0)."""
    r = np.asarray(residuals, float)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = r[1:] / r[:-1]
    return [float(x) for x in q[-k:]]


def _info(prob: NitscheFrictionProblem, fs: nf.FrictionState, why: str, records: list,
          extra: dict) -> dict:
    lam_n, lam_t = nf.tractions(fs)
    info = {"reason": why, "theta": float(prob.theta), "gamma0": float(prob.gamma0),
            "law": prob.law, "load_steps": records, "steps_solved": len(records),
            "n_active_points": int(fs.normal.active.sum()),
            "friction_residuals": nf.condition_residuals(prob, fs),
            "lam": "L2 projection of the Nitsche pressure -[P_gamma(u)]_- on the "
                   "multiplier space", **extra,
            "lam_n_points": lam_n, "lam_t_points": lam_t, "slip_points": fs.slip,
            "states_points": list(nf.point_states(fs)), "ut_prev_points": prob.ut_prev,
            "S_points": fs.S}
    if fs.coefficient is not None:
        info["coefficient_points"] = fs.coefficient
    return info


def solve_friction(solver: Any, problem: NitscheFrictionProblem,
                   warm_start: np.ndarray | None = None) -> SolveResult:
    """The load steps of ``problem`` in order (module docstring); ``solver`` is the
    :class:`~rbbench_plugins.solvers.newton.NewtonSolver` (its stop tests and options)."""
    t0 = time.perf_counter()
    nq = problem.weights.size
    if not _finite(problem):
        u = np.full(problem.A.shape[0], np.nan)
        return SolveResult(u=problem.expand(u), lam=np.full(problem.Mlam.shape[1], np.nan),
                           iterations=0, stop_reason="nan",
                           times={"newton_s": time.perf_counter() - t0},
                           info={"reason": "non-finite entries in the problem data",
                                 "law": problem.law})
    u, start = solver._initial_guess(problem, warm_start)
    ut_prev, records, total = np.zeros(nq), [], 0
    for k, step in enumerate(problem.steps):
        prob = at_step(problem, step, ut_prev)
        u, it, (reason, why), residuals, fs = newton_step_solve(solver, prob, u)
        total += it
        records.append({"iterations": int(it), "stop_reason": reason,
                        "residual": float(residuals[-1]), "ratios": _ratios(residuals)})
        if reason != "converged" or k == len(problem.steps) - 1:
            break
        ut_prev = fs.ut
    lam = nt.project_pressure(prob, -fs.normal.neg) if np.all(np.isfinite(u)) \
        else np.full(prob.Mlam.shape[1], np.nan)
    if k < len(problem.steps) - 1 or reason != "converged":
        why = f"load step {k + 1} of {len(problem.steps)}: {why}"
    info = _info(prob, fs, why, records, {"start": start})
    return SolveResult(u=prob.expand(u), lam=lam, iterations=total, stop_reason=reason,
                       residuals=residuals, times={"newton_s": time.perf_counter() - t0},
                       info=info)

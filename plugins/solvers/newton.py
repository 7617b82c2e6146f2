"""Generalised (semismooth) Newton for the Nitsche contact problem, with a line search.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slide "HF model" of Nitsche's method:
``u_{k+1} = u_k + delta u_k`` with ``(A_gamma + B_gamma(u_k)) delta u_k = -R_gamma(u_k)``, the
tangent built with the Heaviside function ``H(-P_gamma(u_k))``
(:func:`rbbench.hf.algebra.nitsche.tangent`). The
residual is piecewise affine in ``u``: once the active set is right, one full
step solves the problem to rounding.

Safeguard (so that a cold start ``u = 0`` converges):

* ``theta = 1``: ``R`` is the gradient of the Nitsche energy ``J``
  (:func:`rbbench.hf.algebra.nitsche.energy`); the step minimises ``J`` exactly along the
  Newton direction over ``t`` in [0, 1] (:func:`_energy_step`: ``J`` is piecewise
  quadratic in ``t``). A Newton direction that is not a descent direction means
  the tangent is not positive definite, i.e. ``gamma0`` is too small for the
  energy to be convex: the solve stops with ``diverged`` and says so.
* ``theta != 1``: the step minimises ``||R||`` exactly along the direction
  (:func:`_residual_step`: ``R`` is piecewise affine in ``t``).
* A step the line search cannot improve is taken in full (the residual is
  piecewise affine, a full step may jump to the right active set); three such
  steps in a row stop with ``stagnation``. A singular tangent, a residual
  growing ``blowup`` times above its best value, or non-finite iterates stop with
  ``diverged`` / ``nan``. Every stop carries ``info["reason"]``.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from rbbench_plugins.solvers.nitsche_friction_newton import solve_friction

from rbbench.hf.algebra import nitsche as nt
from rbbench.hf.condensation.dense import factorize
from rbbench.interfaces import (
    FrictionProblem,
    NitscheFrictionProblem,
    NitscheProblem,
    Solver,
    SolveResult,
)

#: Rounding floor: with the active set settled (full steps, same active set) and no
#: further progress, a relative residual below this is the solution to rounding
#: (large gamma makes the tangent ill-conditioned).
FLOOR_TOL = 1e-7


def _finite_problem(p: NitscheProblem) -> bool:
    arrays = (p.A.data, p.F, p.Un.data, p.Snn.data, p.gap, p.snn_lift, p.weights, p.gamma)
    return all(np.all(np.isfinite(a)) for a in arrays) and np.isfinite(p.theta)


def _breakpoints(P: np.ndarray, dP: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Points whose sign of ``P + t dP`` changes for ``t`` in (0, 1), sorted by ``t``."""
    with np.errstate(divide="ignore", invalid="ignore"):
        tq = -P / dP
    idx = np.flatnonzero((tq > 0.0) & (tq < 1.0) & np.isfinite(tq))
    order = np.argsort(tq[idx], kind="stable")
    return idx[order], tq[idx][order]


def _energy_step(prob: NitscheProblem, d: np.ndarray, st: nt.NitscheState,
                 R: np.ndarray) -> float:
    """Exact line search on the Nitsche energy (theta = 1) over ``t`` in [0, 1].

    ``phi(t) = J(u + t d)`` is piecewise quadratic; ``phi'(t) = R(u + t d) . d`` is
    piecewise affine, with kinks where a point changes status, and non-decreasing when
    ``J`` is convex: its root is found by bisection on scalars (O(n_q) per evaluation).
    """
    dw = prob.weights / prob.gamma
    sd = prob.Snn @ d
    dP = sd - prob.gamma * (prob.Un @ d)
    a0 = float(R @ d)  # phi'(0)
    # phi'(t) = a0 + t a1 + sum dw dP (min(P + t dP, 0) - min(P, 0))
    a1 = float(d @ (prob.A @ d) - np.sum(dw * sd**2))
    neg0 = np.minimum(st.P, 0.0)

    def dphi(t: float) -> float:
        return a0 + t * a1 + float(np.sum(dw * dP * (np.minimum(st.P + t * dP, 0.0) - neg0)))

    if dphi(1.0) <= 0.0:
        return 1.0
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if dphi(mid) > 0.0:
            hi = mid
        else:
            lo = mid
    return hi


def _residual_step(prob: NitscheProblem, d: np.ndarray, st: nt.NitscheState,
                   R: np.ndarray) -> float:
    """Exact minimisation of ``||R(u + t d)||`` over ``t`` in [0, 1] (any theta).

    ``R(u + t d)`` is affine in ``t`` between the breakpoints where a point changes
    status: on each segment ``R = R_s + (t - t_s) V`` with ``V`` updated by one sparse
    column per breakpoint, and ``||R||^2`` is minimised in closed form.
    """
    dw = prob.weights / prob.gamma
    th = float(prob.theta)
    sd = prob.Snn @ d
    dP = sd - prob.gamma * (prob.Un @ d)
    # dR/dt on a segment: A d - theta S^T D S d + (theta S - G U)^T D H dP
    L = (th * prob.Snn - sp.diags(prob.gamma) @ prob.Un).T.tocsc()  # (n, n_q)
    active = (st.P < 0.0) | ((st.P == 0.0) & (dP < 0.0))
    V = prob.A @ d - th * (prob.Snn.T @ (dw * sd)) + L @ (dw * active * dP)
    idx, tq = _breakpoints(st.P, dP)
    best_t, best = 0.0, float(R @ R)
    Rs, ts = R.copy(), 0.0
    bounds = np.append(tq, 1.0)
    for k, t_end in enumerate(bounds):
        length = t_end - ts
        vv = float(V @ V)
        tau = min(max(-float(Rs @ V) / vv, 0.0), length) if vv > 0 else 0.0
        val = float((Rs + tau * V) @ (Rs + tau * V))
        if val < best:
            best, best_t = val, ts + tau
        if k == len(tq):
            break
        Rs = Rs + length * V
        q = idx[k]
        sign = -1.0 if active[q] else 1.0  # the point leaves / enters the active set
        active[q] = not active[q]
        col = L[:, q]
        V = V + sign * dw[q] * dP[q] * col.toarray().ravel()
        ts = t_end
    return float(best_t)


class NewtonSolver(Solver):
    """Generalised Newton with line search for :class:`~rbbench.interfaces.NitscheProblem`.

    Parameters
    ----------
    max_iter : int
        Largest number of Newton steps (stop reason ``max_iterations``).
    tol : float
        Convergence: ``||R(u)|| <= tol * max(||F||, ||A u||, ||R(u) - A u + F||)``; or,
        once the active set is settled (two full steps with the same active set) and
        the residual stopped decreasing, ``<=`` :data:`FLOOR_TOL` (the rounding floor of
        an ill-conditioned tangent, large ``gamma0``; the reason says so).
    max_backtracks : int
        Kept for compatibility (the line searches are exact).
    blowup : float
        Stop (``diverged``) when the relative residual exceeds ``blowup`` times its
        best value so far.
    """

    name = "newton"
    #: :data:`FLOOR_TOL`, for the friction steps
    FLOOR_TOL = FLOOR_TOL

    def __init__(self, max_iter: int = 50, tol: float = 1e-10, max_backtracks: int = 30,
                 blowup: float = 1e8):
        self.max_iter, self.tol = int(max_iter), float(tol)
        self.max_backtracks, self.blowup = int(max_backtracks), float(blowup)

    # ------------------------------------------------------------------ helpers
    @staticmethod
    def _relative(prob: NitscheProblem, u: np.ndarray, R: np.ndarray) -> float:
        Au = prob.A @ u
        scale = max(np.linalg.norm(prob.F), np.linalg.norm(Au),
                    np.linalg.norm(R - Au + prob.F), np.finfo(float).tiny)
        return float(np.linalg.norm(R) / scale)

    @staticmethod
    def _direction(prob: NitscheProblem, K, R: np.ndarray, symmetric: bool | None = None
                   ) -> np.ndarray:
        """``K^{-1} (-R)``: the backend's direct solver for symmetric tangents (checked),
        else SuperLU in symmetric mode (:func:`rbbench.hf.condensation.dense.factorize`: the
        ordering of ``K + K^T``, no pivoting; checked, the tangent's pattern is symmetric
        for every theta), else SuperLU with COLAMD and partial pivoting (``symmetric``:
        default ``theta == 1``)."""
        symmetric = prob.theta == 1.0 if symmetric is None else symmetric
        if prob.factorize is not None and symmetric:
            try:
                d = prob.factorize(K)(-R)
                if np.all(np.isfinite(d)) and \
                        np.linalg.norm(K @ d + R) <= 1e-8 * np.linalg.norm(R):
                    return d
            except Exception:  # noqa: BLE001 - e.g. not positive definite: use SuperLU
                pass
        try:  # SuperLU in symmetric mode (fill-reducing on A + A^T: 3D tangents), checked
            d = factorize(K).solve(-R)
            if np.all(np.isfinite(d)) and np.linalg.norm(K @ d + R) <= 1e-8 * np.linalg.norm(R):
                return d
        except RuntimeError:  # a zero pivot without pivoting: COLAMD with partial pivoting
            pass
        return spla.splu(K.tocsc()).solve(-R)

    def _result(self, prob, u, it, reason, why, residuals, t0, extra=None) -> SolveResult:
        ok = np.all(np.isfinite(u))
        st = nt.state(prob, u) if ok else None
        p = -st.neg if ok else np.full(prob.weights.size, np.nan)  # pressure -[P_gamma]_-
        lam = nt.project_pressure(prob, p) if ok else np.full(prob.Mlam.shape[1], np.nan)
        info = {"reason": why, "theta": float(prob.theta), "gamma0": float(prob.gamma0),
                "n_active_points": int(st.active.sum()) if st is not None else None,
                "lam": "L2 projection of the Nitsche pressure -[P_gamma(u)]_- on the "
                       "multiplier space", **(extra or {})}
        return SolveResult(u=prob.expand(u), lam=lam, iterations=int(it), stop_reason=reason,
                           residuals=residuals, times={"newton_s": time.perf_counter() - t0},
                           info=info)

    @staticmethod
    def _initial_guess(prob: NitscheProblem, warm_start: np.ndarray | None
                       ) -> tuple[np.ndarray, str]:
        """``(u, how)``: the warm start on the free dofs if usable, else 0."""
        nf = prob.A.shape[0]
        u = np.zeros(nf)
        start = "cold (u = 0)"
        if warm_start is not None:
            w = np.asarray(warm_start, dtype=float).ravel()
            if w.size == prob.u_lift.size:
                w = w[prob.free]
            if w.size == nf and np.all(np.isfinite(w)):
                u, start = w.copy(), "warm"
            else:
                start = f"cold (warm start of size {w.size} or non-finite ignored)"
        return u, start

    def _stop(self, prob: NitscheProblem, rel: float, residuals: list[float], settled: int,
              best: float, it: int) -> tuple[str, str] | None:
        """``(reason, why)`` if the iteration stops at relative residual ``rel``, else None."""
        if not np.isfinite(rel):
            return "nan", "non-finite residual"
        if rel <= self.tol:
            return "converged", f"relative residual {rel:.2e} <= tol {self.tol:g}"
        stuck = settled >= 2 and rel >= 0.1 * residuals[-2]
        if stuck and rel <= FLOOR_TOL:
            return "converged", (f"active set settled, relative residual {rel:.2e} at "
                                 f"the rounding floor (<= {FLOOR_TOL:g}; tol {self.tol:g} not "
                                 "reachable: ill-conditioned tangent)")
        if stuck and settled >= 4:
            return "diverged", (f"active set settled but the relative residual "
                                f"stagnates at {rel:.2e} > {FLOOR_TOL:g}: the tangent is too "
                                f"ill-conditioned (gamma0 = {prob.gamma0:g} too large?)")
        if rel > self.blowup * best:
            return "diverged", (f"the residual grew {rel / best:.1e} times above its "
                                f"best value {best:.2e}")
        if it >= self.max_iter:
            return "max_iterations", (f"no convergence in {self.max_iter} Newton steps "
                                      f"(relative residual {rel:.2e})")
        return None

    def _newton_direction(self, prob: NitscheProblem, u: np.ndarray, st: nt.NitscheState,
                          R: np.ndarray) -> tuple[np.ndarray | None, str]:
        """``(d, "")``, or ``(None, why)`` when the tangent is singular."""
        K = nt.tangent(prob, u, st)
        try:
            d = self._direction(prob, K, R)
        except RuntimeError as exc:  # SuperLU: exactly singular
            return None, f"singular tangent ({exc})"
        if not np.all(np.isfinite(d)):
            return None, "singular tangent (non-finite Newton direction)"
        return d, ""

    # -------------------------------------------------------------------- solve
    def solve(self, problem: NitscheProblem | NitscheFrictionProblem,
              warm_start: np.ndarray | None = None) -> SolveResult:
        """Newton from ``warm_start`` (a displacement on the free or on all dofs) or 0;
        a :class:`~rbbench.interfaces.NitscheFrictionProblem` over its load steps
        (:func:`rbbench_plugins.solvers.nitsche_friction_newton.solve_friction`)."""
        if isinstance(problem, NitscheFrictionProblem):
            return solve_friction(self, problem, warm_start)
        if isinstance(problem, FrictionProblem):
            raise TypeError("newton: a mixed FrictionProblem is solved by the mixed "
                            "formulation's solvers (friction-ssn, friction-uzawa, petsc-vi, "
                            "petsc-tao); newton solves the Nitsche formulation's problems")
        return self._solve_frictionless(problem, warm_start)

    def _solve_frictionless(self, problem: NitscheProblem, warm_start: np.ndarray | None
                            ) -> SolveResult:
        """The frictionless Newton (module docstring)."""
        t0 = time.perf_counter()
        prob = problem
        if not _finite_problem(prob):
            return self._result(prob, np.full(prob.A.shape[0], np.nan), 0, "nan",
                                "non-finite entries in the problem data", [], t0)
        u, start = self._initial_guess(prob, warm_start)
        theta = float(prob.theta)
        residuals: list[float] = []
        steps: list[float] = []
        st = nt.state(prob, u)
        R = nt.residual(prob, u, st)
        best, failures, it = np.inf, 0, 0
        extra = {"start": start, "steps": steps}
        prev_active, settled = None, 0

        def done(reason: str, why: str) -> SolveResult:  # at the current u and it
            return self._result(prob, u, it, reason, why, residuals, t0, extra)

        while True:
            rel = self._relative(prob, u, R)
            residuals.append(rel)
            same = prev_active is not None and np.array_equal(prev_active, st.active)
            settled = settled + 1 if same and steps and steps[-1] == 1.0 else 0
            prev_active = st.active
            best = min(best, rel)
            stop = self._stop(prob, rel, residuals, settled, best, it)
            if stop is not None:
                return done(*stop)
            d, why = self._newton_direction(prob, u, st, R)
            if d is None:
                return done("diverged", why)
            it += 1
            if rel <= FLOOR_TOL:  # near the solution: the full (piecewise exact) step
                st = nt.state(prob, u + d)
                R = nt.residual(prob, u + d, st)
                steps.append(1.0)
                u = u + d
                failures = 0
                continue
            if theta == 1.0 and float(R @ d) >= 0.0:
                return done("diverged", "the Newton direction is not a descent direction "
                            "of the Nitsche energy: the tangent is not positive definite "
                            f"(gamma0 = {prob.gamma0:g} is too small for theta = 1)")
            t, st_new, R_new = _line_search(prob, u, d, st, R)
            if t is not None:
                failures = 0
            else:  # no decrease: take the full step (piecewise affine residual)
                failures += 1
                if failures >= 3:
                    return done("stagnation", "the line search found no decrease in 3 "
                                f"successive steps (relative residual {rel:.2e})")
                t = 1.0
                st_new = nt.state(prob, u + d)
                R_new = nt.residual(prob, u + d, st_new)
            steps.append(t)
            u = u + t * d
            st, R = st_new, R_new


def _line_search(prob: NitscheProblem, u: np.ndarray, d: np.ndarray, st: nt.NitscheState,
                 R: np.ndarray) -> tuple[float | None, nt.NitscheState, np.ndarray]:
    """``(t, state, residual)`` at ``u + t d`` after the exact line search (energy for
    theta = 1, residual norm otherwise); ``t = None`` when it brought no decrease."""
    theta = float(prob.theta)
    t = _energy_step(prob, d, st, R) if theta == 1.0 else _residual_step(prob, d, st, R)
    st_new = nt.state(prob, u + t * d)
    R_new = nt.residual(prob, u + t * d, st_new)
    decrease = (nt.energy(prob, u + t * d, st_new) < nt.energy(prob, u, st)
                if theta == 1.0 else np.linalg.norm(R_new) < np.linalg.norm(R))
    if t > 0.0 and np.all(np.isfinite(R_new)) and decrease:
        return t, st_new, R_new
    return None, st_new, R_new

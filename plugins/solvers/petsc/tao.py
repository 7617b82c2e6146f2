"""PETSc TAO bound-constrained QP on the condensed dual of the mixed contact problem
(:class:`PetscTaoSolver`; see :mod:`rbbench_plugins.solvers.petsc`)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from rbbench_plugins.solvers.petsc.common import (
    _check_warm,
    _choice,
    _finish,
    _finite_problem,
    _nan_result,
    _PetscSolver,
    _reason_name,
    _vec,
    kkt_errors,
    petsc,
    scaled_qp,
)

from rbbench.hf.algebra import friction as fa
from rbbench.hf.condensation.schur import condense_problem
from rbbench.interfaces import ContactProblem, FrictionProblem, SolveResult

__all__ = ["TAO_TYPES", "PetscTaoSolver"]

#: TAO types offered by :class:`PetscTaoSolver` (bound-constrained QP solvers).
TAO_TYPES = ("tron", "gpcg")


def _tao_callbacks(Ds: np.ndarray, q: np.ndarray, qnorm: float, counts: dict[str, int],
                   history: list[float]) -> tuple[Callable[..., Any], ...]:
    """TAO ``(objective_gradient, hessian, monitor)`` of the scaled dual QP."""

    def objective_gradient(tao: Any, xv: Any, gv: Any) -> float:
        counts["objective"] += 1
        mu = xv.getArray(readonly=True)
        g = Ds @ mu + q
        gv.setArray(g)
        return float(0.5 * mu @ (g + q))  # 1/2 mu^T Ds mu + q^T mu

    def hessian(tao: Any, xv: Any, Hm: Any, Pm: Any) -> None:
        return None  # constant Hessian, assembled once

    def monitor(tao: Any) -> None:
        history.append(float(tao.getSolutionStatus()[2]) / qnorm)

    return objective_gradient, hessian, monitor


class PetscTaoSolver(_PetscSolver):
    """PETSc TAO bound-constrained QP on the condensed dual problem.

    :func:`rbbench.hf.condensation.schur.condense_problem` (the Schur complement of the KKT
    matrix; a backend's own solver: the dense columns) forms the Delassus
    operator ``D = B A^{-1} B^T`` and ``q = G - B A^{-1} F``; the multipliers
    solve LCP(q, D), the optimality system of::

        min_{lam >= 0}  1/2 lam^T D lam + q^T lam

    (gradient ``D lam + q = G - B u``, the gap). TAO solves it scaled, in
    ``mu = lam / (c sigma)`` with ``c = 1 / mean(diag D)`` and ``sigma = max|q|``:
    ``1/2 mu^T (c D) mu + (q / sigma)^T mu`` (unit-mean Hessian diagonal, unit
    data; TAO's trust-region and line-search defaults are absolute numbers).
    Then ``u = A^{-1}(F - B^T lam)`` via the condensed object.

    Parameters
    ----------
    tao_type : {"tron", "gpcg"}
        Trust-region Newton (default) or gradient-projection conjugate gradient.
    gatol : float
        Stop when the projected-gradient norm is below ``gatol * ||q||``.
        ``grtol`` and ``gttol`` are set to 0: TAO's defaults stop early.
    max_iter : int
        Maximum number of TAO iterations.
    ksp_rtol : float
        Relative tolerance of the inner (trust-region) Krylov solve.
    pc_type : str
        Preconditioner of the inner Krylov solve on the dense reduced Hessian:
        ``"jacobi"`` (default), ``"none"``, or ``"cholesky"`` (exact, one
        Krylov step, but a singular reduced Hessian, e.g. from repeated
        constraints, raises a PETSc error: stop reason ``"diverged"``).
    kkt_tol : float
        A TAO "converged" whose relative KKT error (:func:`kkt_errors`)
        exceeds this becomes ``"stagnation"``.
    petsc_options : dict, optional
        Extra PETSc options for this solver only, without the prefix.

    Raises
    ------
    TypeError
        On an unknown option (the message lists the valid ones).
    ValueError
        On an invalid ``tao_type``.
    """

    name = "petsc-tao"
    _stem = "tao"
    OPTIONS = ("tao_type", "gatol", "max_iter", "ksp_rtol", "pc_type", "kkt_tol",
               "petsc_options")

    def __init__(self, tao_type: str = "tron", gatol: float = 1e-13, max_iter: int = 200,
                 ksp_rtol: float = 1e-14, pc_type: str = "jacobi", kkt_tol: float = 1e-8,
                 petsc_options: dict[str, Any] | None = None, **unknown: Any):
        super().__init__(kkt_tol, petsc_options, unknown)
        self.tao_type = _choice(type(self).__name__, "tao_type", tao_type, TAO_TYPES)
        self.gatol, self.ksp_rtol = float(gatol), float(ksp_rtol)
        self.max_iter = int(max_iter)
        self.pc_type = str(pc_type)

    def solve(self, problem: ContactProblem | FrictionProblem,
              warm_start: np.ndarray | None = None) -> SolveResult:
        """Solve the contact problem; see the class docstring.

        Parameters
        ----------
        problem : ContactProblem or FrictionProblem
            A friction problem goes to :meth:`solve_friction` (:meth:`tresca` per step).
        warm_start : (m,) ndarray, optional
            Initial multipliers (clipped at 0).

        Returns
        -------
        SolveResult
            ``info["petsc_reason"]`` holds the TAO converged reason.
        """
        if isinstance(problem, FrictionProblem):
            return self.solve_friction(problem, warm_start)
        if not _finite_problem(problem, warm_start):
            return _nan_result(problem, "non-finite data or warm start")
        m = problem.B.shape[0]
        lam0 = _check_warm(warm_start, m)
        cond = condense_problem(problem.A, problem.F, problem.B, problem.G,
                                factorize=problem.factorize)
        times = {"factor_s": cond.t_factor, "condense_s": cond.t_condense}
        info: dict[str, Any] = {"tao_type": self.tao_type, "n_contact_unknowns": m,
                                "options_prefix": self.prefix}
        if m == 0:
            return self._no_contact(problem, cond, times, info)
        PETSc = petsc()
        t0 = time.perf_counter()
        # normalise the data too (max|q| = 1): TAO's trust-region radius and line search
        # have absolute defaults; the problem is linear, mu scales with q
        qp = scaled_qp(cond.D, cond.q)
        c, sigma = qp[0], qp[2]
        mu0 = np.zeros(m) if lam0 is None else lam0 / (c * sigma)
        code, its, mu, history, t_setup, t_solve = self._tao(
            PETSc, qp, mu0, (np.zeros(m), np.full(m, PETSc.INFINITY)), info, t0)
        lam = (c * sigma) * mu
        tr = time.perf_counter()
        u = cond.displacement(lam)
        times.update(tao_setup_s=t_setup, tao_s=t_solve, recover_s=time.perf_counter() - tr)
        finite = bool(np.all(np.isfinite(lam)) and np.all(np.isfinite(u)))
        reason = self._stop_reason(code, finite, problem, u, lam, info)
        info["scale"] = c
        info["scale_data"] = sigma
        return SolveResult(u=problem.expand(u), lam=lam, iterations=its, stop_reason=reason,
                           residuals=history, times=times, info=info)

    def _no_contact(self, problem: ContactProblem, cond: Any,
                    times: dict[str, float], info: dict[str, Any]) -> SolveResult:
        """The solution without contact unknowns (TAO not run)."""
        info["petsc_reason"] = "not run (no contact unknowns)"
        u = cond.displacement(np.zeros(0))
        reason = _finish("converged", kkt_errors(problem, u, np.zeros(0)), self.kkt_tol,
                         info)
        return SolveResult(u=problem.expand(u), lam=np.zeros(0), iterations=0,
                           stop_reason=reason, residuals=[0.0],
                           times={**times, "tao_s": 0.0}, info=info)

    def tresca(self, D: np.ndarray, q: np.ndarray, s: float | np.ndarray,
               lam0: np.ndarray | None = None) -> fa.FrictionResult:
        """Condensed Tresca friction by TAO: the box QP ``min 1/2 x^T D x + q^T x``,
        ``lam_n >= 0``, ``|lam_t| <= s`` of :mod:`rbbench.hf.algebra.friction`, scaled as the
        contact dual (:func:`~rbbench_plugins.solvers.petsc.common.scaled_qp`), bounds
        ``[0, inf) x [-s, s] / (c sigma)``. The stop reason is PETSc's
        (``info["petsc_reason"]``), checked on the friction residuals (``kkt_tol``).
        """
        st, early = self._tresca_setup(D, q, s, lam0)
        if st is None:
            return early
        info: dict[str, Any] = {"tao_type": self.tao_type, "scale_data": st.k}
        code, its, mu, history, _, info["tao_s"] = self._tao(st.PETSc, st.qp, st.x0, st.bounds,
                                                             info, st.t0)
        return self._tresca_result(D, q, st.k * mu, st.s, code, its, history, info)

    def _tao(self, PETSc: Any, qp: tuple, mu0: np.ndarray,
             bounds: tuple[np.ndarray, np.ndarray], info: dict[str, Any], t0: float
             ) -> tuple[int | None, int, np.ndarray, list[float], float, float]:
        """Run TAO on the scaled QP ``qp`` (:func:`scaled_qp`) from ``mu0`` within ``bounds``.

        Returns ``(reason code or None after a PETSc error, iterations, mu, history,
        setup seconds, solve seconds)``; every PETSc object is destroyed.
        """
        _, Ds, _, q, qnorm = qp
        m = mu0.size
        H = PETSc.Mat().createDense((m, m), array=Ds.copy(order="F"), comm=PETSc.COMM_SELF)
        H.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        H.assemble()
        x, lo, hi = _vec(PETSc, mu0), _vec(PETSc, bounds[0]), _vec(PETSc, bounds[1])
        counts = {"objective": 0}
        history: list[float] = []
        objective_gradient, hessian, monitor = _tao_callbacks(Ds, q, qnorm, counts, history)
        tao = PETSc.TAO().create(comm=PETSc.COMM_SELF)
        try:
            tao.setOptionsPrefix(self.prefix)
            tao.setType(self.tao_type)
            tao.setObjectiveGradient(objective_gradient, None)
            tao.setHessian(hessian, H, H)
            tao.setVariableBounds((lo, hi))
            tao.setSolution(x)
            self._configure(tao, monitor, qnorm, m)
            t_setup, t_solve = self._run(tao, tao.solve, t0)
            code, its = self._outcome(PETSc, tao, qnorm, counts, info)
            mu = x.getArray().copy()
        except PETSc.Error as exc:
            t_setup, t_solve = self._failed(exc, t0, info)
            code, its, mu = None, 0, np.full(m, np.nan)
        finally:
            for obj in (tao, H, x, lo, hi):
                obj.destroy()
        return code, its, mu, history, t_setup, t_solve

    def _configure(self, tao: Any, monitor: Callable[[Any], None], qnorm: float,
                   m: int) -> None:
        """Tolerances, the monitor and the inner Krylov solve (class docstring)."""
        tao.setTolerances(gatol=self.gatol * qnorm, grtol=0.0, gttol=0.0)
        tao.setMaximumIterations(self.max_iter)
        tao.setMonitor(monitor)
        ksp = tao.getKSP()
        if ksp is not None:
            ksp.setTolerances(rtol=self.ksp_rtol, atol=0.0, max_it=max(10 * m, 100))
            ksp.getPC().setType(self.pc_type)

    @staticmethod
    def _outcome(PETSc: Any, tao: Any, qnorm: float, counts: dict[str, int],
                 info: dict[str, Any]) -> tuple[int, int]:
        """``(reason code, iterations)`` of a finished TAO run; its statistics go to
        ``info``."""
        code = int(tao.getConvergedReason())
        its = int(tao.getIterationNumber())
        info["petsc_reason"] = _reason_name(PETSc.TAO.ConvergedReason, code)
        info["gradient_norm"] = float(tao.getSolutionStatus()[2]) / qnorm
        info["objective_evals"] = counts["objective"]
        ksp = tao.getKSP()
        info["last_ksp_iterations"] = int(ksp.getIterationNumber()) if ksp else None
        return code, its

"""Condensed VI solvers: semismooth Newton (primal-dual active set) and Uzawa.

Both condense the contact problem on its multipliers once per mu
(:func:`rbbench.hf.condensation.schur.condense_problem`) and work on the LCP of the contact
unknowns (:mod:`rbbench.hf.solvers.lcp`). Options of both: ``condensation`` (``"schur"``: the
Schur complement of the KKT matrix, one sparse factorisation; ``"columns"``: the dense
``A^{-1} B^T``, the reference) and ``linear_solver`` (``"auto"``, ``"superlu"``,
``"pardiso"``; :data:`rbbench.hf.condensation.schur.LINEAR_SOLVERS`).
"""

from __future__ import annotations

import time

import numpy as np

from rbbench.hf.condensation.schur import check_options, condense_problem
from rbbench.hf.solvers import lcp
from rbbench.interfaces import ContactProblem, Solver, SolveResult


class CondensationOptions:
    """The ``condensation`` and ``linear_solver`` options (checked when the solver is made)."""

    def _set_condensation(self, condensation: str, linear_solver: str) -> None:
        """Check the options; a Schur condensation that may use PARDISO loads it now
        (:func:`rbbench.hf.condensation.pardiso.warm_up`: its first call is a per-process cost,
        paid at construction, outside the timed solves)."""
        check_options(condensation, linear_solver)
        self.condensation, self.linear_solver = condensation, linear_solver
        if condensation == "schur" and linear_solver in ("auto", "pardiso"):
            from rbbench.hf.condensation.pardiso import warm_up

            warm_up()

    def condense(self, A, F, B, G, factorize=None):
        """:func:`~rbbench.hf.condensation.schur.condense_problem` with this solver's options."""
        return condense_problem(A, F, B, G, condensation=self.condensation,
                                linear_solver=self.linear_solver, factorize=factorize)


def condensation_info(cond) -> dict:
    """The scalar ``info`` of a condensed problem (method, linear solver, fallback...)."""
    return {f"condensation_{k}" if k != "condensation" else k: v
            for k, v in cond.info.items() if isinstance(v, (str, int, float, bool))}


class _CondensedSolver(Solver, CondensationOptions):
    def _run(self, D, q, lam0):  # pragma: no cover - abstract
        raise NotImplementedError

    def solve(self, problem: ContactProblem, warm_start: np.ndarray | None = None) -> SolveResult:
        cond = self.condense(problem.A, problem.F, problem.B, problem.G, problem.factorize)
        t0 = time.perf_counter()
        lam, it, reason, res, info = self._run(cond.D, cond.q, warm_start)
        t_solve = time.perf_counter() - t0
        u = problem.expand(cond.displacement(lam))
        times = {"factor_s": cond.t_factor, "condense_s": cond.t_condense, "lcp_s": t_solve}
        return SolveResult(u=u, lam=lam, iterations=it, stop_reason=reason, residuals=res,
                           times=times, info={**info, "n_contact_unknowns": int(cond.q.size),
                                              **condensation_info(cond)})


class SemismoothNewtonSolver(_CondensedSolver):
    """Primal-dual active set / semismooth Newton (see :func:`rbbench.hf.solvers.lcp.pdas`)."""

    name = "ssn"

    def __init__(self, max_iter: int = 100, tol: float = 1e-10, condensation: str = "schur",
                 linear_solver: str = "auto"):
        self.max_iter, self.tol = int(max_iter), float(tol)
        self._set_condensation(condensation, linear_solver)

    def _run(self, D, q, lam0):
        return lcp.pdas(D, q, lam0, max_iter=self.max_iter, tol=self.tol)


class UzawaSolver(_CondensedSolver):
    """Uzawa (the baseline of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction
    methods: parametric variational inequalities" (talk), slide "Uzawa"; see
    :func:`rbbench.hf.solvers.lcp.uzawa`)."""

    name = "uzawa"

    def __init__(self, omega: float = 1.0, tol: float = 1e-9, max_iter: int = 200_000,
                 condensation: str = "schur", linear_solver: str = "auto"):
        self.omega, self.tol, self.max_iter = float(omega), float(tol), int(max_iter)
        self._set_condensation(condensation, linear_solver)

    def _run(self, D, q, lam0):
        return lcp.uzawa(D, q, lam0, omega=self.omega, tol=self.tol, max_iter=self.max_iter)

"""Condensed VI solvers: semismooth Newton (primal-dual active set) and Uzawa.

Both factorise the stiffness once per mu and work on the LCP of the contact
unknowns (:mod:`rbbench.hf.lcp`).
"""

from __future__ import annotations

import time

import numpy as np

from rbbench.hf import lcp
from rbbench.interfaces import ContactProblem, Solver, SolveResult


class _CondensedSolver(Solver):
    def _run(self, D, q, lam0):  # pragma: no cover - abstract
        raise NotImplementedError

    def solve(self, problem: ContactProblem, warm_start: np.ndarray | None = None) -> SolveResult:
        cond = lcp.condense(problem.A, problem.F, problem.B, problem.G,
                            factorize=problem.factorize)
        t0 = time.perf_counter()
        lam, it, reason, res, info = self._run(cond.D, cond.q, warm_start)
        t_solve = time.perf_counter() - t0
        u = problem.expand(cond.displacement(lam))
        times = {"factor_s": cond.t_factor, "condense_s": cond.t_condense, "lcp_s": t_solve}
        return SolveResult(u=u, lam=lam, iterations=it, stop_reason=reason, residuals=res,
                           times=times, info={**info, "n_contact_unknowns": int(cond.q.size)})


class SemismoothNewtonSolver(_CondensedSolver):
    """Primal-dual active set / semismooth Newton (see :func:`rbbench.hf.lcp.pdas`)."""

    name = "ssn"

    def __init__(self, max_iter: int = 100, tol: float = 1e-10):
        self.max_iter, self.tol = int(max_iter), float(tol)

    def _run(self, D, q, lam0):
        return lcp.pdas(D, q, lam0, max_iter=self.max_iter, tol=self.tol)


class UzawaSolver(_CondensedSolver):
    """Uzawa (seed 000 baseline; see :func:`rbbench.hf.lcp.uzawa`)."""

    name = "uzawa"

    def __init__(self, omega: float = 1.0, tol: float = 1e-9, max_iter: int = 200_000):
        self.omega, self.tol, self.max_iter = float(omega), float(tol), int(max_iter)

    def _run(self, D, q, lam0):
        return lcp.uzawa(D, q, lam0, omega=self.omega, tol=self.tol, max_iter=self.max_iter)

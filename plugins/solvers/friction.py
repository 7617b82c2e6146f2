"""Solvers of the mixed friction problem: ``friction-ssn`` and ``friction-uzawa``.

Both factorise the stiffness once per mu, condense on the contact nodes
(``x = [lam_n; lam_t]``, ``D = B A^{-1} B^T``, ``B = [Bn; Bt]``;
:mod:`rbbench.hf.algebra.friction`) and run the load steps in order: the slip of a step is
measured from the tangential jump at the end of the previous one (``ut_prev``), and each
step is warm-started from the multipliers of the previous one. A step that does not
converge stops the sequence (its stop reason is the result's).

* ``friction-ssn``: Tresca by the primal-dual active set (:func:`pdas_tresca`); Coulomb
  directly on the wedge (:func:`coulomb_direct`, ``method="direct"``) or by the fixed point on
  Tresca of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
  variational inequalities" (talk) (:func:`coulomb_fixed_point`, ``method="fixed_point"``); a
  slip law (model B) by a fixed point on the coefficient (:func:`coulomb_model_b`) or, with
  ``method="newton"``, by a semismooth Newton with the law's derivative
  (:func:`model_b_newton`, the fixed point as its fallback).
* ``friction-uzawa``: Benaceur et al.'s Uzawa (:func:`uzawa_friction`; model B: the same fixed
  point on the coefficient with Uzawa inside).
* any Tresca solver of the box QP (PETSc's ``petsc-vi`` / ``petsc-tao``):
  :func:`tresca_runner` builds the Coulomb and model-B fixed points around it.

A frictionless :class:`~rbbench.interfaces.ContactProblem` is handed to the frictionless
solver of the same kind (``ssn``, ``uzawa``), so these solvers also run frictionless scenes.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from rbbench_plugins.solvers.condensed import (
    CondensationOptions,
    SemismoothNewtonSolver,
    UzawaSolver,
    condensation_info,
)

from rbbench.hf.algebra import friction as fa
from rbbench.hf.solvers import friction as fs
from rbbench.interfaces import ContactProblem, FrictionProblem, Solver, SolveResult


def scaled_law(name: str, node_weights: np.ndarray) -> fa.CoefficientLaw:
    """The slip law ``name`` of the weighted jump ``Bt u``: ``F(t / int phi_i)``, so that
    the law sees the mean tangential jump near each node (m)."""
    law = fa.COEFFICIENT_LAWS[name]
    w = np.where(node_weights > 0, node_weights, 1.0)
    df = None if law.df is None else (lambda t: law.df(np.asarray(t) / w) / w)
    return fa.CoefficientLaw(law.name, lambda t: law.f(np.asarray(t) / w), df)


class _Condensed:
    """One condensation of the friction problem for all load steps
    (:func:`rbbench.hf.algebra.friction.condense_friction` at the first step, ``solver``'s
    ``condensation`` / ``linear_solver`` options)."""

    def __init__(self, problem: FrictionProblem, solver: CondensationOptions) -> None:
        first = problem.steps[0]
        self.c = fa.condense_friction(problem.A, first.F, problem.Bn, problem.Bt, first.Gn,
                                      -first.ut_lift, factorize=problem.factorize,
                                      condensation=solver.condensation,
                                      linear_solver=solver.linear_solver)
        self.D = self.c.D
        self.t_factor, self.t_condense = self.c.t_factor, self.c.t_condense

    def step(self, step: Any, ut_prev: np.ndarray) -> Any:
        """The condensed problem of a load step (its ``q`` and ``displacement``):
        ``G = [Gn; ut_prev - ut_lift]``, so ``q = [Gn - Bn u0; ut_prev - ut_lift - Bt u0]``."""
        return self.c.load(np.asarray(step.F, float),
                           np.concatenate([step.Gn, ut_prev - step.ut_lift]))


def _warm(warm_start: np.ndarray | None, m: int) -> np.ndarray | None:
    """A warm start of length ``2m`` (``[lam_n; lam_t]``) or ``m`` (``lam_n``, ``lam_t = 0``)."""
    if warm_start is None:
        return None
    w = np.asarray(warm_start, float).ravel()
    if w.size == 2 * m:
        return w.copy()
    if w.size == m:
        return np.concatenate([w, np.zeros(m)])
    raise ValueError(f"warm start has {w.size} entries; expected {m} (lam_n) or {2 * m} "
                     "(lam_n, lam_t)")


def _step_record(r: fa.FrictionResult) -> dict:
    return {"iterations": int(r.iterations), "stop_reason": r.stop_reason,
            "residual": float(r.residuals["max"])}


def _law_info(info: dict) -> dict:
    """The JSON-friendly scalars of a law solver's own info (contraction, fallbacks...)."""
    out = {}
    for k, v in info.items():
        if isinstance(v, (str, bool, int, float, np.floating, np.integer)):
            out[k] = v.item() if isinstance(v, (np.floating, np.integer)) else v
        elif k == "ratios":
            out[k] = [float(x) for x in v]
    return out


def solve_steps(problem: FrictionProblem, run: Callable[..., fa.FrictionResult],
                warm_start: np.ndarray | None = None,
                solver: CondensationOptions | None = None) -> SolveResult:
    """Solve the load steps of ``problem`` in order with ``run(D, q, ut_prev, x0)``;
    condensed with ``solver``'s options (default: the Schur complement, ``"auto"``)."""
    if solver is None:
        solver = CondensationOptions()
        solver._set_condensation("schur", "auto")
    cond = _Condensed(problem, solver)
    m = problem.n_nodes
    x, ut_prev = _warm(warm_start, m), np.zeros(m)
    records, history, t0 = [], [], time.perf_counter()
    for k, step in enumerate(problem.steps):
        loaded = cond.step(step, ut_prev)
        q = loaded.q
        r = run(cond.D, q, ut_prev, x)
        records.append(_step_record(r))
        history = [float(h) for h in r.history]
        u_free = loaded.displacement(r.x) if np.all(np.isfinite(r.x)) \
            else np.full(problem.A.shape[0], np.nan)
        if r.stop_reason != "converged" or k == len(problem.steps) - 1:
            break
        x, ut_prev = r.x, np.asarray(problem.Bt @ u_free).ravel() + step.ut_lift
    u = step.u_lift.copy()
    u[problem.free] = u_free
    info = {**_law_info(r.info), "law": problem.law, "n_contact_unknowns": int(2 * m),
            "load_steps": records, "steps_solved": len(records),
            "friction_residuals": dict(r.residuals),
            "lam_t": r.lam_t, "states": list(r.states), "ut_prev": ut_prev,
            "slip": fa.slip(cond.D, q, r.lam_n, r.lam_t), **condensation_info(cond.c)}
    if "coefficient" in r.info:  # model B: the final coefficient per node
        info["coefficient"] = np.asarray(r.info["coefficient"], float)
    times = {"factor_s": cond.t_factor, "condense_s": cond.t_condense,
             "lcp_s": time.perf_counter() - t0}
    return SolveResult(u=u, lam=r.lam_n, iterations=sum(s["iterations"] for s in records),
                       stop_reason=r.stop_reason, residuals=history, times=times, info=info)


def tresca_runner(problem: FrictionProblem, tresca: Callable[..., fa.FrictionResult],
                  tol: float = 1e-10) -> Callable[..., fa.FrictionResult]:
    """The :func:`solve_steps` runner of ``problem`` around one Tresca solve
    ``tresca(D, q, s, lam0=x0)`` (the box QP of :mod:`rbbench.hf.algebra.friction`).

    Tresca: ``tresca`` itself; Coulomb: Benaceur et al.'s fixed point on Tresca
    (:func:`~rbbench.hf.solvers.friction.coulomb_fixed_point` with ``tresca`` inside);
    model B: the fixed point on the coefficient around that one. The scalar ``info`` of the
    last Tresca solve is copied into the result's ``info`` under ``"inner_<key>"``.
    """
    last: dict = {}

    def inner(D, q, s, lam0=None):
        r = tresca(D, q, s, lam0=lam0)
        last.clear()
        last.update(r.info)
        return r

    def tagged(r: fa.FrictionResult) -> fa.FrictionResult:
        if problem.law != "tresca":
            r.info.update({f"inner_{k}": v for k, v in _law_info(last).items()})
        return r

    if problem.law == "tresca":
        return lambda D, q, ut, x0: inner(D, q, problem.threshold, lam0=x0)
    if problem.coefficient_law is not None:
        law = scaled_law(problem.coefficient_law, problem.node_weights)

        def coulomb(D, q, F, lam0=None):
            return fs.coulomb_fixed_point(D, q, F, lam0=lam0, tol=tol, tresca=inner)

        return lambda D, q, ut, x0: tagged(fs.coulomb_model_b(D, q, law, ut_prev=ut,
                                                              inner=coulomb, tol=tol))
    return lambda D, q, ut, x0: tagged(fs.coulomb_fixed_point(
        D, q, problem.coefficient, lam0=x0, tol=tol, tresca=inner))


class _FrictionSolver(Solver, CondensationOptions):
    """Common driver: a ContactProblem goes to ``self.frictionless``, a FrictionProblem
    through :func:`solve_steps` with :meth:`_runner`; options ``condensation`` and
    ``linear_solver`` as :mod:`rbbench_plugins.solvers.condensed`."""

    frictionless: Solver

    def solve(self, problem: Any, warm_start: np.ndarray | None = None) -> SolveResult:
        if isinstance(problem, ContactProblem):
            return self.frictionless.solve(problem, warm_start)
        if not isinstance(problem, FrictionProblem):
            raise TypeError(f"{self.name}: expected a FrictionProblem or a ContactProblem, "
                            f"got {type(problem).__name__}")
        return solve_steps(problem, self._runner(problem), warm_start, solver=self)

    def _runner(self, problem: FrictionProblem) -> Callable[..., fa.FrictionResult]:
        raise NotImplementedError  # pragma: no cover - abstract


class FrictionSSNSolver(_FrictionSolver):
    """Active set / semismooth Newton for friction (Tresca: PDAS; Coulomb: ``method``
    ``"direct"`` on the wedge or ``"fixed_point"`` on Tresca; model B: fixed point on
    the coefficient with the direct Coulomb solve inside (``"direct"``) or the fixed point
    on Tresca inside (``"fixed_point"``), or ``"newton"``: semismooth Newton with the law's
    derivative, the fixed point as its fallback (:func:`~rbbench.hf.solvers.friction.
    model_b_newton`; a constant coefficient then runs ``"direct"``, itself a semismooth
    Newton on the wedge))."""

    name = "friction-ssn"
    METHODS = ("direct", "fixed_point", "newton")

    def __init__(self, method: str = "direct", max_iter: int = 100, tol: float = 1e-10,
                 condensation: str = "schur", linear_solver: str = "auto"):
        if method not in self.METHODS:
            raise ValueError(f"friction-ssn: method {method!r} is not valid; expected one of "
                             + ", ".join(map(repr, self.METHODS)))
        self.method, self.max_iter, self.tol = method, int(max_iter), float(tol)
        self._set_condensation(condensation, linear_solver)
        self.frictionless = SemismoothNewtonSolver(max_iter=max_iter, tol=tol,
                                                   condensation=condensation,
                                                   linear_solver=linear_solver)

    def _runner(self, problem: FrictionProblem) -> Callable[..., fa.FrictionResult]:
        kw = {"max_iter": self.max_iter, "tol": self.tol}
        if problem.law == "tresca":
            return lambda D, q, ut, x0: fs.pdas_tresca(D, q, problem.threshold, lam0=x0, **kw)
        if problem.coefficient_law is not None:
            law = scaled_law(problem.coefficient_law, problem.node_weights)
            if self.method == "newton":
                return lambda D, q, ut, x0: fs.model_b_newton(D, q, law, ut_prev=ut, lam0=x0,
                                                              **kw)
            inner = fs.coulomb_direct if self.method == "direct" else fs.coulomb_fixed_point
            return lambda D, q, ut, x0: fs.coulomb_model_b(D, q, law, ut_prev=ut, inner=inner,
                                                           **kw)
        solve = fs.coulomb_fixed_point if self.method == "fixed_point" else fs.coulomb_direct
        return lambda D, q, ut, x0: solve(D, q, problem.coefficient, lam0=x0, **kw)


class FrictionUzawaSolver(_FrictionSolver):
    """Benaceur et al.'s Uzawa for friction (normal then tangential projection; model B: a fixed
    point on the coefficient with Uzawa inside)."""

    name = "friction-uzawa"

    def __init__(self, omega: float = 1.0, tol: float = 1e-9, max_iter: int = 200_000,
                 condensation: str = "schur", linear_solver: str = "auto"):
        self.omega, self.tol, self.max_iter = float(omega), float(tol), int(max_iter)
        self._set_condensation(condensation, linear_solver)
        self.frictionless = UzawaSolver(omega=omega, tol=tol, max_iter=max_iter,
                                        condensation=condensation, linear_solver=linear_solver)

    def _uzawa(self, D, q, s=None, F=None, lam0=None) -> fa.FrictionResult:
        return fa.uzawa_friction(D, q, s=s, F=F, lam0=lam0, omega=self.omega, tol=self.tol,
                                 max_iter=self.max_iter)

    def _runner(self, problem: FrictionProblem) -> Callable[..., fa.FrictionResult]:
        if problem.law == "tresca":
            return lambda D, q, ut, x0: self._uzawa(D, q, s=problem.threshold, lam0=x0)
        if problem.coefficient_law is not None:
            law = scaled_law(problem.coefficient_law, problem.node_weights)

            def inner(D, q, F, lam0=None):
                return self._uzawa(D, q, F=F, lam0=lam0)

            return lambda D, q, ut, x0: fs.coulomb_model_b(D, q, law, ut_prev=ut, inner=inner,
                                                           tol=self.tol)
        return lambda D, q, ut, x0: self._uzawa(D, q, F=problem.coefficient, lam0=x0)

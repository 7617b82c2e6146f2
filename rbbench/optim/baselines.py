"""Smooth baseline for the shape optimisation: scipy's SLSQP on the same oracle.

SLSQP (Kraft 1988) treats the oracle's subgradient as a gradient. On a nonsmooth ``Theta`` its
quasi-Newton model and line search have no convergence guarantee; it is the baseline the bundle
trust method (as in the talk "On coupling of complementarity with friction in contact shape
optimization") is compared with, not a second optimiser to trust.
Same result type as :func:`rbbench.optim.bundle.bundle_trust`; ``f`` and ``g`` are divided
by :func:`~rbbench.optim.bundle.objective_scale` internally so that ``ftol`` is relative
to ``|f(x0)|``. SLSQP keeps the bounds at every evaluation but may evaluate the oracle
where the general rows ``cl <= C x <= cu`` are violated (inside its line search); its
final ``x`` satisfies them only to its own tolerance: check ``polyhedron.residuals``.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, minimize

from rbbench.optim.bundle import (
    BundleResult,
    Oracle,
    OracleFailure,
    Polyhedron,
    call_oracle,
    objective_scale,
)


class _Cached:
    """The oracle in normalised units, remembering every point it was asked for."""

    def __init__(self, oracle: Oracle, n: int) -> None:
        self.oracle, self.n = oracle, n
        self.seen: dict[bytes, tuple[float, np.ndarray]] = {}
        self.evals, self.scale = 0, 1.0

    def raw(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        key = np.ascontiguousarray(x, dtype=float).tobytes()
        if key not in self.seen:
            self.evals += 1
            self.seen[key] = call_oracle(self.oracle, np.array(x, dtype=float), self.n)
        return self.seen[key]

    def __call__(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        f, g = self.raw(x)
        return f / self.scale, g / self.scale


def _row(k: int, cache: _Cached, x: np.ndarray, x_prev: np.ndarray) -> dict:
    """A history row in the keys of the bundle method (``agg_norm`` = |g(x)|)."""
    f, g = cache.raw(x)
    return {"iteration": k, "kind": "start" if k == 0 else "serious", "serious": True,
            "f": f, "f_trial": f, "step_norm": float(np.linalg.norm(x - x_prev)),
            "t": math.nan, "agg_norm": float(np.linalg.norm(g)), "pred": math.nan,
            "evaluations": cache.evals, "bundle_size": 0}


def slsqp(oracle: Oracle, x0: np.ndarray, polyhedron: Polyhedron, max_iter: int = 100,
          callback: Callable[[dict], None] | None = None, ftol: float = 1e-10) -> BundleResult:
    """Minimise ``f`` over ``polyhedron`` by scipy's SLSQP with the subgradient as gradient.

    Parameters
    ----------
    oracle : ``x -> (f(x), g)``; an exception or a non-finite value ends the run with
        ``stop_reason = "oracle failed: <message>"`` and the history so far.
    x0 : a feasible start (ValueError naming the violated groups otherwise).
    max_iter, callback, ftol : SLSQP's iteration limit; called with each history row
        (one per SLSQP iteration); SLSQP's ``ftol`` on ``f / |f(x0)|``.
    """
    x0 = np.array(x0, dtype=float).ravel()
    polyhedron.check(x0, "x0")
    cache = _Cached(oracle, x0.size)
    history: list[dict] = []
    state = {"x": x0, "k": 0}

    def emit(x: np.ndarray) -> None:
        row = _row(state["k"], cache, x, state["x"])
        state["x"], state["k"] = np.array(x, dtype=float), state["k"] + 1
        history.append(row)
        if callback is not None:
            callback(row)

    try:
        f0, g0 = cache.raw(x0)
    except OracleFailure as exc:
        return BundleResult(x0, math.nan, np.full(x0.size, math.nan), 0, cache.evals,
                            f"oracle failed: {exc}", history)
    cache.scale = objective_scale(f0, g0)
    emit(x0)
    cons = ([LinearConstraint(polyhedron.C, polyhedron.cl, polyhedron.cu)]
            if polyhedron.C.shape[0] else [])
    try:
        res = minimize(cache, x0, jac=True, method="SLSQP",
                       bounds=Bounds(polyhedron.lb, polyhedron.ub), constraints=cons,
                       callback=emit, options={"maxiter": max_iter, "ftol": ftol})
        x, reason, nit = np.asarray(res.x, dtype=float), f"slsqp: {res.message}", int(res.nit)
        f, g = cache.raw(x)
    except OracleFailure as exc:
        x, reason, nit = state["x"], f"oracle failed: {exc}", state["k"] - 1
        f, g = cache.raw(x)
    return BundleResult(x=x, f=f, g=g, iterations=nit, evaluations=cache.evals,
                        stop_reason=reason, history=history)

"""A solver plugin: projected gradient on the condensed dual problem
``min_{lam >= 0} 1/2 lam^T D lam + q^T lam`` of a mixed ``ContactProblem``."""

from __future__ import annotations

import numpy as np
import scipy.linalg as sla

from rbbench.plugin import ComponentSpec, ContactProblem, Solver, SolveResult, hookimpl


class ProjectedGradient(Solver):
    """Projected gradient with step ``1 / ||D||_2``; never hangs (``max_iter``)."""

    name = "pgd"

    def __init__(self, tol: float = 1e-10, max_iter: int = 2000) -> None:
        self.tol, self.max_iter = float(tol), int(max_iter)

    def solve(self, problem: ContactProblem, warm_start: np.ndarray | None = None
              ) -> SolveResult:
        A, B = problem.A.toarray(), problem.B.toarray()
        cho = sla.cho_factor(A)
        AiBt, AiF = sla.cho_solve(cho, B.T), sla.cho_solve(cho, problem.F)
        D, q = B @ AiBt, problem.G - B @ AiF  # lam >= 0 _|_ D lam + q >= 0
        m = B.shape[0]
        lam = np.zeros(m) if warm_start is None or len(warm_start) != m else \
            np.maximum(np.asarray(warm_start, dtype=float), 0.0)
        step = 1.0 / max(np.linalg.norm(D, 2), 1e-300)
        it, res = 0, np.inf
        while m:
            grad = D @ lam + q
            res = float(np.linalg.norm(np.minimum(lam, grad)))  # the complementarity residual
            if not np.isfinite(res) or res <= self.tol * (1 + np.linalg.norm(q)) \
                    or it >= self.max_iter:
                break
            lam, it = np.maximum(lam - step * grad, 0.0), it + 1
        reason = ("converged" if m == 0 or res <= self.tol * (1 + np.linalg.norm(q))
                  else "nan" if not np.isfinite(res) else "max_iterations")
        u = AiF - AiBt @ lam
        return SolveResult(u=problem.expand(u), lam=lam, iterations=it, stop_reason=reason,
                           residuals=[res if m else 0.0])


@hookimpl
def rbbench_register(registry):
    registry.add(ComponentSpec(
        name="pgd", role="solver", target="pgd_solver:ProjectedGradient",
        capabilities={"formulations": ("mixed",)},
        description="projected gradient on the condensed dual contact problem",
    ))

"""Contract of the solver role: mixed (LCP-type) and Nitsche solvers on small random
problems, degenerate and broken ones included; solvers never hang and never raise."""

from __future__ import annotations

import inspect
import threading
from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp

from rbbench.interfaces import (
    STOP_REASONS,
    ContactProblem,
    FrictionProblem,
    LoadStep,
    NitscheProblem,
    SolveResult,
)
from rbbench.registry import ComponentSpec, Registry
from rbbench.testing.contract_base import (
    ContractViolation,
    RoleContract,
    component_label,
    require,
    spd_matrix,
)


# ---------------------------------------------------------------------------
# test problems
# ---------------------------------------------------------------------------
def _problem(A, F, B, G, n_fixed: int, rng) -> ContactProblem:
    nf = A.shape[0]
    n = nf + n_fixed
    fixed = np.sort(rng.choice(n, size=n_fixed, replace=False))
    free = np.setdiff1d(np.arange(n), fixed)
    u_lift = np.zeros(n)
    u_lift[fixed] = rng.standard_normal(n_fixed)
    return ContactProblem(A=sp.csr_matrix(A), F=np.asarray(F, float), B=sp.csr_matrix(B),
                          G=np.asarray(G, float), free=free, u_lift=u_lift,
                          X=sp.identity(nf, format="csr"),
                          W=sp.identity(B.shape[0], format="csr"))


def random_contact_problem(seed: int = 0, n: int = 30, m: int = 8,
                           n_fixed: int = 4) -> ContactProblem:
    """A small, well-posed LCP-type problem: SPD ``A`` (n x n), full-rank ``B`` (m x n).

    ``G`` has negative entries so some constraints are active at the solution.
    ``n_fixed`` extra global dofs carry a Dirichlet lifting.
    """
    rng = np.random.default_rng(seed)
    A = spd_matrix(rng, n)
    B = rng.standard_normal((m, n))
    F = rng.standard_normal(n)
    G = rng.standard_normal(m)
    G[: max(1, m // 3)] = -np.abs(G[: max(1, m // 3)])
    return _problem(A, F, B, G, n_fixed, rng)


def redundant_contact_problem(seed: int = 0) -> ContactProblem:
    """:func:`random_contact_problem` with its first three constraints repeated.

    Still solvable (same ``u``), but the Delassus operator ``B A^{-1} B^T`` is
    singular and the multipliers are not unique.
    """
    p = random_contact_problem(seed)
    B = sp.vstack([p.B, p.B[:3]]).tocsr()
    return ContactProblem(A=p.A, F=p.F, B=B, G=np.r_[p.G, p.G[:3]], free=p.free,
                          u_lift=p.u_lift, X=p.X, W=sp.identity(B.shape[0], format="csr"))


def infeasible_contact_problem(seed: int = 0, n: int = 30) -> ContactProblem:
    """Constraints ``b.u <= -1`` and ``-b.u <= -1``: no ``u`` satisfies both, no solution."""
    rng = np.random.default_rng(seed)
    A = spd_matrix(rng, n)
    b = rng.standard_normal(n)
    B = np.vstack([rng.standard_normal((2, n)), b, -b])
    G = np.array([1.0, 1.0, -1.0, -1.0])
    return _problem(A, rng.standard_normal(n), B, G, 0, rng)


def random_nitsche_problem(seed: int = 0, n: int = 30, n_q: int = 12, n_fixed: int = 4,
                           theta: float = 1.0, gamma: float = 10.0) -> NitscheProblem:
    """A small Nitsche problem: SPD ``A``, random ``Un`` and a small ``Snn``, some negative
    gaps (so some points are in contact), P0 multipliers on pairs of points.

    ``Snn`` is scaled so that ``A - Snn^T diag(w / gamma) Snn`` stays positive definite
    for ``gamma >= 1`` (``theta = 1`` is then a convex minimisation).
    """
    rng = np.random.default_rng(seed)
    A = spd_matrix(rng, n)
    Un = rng.standard_normal((n_q, n)) / np.sqrt(n)
    Snn = 0.3 * rng.standard_normal((n_q, n)) / np.sqrt(n)
    gap = rng.uniform(0.05, 0.5, n_q)
    gap[: max(1, n_q // 3)] *= -1.0
    fixed = np.sort(rng.choice(n + n_fixed, size=n_fixed, replace=False))
    free = np.setdiff1d(np.arange(n + n_fixed), fixed)
    u_lift = np.zeros(n + n_fixed)
    u_lift[fixed] = rng.standard_normal(n_fixed)
    m = max(n_q // 2, 1)
    Mlam = sp.csr_matrix((np.ones(n_q), (np.arange(n_q), np.minimum(np.arange(n_q) // 2,
                                                                      m - 1))), (n_q, m))
    return NitscheProblem(A=sp.csr_matrix(A), F=rng.standard_normal(n), Un=sp.csr_matrix(Un),
                          Snn=sp.csr_matrix(Snn), gap=gap, snn_lift=0.1 * rng.standard_normal(n_q),
                          weights=rng.uniform(0.5, 1.5, n_q), gamma=np.full(n_q, float(gamma)),
                          theta=float(theta), gamma0=float(gamma), E=1.0, h=np.ones(n_q),
                          free=free, u_lift=u_lift, X=sp.identity(n, format="csr"), Mlam=Mlam)


# ---------------------------------------------------------------------------
# independent optimality checks
# ---------------------------------------------------------------------------
def _kkt_violations(prob: ContactProblem, res: SolveResult, tol: float = 1e-8) -> list[str]:
    """KKT conditions of ``A u + B^T lam = F, lam >= 0, B u <= G, lam.(G - B u) = 0``."""
    u = np.asarray(res.u, dtype=float)[prob.free]
    lam = np.asarray(res.lam, dtype=float)
    A, B, F, G = prob.A, prob.B, prob.F, prob.G
    Au, Btl = A @ u, B.T @ lam
    out = []
    eq = np.linalg.norm(Au + Btl - F)
    eq_scale = max(np.linalg.norm(F), np.linalg.norm(Au), np.linalg.norm(Btl),
                   np.finfo(float).tiny)
    if not eq <= tol * eq_scale:
        out.append(f"equilibrium ||A u + B^T lam - F|| = {eq:.3e} > {tol:g} * {eq_scale:.3e}")
    lam_scale = max(np.abs(lam).max(initial=0.0), np.finfo(float).tiny)
    if lam.size and not lam.min() >= -1e-10 * lam_scale:
        out.append(f"dual feasibility: min lam = {lam.min():.3e} < 0")
    Bu = B @ u
    s = G - Bu
    s_scale = np.abs(G).max(initial=0.0) + np.abs(Bu).max(initial=0.0)
    if s.size and not s.min() >= -tol * s_scale:
        out.append(f"primal feasibility: max(B u - G) = {-s.min():.3e} > {tol:g} * {s_scale:.3e}")
    comp = abs(float(lam @ s))
    comp_scale = np.linalg.norm(lam) * (np.linalg.norm(G) + np.linalg.norm(Bu))
    if not comp <= tol * max(comp_scale, np.finfo(float).tiny):
        out.append(f"complementarity |lam.(G - B u)| = {comp:.3e} > {tol:g} * {comp_scale:.3e}")
    return out


def _nitsche_residual(prob: NitscheProblem, u: np.ndarray) -> tuple[float, np.ndarray]:
    """Relative residual of the Nitsche equations at ``u`` (free dofs) and the point
    pressures ``-[P]_-``, written out here independently of :mod:`rbbench.hf.algebra.nitsche`."""
    s = prob.Snn @ u + prob.snn_lift
    P = s - prob.gamma * (prob.Un @ u - prob.gap)
    neg = np.minimum(P, 0.0)
    dw = prob.weights / prob.gamma
    Au = prob.A @ u
    boundary = -prob.theta * (prob.Snn.T @ (dw * s)) + (prob.theta * prob.Snn.T @ (dw * neg)
                                                       - prob.Un.T @ (prob.weights * neg))
    R = Au - prob.F + boundary
    scale = max(np.linalg.norm(prob.F), np.linalg.norm(Au), np.linalg.norm(boundary),
                np.finfo(float).tiny)
    return float(np.linalg.norm(R) / scale), -neg


# ---------------------------------------------------------------------------
# running a solver under the contract
# ---------------------------------------------------------------------------
def _call_with_timeout(fn: Callable[[], Any], timeout: float, what: str) -> Any:
    """Run ``fn`` in a daemon thread; a hang becomes a ContractViolation, not a stuck run.

    The thread of a hung call is abandoned (it cannot be killed) and keeps running
    until the process exits.
    """
    box: dict[str, Any] = {}

    def target():
        try:
            box["value"] = fn()
        except BaseException as exc:  # noqa: BLE001 - re-raised in the caller
            box["error"] = exc

    th = threading.Thread(target=target, daemon=True, name=f"rbbench-contract: {what}")
    th.start()
    th.join(timeout)
    if th.is_alive():
        raise ContractViolation(f"{what}: did not return within {timeout:g} s "
                                "(solvers must never hang: every return carries a stop reason)")
    if "error" in box:
        raise box["error"]
    return box["value"]


def _check_result(res: Any, prob: Any, n_mult: int, label: str) -> SolveResult:
    """The form of any solver's result: a :class:`SolveResult` with a known stop reason, a
    non-negative iteration count, ``u`` on the global dofs of ``prob`` and ``n_mult``
    multipliers."""
    require(isinstance(res, SolveResult),
            f"{label}: solve() returned {type(res).__name__}, not a SolveResult")
    require(res.stop_reason in STOP_REASONS,
            f"{label}: stop_reason {res.stop_reason!r} is not one of {STOP_REASONS}")
    require(isinstance(res.iterations, (int, np.integer)) and res.iterations >= 0,
            f"{label}: iterations must be a non-negative int, got {res.iterations!r}")
    n = prob.u_lift.size
    require(np.shape(res.u) == (n,), f"{label}: u has shape {np.shape(res.u)}, expected "
            f"({n},) (global dofs, Dirichlet lifting included)")
    require(np.shape(res.lam) == (n_mult,), f"{label}: lam has shape {np.shape(res.lam)}, "
            f"expected ({n_mult},)")
    return res


def _accepts(factory: Callable[..., Any], option: str) -> bool:
    """Whether ``factory`` takes the keyword ``option`` (False if it has no signature)."""
    try:
        return option in inspect.signature(factory).parameters
    except (TypeError, ValueError):
        return False


def _solve_checked(factory: Callable[..., Any], opts: dict, prob: Any, warm: Any,
                   where: str, timeout: float) -> Any:
    """``factory(**opts).solve(prob, warm_start=warm)`` within ``timeout``; any exception
    breaks the contract (a solver returns a stop reason instead)."""
    solver = factory(**opts)
    try:
        return _call_with_timeout(lambda: solver.solve(prob, warm_start=warm), timeout, where)
    except ContractViolation:
        raise
    except Exception as exc:  # noqa: BLE001 - any exception breaks the contract
        raise ContractViolation(f"{where}: solve() raised {type(exc).__name__}: {exc} "
                                "instead of returning a stop reason") from exc


class _Runner:
    """Solves under the contract: ``factory(**options)`` within ``timeout``, the result's
    form checked (:func:`_check_result`), plus the formulation's :meth:`check`."""

    def __init__(self, factory: Callable[..., Any], options: dict | None, name: str | None,
                 timeout: float) -> None:
        self.factory, self.options, self.timeout = factory, dict(options or {}), timeout
        self.label = f"solver {component_label(factory, name)!r}"

    def n_mult(self, prob: Any) -> int:
        raise NotImplementedError

    def check(self, prob: Any, res: SolveResult, where: str) -> None:
        """Formulation-specific checks of every result."""

    def run(self, prob: Any, opts: dict | None = None, warm: Any = None,
            what: str = "solve") -> SolveResult:
        where = f"{self.label}: {what}"
        opts = self.options if opts is None else opts
        res = _solve_checked(self.factory, opts, prob, warm, where, self.timeout)
        _check_result(res, prob, self.n_mult(prob), where)
        self.check(prob, res, where)
        return res

    def keeps_lifting(self, prob: Any, res: SolveResult) -> None:
        """``u`` carries ``u_lift`` on the constrained dofs."""
        fixed = np.setdiff1d(np.arange(prob.u_lift.size), prob.free)
        require(np.array_equal(np.asarray(res.u)[fixed], prob.u_lift[fixed]),
                f"{self.label}: u does not keep the Dirichlet values u_lift on the "
                "constrained dofs")

    def same_u(self, res2: SolveResult, res: SolveResult, rtol: float) -> None:
        """A warm start from ``res`` did not move ``u`` (relative ``rtol``)."""
        du = np.linalg.norm(np.asarray(res2.u) - np.asarray(res.u))
        require(du <= rtol * np.linalg.norm(res.u),
                f"{self.label}: warm start changed the solution (||du|| = {du:.3e})")

    def max_iter_one(self, prob: Any) -> SolveResult | None:
        """With ``max_iter=1`` (when the constructor takes it): at most one iteration."""
        if not _accepts(self.factory, "max_iter"):
            return None
        r1 = self.run(prob, opts={**self.options, "max_iter": 1}, what="max_iter=1")
        require(r1.iterations <= 1, f"{self.label}: max_iter=1 but {r1.iterations} iterations")
        return r1


# ---------------------------------------------------------------------------
# mixed (LCP-type) solvers
# ---------------------------------------------------------------------------
class _MixedRunner(_Runner):
    def n_mult(self, prob: ContactProblem) -> int:
        return prob.B.shape[0]

    def check(self, prob: ContactProblem, res: SolveResult, where: str) -> None:
        require(isinstance(res.residuals, list), f"{where}: residuals must be a list")

    def kkt(self, prob: ContactProblem, res: SolveResult, what: str) -> None:
        """A ``"converged"`` result satisfies the KKT conditions."""
        if not res.converged:
            return
        bad = _kkt_violations(prob, res)
        require(not bad, f"{self.label}: {what}: stop_reason 'converged' but KKT fails: "
                + "; ".join(bad))


def _solver_well_posed(r: _MixedRunner, prob: ContactProblem) -> SolveResult:
    """1. Converges, KKT, Dirichlet lifting kept, some constraint active."""
    res = r.run(prob, what="random problem")
    require(res.converged, f"{r.label}: did not converge on a small well-posed problem "
            f"(stop_reason {res.stop_reason!r} after {res.iterations} iterations)")
    r.kkt(prob, res, "random problem")
    r.keeps_lifting(prob, res)
    lam = np.asarray(res.lam, dtype=float)
    require(np.any(lam > 0), f"{r.label}: no active constraint on a problem built to have some")
    return res


def _solver_warm_start(r: _MixedRunner, prob: ContactProblem, res: SolveResult) -> None:
    """2. A warm start from the solution converges to the same ``u``."""
    lam = np.asarray(res.lam, dtype=float)
    res2 = r.run(prob, warm=lam.copy(), what="warm start from the solution")
    require(res2.converged, f"{r.label}: warm start from the solution did not converge "
            f"({res2.stop_reason!r})")
    r.kkt(prob, res2, "warm start")
    r.same_u(res2, res, 1e-6)


def _solver_no_contact(r: _MixedRunner, prob: ContactProblem) -> None:
    """3. Without contact unknowns, ``u = A^{-1} F``."""
    p0 = ContactProblem(A=prob.A, F=prob.F, B=sp.csr_matrix((0, prob.A.shape[0])),
                        G=np.zeros(0), free=prob.free, u_lift=prob.u_lift, X=prob.X,
                        W=sp.csr_matrix((0, 0)))
    r0 = r.run(p0, what="problem without contact unknowns")
    require(r0.converged, f"{r.label}: no contact unknowns: stop_reason {r0.stop_reason!r}")
    u_ref = np.linalg.solve(p0.A.toarray(), p0.F)
    require(np.allclose(np.asarray(r0.u)[p0.free], u_ref, rtol=1e-8, atol=1e-12),
            f"{r.label}: without contact unknowns u must solve A u = F")


def _solver_degenerate(r: _MixedRunner, seed: int, n_degenerate: int) -> None:
    """5. Redundant and infeasible constraints: always return; never a false "converged"."""
    for k in range(seed, seed + n_degenerate):
        pr = redundant_contact_problem(k)
        rr = r.run(pr, what=f"redundant constraints (seed {k})")
        r.kkt(pr, rr, f"redundant constraints (seed {k})")
    for k in range(seed, seed + n_degenerate):
        pinf = infeasible_contact_problem(k)
        rinf = r.run(pinf, what=f"infeasible problem (seed {k})")
        require(rinf.stop_reason != "converged",
                f"{r.label}: claims 'converged' on a problem without solution "
                f"(b.u <= -1 and -b.u <= -1; seed {k})")


def check_solver(factory: Callable[..., Any], options: dict | None = None,
                 name: str | None = None, timeout: float = 20.0, seed: int = 0,
                 n_degenerate: int = 5) -> None:
    """Contract of the solver role (``factory(**options)`` builds it).

    1. On a small random well-posed problem the solver converges, the result
       satisfies the KKT conditions and keeps the Dirichlet lifting.
    2. A warm start from that solution converges to the same ``u``.
    3. Without contact unknowns, ``u = A^{-1} F``.
    4. With ``max_iter=1`` (when the constructor takes ``max_iter``) it returns
       after at most one iteration.
    5. On degenerate problems (``n_degenerate`` seeds each): redundant
       constraints (feasible, singular Delassus operator) and infeasible
       constraints (``b.u <= -1`` and ``-b.u <= -1``), it returns.

    Every solve must return within ``timeout`` seconds, without raising, with a
    stop reason in :data:`~rbbench.interfaces.STOP_REASONS`; a ``"converged"``
    result must satisfy the KKT conditions (so none is possible on the
    infeasible problems).
    """
    r = _MixedRunner(factory, options, name, timeout)
    prob = random_contact_problem(seed)
    res = _solver_well_posed(r, prob)
    _solver_warm_start(r, prob, res)
    _solver_no_contact(r, prob)
    r1 = r.max_iter_one(prob)
    if r1 is not None:
        r.kkt(prob, r1, "max_iter=1")
    _solver_degenerate(r, seed, n_degenerate)


# ---------------------------------------------------------------------------
# Nitsche solvers
# ---------------------------------------------------------------------------
class _NitscheRunner(_Runner):
    def n_mult(self, prob: NitscheProblem) -> int:
        return prob.Mlam.shape[1]

    def check(self, prob: NitscheProblem, res: SolveResult, where: str) -> None:
        """A ``"converged"`` result solves the Nitsche equations (relative ``1e-8``)."""
        if res.converged:
            rel, _ = _nitsche_residual(prob, np.asarray(res.u, dtype=float)[prob.free])
            require(rel <= 1e-8, f"{where}: stop_reason 'converged' but the Nitsche residual "
                    f"is {rel:.3e} (relative)")


def _nitsche_theta(r: _NitscheRunner, seed: int, theta: float) -> None:
    """1.-2. A cold start converges, keeps the lifting, has contact; a warm start from the
    solution converges in at most one iteration to the same ``u``."""
    prob = random_nitsche_problem(seed, theta=theta)
    res = r.run(prob, what=f"random problem, theta = {theta:g}")
    require(res.converged, f"{r.label}: theta = {theta:g}: a cold start did not converge "
            f"on a small well-posed problem ({res.stop_reason!r})")
    r.keeps_lifting(prob, res)
    _, p = _nitsche_residual(prob, np.asarray(res.u)[prob.free])
    require(np.any(p > 0), f"{r.label}: no point in contact on a problem built to have some")
    res2 = r.run(prob, warm=np.asarray(res.u).copy(), what="warm start from the solution")
    require(res2.converged and res2.iterations <= 1,
            f"{r.label}: a warm start from the solution took {res2.iterations} iterations "
            f"({res2.stop_reason!r})")
    r.same_u(res2, res, 1e-8)


def _nitsche_nan(r: _NitscheRunner, seed: int) -> None:
    """3. NaN in the data: stop reason ``"nan"``."""
    bad = random_nitsche_problem(seed)
    bad.F = bad.F.copy()
    bad.F[0] = np.nan
    rn = r.run(bad, what="NaN in F")
    require(rn.stop_reason == "nan", f"{r.label}: NaN in the data gave stop_reason "
            f"{rn.stop_reason!r}, expected 'nan'")


def check_nitsche_solver(factory: Callable[..., Any], options: dict | None = None,
                         name: str | None = None, timeout: float = 20.0, seed: int = 0) -> None:
    """Contract of a solver of the Nitsche formulation (``factory(**options)`` builds it).

    1. For ``theta`` = 1, 0, -1 on :func:`random_nitsche_problem`, a cold start
       converges; the result solves the Nitsche equations (residual recomputed
       here, relative ``1e-8``), keeps the Dirichlet lifting, has some points in
       contact, and ``lam`` has one entry per multiplier.
    2. A warm start from that solution converges in at most one iteration to the
       same ``u``.
    3. NaN in the data: stop reason ``"nan"``.
    4. With ``max_iter=1`` (when the constructor takes it): at most one iteration.
    5. ``theta = 1`` with ``gamma`` far too small (the energy is not convex) and huge
       ``gamma``: it returns, and a ``"converged"`` result solves the equations.

    Every solve must return within ``timeout`` seconds with a stop reason in
    :data:`~rbbench.interfaces.STOP_REASONS`, without raising.
    """
    r = _NitscheRunner(factory, options, name, timeout)
    for theta in (1.0, 0.0, -1.0):
        _nitsche_theta(r, seed, theta)
    _nitsche_nan(r, seed)
    r.max_iter_one(random_nitsche_problem(seed))
    for gamma in (1e-4, 1e8):
        r.run(random_nitsche_problem(seed, theta=1.0, gamma=gamma),
              what=f"theta = 1, gamma = {gamma:g}")


# ---------------------------------------------------------------------------
# friction solvers (mixed formulation, FrictionProblem)
# ---------------------------------------------------------------------------
def random_friction_problem(seed: int = 0, law: str = "coulomb", n: int = 30, m: int = 8,
                            n_fixed: int = 4) -> FrictionProblem:
    """A small friction problem with two load steps (the second adds a shear): SPD ``A``,
    random ``Bn``, ``Bt`` (m x n), some negative gaps; Coulomb ``F = 0.3`` or Tresca
    ``s = 0.3``."""
    rng = np.random.default_rng(seed)
    A = spd_matrix(rng, n)
    Bn, Bt = rng.standard_normal((m, n)), rng.standard_normal((m, n))
    Gn = rng.uniform(0.1, 1.0, m)
    Gn[: max(1, m // 2)] *= -1.0
    fixed = np.sort(rng.choice(n + n_fixed, size=n_fixed, replace=False))
    free = np.setdiff1d(np.arange(n + n_fixed), fixed)
    F0, shear = rng.standard_normal(n), rng.standard_normal(n)
    steps = [LoadStep(F=F0 + a * shear, Gn=Gn.copy(), ut_lift=np.zeros(m),
                      u_lift=np.zeros(n + n_fixed)) for a in (0.0, 1.0)]
    law_data = {"threshold": np.full(m, 0.3)} if law == "tresca" else \
        {"coefficient": np.full(m, 0.3)}
    return FrictionProblem(A=sp.csr_matrix(A), F=steps[-1].F, Bn=sp.csr_matrix(Bn), Gn=Gn,
                           Bt=sp.csr_matrix(Bt), free=free, u_lift=steps[-1].u_lift,
                           X=sp.identity(n, format="csr"), W=sp.identity(m, format="csr"),
                           law=law, steps=steps, node_weights=np.ones(m), **law_data)


def friction_violations(prob: FrictionProblem, res: SolveResult, tol: float = 1e-7
                        ) -> list[str]:
    """The conditions of the last load step at ``res.u``, ``res.lam`` (= ``lam_n``),
    ``res.info["lam_t"]``, ``res.info["ut_prev"]``, written out here independently."""
    u, ln = np.asarray(res.u, float)[prob.free], np.asarray(res.lam, float)
    lt, ut_prev = np.asarray(res.info["lam_t"], float), np.asarray(res.info["ut_prev"], float)
    step = prob.steps[-1]
    Au, Bl = prob.A @ u, prob.Bn.T @ ln + prob.Bt.T @ lt
    eq_scale = max(np.linalg.norm(step.F), np.linalg.norm(Au), np.linalg.norm(Bl), 1e-300)
    gap = step.Gn - prob.Bn @ u
    v = prob.Bt @ u + step.ut_lift - ut_prev
    s = prob.threshold if prob.law == "tresca" else prob.coefficient * ln
    fs_ = max(np.abs(ln).max(initial=0.0), np.abs(lt).max(initial=0.0), 1e-300)
    ds = max(np.abs(gap).max(initial=0.0), np.abs(v).max(initial=0.0),
             np.abs(step.Gn).max(initial=0.0), 1e-300)
    checks = {
        "equilibrium": np.linalg.norm(Au + Bl - step.F) / eq_scale,
        "non-penetration": max(0.0, -gap.min(initial=0.0)) / ds,
        "lam_n >= 0": max(0.0, -ln.min(initial=0.0)) / fs_,
        "normal complementarity": np.abs(ln * gap).max(initial=0.0) / (fs_ * ds),
        "|lam_t| <= s": max(0.0, (np.abs(lt) - s).max(initial=0.0)) / fs_,
        "stick / slip": np.abs(v * (s - lt * np.sign(v))).max(initial=0.0) / (fs_ * ds),
    }
    return [f"{k}: {val:.3e} > {tol:g}" for k, val in checks.items() if not val <= tol]


def check_friction_solver(factory: Callable[..., Any], options: dict | None = None,
                          name: str | None = None, timeout: float = 60.0,
                          seed: int = 0) -> None:
    """Contract of a friction solver (``capabilities["friction"]`` beyond ``"none"``).

    On :func:`random_friction_problem` (Tresca and Coulomb, two load steps) it converges,
    ``lam`` is ``lam_n`` (one per node), ``info`` holds ``lam_t``, ``states``, ``ut_prev``
    and one record per load step, the conditions hold (:func:`friction_violations`) and
    the lifting is kept; NaN in the load never gives ``"converged"``.
    """
    r = _Runner(factory, options, name, timeout)
    r.n_mult = lambda prob: prob.n_nodes  # type: ignore[method-assign]
    for law in ("tresca", "coulomb"):
        prob = random_friction_problem(seed, law)
        res = r.run(prob, what=f"random {law} problem")
        require(res.converged, f"{r.label}: {law}: did not converge on a small friction "
                f"problem ({res.stop_reason!r})")
        for key in ("lam_t", "states", "ut_prev", "load_steps"):
            require(key in res.info, f"{r.label}: {law}: info has no {key!r}")
        require(len(res.info["load_steps"]) == 2, f"{r.label}: one record per load step")
        bad = friction_violations(prob, res)
        require(not bad, f"{r.label}: {law}: 'converged' but " + "; ".join(bad))
        r.keeps_lifting(prob, res)
    bad_prob = random_friction_problem(seed)
    bad_prob.steps[0].F = bad_prob.steps[0].F.copy()
    bad_prob.steps[0].F[0] = np.nan
    rn = r.run(bad_prob, what="NaN in F")
    require(rn.stop_reason != "converged", f"{r.label}: NaN in the data gave 'converged'")


def _check_registered(obj: Any, spec: ComponentSpec, registry: Registry, name: str) -> None:
    """A solver declares the formulations it solves; the mixed contract is the default.
    A mixed solver declaring friction laws also passes the (mixed) friction contract; a
    Nitsche solver's friction is checked by its own tests
    (``tests/plugins/solvers/test_nitsche_friction_newton.py``: the friction problem is the
    formulation's, built from a backend's operators)."""
    forms = tuple(spec.capabilities.get("formulations", ("mixed",)))
    mixed = "mixed" in forms or "nitsche" not in forms
    if "nitsche" in forms:
        check_nitsche_solver(obj, name=name)
    if mixed:
        check_solver(obj, name=name)
    if mixed and set(spec.capabilities.get("friction", ("none",))) - {"none"}:
        check_friction_solver(obj, name=name)


CONTRACT = RoleContract("solver", "solve", _check_registered)

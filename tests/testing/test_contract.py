"""The plugin contract suite on every registered component, and proof that it can fail."""

from __future__ import annotations

import dataclasses
import threading

import numpy as np
import pytest
import scipy.sparse as sp

from rbbench.interfaces import ContactProblem, SolveResult
from rbbench.registry import ComponentSpec, Registry, default_registry
from rbbench.scene.loading import load_scene
from rbbench.testing import (
    HERTZ_COARSE,
    ContractViolation,
    check_backend,
    check_component,
    check_formulation,
    check_solver,
    check_spec,
    component_params,
    random_contact_problem,
    reference_discretization,
)
from rbbench.testing.contract_base import check_spd

pytestmark = pytest.mark.timeout(120)

#: Contract failures caused by known bugs in code outside the contract suite:
#: (role, name) -> (text the violation must contain, bug reference). The test
#: xfails only on that exact violation and fails once the bug is fixed.
KNOWN_BUGS: dict[tuple[str, str], tuple[str, str]] = {}


# ---------------------------------------------------------------------------
# every registered component passes its contract
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("spec", component_params(default_registry()))
def test_component_contract(spec):
    bug = KNOWN_BUGS.get((spec.role, spec.name))
    try:
        check_component(spec)
    except ContractViolation as exc:
        if bug and bug[0] in str(exc):
            pytest.xfail(f"known bug: {bug[1]} ({exc})")
        raise
    if bug:
        pytest.fail(f"known bug appears fixed, remove it from KNOWN_BUGS: {bug[1]}")


def test_builtin_roles_are_all_exercised():
    ids = {p.id for p in component_params(default_registry())}
    assert {"backend:skfem", "formulation:mixed", "solver:ssn", "solver:uzawa"} <= ids


# ---------------------------------------------------------------------------
# the contract rejects broken components
# ---------------------------------------------------------------------------
def _reference_solver(problem: ContactProblem, warm_start=None) -> SolveResult:
    from rbbench.hf.condensation.dense import condense
    from rbbench.hf.solvers.lcp import nnls_dual

    cond = condense(problem.A, problem.F, problem.B, problem.G)
    lam = nnls_dual(cond.D, cond.q) if cond.q.size else np.zeros(0)
    return SolveResult(u=problem.expand(cond.displacement(lam)), lam=lam, iterations=1,
                       stop_reason="converged")


class _IgnoresContact:
    """Claims convergence for the unconstrained solution."""

    def solve(self, problem, warm_start=None):
        u = np.linalg.solve(problem.A.toarray(), problem.F)
        return SolveResult(u=problem.expand(u), lam=np.zeros(problem.B.shape[0]),
                           iterations=1, stop_reason="converged")


class _BadStopReason:
    def solve(self, problem, warm_start=None):
        res = _reference_solver(problem)
        res.stop_reason = "done"
        return res


class _ForgetsLifting:
    def solve(self, problem, warm_start=None):
        res = _reference_solver(problem)
        res.u = res.u[problem.free]
        return res


class _NegativeMultipliers:
    """Solves the equality-constrained problem (all constraints active): lam may be < 0."""

    def solve(self, problem, warm_start=None):
        from rbbench.hf.condensation.dense import condense

        cond = condense(problem.A, problem.F, problem.B, problem.G)
        lam = np.linalg.lstsq(cond.D, -cond.q, rcond=None)[0]
        return SolveResult(u=problem.expand(cond.displacement(lam)), lam=lam, iterations=1,
                           stop_reason="converged")


@pytest.mark.parametrize("solver, match", [
    (_IgnoresContact, "KKT fails"),
    (_BadStopReason, "stop_reason 'done'"),
    (_ForgetsLifting, "global dofs"),
    (_NegativeMultipliers, "dual feasibility"),
])
def test_solver_contract_rejects(solver, match):
    with pytest.raises(ContractViolation, match=match):
        check_solver(solver)


class _Exact:
    def solve(self, problem, warm_start=None):
        return _reference_solver(problem, warm_start)


def test_solver_contract_accepts_an_exact_solver():
    # NNLS on an SPD Delassus operator is exact; degenerate problems are out of its scope
    check_solver(_Exact, n_degenerate=0)


def test_solver_contract_catches_a_hang():
    release = threading.Event()

    class Hangs:
        def solve(self, problem, warm_start=None):
            release.wait(30)
            return _reference_solver(problem)

    try:
        with pytest.raises(ContractViolation, match="did not return within"):
            check_solver(Hangs, timeout=0.2)
    finally:
        release.set()


def test_solver_contract_rejects_false_convergence_on_infeasible_problem():
    class AlwaysConverged:
        def __init__(self, max_iter: int = 50):
            self.max_iter = max_iter

        def solve(self, problem, warm_start=None):
            from rbbench.hf.condensation.dense import condense
            from rbbench.hf.solvers.lcp import uzawa

            cond = condense(problem.A, problem.F, problem.B, problem.G)
            lam, it, _, res, _ = uzawa(cond.D, cond.q, warm_start, tol=1e-13,
                                       max_iter=max(self.max_iter, 1))
            return SolveResult(u=problem.expand(cond.displacement(lam)), lam=lam,
                               iterations=min(it, self.max_iter), stop_reason="converged")

    with pytest.raises(ContractViolation, match="KKT fails|without solution"):
        check_solver(AlwaysConverged, options={"max_iter": 100_000})


class _Mutated:
    """A skfem backend whose Discretization is corrupted by ``mutate(disc, mu)``."""

    def __init__(self, mutate):
        self.mutate = mutate

    def __call__(self, scene):
        backend = default_registry().create("backend", "skfem", scene=scene)
        mutate = self.mutate

        class Wrapped:
            def discretize(self, mu):
                return mutate(backend, mu)

        return Wrapped()


def _asymmetric(b, mu):
    d = b.discretize(mu)
    A = d.A.tolil()
    A[0, 1] += 1e-6 * abs(d.A).max()
    return dataclasses.replace(d, A=A.tocsr())


def _no_dirichlet(b, mu):
    d = b.discretize(mu)
    return dataclasses.replace(d, dirichlet_dofs=np.zeros(0, dtype=int),
                               dirichlet_values=np.zeros(0))


def _mu_dependent_contact(b, mu):
    d = b.discretize(mu)
    if np.allclose(d.mu, b.scene.default_mu):
        return d
    c = d.contact
    keep = slice(0, c.n_quad - 1)
    c2 = dataclasses.replace(c, Un=c.Un[keep], gap=c.gap[keep], weights=c.weights[keep],
                             points=c.points[keep], normals=c.normals[keep],
                             Mlam=c.Mlam[keep][:, : c.n_mult - 1],
                             mult_points=c.mult_points[: c.n_mult - 1],
                             mult_extent=c.mult_extent[: c.n_mult - 1])
    return dataclasses.replace(d, contact=c2)


def _no_domain_check(b, mu):
    return b._discretize_square(np.atleast_1d(np.asarray(mu, dtype=float)))


def _zero_weight(b, mu):
    d = b.discretize(mu)
    w = d.contact.weights.copy()
    w[0] = 0.0
    return dataclasses.replace(d, contact=dataclasses.replace(d.contact, weights=w))


def _dirichlet_rows_in_A(b, mu):
    d = b.discretize(mu)
    A = d.A.tolil()
    for i in d.dirichlet_dofs:  # symmetric elimination baked into A: not the free operator
        A[i, :] = 0
        A[:, i] = 0
        A[i, i] = 1.0
    return dataclasses.replace(d, A=A.tocsr())


@pytest.mark.parametrize("mutate, match", [
    (_asymmetric, "not symmetric"),
    (_no_dirichlet, "not positive definite"),
    (_mu_dependent_contact, "must not depend on mu"),
    (_no_domain_check, "must raise SceneError"),
    (_zero_weight, "weights must be > 0"),
    (_dirichlet_rows_in_A, "annihilate"),
])
def test_backend_contract_rejects(mutate, match):
    with pytest.raises(ContractViolation, match=match):
        check_backend(_Mutated(mutate), load_scene("membrane_obstacle"))


def test_backend_contract_checks_the_mu_mapping_of_the_contact_weights():
    # weights frozen at the default radius: the contact arc no longer follows R1(mu)
    def frozen(b, mu):
        d = b.discretize(mu)
        d0 = b.discretize(b.scene.default_mu)
        return dataclasses.replace(d, contact=dataclasses.replace(
            d.contact, weights=d0.contact.weights))

    with pytest.raises(ContractViolation, match="contact arc"):
        check_backend(_Mutated(frozen), load_scene("hertz_halfdisks", HERTZ_COARSE))


def test_formulation_contract_rejects_a_lost_lifting():
    from rbbench_plugins.formulations.mixed import MixedFormulation

    class NoLift(MixedFormulation):
        def build(self, disc):
            p = super().build(disc)
            return dataclasses.replace(p, u_lift=np.zeros_like(p.u_lift))

    disc = reference_discretization("elasticity")
    assert np.any(disc.dirichlet_values != 0)  # the Hertz scene imposes d != 0
    with pytest.raises(ContractViolation, match="Dirichlet values"):
        check_formulation(NoLift, disc)


def test_formulation_contract_rejects_a_nonsymmetric_operator():
    from rbbench_plugins.formulations.mixed import MixedFormulation

    class Skewed(MixedFormulation):
        def build(self, disc):
            p = super().build(disc)
            n = p.A.shape[0]
            skew = sp.diags([np.full(n - 1, 1e-3 * abs(p.A).max())], [1])
            return dataclasses.replace(p, A=(p.A + skew).tocsr())

    with pytest.raises(ContractViolation, match="not symmetric"):
        check_formulation(Skewed, reference_discretization("poisson"))


def test_spec_check_rejects_bad_declarations():
    reg = Registry()
    good = dict(name="x", role="solver", target="rbbench.hf.solvers.lcp:pdas", description="d")
    bad = {
        "empty description": (dict(good, name="a", description=" "), "empty description"),
        "capabilities list": (dict(good, name="b", capabilities=["ssn"]), "must be a dict"),
        "missing attribute": (dict(good, name="c", target="rbbench.hf.solvers.lcp:no_such_attr"),
                              "does not resolve"),
        "missing module": (dict(good, name="d", target="rbbench.no_such_mod:X"),
                           "does not resolve"),
        "unknown physics": (dict(good, name="e", capabilities={"physics": ("acoustics",)}),
                            "known physics"),
        "no solve method": (dict(good, name="f", target="rbbench.interfaces:ContactProblem"),
                            "no solve"),
    }
    for kw, match in bad.values():
        spec = ComponentSpec(**kw)
        reg.add(spec)
        with pytest.raises(ContractViolation, match=match):
            check_spec(reg, reg.get(spec.role, spec.name))
    reg.add(ComponentSpec(**good))
    assert check_spec(reg, reg.get("solver", "x")) is not None  # the good one passes


def test_spd_check_sparse_path():
    n = 2500  # above the dense limit: LDL^T pivots
    lap = sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1]).tocsr()
    check_spd(lap, "Dirichlet Laplacian")  # SPD, lambda_min ~ (pi / n)^2
    shifted = (lap - 1e-4 * sp.identity(n)).tocsr()  # one negative eigenvalue at least
    with pytest.raises(ContractViolation, match="not positive definite"):
        check_spd(shifted, "shifted")
    neumann = lap.tolil()
    neumann[0, 0] = neumann[n - 1, n - 1] = 1.0  # singular: constants in the kernel
    with pytest.raises(ContractViolation, match="not positive definite"):
        check_spd(neumann.tocsr(), "Neumann Laplacian")


# ---------------------------------------------------------------------------
# independent algebra of the built-in mixed formulation
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("physics", ["poisson", "elasticity"])
def test_mixed_formulation_is_the_restriction_of_the_backend_operators(physics):
    disc = reference_discretization(physics)
    prob = default_registry().create("formulation", "mixed").build(disc)
    rng = np.random.default_rng(7)
    v = rng.standard_normal(prob.free.size)
    u = prob.expand(v)
    # reduced residuals equal the full ones restricted to the free dofs / all multipliers
    full_r = disc.A @ u - disc.F
    red_r = prob.A @ v - prob.F
    assert np.allclose(red_r, full_r[prob.free], rtol=1e-10, atol=1e-10 * abs(full_r).max())
    c = disc.contact
    full_g = (c.Mlam.T @ (c.weights * (c.Un @ u - c.gap)))  # int phi_i (Un u - gap)
    assert np.allclose(prob.B @ v - prob.G, full_g, rtol=1e-10,
                       atol=1e-12 * abs(full_g).max())


def test_random_problem_is_well_posed():
    p = random_contact_problem(0)
    D = (p.B @ np.linalg.solve(p.A.toarray(), p.B.T.toarray()))
    assert np.linalg.eigvalsh(D)[0] > 0  # full-rank constraints: unique multipliers
    assert np.any(p.G < 0) and p.free.size == p.A.shape[0] < p.u_lift.size

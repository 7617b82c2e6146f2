"""The load-equalising phase and the staged strategy on a coarse shape_coulomb scene:
the compensated design against a manufactured solution, the phase's design against an
independent HF solve (uniform forces, Jensen's bound), J against the plain bundle method
with the same budget, raw constraint values at every evaluated design, option validation."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rbbench.optim.bundle import BundleOptions, Polyhedron, bundle_trust
from rbbench.optim.run import HFOracle, OptimizeConfig
from rbbench.optim.shape_scene import load_shape_scene
from rbbench.optim.shape_state import StateSolveError, solve_state
from rbbench.optim.strategy import (
    EqualiseOptions,
    compensated_design,
    equalise_phase,
    staged,
)
from rbbench.scene.parameters import SceneError

COARSE = {"geometry.contact_nodes": 21, "geometry.ny": 8}
FEAS = 1e-9     # the projection's accuracy (daqp, primal_tol 1e-12) with margin


@settings(max_examples=25, deadline=None)
@given(n=st.integers(2, 12), seed=st.integers(0, 2**31 - 1))
def test_compensated_design_recovers_a_manufactured_design(n, seed):
    """S with the vertical translation as its kernel, a design alpha (min 0), a state with
    zero gap at every node under arbitrary forces: f = S u - (tau, lam). The compensated
    design of (S, f, tau, lam) is alpha."""
    rng = np.random.default_rng(seed)
    m = 2 * n - 1
    e = np.r_[np.zeros(n - 1), np.ones(n)]
    Q = np.eye(m) - np.outer(e, e) / (e @ e)
    R = rng.standard_normal((m, m))
    S = Q @ (R @ R.T + m * np.eye(m)) @ Q
    alpha = rng.uniform(0, 0.1, n)
    alpha -= alpha.min()
    u = np.r_[rng.standard_normal(n - 1), -alpha + rng.standard_normal()]   # zero gap
    lam, tau = rng.uniform(0.5, 2.0, n), rng.standard_normal(n - 1)
    f = S @ u - np.r_[tau, lam]
    got = compensated_design(S, f, tau, lam)
    assert np.max(np.abs(got - alpha)) <= 1e-10
    with pytest.raises(ValueError, match="do not fit"):
        compensated_design(S, f, tau[:-1], lam)


class Recorder:
    """The HF state solver, recording every design it is asked for."""

    def __init__(self, sc):
        self.sc, self.designs = sc, []

    def __call__(self, alpha):
        self.designs.append(np.array(alpha, dtype=float))
        return solve_state(self.sc, alpha)


@pytest.fixture(scope="module")
def phase():
    sc = load_shape_scene(overrides=COARSE)
    rec, rows = Recorder(sc), []
    ph = equalise_phase(sc, sc.initial_design(), rec, callback=rows.append)
    return sc, ph, rec, rows


def test_phase_reaches_uniform_forces_by_an_independent_solve(phase):
    sc, ph, rec, rows = phase
    P, n = sc.pressure * (sc.b - sc.a), sc.n_contact
    st_ = solve_state(sc, ph.x)                           # cold start: independent
    lam = st_.lam
    assert abs(lam.sum() - P) <= 1e-8 * P                 # equilibrium
    assert np.max(np.abs(lam - P / n)) <= EqualiseOptions().force_rtol * P / n
    assert st_.contact.all()                              # every node carries load
    J = float(np.sum(lam ** sc.power))
    assert abs(J - ph.J) <= 1e-8 * J
    bound = sc.uniform_pressure_bound()
    assert bound <= J <= 1.01 * bound                     # Jensen; close to it
    J0 = float(np.sum(solve_state(sc, sc.initial_design()).lam ** sc.power))
    assert ph.J_start == pytest.approx(J0, rel=1e-10) and J0 > 50 * bound
    assert ph.solves == len(rec.designs) == len(rows)


def test_phase_designs_feasible_and_accepted_j_decreasing(phase):
    sc, ph, rec, rows = phase
    for alpha in rec.designs:                             # every evaluated design, raw
        res = sc.residuals(alpha)
        assert max(res.values()) <= FEAS, res
    accepted = [r["J"] for r in rows if r["serious"]]
    assert rows[0]["kind"] == "start" and len(accepted) == ph.accepted + 1
    assert np.all(np.diff(accepted) < 0)


def test_failed_trial_is_a_rejection():
    """A state solve failing on a trial halves the relaxation; the run goes on."""
    sc = load_shape_scene(overrides=COARSE)
    calls = {"n": 0}

    def flaky(alpha):
        calls["n"] += 1
        if calls["n"] == 2:
            raise StateSolveError("injected")
        return solve_state(sc, alpha)

    rows = []
    ph = equalise_phase(sc, sc.initial_design(), flaky, callback=rows.append)
    assert rows[1]["kind"] == "equalise_rejected" and rows[2]["relax"] == 0.5
    assert ph.J < rows[0]["J"]


@pytest.fixture(scope="module")
def both():
    """Plain bundle method and the staged strategy, the same local budget, one scene."""
    sc = load_shape_scene(overrides=COARSE)
    poly = Polyhedron(**sc.admissible())
    opts = BundleOptions(max_iter=25, max_evals=60)
    plain_oracle = HFOracle(sc)
    plain = bundle_trust(plain_oracle, sc.initial_design(), poly, opts)
    oracle, seen = HFOracle(sc), []
    solve = oracle.state

    def state(alpha):
        seen.append(np.array(alpha, dtype=float))
        return solve(alpha)

    def local(x0):
        def rec(alpha):
            seen.append(np.array(alpha, dtype=float))
            return oracle(alpha)
        res = bundle_trust(rec, x0, poly, BundleOptions(
            max_iter=25, max_evals=60, f_lower=sc.uniform_pressure_bound()))
        return res, res.f

    result = staged(sc, sc.initial_design(), state, local)
    return sc, plain, result, seen, oracle


def test_strategy_beats_the_plain_method(both):
    sc, plain, result, _, _ = both
    bound = sc.uniform_pressure_bound()
    J = float(np.sum(solve_state(sc, result.final.x).lam ** sc.power))   # independent
    assert J == pytest.approx(result.final.f, rel=1e-8)
    assert J <= 2 * bound and plain.f > 10 * bound
    assert J < plain.f
    assert result.stages[0].phase.J >= result.final.f            # never increases


def test_strategy_never_leaves_the_feasible_set(both):
    sc, _, result, seen, oracle = both
    assert len(seen) == oracle.solves >= 2
    for alpha in seen:
        res = sc.residuals(alpha)
        assert max(res.values()) <= FEAS, res
    assert max(sc.residuals(result.final.x).values()) <= 1e-8
    assert result.reason


@pytest.mark.parametrize("kw, key", [
    ({"relax0": 0.0}, "relax0"), ({"relax0": 1.5}, "relax0"),
    ({"relax_min": 2.0, "relax0": 1.0}, "relax0"), ({"max_steps": 0}, "max_steps"),
    ({"max_steps": 2.5}, "max_steps"), ({"force_rtol": 0.0}, "force_rtol"),
    ({"force_rtol": float("nan")}, "force_rtol"), ({"max_stages": True}, "max_stages"),
    ({"stage_rtol": -1.0}, "stage_rtol"),
])
def test_options_validation(kw, key):
    with pytest.raises(ValueError, match=f"EqualiseOptions.{key}"):
        EqualiseOptions(**kw)


def test_strategy_option_names_the_valid_values():
    with pytest.raises(SceneError, match="strategy = 'gaps'.*equalise, none"):
        OptimizeConfig(strategy="gaps")
    assert OptimizeConfig().strategy == "equalise"


def test_infeasible_start_is_refused():
    sc = load_shape_scene(overrides=COARSE)
    with pytest.raises(ValueError, match="alpha0 is infeasible"):
        equalise_phase(sc, sc.initial_design() + 1.0, lambda a: solve_state(sc, a))


def close_gaps(sc, steps):
    """Lower every node by its gap (projected), ``steps`` times: the naive gap closing."""
    poly = Polyhedron(**sc.admissible())
    alpha = sc.initial_design()
    for _ in range(steps):
        st_ = solve_state(sc, alpha)
        alpha = poly.project(alpha - np.maximum(st_.u_n + alpha, 0.0))
    return solve_state(sc, alpha)


def test_closing_the_gaps_alone_leaves_the_load_where_it_is():
    """Why the phase prescribes forces: with every gap closed the free nodes touch with
    zero force, and J stays far above the bound (the plain method's valley)."""
    sc = load_shape_scene(overrides=COARSE)
    st_ = close_gaps(sc, 10)
    gap = st_.u_n + st_.alpha
    assert np.max(gap) <= 1e-9                               # every gap closed
    assert np.sum(np.abs(st_.lam) <= 1e-8 * st_.lam.max()) >= 3   # touching, no force
    assert np.sum(st_.lam ** sc.power) > 50 * sc.uniform_pressure_bound()

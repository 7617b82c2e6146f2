"""Friction, high fidelity: the mixed formulation's FrictionProblem, the
``friction-ssn`` / ``friction-uzawa`` solvers over the load steps, the friction metrics.

Small meshes (hertz_halfdisks, level 0, h_contact = 0.04, P1 multipliers so that the
frictionless B equals the nodal one), one discretisation per scene, solves on the
condensed nodal problem. Every converged result is checked against the conditions written
out here from the full operators (:func:`_violations`).
"""

from __future__ import annotations

import numpy as np
import pytest

from rbbench.hf.components import friction_at, make_components
from rbbench.hf.metrics import DEFINITIONS
from rbbench.hf.model import HFModel
from rbbench.interfaces import ContactProblem, FrictionLaw, FrictionProblem
from rbbench.scene.loading import load_scene
from rbbench.scene.parameters import SceneError

MESH = ["discretization.level=0", "discretization.h_contact=0.04", "discretization.h_max=0.25",
        'discretization.multiplier="p1"']
COULOMB = ['friction.law="coulomb"', "friction.coefficient=0.2"]
#: normal load, then a shear of 2 mm: stick in the middle, slip at the edges (nu_F = 0.2)
SHEAR = ["load.tangential_displacement=0.002",
         "load.load_steps=[{normal = 1.0}, {normal = 1.0, tangential = 1.0}]"]
#: Uzawa stops on a natural residual of 1e-9: its multipliers agree with the active-set
#: solutions to this tolerance, relative to max lam_n (measured: 1e-7 normal, 4e-6 tangential)
UZAWA_RTOL = 2e-5


@pytest.fixture(scope="module")
def shear():
    """The discretisation and the mixed formulation of the sheared Coulomb scene."""
    sc = load_scene("hertz_halfdisks", MESH + COULOMB + SHEAR)
    b, f, _ = make_components(sc)
    return sc, b.discretize(sc.default_mu), f


def _solve(shear, law: FrictionLaw, solver: str = "friction-ssn", **options):
    from rbbench.registry import default_registry

    _, disc, f = shear
    prob = f.build(disc, friction=law)
    res = default_registry().create("solver", solver, **options).solve(prob)
    return prob, res


def _violations(disc, prob: FrictionProblem, res, law: FrictionLaw) -> dict[str, float]:
    """Relative residuals of the last load step from the full operators, written out here:
    equilibrium on the free dofs, Signorini, the friction bound and the stick / slip law
    (``v = Bt u - ut_prev``, ``|lam_t| < s => v = 0``, ``v != 0 => lam_t = s sign v``)."""
    c = disc.contact
    u, ln, lt = res.u, res.lam, np.asarray(res.info["lam_t"])
    Bn, Bt = c.B_nodal(), c.Bt()
    r = disc.A @ u + Bn.T @ ln + Bt.T @ lt - disc.F
    eq = np.linalg.norm(r[prob.free]) / np.linalg.norm((disc.A @ u)[prob.free])
    gap = c.G_nodal() - Bn @ u
    v = Bt @ u - np.asarray(res.info["ut_prev"])
    s = np.full(ln.size, law.threshold) if law.law == "tresca" else law.coefficient * ln
    fs = np.abs(ln).max()
    ds = max(np.abs(gap).max(), np.abs(v).max())
    return {"equilibrium": eq, "penetration": max(0.0, -gap.min()) / ds,
            "lam_n < 0": max(0.0, -ln.min()) / fs,
            "complementarity": np.abs(ln * gap).max() / (fs * ds),
            "bound": max(0.0, (np.abs(lt) - s).max()) / fs,
            "stick / slip": np.abs(v * (s - lt * np.sign(v))).max() / (fs * ds)}


def _check(disc, prob, res, law, tol=1e-8):
    assert res.converged, (res.stop_reason, res.info.get("why"), res.info["load_steps"])
    bad = {k: v for k, v in _violations(disc, prob, res, law).items() if not v <= tol}
    assert not bad, bad


def _states(res) -> dict[str, int]:
    st = list(res.info["states"])
    return {k: st.count(k) for k in ("open", "stick", "slip")}


def test_frictionless_scene_builds_the_same_contact_problem():
    sc = load_scene("hertz_halfdisks", MESH)
    b, f, s = make_components(sc)
    disc = b.discretize(sc.default_mu)
    assert friction_at(sc, sc.default_mu) is None and type(f.build(disc)) is ContactProblem
    assert s.name == "ssn"


def test_coefficient_zero_reproduces_the_frictionless_solve():
    """nu_F = 0 (one step, no shear): u and lam_n equal the frictionless solve to 1e-10."""
    ref = HFModel(load_scene("hertz_halfdisks", MESH)).solve()
    sol = HFModel(load_scene("hertz_halfdisks", MESH + ['friction.law="coulomb"',
                                                        "friction.coefficient=0.0"])).solve()
    assert isinstance(sol.problem, FrictionProblem) and sol.result.converged
    assert np.abs(sol.result.u - ref.result.u).max() <= 1e-10 * np.abs(ref.result.u).max()
    assert np.abs(sol.result.lam - ref.result.lam).max() <= 1e-10 * ref.result.lam.max()
    assert np.all(sol.result.info["lam_t"] == 0.0) and sol.metrics["tangential_force"] == 0.0
    assert sol.metrics["contact_force"] == pytest.approx(ref.metrics["contact_force"],
                                                         rel=1e-10)


def test_large_coefficient_sticks_everywhere_on_the_active_zone(shear):
    _, disc, _ = shear
    law0, law = FrictionLaw("coulomb", coefficient=0.0), FrictionLaw("coulomb", coefficient=1e3)
    p0, free = _solve(shear, law0)
    prob, res = _solve(shear, law)
    _check(disc, p0, free, law0)
    _check(disc, prob, res, law)
    st = _states(res)
    assert st["slip"] == 0 and st["stick"] > 5
    active = res.lam > 1e-8 * res.lam.max()
    v, v0 = np.abs(res.info["slip"][active]), np.abs(free.info["slip"][active])
    assert v.max() <= 1e-9 * v0.max()


def test_solvers_agree_with_stick_and_slip(shear):
    """friction-ssn direct, fixed point and friction-uzawa on one case with stick in the
    middle and slip at the edges: lam_n, lam_t and the tangential force agree (active-set
    solutions to 1e-9, Uzawa to UZAWA_RTOL, relative to max lam_n)."""
    _, disc, _ = shear
    law = FrictionLaw("coulomb", coefficient=0.2)
    prob, direct = _solve(shear, law)
    _, fixed = _solve(shear, law, method="fixed_point")
    _, uzawa = _solve(shear, law, "friction-uzawa", omega=1.9, tol=1e-9)
    st = _states(direct)
    assert st["stick"] > 0 and st["slip"] > 0 and st["open"] > 0
    assert len(direct.info["load_steps"]) == 2
    for res, rtol in ((fixed, 1e-9), (uzawa, UZAWA_RTOL)):
        _check(disc, prob, res, law, tol=1e-8 if res is fixed else 1e-6)
        scale = direct.lam.max()
        assert np.abs(res.lam - direct.lam).max() <= rtol * scale
        assert np.abs(res.info["lam_t"] - direct.info["lam_t"]).max() <= rtol * scale
        Ft = [float(np.sum(r.info["lam_t"] * prob.node_weights)) for r in (res, direct)]
        assert Ft[0] == pytest.approx(Ft[1], rel=rtol)
    _check(disc, prob, direct, law)


def test_tresca_extremes(shear):
    """A huge threshold sticks everywhere; threshold 0 is frictionless.

    Tresca's bound does not depend on lam_n, so with a huge ``s`` every node of the
    potential zone is glued tangentially, open ones included (unlike Coulomb)."""
    _, disc, _ = shear
    huge, zero = FrictionLaw("tresca", threshold=1e15), FrictionLaw("tresca", threshold=0.0)
    prob, res = _solve(shear, huge)
    _check(disc, prob, res, huge)
    assert _states(res)["slip"] == 0
    free = _solve(shear, FrictionLaw("coulomb", coefficient=0.0))[1]
    assert np.abs(res.info["slip"]).max() <= 1e-9 * np.abs(free.info["slip"]).max()
    prob, res = _solve(shear, zero)
    _check(disc, prob, res, zero)
    assert np.all(res.info["lam_t"] == 0.0)
    assert np.abs(res.u - free.u).max() <= 1e-10 * np.abs(free.u).max()
    assert np.abs(res.lam - free.lam).max() <= 1e-10 * free.lam.max()


def test_model_b_reports_its_contraction(shear):
    _, disc, _ = shear
    prob, res = _solve(shear, FrictionLaw("coulomb", coefficient_law="model_b"))
    assert res.stop_reason in ("converged", "stagnation", "diverged", "max_iterations")
    assert "contraction" in res.info and "ratios" in res.info
    assert res.converged, res.info.get("why")
    F = res.info["coefficient"]
    assert F.shape == (prob.n_nodes,) and np.all((F > 0) & (F <= 0.25))
    _check(disc, prob, res, FrictionLaw("coulomb", coefficient=F))


def test_hf_model_friction_metrics():
    sol = HFModel(load_scene("hertz_halfdisks", MESH + COULOMB + SHEAR)).solve()
    m = sol.metrics
    assert sol.components["solver"] == "friction-ssn" and m["converged"]
    assert m["n_stick"] + m["n_slip"] + m["n_open"] == sol.problem.n_nodes == m["n_contact"]
    assert m["n_stick"] > 0 and m["n_slip"] > 0
    assert 0 < m["tangential_force"] < 0.2 * m["contact_force"]
    assert 0 < m["stick_half_width"] < m["contact_half_width"]
    assert m["friction_residual"] <= 1e-10
    for key in ("tangential_force", "n_stick", "n_slip", "n_open", "stick_half_width",
                "friction_residual"):
        assert key in DEFINITIONS and key in m["definitions"]
    assert "lam_t" not in m["solver_info"] and len(m["solver_info"]["load_steps"]) == 2


def test_frictionless_only_solver_is_refused_on_a_friction_scene():
    sc = load_scene("hertz_halfdisks", MESH + COULOMB)
    with pytest.raises(SceneError, match=r"'uzawa' solver supports 'none' only.*"
                                         r"'friction-ssn', 'friction-uzawa'"):
        make_components(sc, solver="uzawa")


def test_friction_solvers_solve_frictionless_problems_as_their_frictionless_kin():
    sc = load_scene("hertz_halfdisks", MESH)
    ref = HFModel(sc, solver="ssn").solve()
    sol = HFModel(sc, solver="friction-ssn").solve()
    assert np.array_equal(sol.result.u, ref.result.u)
    assert np.array_equal(sol.result.lam, ref.result.lam)


@pytest.mark.parametrize("method", ["direct", "fixed_point"])
def test_coulomb_extremes_converge_or_stop_with_a_reason(shear, method):
    """nu_F in {0, 1e-3, 0.2, 1, 10}: each converges (and then satisfies the
    conditions) or stops with a reason; more friction, fewer slipping nodes."""
    _, disc, _ = shear
    slipping = []
    for nu in (0.0, 1e-3, 0.2, 1.0, 10.0):
        law = FrictionLaw("coulomb", coefficient=nu)
        prob, res = _solve(shear, law, method=method)
        assert res.stop_reason in ("converged", "stagnation", "max_iterations", "diverged",
                                   "nan")
        _check(disc, prob, res, law)
        slipping.append(_states(res)["slip"])
    assert slipping == sorted(slipping, reverse=True) and slipping[-1] < slipping[0]


@pytest.mark.parametrize("solver", ["friction-ssn",
                                    pytest.param("friction-uzawa", marks=pytest.mark.slow)])
def test_tresca_thresholds(shear, solver):
    """Tresca s in {0, 1e9 Pa (stick and slip), 1e15 (friction-ssn only: Uzawa is slow on
    full stick)}: each converges."""
    _, disc, _ = shear
    opts = {"omega": 1.9, "tol": 1e-9} if solver == "friction-uzawa" else {}
    for s in (0.0, 1e9) if opts else (0.0, 1e9, 1e15):
        law = FrictionLaw("tresca", threshold=s)
        prob, res = _solve(shear, law, solver, **opts)
        _check(disc, prob, res, law, tol=1e-8 if solver == "friction-ssn" else 1e-6)


def test_skfem_and_ngsolve_agree_on_one_mesh():
    """The same friction solve on both backends (NGSolve on the scikit-fem mesh): the
    nodal multipliers and the forces agree to 1e-8 (the operators agree to 1e-12)."""
    pytest.importorskip("ngsolve", reason="NGSolve backend not installed")
    sc = load_scene("hertz_halfdisks", MESH + COULOMB + SHEAR)
    ref = HFModel(sc).solve()
    comps = make_components(sc, "ngsolve", component_options={"backend": {"mesh": "skfem"}})
    sol = HFModel(sc, backend="ngsolve", components=comps).solve()
    assert sol.result.converged and ref.result.converged
    scale = ref.result.lam.max()
    assert np.abs(sol.result.lam - ref.result.lam).max() <= 1e-8 * scale
    assert np.abs(sol.result.info["lam_t"] - ref.result.info["lam_t"]).max() <= 1e-8 * scale
    for key in ("contact_force", "tangential_force", "stick_half_width"):
        assert sol.metrics[key] == pytest.approx(ref.metrics[key], rel=1e-8, abs=1e-12)
    assert list(sol.result.info["states"]) == list(ref.result.info["states"])

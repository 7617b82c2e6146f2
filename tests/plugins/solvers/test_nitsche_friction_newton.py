"""Nitsche friction: the shear stress operator ``Snt``, the
Chouly-Hild-Renard tangential term (:mod:`rbbench.hf.algebra.nitsche_friction`) and the generalised
Newton over the load steps, checked against the frictionless Nitsche solve, the mixed
friction solve (``friction-ssn``), the other backend, and the algebra written out here.

Coarse meshes: hertz_halfdisks (level 0, h_contact = 0.04, a shear of 2 mm) and
mindlin_cylinders with h_contact = 0.004 (about 3,400 dofs).
"""

from __future__ import annotations

import numpy as np
import pytest
from rbbench_plugins.formulations.nitsche import NitscheFormulation
from rbbench_plugins.solvers.newton import NewtonSolver
from rbbench_plugins.solvers.nitsche_friction_newton import at_step
from support.fields import affine_field

from rbbench.hf.algebra import nitsche_friction as nf
from rbbench.hf.components import make_components
from rbbench.hf.model import HFModel
from rbbench.interfaces import STOP_REASONS, FrictionLaw, NitscheFrictionProblem
from rbbench.registry import default_registry
from rbbench.scene.loading import load_scene

MESH = ["discretization.level=0", "discretization.h_contact=0.04", "discretization.h_max=0.25",
        'discretization.multiplier="p1"']
COULOMB = ['friction.law="coulomb"', "friction.coefficient=0.2"]
SHEAR = ["load.tangential_displacement=0.002",
         "load.load_steps=[{normal = 1.0}, {normal = 1.0, tangential = 1.0}]"]
MINDLIN = ["discretization.h_contact=0.004"]
STRESS = frozenset({"stress"})


def _disc(name: str, overrides: list[str], backend: str = "skfem", **options):
    sc = load_scene(name, overrides)
    b = default_registry().create("backend", backend, scene=sc, **options)
    return b.discretize(sc.default_mu, needs=STRESS)


@pytest.fixture(scope="module")
def shear():
    """hertz_halfdisks sheared by 2 mm in a second load step (Coulomb scene)."""
    return _disc("hertz_halfdisks", MESH + COULOMB + SHEAR)


@pytest.fixture(scope="module")
def mindlin():
    return _disc("mindlin_cylinders", MINDLIN)


def _nitsche(disc, law: FrictionLaw, theta: float = 1.0, gamma0: float = 10.0):
    prob = NitscheFormulation(theta, gamma0).build(disc, friction=law)
    return prob, NewtonSolver().solve(prob)


def _forces(disc, lam_n_q: np.ndarray, lam_t_q: np.ndarray) -> tuple[float, float]:
    """(P, Q): the vertical and horizontal resultants of point tractions."""
    c = disc.contact
    w = c.weights * -c.normals[:, 1]
    return float(w @ lam_n_q), float(w @ lam_t_q)


def _mixed_forces(disc, law: FrictionLaw) -> tuple[float, float]:
    reg = default_registry()
    res = reg.create("solver", "friction-ssn").solve(
        reg.create("formulation", "mixed").build(disc, friction=law))
    assert res.converged
    Mt = disc.contact.Mt
    return _forces(disc, Mt @ res.lam, Mt @ res.info["lam_t"])


def _states(res) -> dict[str, int]:
    st = list(res.info["states_points"])
    return {k: st.count(k) for k in ("open", "stick", "slip")}


# ---------------------------------------------------------------------------
# the shear stress operator
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("degree", [1, 2])
def test_snt_is_exact_for_affine_fields_and_only_with_friction(degree):
    sc = load_scene("hertz_halfdisks", MESH + COULOMB + [f"discretization.degree={degree}"])
    b = default_registry().create("backend", "skfem", scene=sc)
    assert b.discretize(0.8).contact.Snt is None  # tangential only: no stress
    frictionless = load_scene("hertz_halfdisks", MESH)
    bf = default_registry().create("backend", "skfem", scene=frictionless)
    assert bf.discretize(0.8, needs=STRESS).contact.Snt is None  # stress only
    d = b.discretize(0.8, needs=STRESS)
    G = np.array([[1e-3, 2e-3], [-5e-4, 3e-3]])
    E, nu = sc.material("upper")
    lam, mu_l = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    eps = 0.5 * (G + G.T)
    sig = lam * np.trace(eps) * np.eye(2) + 2 * mu_l * eps
    n = d.contact.normals
    t = np.stack([-n[:, 1], n[:, 0]], axis=1)
    want = np.einsum("qi,ij,qj->q", t, sig, n)
    got = d.contact.Snt @ affine_field(b, d, 0.8, G)
    assert np.abs(got - want).max() <= 1e-10 * np.abs(want).max()


# ---------------------------------------------------------------------------
# the algebra
# ---------------------------------------------------------------------------
def test_tangent_is_the_derivative_of_the_residual_off_the_kinks(shear):
    """Coulomb (non-symmetric K): K d equals the central difference of R along d."""
    prob, res = _nitsche(shear, FrictionLaw("coulomb", coefficient=0.2))
    p = at_step(prob, prob.steps[-1], res.info["ut_prev_points"])
    rng = np.random.default_rng(0)
    u = res.u[prob.free] * (1 + 0.01 * rng.standard_normal(prob.free.size))
    fs = nf.state(p, u)
    assert _states_of(fs) >= {"stick", "slip", "open"}
    d = rng.standard_normal(u.size) * np.abs(u).max() * 1e-9
    K = nf.tangent(p, u, fs)
    fd = (nf.residual(p, u + d) - nf.residual(p, u - d)) / 2
    assert np.linalg.norm(K @ d - fd) <= 1e-6 * np.linalg.norm(fd)
    assert abs(K - K.T).max() > 1e-6 * abs(K).max()  # the slip term: non-symmetric


def _states_of(fs) -> set:
    return set(nf.point_states(fs))


def test_sign_of_the_shear_traction_matches_the_mixed_one(shear):
    """A shear of the upper body along +x: the mixed tangential force (lam_t enters A u +
    Bt^T lam_t = F as lam_n does) and the Nitsche one (-[P_t]_S) are both positive."""
    law = FrictionLaw("coulomb", coefficient=0.2)
    _, res = _nitsche(shear, law)
    Q = _forces(shear, res.info["lam_n_points"], res.info["lam_t_points"])[1]
    Qm = _mixed_forces(shear, law)[1]
    assert Q > 0 and Qm > 0 and Q == pytest.approx(Qm, rel=0.05)


# ---------------------------------------------------------------------------
# limits: nu_F = 0 and a large nu_F
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("theta", [0.0, 1.0])
def test_zero_coefficient_reproduces_the_frictionless_solve(theta):
    """nu_F = 0: S = 0 and the tangential term is ``-theta int sigma_nt(u) sigma_nt(v) /
    gamma``, Nitsche's imposition of sigma_nt = 0. It vanishes for theta = 0: u to 1e-10;
    for theta = 1 it is a consistent O(h) perturbation (measured 2.0e-4 relative in u)."""
    def solve(extra):
        sc = load_scene("hertz_halfdisks", MESH + extra)
        b = default_registry().create("backend", "skfem", scene=sc)
        return HFModel(sc, formulation="nitsche", components=(
            b, NitscheFormulation(theta), NewtonSolver())).solve()

    ref = solve([])
    sol = solve(['friction.law="coulomb"', "friction.coefficient=0.0"])
    assert isinstance(sol.problem, NitscheFrictionProblem) and sol.result.converged
    du = np.abs(sol.result.u - ref.result.u).max() / np.abs(ref.result.u).max()
    assert np.all(sol.result.info["lam_t_points"] == 0.0)
    assert sol.metrics["tangential_force"] == 0.0
    assert du <= (1e-10 if theta == 0.0 else 1e-3)


def test_large_coefficient_sticks_the_active_zone(shear):
    """nu_F = 1e3: no slipping point. Nitsche imposes stick weakly: the raw slip at the
    active points is ``(sigma_nt(u) - [P_t]_S) / gamma``, not zero; measured 3.3 % of the
    frictionless slip at gamma0 = 10 and 0.6 % at gamma0 = 100 (it falls with 1 / gamma)."""
    ratios = []
    for g0 in (10.0, 100.0):
        _, free = _nitsche(shear, FrictionLaw("coulomb", coefficient=0.0), gamma0=g0)
        _, res = _nitsche(shear, FrictionLaw("coulomb", coefficient=1e3), gamma0=g0)
        assert res.converged and _states(res)["slip"] == 0 and _states(res)["stick"] > 5
        active = np.asarray(res.info["states_points"]) != "open"
        v = np.abs(res.info["slip_points"][active]).max()
        ratios.append(v / np.abs(free.info["slip_points"][active]).max())
    assert ratios[0] <= 0.05 and ratios[1] <= ratios[0] / 3


# ---------------------------------------------------------------------------
# against the mixed formulation, the other backend, extremes, convergence
# ---------------------------------------------------------------------------
@pytest.mark.parametrize(("law", "theta"), [(FrictionLaw("coulomb", coefficient=0.2), 1.0),
                                            (FrictionLaw("tresca", threshold=1e8), -1.0)])
def test_forces_agree_with_the_mixed_solve_within_the_discretisation_error(mindlin, law,
                                                                           theta):
    """mindlin_cylinders, h_contact = 0.004: |P, Q (Nitsche) - P, Q (friction-ssn)| is below
    half the change of the mixed P, Q when h_contact halves (its discretisation error).
    Measured: Nitsche - mixed <= 1.2e-3 relative; the mixed change 5.9e-3 (P), 8.3e-3 (Q)."""
    _, res = _nitsche(mindlin, law, theta)
    assert res.converged, res.info["reason"]
    P, Q = _forces(mindlin, res.info["lam_n_points"], res.info["lam_t_points"])
    Pm, Qm = _mixed_forces(mindlin, law)
    Pf, Qf = _mixed_forces(_disc("mindlin_cylinders", ["discretization.h_contact=0.002"]), law)
    assert abs(P - Pm) <= 0.5 * abs(Pf - Pm)
    assert abs(Q - Qm) <= 0.5 * abs(Qf - Qm)
    assert 0 < Q < (0.2 * P if law.law == "coulomb" else np.inf)


def test_skfem_and_ngsolve_agree_on_one_mesh():
    """The same Nitsche friction solve on both backends (NGSolve on the scikit-fem mesh):
    point tractions, forces and point states agree to 1e-8."""
    pytest.importorskip("ngsolve", reason="NGSolve backend not installed")
    sc = load_scene("mindlin_cylinders", MINDLIN)
    ref = HFModel(sc, formulation="nitsche").solve()
    comps = make_components(sc, "ngsolve", "nitsche",
                            component_options={"backend": {"mesh": "skfem"}})
    sol = HFModel(sc, backend="ngsolve", formulation="nitsche", components=comps).solve()
    assert sol.result.converged and ref.result.converged
    info, rinfo = sol.result.info, ref.result.info
    scale = rinfo["lam_n_points"].max()
    for key in ("lam_n_points", "lam_t_points"):
        assert np.abs(info[key] - rinfo[key]).max() <= 1e-8 * scale
    for key in ("contact_force", "tangential_force", "stick_half_width"):
        assert sol.metrics[key] == pytest.approx(ref.metrics[key], rel=1e-8, abs=1e-12)
    assert info["states_points"] == rinfo["states_points"]
    assert sol.metrics["mindlin"]["c"] == pytest.approx(ref.metrics["mindlin"]["c"], rel=1e-8)


def test_extremes_converge_or_stop_with_a_reason(shear):
    """nu_F in {1e-3, 10}, Tresca s in {1e-3 Pa, 1e15 Pa}: each converges (all did, in at
    most 8 Newton steps per load step); more friction, fewer slipping points; a huge s
    glues the whole zone, a tiny one carries no shear."""
    out = {}
    for name, law in (("nu 1e-3", FrictionLaw("coulomb", coefficient=1e-3)),
                      ("nu 10", FrictionLaw("coulomb", coefficient=10.0)),
                      ("s tiny", FrictionLaw("tresca", threshold=1e-3)),
                      ("s huge", FrictionLaw("tresca", threshold=1e15))):
        _, res = _nitsche(shear, law)
        assert res.stop_reason in STOP_REASONS and res.info["reason"]
        assert res.converged, (name, res.info["reason"])
        out[name] = res
    assert _states(out["nu 10"])["slip"] < _states(out["nu 1e-3"])["slip"]
    assert _states(out["s huge"])["slip"] == 0
    P, Q = _forces(shear, out["s tiny"].info["lam_n_points"], out["s tiny"].info["lam_t_points"])
    assert abs(Q) <= 1e-3 * np.sum(shear.contact.weights)  # |lam_t| <= s pointwise


def test_newton_converges_superlinearly_on_tresca(mindlin):
    """Tresca on mindlin_cylinders: every load step ends with a residual ratio below 1e-6
    (the piecewise affine R is solved in one step once the sets are right), and the final
    R, recomputed here at the returned u, is at rounding level."""
    prob, res = _nitsche(mindlin, FrictionLaw("tresca", threshold=1e8))
    assert res.converged and len(res.info["load_steps"]) == 2
    for rec in res.info["load_steps"]:
        assert rec["ratios"][-1] <= 1e-6
    p = at_step(prob, prob.steps[-1], res.info["ut_prev_points"])
    u = res.u[prob.free]
    R = nf.residual(p, u)
    assert np.linalg.norm(R) <= 1e-9 * np.linalg.norm(p.A @ u)


def test_model_b_and_the_summary_block():
    """model_b (F(|u_t|)) converges on the shear case; rbbench's HF model writes the friction
    outputs and the Mindlin block for a Nitsche solve."""
    sc = load_scene("hertz_halfdisks", MESH + SHEAR + ['friction.law="coulomb"',
                                                       'friction.coefficient="model_b"'])
    sol = HFModel(sc, formulation="nitsche").solve()
    assert sol.result.converged and sol.components["solver"] == "newton"
    F = sol.result.info["coefficient_points"]
    assert np.all((F > 0) & (F <= 0.25))
    m = HFModel(load_scene("mindlin_cylinders", MINDLIN), formulation="nitsche").solve().metrics
    for key in ("tangential_force", "n_stick", "n_slip", "n_open", "stick_half_width",
                "friction_residual", "mindlin"):
        assert key in m
    assert np.isfinite(m["mindlin"]["c_rel_error"]) and 0 < m["mindlin"]["c"] < m["mindlin"]["a"]
    assert "lam_t_points" not in m["solver_info"]

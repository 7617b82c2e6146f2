"""Model-B Coulomb state of shape_coulomb: an exact solution without friction, the contact
and friction laws on raw values, global equilibrium, and the scene's input errors."""
import numpy as np
import pytest

from rbbench.optim.shape_mesh import assemble_stiffness, top_load, trapezoid_weights
from rbbench.optim.shape_scene import load_shape_scene
from rbbench.optim.shape_state import objective, solve_state
from rbbench.scene.parameters import SceneError

COARSE = {"geometry.contact_nodes": 21, "geometry.ny": 8}


def test_frictionless_flat_body_is_the_uniaxial_stress_state():
    """F = 0, flat bottom, pressure p, roller on the left: sigma_yy = -p, sigma_xx = 0.

    Q1 reproduces the linear displacement exactly: nodal forces p w_i, u_1 at the bottom
    nu (1 + nu) p x / E (plane strain), all nodes in contact.
    """
    sc = load_shape_scene(overrides={**COARSE, "friction.coefficient": 0.0,
                                     "load.traction": 0.0, "design.initial": "flat",
                                     "design.initial_height": 0.05})
    st = solve_state(sc, sc.initial_design())
    w = trapezoid_weights(sc.grid)
    assert np.abs(st.lam - sc.pressure * w).max() <= 1e-10 * sc.pressure * w.max()
    exx = sc.nu * (1 + sc.nu) * sc.pressure / sc.E
    x = sc.grid.x1[1:]
    assert np.abs(st.u_t - exx * x).max() <= 1e-10 * exx * x.max()
    assert np.abs(st.u_n + sc.initial_design()).max() <= 1e-12
    assert st.contact.all()


@pytest.fixture(scope="module")
def state():
    sc = load_shape_scene(overrides=COARSE)
    return sc, solve_state(sc, sc.initial_design())


def test_signorini_and_coulomb_laws_hold_on_raw_values(state):
    sc, st = state
    scale = np.abs(st.lam).max()
    gap = st.u_n + st.alpha
    assert st.lam.min() >= -1e-10 * scale
    assert gap.min() >= -1e-12
    assert np.abs(st.lam * gap).max() <= 1e-10 * scale * np.abs(gap).max()
    F = sc.friction(np.abs(st.u_t))[0]
    bound = F * st.lam[1:]
    assert (np.abs(st.tau) - bound).max() <= 1e-10 * scale
    slip = np.abs(st.u_t) > 1e-12 * np.abs(st.u_t).max()
    # sliding nodes: tau = -F(|u_t|) lam sign(u_t) (Q~ of model B of the talk "On coupling of
    # complementarity with friction in contact shape optimization")
    np.testing.assert_allclose(st.tau[slip], -bound[slip] * np.sign(st.u_t[slip]),
                               atol=1e-10 * scale)
    assert slip.any() and (~slip & (st.lam[1:] > 0)).any()     # both sliding and sticking


def test_global_equilibrium(state):
    """Every free dof in equilibrium; the vertical load goes through the contact nodes."""
    sc, st = state
    A = assemble_stiffness(sc.grid, st.alpha, sc.D)
    r = A @ st.u - top_load(sc.grid, sc.pressure, sc.traction)
    b = sc.grid.bottom()
    r[2 * b + 1] -= st.lam
    r[2 * b[1:]] -= st.tau
    r[2 * sc.grid.left()] = 0.0            # roller reactions
    assert np.abs(r).max() <= 1e-9 * sc.pressure * sc.grid.h
    assert st.lam.sum() == pytest.approx(sc.pressure * (sc.b - sc.a), rel=1e-10)


def test_objective_is_bounded_below_by_the_uniform_pressure(state):
    """sum lam = P fixed, so J = sum lam^6 >= I (P / I)^6 (Jensen); the parabola is above."""
    sc, st = state
    P, n = sc.pressure * (sc.b - sc.a), sc.n_contact
    assert objective(sc, st.lam) > n * (P / n) ** 6


@pytest.mark.parametrize("key, value, match", [
    ("design.C2", 2.1, "design.C2"),
    ("geometry.contact_nodes", 1, "geometry.contact_nodes"),
    ("design.initial_height", 0.9, "not admissible"),
    ("material.nu", 0.5, "material.nu"),
    ("design.initial", "wavy", "design.initial"),
    ("geometry.ny", 2.5, "geometry.ny"),
])
def test_bad_input_names_the_key(key, value, match):
    with pytest.raises(SceneError, match=match):
        load_shape_scene(overrides={**COARSE, key: value})


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_jacobian_solve_by_force_elimination_equals_dense_solve(seed):
    """``solve_jacobian`` (forces eliminated, ``m x m``) against a dense LU of the whole
    generalised Jacobian, both ways, at random points ``y`` (random contact / stick
    branches) of a coarse scene."""
    import scipy.linalg as sla

    from rbbench.optim.shape_state import _residual_and_jacobian, condense, solve_jacobian

    sc = load_shape_scene(overrides={"geometry.contact_nodes": 21, "geometry.ny": 8})
    alpha = sc.initial_design()
    cond = condense(sc, alpha)
    n = len(alpha)
    m = 2 * n - 1
    rng = np.random.default_rng(seed)
    y = np.concatenate([1e-3 * rng.standard_normal(m), rng.uniform(-5, 20, n),
                        rng.uniform(-5, 5, n - 1)])
    c = float(np.mean(np.diag(cond.S)))
    _, jac, active, stick = _residual_and_jacobian(sc, cond.S, cond.f, alpha, y, c)
    assert 0 < active.sum() < n and 0 < stick.sum() < n - 1     # mixed branches
    b = rng.standard_normal(len(y))
    for transpose in (False, True):
        ref = sla.solve(jac.T if transpose else jac, b)
        got = solve_jacobian(jac, b, m, transpose)
        assert np.abs(got - ref).max() <= 1e-10 * np.abs(ref).max()

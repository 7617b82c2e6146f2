"""Reduced state model of shape_coulomb: the affine decomposition against the
moving-mesh assembly, the reduced model with the full interior basis against the HF solver,
exactness at the centre of an HF interior space, the Galerkin bound S_N >= S, and the
reduced subgradient against central differences of the reduced objective."""
import numpy as np
import pytest

from rbbench.optim.shape_adjoint import branch_margins, evaluate
from rbbench.optim.shape_mesh import assemble_stiffness
from rbbench.optim.shape_reduced import ReducedModel, assemble_affine, hf_snapshots, interior_space
from rbbench.optim.shape_scene import load_shape_scene
from rbbench.optim.shape_state import condense

TINY = {"geometry.contact_nodes": 11, "geometry.ny": 4}
COARSE = {"geometry.contact_nodes": 21, "geometry.ny": 8}


def _perturbed(sc, scale, seed):
    """The initial design moved by ``scale`` normal noise where it is not at the bound 0."""
    a0 = sc.initial_design()
    rng = np.random.default_rng(seed)
    return a0 + scale * rng.standard_normal(a0.size) * (a0 > 0.01)


@pytest.mark.parametrize("seed", [0, 1])
def test_affine_decomposition_equals_assembly(seed):
    sc = load_shape_scene(overrides=COARSE)
    alpha = np.random.default_rng(seed).uniform(0.0, 0.5, sc.n_contact)
    A = assemble_stiffness(sc.grid, alpha, sc.D)
    assert abs(assemble_affine(sc, alpha) - A).max() <= 1e-12 * abs(A).max()


def test_full_interior_basis_is_the_hf_model():
    sc = load_shape_scene(overrides=TINY)
    model = ReducedModel(sc)
    model.enrich(np.eye(2 * sc.grid.n_nodes))
    assert model.N == int(model.interior_mask.sum())
    for alpha in (sc.initial_design(), _perturbed(sc, 0.005, 3)):
        hf, rb = evaluate(sc, alpha), model.evaluate(alpha)
        assert abs(rb.J - hf.J) <= 1e-10 * hf.J
        assert np.abs(rb.xi - hf.xi).max() <= 1e-10 * np.abs(hf.xi).max()
        assert np.abs(rb.state.u - hf.state.u).max() <= 1e-10 * np.abs(hf.state.u).max()
        assert np.abs(rb.state.lam - hf.state.lam).max() <= 1e-10 * np.abs(hf.state.lam).max()


def test_interior_space_exact_at_centre_and_galerkin_bound():
    sc = load_shape_scene(overrides=COARSE)
    centre = _perturbed(sc, 0.002, 4)
    hf = evaluate(sc, centre)
    model = ReducedModel(sc)
    model.enrich(interior_space(sc, hf.state))
    rb = model.evaluate(centre)
    assert abs(rb.J - hf.J) <= 1e-10 * hf.J
    assert np.abs(rb.xi - hf.xi).max() <= 1e-9 * np.abs(hf.xi).max()
    # away from the centre: S_N - S is positive semi-definite (Galerkin on the interior)
    other = _perturbed(sc, 0.004, 5)
    S, S_N = condense(sc, other).S, model.condense(other).S
    assert np.linalg.eigvalsh(S_N - S).min() >= -1e-10 * np.abs(S).max()
    assert np.abs(S_N - S).max() > 1e-8 * np.abs(S).max()   # and not trivially equal


def test_snapshots_make_model_exact_at_a_second_design():
    sc = load_shape_scene(overrides=COARSE)
    a0, a1 = sc.initial_design(), _perturbed(sc, 0.003, 6)
    model = ReducedModel(sc)
    model.enrich(interior_space(sc, evaluate(sc, a0).state))
    hf1 = evaluate(sc, a1)
    assert model.enrich(hf_snapshots(sc, hf1.state)) == 2
    rb1 = model.evaluate(a1)
    assert abs(rb1.J - hf1.J) <= 1e-9 * hf1.J
    assert np.abs(rb1.xi - hf1.xi).max() <= 1e-8 * np.abs(hf1.xi).max()


def test_reduced_subgradient_matches_central_differences():
    sc = load_shape_scene(overrides=COARSE)
    model = ReducedModel(sc)
    model.enrich(interior_space(sc, evaluate(sc, sc.initial_design()).state))
    alpha = _perturbed(sc, 0.002, 1)
    ev = model.evaluate(alpha, tol=1e-14)
    assert min(branch_margins(sc, ev.state).values()) > 1e-2   # stable active sets

    def J(a):
        return model.evaluate(a, tol=1e-14).J

    rng = np.random.default_rng(7)
    for _ in range(3):
        d = rng.standard_normal(alpha.size)
        d /= np.linalg.norm(d)

        def D(h, d=d):
            return (J(alpha + h * d) - J(alpha - h * d)) / (2 * h)

        h = 1e-5
        richardson = (4 * D(h / 2) - D(h)) / 3
        assert abs(richardson - ev.xi @ d) <= 1e-7 * abs(ev.xi @ d)


def test_incremental_update_equals_rebuilt_model_and_hf_projection():
    """Snapshots added one batch at a time (operators updated by the new rows / columns
    only) give the operators of a model projected from scratch on the same basis, and both
    equal ``W^T A(alpha) W`` from the moving-mesh assembly, to round-off."""
    sc = load_shape_scene(overrides=COARSE)
    a0, a1, a2 = (sc.initial_design(), _perturbed(sc, 0.003, 7), _perturbed(sc, 0.003, 8))
    inc = ReducedModel(sc)
    inc.enrich(interior_space(sc, evaluate(sc, a0).state))
    for a in (a1, a2):
        assert inc.enrich(hf_snapshots(sc, evaluate(sc, a).state)) == 2
    rebuilt = ReducedModel(sc)
    rebuilt.V = inc.V.copy()
    rebuilt._project()
    alpha = _perturbed(sc, 0.004, 9)
    G_inc, G_re = inc.galerkin(alpha), rebuilt.galerkin(alpha)
    W = np.zeros((2 * sc.grid.n_nodes, inc.m + inc.N))
    W[inc.contact_dofs, np.arange(inc.m)] = 1.0
    W[:, inc.m:] = inc.V
    G_hf = W.T @ (assemble_stiffness(sc.grid, alpha, sc.D) @ W)
    scale = np.abs(G_hf).max()
    assert np.abs(G_inc - G_re).max() <= 1e-13 * scale
    assert np.abs(G_inc - G_hf).max() <= 1e-12 * scale
    assert np.abs(inc.L_red - rebuilt.L_red).max() <= 1e-14 * np.abs(rebuilt.L_red).max()
    q, x = np.random.default_rng(10).standard_normal((2, inc.m + inc.N))
    d_inc, d_re = inc.design_products(alpha, q, x), rebuilt.design_products(alpha, q, x)
    assert np.abs(d_inc - d_re).max() <= 1e-12 * np.abs(d_re).max()

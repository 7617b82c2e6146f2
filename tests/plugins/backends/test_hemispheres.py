"""The slave solid behind the 3D normal stress ``Snn`` of a ``hemispheres`` scene: the
tetrahedron under each contact triangle (brute force), ``Snn`` of polynomial displacement
fields against Hooke's law by hand on the backends' own bodies (P1, P2), and NGSolve
against scikit-fem on one mesh."""

from __future__ import annotations

import numpy as np
import pytest
from rbbench_plugins.backends.hemispheres import tets_of_faces
from rbbench_plugins.backends.skfem.hemispheres import skfem_hemisphere_model

from rbbench.scene.loading import load_scene

pytestmark = pytest.mark.netgen

COARSE = ["discretization.h_contact=0.08", "discretization.h_max=0.4"]


def _model(degree=1, builder=skfem_hemisphere_model):
    scene = load_scene("hertz_sphere", overrides=[*COARSE, f"discretization.degree={degree}"])
    d = scene.data["discretization"]
    return scene, builder(scene, degree, d["h_contact"], d["h_max"], d["grading"])


def _hooke(scene, grad: np.ndarray) -> np.ndarray:
    """``lambda tr(eps) I + 2 mu eps`` of the upper body for gradients (..., 3, 3)."""
    E, nu = scene.material("upper", [1.0])
    lam, mu_l = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    eps = 0.5 * (grad + np.swapaxes(grad, -1, -2))
    return lam * np.trace(eps, axis1=-2, axis2=-1)[..., None, None] * np.eye(3) + 2 * mu_l * eps


def test_tets_of_faces_against_brute_force():
    _, model = _model()
    body = model.bodies[0]
    model.contact_layout()
    tri = model._slave_triangles[:, :3]
    tets = body.tet_nodes()
    owner = tets_of_faces(tets, tri)
    for k in range(0, tri.shape[0], 7):  # every 7th: the brute force is O(n_tri n_tet)
        holds = np.flatnonzero(np.isin(tets, tri[k]).sum(axis=1) == 3)
        assert holds.tolist() == [owner[k]]
    with pytest.raises(ValueError, match="not a face of any tetrahedron"):
        tets_of_faces(tets, np.array([[tets[0, 0]] * 3]))  # a repeated vertex: no face


@pytest.mark.parametrize("degree", [1, 2])
@pytest.mark.parametrize("mu", [0.7, 1.3])
def test_snn_of_a_linear_field_is_hookes_law(degree, mu):
    """``u = G x + b`` on the mapped upper body: ``sigma_nn`` is ``n . sigma(G) n`` at every
    contact point; the lower body's displacement does not enter."""
    scene, model = _model(degree)
    d = model.discretize([mu], "skfem", model.stiffness([mu]), stress=True)
    c = d.contact
    rng = np.random.default_rng(3)
    G, b = 1e-3 * rng.normal(size=(3, 3)), 1e-3 * rng.normal(size=3)
    up, lo = model.bodies
    x = model.maps["upper"]([mu], up.node_points)
    u = np.zeros(model.ndofs)
    u[up.node_dofs] = x @ G.T + b
    u[lo.node_dofs] = rng.normal(size=lo.node_dofs.shape)
    want = np.einsum("qi,ij,qj->q", c.normals, _hooke(scene, G), c.normals)
    assert np.abs(c.Snn @ u - want).max() <= 1e-10 * np.abs(want).max()
    assert c.Snn.shape == (c.n_quad, model.ndofs)
    # h of gamma0 E / h: the mapped slave triangle's longest edge
    assert np.all(c.facet_length > 0) and c.facet_length.max() < 0.08 * mu * 2.0


def test_snn_of_a_quadratic_field_is_exact_with_p2():
    """``u_i = x^T Q_i x / 2`` on the upper body: ``grad u_i = Q_i x`` varies linearly, so
    P2 evaluates the stress exactly at each contact point (checks the edge-midpoint dofs)."""
    scene, model = _model(2)
    mu = 1.3
    c = model.discretize([mu], "skfem", model.stiffness([mu]), stress=True).contact
    rng = np.random.default_rng(4)
    Q = rng.normal(size=(3, 3, 3))
    Q = 1e-3 * (Q + np.swapaxes(Q, 1, 2))
    up = model.bodies[0]
    x = model.maps["upper"]([mu], up.node_points)
    u = np.zeros(model.ndofs)
    u[up.node_dofs] = 0.5 * np.einsum("nj,ijk,nk->ni", x, Q, x)
    grad = np.einsum("ijk,qk->qij", Q, c.points)
    want = np.einsum("qi,qij,qj->q", c.normals, _hooke(scene, grad), c.normals)
    assert np.abs(c.Snn @ u - want).max() <= 1e-9 * np.abs(want).max()


def test_snn_is_the_same_on_ngsolve_and_skfem_on_one_mesh():
    pytest.importorskip("ngsolve")
    from rbbench_plugins.backends.ngsolve.hemispheres import ngsolve_hemisphere_model

    _, sk = _model()
    _, ng = _model(builder=ngsolve_hemisphere_model)
    perm = np.empty(ng.ndofs, dtype=int)  # ngsolve dof -> skfem dof
    for a, b in zip(sk.bodies, ng.bodies, strict=True):
        np.testing.assert_array_equal(a.node_points, b.node_points)
        perm[b.node_dofs.ravel()] = a.node_dofs.ravel()
    mu = 0.7
    c_sk = sk.discretize([mu], "skfem", sk.stiffness([mu]), stress=True).contact
    c_ng = ng.discretize([mu], "ngsolve", ng.stiffness([mu]), stress=True).contact
    S_sk = c_sk.Snn.tocsc()[:, perm]
    assert abs(c_ng.Snn - S_sk).max() <= 1e-10 * abs(S_sk).max()
    np.testing.assert_allclose(c_ng.facet_length, c_sk.facet_length, rtol=1e-14)


def test_stress_only_on_request():
    _, model = _model()
    plain = model.discretize([1.0], "skfem", model.stiffness([1.0])).contact
    assert plain.Snn is None and plain.facet_length is None

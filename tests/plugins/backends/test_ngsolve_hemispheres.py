"""The NGSolve 3D operators of a ``hemispheres`` scene against the scikit-fem ones on the
same reference mesh (equal up to dof numbering), P1 and P2, and the refusal of other
degrees."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("ngsolve",
                    reason='NGSolve backend not installed: pip install "rbbench[ngsolve]"')

from rbbench_plugins.backends.ngsolve.hemispheres import ngsolve_hemisphere_model  # noqa: E402
from rbbench_plugins.backends.skfem.hemispheres import skfem_hemisphere_model  # noqa: E402

from rbbench.scene.loading import SceneError, load_scene  # noqa: E402

COARSE = ["discretization.h_contact=0.08", "discretization.h_max=0.4"]


def _models(degree: int = 1):
    scene = load_scene("hertz_sphere", overrides=[*COARSE, f"discretization.degree={degree}"])
    d = scene.data["discretization"]
    args = (scene, degree, d["h_contact"], d["h_max"], d["grading"])
    return scene, skfem_hemisphere_model(*args), ngsolve_hemisphere_model(*args)


def _node_perm(a, b) -> np.ndarray:
    """``perm[j] = i``: the node ``i`` of ``a`` at the point of node ``j`` of ``b`` (P2:
    the edge midpoints are numbered in each library's own edge order), exact match."""
    ia, ib = np.lexsort(a.node_points.T), np.lexsort(b.node_points.T)
    np.testing.assert_array_equal(a.node_points[ia], b.node_points[ib])
    perm = np.empty(len(ib), dtype=int)
    perm[ib] = ia
    return perm


def _assert_same_operators(sk, ng, perm, mu):
    """Stiffness, H1 product, contact data and Dirichlet dofs of the NGSolve model equal
    scikit-fem's up to the dof permutation ``perm`` (ngsolve dof -> skfem dof), to 1e-10."""
    A_sk, A_ng = sk.stiffness([mu]), ng.stiffness([mu])
    assert abs(A_ng - A_sk[perm][:, perm]).max() <= 1e-10 * abs(A_sk).max()
    X_sk, X_ng = sk.inner_product("h1"), ng.inner_product("h1")
    assert abs(X_ng - X_sk[perm][:, perm]).max() <= 1e-10 * abs(X_sk).max()
    c_sk = sk.discretize([mu], "skfem", A_sk).contact
    c_ng = ng.discretize([mu], "ngsolve", A_ng).contact
    for name in ("gap", "weights", "points", "normals", "mult_points", "mult_extent"):
        np.testing.assert_allclose(getattr(c_ng, name), getattr(c_sk, name), rtol=0,
                                   atol=1e-10 * np.abs(getattr(c_sk, name)).max())
    assert abs(c_ng.Un - c_sk.Un.tocsc()[:, perm]).max() <= 1e-10
    assert abs(c_ng.Mlam - c_sk.Mlam).max() == 0.0
    assert set(perm[ng.dirichlet].tolist()) == set(sk.dirichlet.tolist())


@pytest.mark.parametrize("mu", [0.7, 1.3])
def test_operators_equal_skfem_on_one_mesh(mu):
    scene, sk, ng = _models()
    perm = np.empty(ng.ndofs, dtype=int)  # ngsolve dof -> skfem dof
    for a, b in zip(sk.bodies, ng.bodies, strict=True):
        np.testing.assert_array_equal(a.node_points, b.node_points)
        perm[b.node_dofs.ravel()] = a.node_dofs.ravel()
    _assert_same_operators(sk, ng, perm, mu)
    d_sk = set(perm[np.isin(perm, sk.dirichlet)].tolist())
    assert set(perm[ng.dirichlet].tolist()) == set(sk.dirichlet.tolist()) == d_sk


def test_p2_operators_equal_skfem_on_one_mesh():
    """NGSolve's hierarchical order-2 operators transformed to nodal P2 equal scikit-fem's
    ``ElementTetP2`` ones on the same mesh to 1e-10 (stiffness, H1 product, contact
    operators), up to the numbering of the edge nodes."""
    mu = 1.3
    scene, sk, ng = _models(2)
    perm = np.empty(ng.ndofs, dtype=int)  # ngsolve dof -> skfem dof
    for a, b in zip(sk.bodies, ng.bodies, strict=True):
        assert len(a.node_points) == len(b.node_points) > len(b.points)
        nodes = _node_perm(a, b)
        perm[b.node_dofs.ravel()] = a.node_dofs[nodes].ravel()
    assert np.array_equal(np.sort(perm), np.arange(ng.ndofs))
    _assert_same_operators(sk, ng, perm, mu)


def test_other_degrees_are_refused_with_the_key():
    """The scene refuses degree 3 itself; the backend's guard too, when called directly."""
    with pytest.raises(SceneError, match=r"\[discretization\] degree: 3 is not valid"):
        load_scene("hertz_sphere", overrides=[*COARSE, "discretization.degree=3"])
    scene = load_scene("hertz_sphere", overrides=COARSE)
    d = scene.data["discretization"]
    with pytest.raises(SceneError, match=r"\[discretization\] degree = 3: the ngsolve backend"):
        ngsolve_hemisphere_model(scene, 3, d["h_contact"], d["h_max"], d["grading"])


@pytest.mark.parametrize("degree", [1, 2])
def test_mixed_solves_agree(degree):
    """One mixed solve per backend (coarse mesh): the same force and peak pressure up to
    the direct solvers' round-off (NGSolve's sparse Cholesky, SuperLU)."""
    from rbbench.hf.model import solve_hf

    scene = load_scene("hertz_sphere", overrides=[*COARSE, f"discretization.degree={degree}"])
    m = [solve_hf(scene, scene.default_mu, backend=b).metrics for b in ("skfem", "ngsolve")]
    assert m[0]["converged"] and m[1]["converged"]
    assert m[1]["contact_force"] == pytest.approx(m[0]["contact_force"], rel=1e-8)
    assert m[1]["max_pressure"] == pytest.approx(m[0]["max_pressure"], rel=1e-8)

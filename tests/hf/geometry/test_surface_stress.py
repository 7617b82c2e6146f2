"""The slave normal stress sigma_nn at 3D contact points against the stress of polynomial
displacement fields (Hooke's law by hand)."""

from __future__ import annotations

import numpy as np
import pytest
from support.surface_meshes import sphere_cap

from rbbench.hf.geometry.chains import AffineMap
from rbbench.hf.geometry.surface import SurfaceLayout, TriSurface, contact_operators_3d
from rbbench.hf.geometry.surface_stress import (
    TET_EDGES,
    SlaveSolid,
    contact_operators_3d_stress,
    normal_stress_3d,
    tet_gradients,
)

E, NU = 2.0e5, 0.3
LAM, MU_L = E * NU / ((1 + NU) * (1 - 2 * NU)), E / (2 * (1 + NU))


def _setup(degree: int, amap: AffineMap):
    """A sphere cap slave (map ``amap``) and, on each triangle, a tetrahedron reaching
    0.05 into the body; every tetrahedron node has its own dofs after the surface's."""
    s = sphere_cap(4, 1.0, 1.05, 0.4, 1)
    s = TriSurface(s.points, s.triangles, s.dofs, s.inside, amap)
    v = s.points[s.triangles]  # (n, 3, 3)
    apex = v.mean(axis=1) + 0.05 * (s.inside - v.mean(axis=1))
    tets = np.concatenate([v, apex[:, None, :]], axis=1)
    if degree == 2:
        nodes = np.concatenate([tets, np.stack([(tets[:, i] + tets[:, j]) / 2
                                                for i, j in TET_EDGES], axis=1)], axis=1)
    else:
        nodes = tets
    first = 3 * s.points.shape[0]
    dofs = first + np.arange(nodes.shape[0] * nodes.shape[1] * 3).reshape(*nodes.shape[:2], 3)
    lay = SurfaceLayout(s, None, 1, 4, "p0", 1, int(dofs.max()) + 1)
    solid = SlaveSolid(tets=tets, dofs=dofs, E=np.array([E, 0.0]), nu=np.array([NU, 0.0]))
    return lay, solid, nodes


def _sigma(grad: np.ndarray) -> np.ndarray:
    """Hooke's law: ``lambda tr(eps) I + 2 mu eps`` for displacement gradients (..., 3, 3)."""
    eps = 0.5 * (grad + np.swapaxes(grad, -1, -2))
    tr = np.trace(eps, axis1=-2, axis2=-1)
    return LAM * tr[..., None, None] * np.eye(3) + 2 * MU_L * eps


MAPS = [AffineMap(scale=np.array([1.0, 0.0]), shift=np.zeros((3, 2))),
        AffineMap(scale=np.array([0.0, 1.0]), shift=np.array([[0.1, 0.0], [0.0, 0.0],
                                                               [0.0, 0.02]]))]


@pytest.mark.parametrize("degree", [1, 2])
@pytest.mark.parametrize("amap", MAPS, ids=["identity", "scaled"])
def test_snn_of_a_linear_field_is_hookes_law(degree, amap):
    mu = np.array([1.3])
    lay, solid, nodes = _setup(degree, amap)
    rng = np.random.default_rng(5)
    A, b = rng.normal(size=(3, 3)), rng.normal(size=3)
    s, c = amap.at(mu)
    u = np.zeros(lay.n_dofs)
    u[solid.dofs] = (s * nodes + c) @ A.T + b
    op = contact_operators_3d(lay, mu)
    Snn = normal_stress_3d(lay, solid, mu)
    expect = np.einsum("qi,ij,qj->q", op.normals, _sigma(A), op.normals)
    assert np.allclose(Snn @ u, expect, rtol=1e-10, atol=1e-10 * np.abs(expect).max())


def test_snn_of_a_quadratic_field_with_p2_is_hookes_law_at_the_points():
    """``u_i = x^T Q_i x / 2``: ``grad u_i = Q_i x``, so sigma varies linearly and P2
    evaluates it exactly at each point."""
    mu = np.array([0.8])
    lay, solid, nodes = _setup(2, MAPS[1])
    rng = np.random.default_rng(6)
    Q = rng.normal(size=(3, 3, 3))
    Q = Q + np.swapaxes(Q, 1, 2)
    s, c = MAPS[1].at(mu)
    X = s * nodes + c
    u = np.zeros(lay.n_dofs)
    u[solid.dofs] = 0.5 * np.einsum("...j,ijk,...k->...i", X, Q, X)
    op = contact_operators_3d(lay, mu)
    grad = np.einsum("ijk,qk->qij", Q, op.points)
    expect = np.einsum("qi,qij,qj->q", op.normals, _sigma(grad), op.normals)
    Snn = normal_stress_3d(lay, solid, mu)
    assert np.allclose(Snn @ u, expect, rtol=1e-9, atol=1e-9 * np.abs(expect).max())


def test_tet_gradients_sum_to_zero_and_reject_other_degrees():
    """Partition of unity: the gradients of a Lagrange basis sum to zero."""
    rng = np.random.default_rng(1)
    tets = rng.normal(size=(5, 4, 3))
    x = np.einsum("nk,nkd->nd", rng.dirichlet(np.ones(4), 5), tets)
    for degree in (1, 2):
        assert np.allclose(tet_gradients(tets, x, degree).sum(axis=1), 0.0, atol=1e-9)
    with pytest.raises(ValueError, match="degree 3 is not one of 1, 2"):
        tet_gradients(tets, x, 3)


def test_operators_with_stress_carry_snn_and_the_triangle_diameter():
    mu = np.array([1.3])
    lay, solid, _ = _setup(1, MAPS[1])
    op = contact_operators_3d_stress(lay, solid, mu)
    plain = contact_operators_3d(lay, mu)
    assert np.array_equal(op.gap, plain.gap) and (op.Un != plain.Un).nnz == 0
    assert (op.Snn != normal_stress_3d(lay, solid, mu)).nnz == 0
    v = lay.slave.points[lay.slave.triangles[0]]
    diam = max(np.linalg.norm(v[i] - v[j]) for i, j in ((0, 1), (1, 2), (0, 2)))
    ng = lay.n_points_per_triangle
    assert np.allclose(op.facet_length[:ng], 1.3 * diam, rtol=1e-13)

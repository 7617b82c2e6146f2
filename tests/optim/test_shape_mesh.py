"""Moving Q1 mesh of shape_coulomb: the numpy kernel against scikit-fem, the design derivative
against finite differences of the assembly, the area against a polygon formula."""
import numpy as np
import pytest

from rbbench.optim.shape_mesh import (
    Grid,
    area,
    assemble_stiffness,
    elasticity_matrix,
    stiffness_design_products,
)

GRID = Grid(0.0, 2.0, 1.0, 8, 4)
D = elasticity_matrix(1.0e4, 0.3)


def _design(seed=0):
    rng = np.random.default_rng(seed)
    return 0.05 + 0.05 * rng.random(GRID.nx + 1)


def test_stiffness_matches_scikit_fem():
    skfem = pytest.importorskip("skfem")
    from skfem.models.elasticity import linear_elasticity

    alpha = _design()
    p = GRID.coordinates(alpha)
    mesh = skfem.MeshQuad(p.T, GRID.elements().T)
    basis = skfem.Basis(mesh, skfem.ElementVector(skfem.ElementQuad1()),
                        intorder=2)
    E, nu = 1.0e4, 0.3
    K = linear_elasticity(E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))).assemble(basis)
    # map scikit-fem's dofs to (u1, u2) interleaved by node
    order = np.empty(2 * GRID.n_nodes, dtype=int)
    order[0::2] = basis.nodal_dofs[0]
    order[1::2] = basis.nodal_dofs[1]
    ours = assemble_stiffness(GRID, alpha, D).toarray()
    ref = K.toarray()[np.ix_(order, order)]
    assert np.abs(ours - ref).max() <= 1e-12 * np.abs(ref).max()


def test_design_derivative_matches_finite_differences():
    alpha = _design(1)
    rng = np.random.default_rng(2)
    n = 2 * GRID.n_nodes
    p, u = rng.standard_normal(n), rng.standard_normal(n)
    g = stiffness_design_products(GRID, alpha, D, p, u)
    h = 1e-6
    for i in (0, 3, GRID.nx):
        e = np.zeros(GRID.nx + 1)
        e[i] = h
        dA = (assemble_stiffness(GRID, alpha + e, D) - assemble_stiffness(GRID, alpha - e, D))
        fd = p @ (dA @ u) / (2 * h)
        assert abs(g[i] - fd) <= 1e-6 * abs(fd)


def test_rigid_motions_in_the_kernel():
    A = assemble_stiffness(GRID, _design(3), D)
    x = GRID.coordinates(_design(3))
    rot = np.stack([-x[:, 1], x[:, 0]], axis=1).ravel()
    for v in (np.tile([1.0, 0.0], GRID.n_nodes), np.tile([0.0, 1.0], GRID.n_nodes), rot):
        assert np.abs(A @ v).max() <= 1e-9 * abs(A).max()


def test_area_is_the_polygon_area():
    alpha = _design(4)
    x = GRID.x1
    # shoelace formula of the polygon (bottom left to right, then the top back)
    px = np.concatenate([x, x[::-1]])
    py = np.concatenate([alpha, np.full_like(x, GRID.gamma)])
    shoelace = 0.5 * abs(np.dot(px, np.roll(py, -1)) - np.dot(py, np.roll(px, -1)))
    assert area(GRID, alpha) == pytest.approx(shoelace, rel=1e-14)

"""The scikit-fem 3D operators of a ``hemispheres`` scene: the similarity scaling of the
stiffness, the rigid motions the symmetry planes allow, a uniaxial-stress patch test, the
Dirichlet data, the contact surfaces, and a level-0 solve against 3D Hertz."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from rbbench_plugins.backends.skfem.hemispheres import skfem_hemisphere_model
from skfem import Basis, ElementTetP1, ElementTetP2, ElementVector, FacetBasis, LinearForm, MeshTet
from skfem import asm as skasm
from skfem.models.elasticity import lame_parameters, linear_elasticity

from rbbench.scene.loading import load_scene

pytestmark = pytest.mark.netgen

COARSE = ["discretization.h_contact=0.08", "discretization.h_max=0.4"]


def _model(degree=1, extra=()):
    scene = load_scene("hertz_sphere", overrides=[*COARSE, f"discretization.degree={degree}",
                                                  *extra])
    disc = scene.data["discretization"]
    return scene, skfem_hemisphere_model(scene, degree, disc["h_contact"], disc["h_max"],
                                         disc["grading"])


@pytest.mark.parametrize("degree", [1, 2])
@pytest.mark.parametrize("mu", [0.7, 1.3])
def test_stiffness_equals_assembly_on_the_mapped_mesh(degree, mu):
    scene, model = _model(degree)
    elem = ElementTetP1() if degree == 1 else ElementTetP2()
    blocks = []
    for body in model.bodies:
        x = model.maps[body.name]([mu], body.mesh.p.T)
        basis = Basis(MeshTet(x.T.copy(), body.mesh.t), ElementVector(elem))
        E, nu = scene.material(body.name, [mu])
        blocks.append(skasm(linear_elasticity(*lame_parameters(E, nu)), basis))
    direct = sp.block_diag(blocks).tocsr()
    A = model.stiffness([mu])
    assert abs(A - direct).max() <= 1e-12 * abs(direct).max()
    # not trivially invariant: the upper body's block scales with its radius mu
    up = slice(0, model.bodies[0].ndofs)
    ratio = abs(A[up, up]).max() / abs(model.stiffness([1.0])[up, up]).max()
    assert ratio == pytest.approx(mu, rel=1e-12)


def test_symmetry_planes_leave_only_the_vertical_translation():
    """With the flat face free, x = 0 and y = 0 (zero normal displacement) allow one rigid
    motion of a body: the translation along z (rotations about z move the planes)."""
    _, model = _model()
    body = model.bodies[0]
    n = body.ndofs
    K = model.stiffness([1.0])[:n, :n].toarray()
    g = body.node_groups()
    held = np.concatenate([body.node_dofs[g["sym_x"], 0], body.node_dofs[g["sym_y"], 1]])
    free = np.setdiff1d(np.arange(n), held)
    ev = np.linalg.eigvalsh(K[np.ix_(free, free)])
    scale = ev[-1]
    assert np.sum(ev < 1e-10 * scale) == 1 and ev[1] > 1e-6 * scale
    tz = np.zeros(n)
    tz[body.node_dofs[:, 2]] = 1.0
    assert np.abs(K @ tz).max() <= 1e-10 * scale


@pytest.mark.parametrize("degree", [1, 2])
def test_uniaxial_stress_patch_test(degree):
    """sigma = -p e_z e_z on the upper body (curved face loaded by -p n_z e_z, flat face
    u_z = 0, symmetry planes): the exact u = p / E (nu x, nu y, -z) is linear, so the FE
    solution equals it at the nodes up to round-off (on the polyhedral body too)."""
    scene, model = _model(degree)
    body = model.bodies[0]
    E, nu = scene.material("upper", [1.0])
    p, n = 1.0e8, body.ndofs
    K = model.stiffness([1.0])[:n, :n].tocsr()  # mu = 1: the unit body
    m = body.mesh
    bf = m.boundary_facets()
    curved = bf[~np.any([np.all(m.p[k, m.facets[:, bf]] == 0.0, axis=0) for k in range(3)],
                        axis=0)]
    fb = FacetBasis(m, body.basis.elem, facets=curved)

    @LinearForm
    def traction(v, w):
        return -p * w.n[2] * v[2]

    f = skasm(traction, fb)
    g = body.node_groups()
    held = np.unique(np.concatenate([body.node_dofs[g["sym_x"], 0],
                                     body.node_dofs[g["sym_y"], 1],
                                     body.node_dofs[g["flat"], 2]]))
    free = np.setdiff1d(np.arange(n), held)
    u = np.zeros(n)
    u[free] = sp.linalg.spsolve(K[free][:, free].tocsc(), f[free])
    x = body.node_points
    exact = p / E * np.column_stack([nu * x[:, 0], nu * x[:, 1], -x[:, 2]])
    err = np.abs(u[body.node_dofs] - exact).max() / np.abs(exact).max()
    assert err < 1e-9


def test_dirichlet_data():
    scene, model = _model()
    up, lo = model.bodies
    gu, gl = up.node_groups(), lo.node_groups()
    d = model.dirichlet
    assert np.unique(d).size == d.size
    assert set(d[model.moving]) == set(up.node_dofs[gu["flat"], 2])
    for body, g in ((up, gu), (lo, gl)):
        expected = set(body.node_dofs[g["flat"]].ravel()) | set(body.node_dofs[g["sym_x"], 0]) \
            | set(body.node_dofs[g["sym_y"], 1])
        assert set(d[np.isin(d, body.node_dofs)]) == expected
    disc = model.discretize(scene.default_mu, "skfem", model.stiffness(scene.default_mu))
    np.testing.assert_array_equal(disc.dirichlet_values[model.moving], -0.03)
    assert not disc.dirichlet_values[~model.moving].any()


@pytest.mark.parametrize("mu", [0.7, 1.3])
def test_contact_surfaces(mu):
    """The slave cap's mapped area is that of the quarter spherical cap of radius mu and
    polar angle 0.1 pi (inscribed facets: a deficit O(h^2)); its points sit on the slave;
    the gaps are those of the exact spheres (the ray from the point's projection on the
    slave sphere, along its radius, to the master sphere) up to the facets' sag
    ``h^2 / 8 (1 / R1 + 1 / R2)`` (both surfaces are inscribed polyhedra), twice."""
    scene, model = _model()
    c = model.discretize([mu], "skfem", model.stiffness([mu])).contact
    cap = 2 * np.pi * mu**2 * (1 - np.cos(0.1 * np.pi)) / 4
    assert 0.0 < 1.0 - c.weights.sum() / cap < 0.02
    centre = np.array([0.0, 0.0, 1.0 + 0.001 + mu])
    np.testing.assert_allclose(np.linalg.norm(c.points - centre, axis=1), mu, rtol=0.01)
    slave = model.contact_layout().slave
    tri = slave.points[slave.triangles]
    h = mu * max(np.linalg.norm(tri[:, i] - tri[:, j], axis=1).max()
                 for i, j in ((0, 1), (1, 2), (0, 2)))
    n = (c.points - centre) / np.linalg.norm(c.points - centre, axis=1)[:, None]
    x = centre + mu * n
    xn = np.sum(x * n, axis=1)
    exact = -xn - np.sqrt(xn**2 - np.sum(x * x, axis=1) + 1.0)
    assert np.abs(c.gap - exact).max() <= 2 * h**2 / 8 * (1 / mu + 1.0)
    assert c.points.shape[1] == 3 and np.all(c.normals[:, 2] < -0.9)

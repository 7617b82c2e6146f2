"""scikit-fem backend: operators checked against rigid motions and geometry."""

from __future__ import annotations

import numpy as np
import pytest

from rbbench.registry import default_registry
from rbbench.scene.loading import load_scene

COARSE = ["discretization.h_contact=0.02", "discretization.h_max=0.2"]


def _backend(overrides=()):
    sc = load_scene("hertz_halfdisks", COARSE + list(overrides))
    return default_registry().create("backend", "skfem", scene=sc)


def _translation(backend, disc, v, bodies=("upper",)):
    """A rigid translation by v of the named bodies: every Lagrange dof of component c = v[c]."""
    u = np.zeros(disc.n_dofs)
    for body in (backend.upper, backend.lower):
        if body is None or body.name not in bodies:
            continue
        basis = body.basis_hat
        for c in range(2):
            dofs = [basis.nodal_dofs[c]]
            if body.degree == 2:
                dofs.append(basis.facet_dofs[c])
            u[np.concatenate(dofs) + body.offset] = v[c]
    return u


@pytest.mark.parametrize("degree", [1, 2])
def test_jump_operators_on_rigid_translations(degree):
    """Translating the slave by v gives Un u = v.n and Ut u = v.t; moving both gives 0."""
    b = _backend([f"discretization.degree={degree}"])
    d = b.discretize(0.9, needs=frozenset({"tangential"}))
    v = np.array([0.3, -0.7])
    n = d.contact.normals
    t = np.stack([-n[:, 1], n[:, 0]], axis=1)
    u1 = _translation(b, d, v)
    assert np.allclose(d.contact.Un @ u1, n @ v, atol=1e-12)
    assert np.allclose(d.contact.Ut @ u1, t @ v, atol=1e-12)
    u12 = _translation(b, d, v, ("upper", "lower"))
    assert np.allclose(d.contact.Un @ u12, 0.0, atol=1e-12)
    assert np.allclose(d.contact.Ut @ u12, 0.0, atol=1e-12)


def test_tangential_operators_only_on_request():
    b = _backend()
    c = b.discretize(1.0).contact
    assert c.Ut is None and c.Snn is None and c.facet_length is None
    with pytest.raises(ValueError, match="unknown needs"):
        b.discretize(1.0, needs=frozenset({"friction"}))


def test_gap_matches_circle_geometry():
    """At the axis the normal gap is g0 (up to the polygonal chord error O(h^2))."""
    b = _backend()
    for mu in (0.7, 1.3):
        d = b.discretize(mu)
        c = d.contact
        i = np.argmin(np.abs(c.points[:, 0]))
        assert abs(c.gap[i] - 0.001) < 2e-4
        # total slave zone length = mu * pi/4 (chords: slightly less)
        assert np.isclose(c.weights.sum(), mu * np.pi / 4, rtol=1e-3)


@pytest.mark.parametrize("overrides", [[], ["material.upper.E='mu.mu'"],
                                       ["geometry.lower='rigid_flat'"]])
@pytest.mark.parametrize("mu", [0.7, 1.3])
def test_stiffness_equals_assembly_on_the_mapped_mesh(overrides, mu):
    """The stiffness combined from the reference Lame terms equals scikit-fem's assembly
    on each body's mesh mapped at mu (2D elasticity is invariant under the similarity
    ``x -> s x + c``, science.md), with a parameter-dependent Young's modulus too."""
    import scipy.sparse as sp
    from skfem import Basis, asm
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    b = _backend(overrides)
    A = b.discretize(mu).A
    blocks = []
    for body in b._bodies():
        mesh = type(body.mesh_hat)(b._mapped(body, np.array([mu])), body.mesh_hat.t)
        basis = Basis(mesh, body.basis_hat.elem)
        E, nu = b.scene.material(body.name, np.array([mu]))
        blocks.append(asm(linear_elasticity(*lame_parameters(E, nu)), basis))
    ref = sp.block_diag(blocks).tocsr()
    assert A.shape == ref.shape
    assert abs(A - ref).max() <= 1e-12 * abs(ref).max()
    if overrides and "E=" in overrides[0]:  # E(mu) = mu enters: not the default stiffness
        assert abs(A - _backend().discretize(mu).A).max() > 0.1 * abs(A).max()


def test_rigid_flat_has_one_body():
    d = _backend(["geometry.lower='rigid_flat'"]).discretize(1.0)
    assert [body.name for body in d.bodies] == ["upper"]
    assert d.info["geometry"]["R2"] is None

"""scikit-fem bodies of a ``hemispheres`` scene (3D Hertz contact).

:class:`SkfemBackend <rbbench_plugins.backends.skfem.backend.SkfemBackend>` hands a
``hemispheres`` scene to :class:`~rbbench_plugins.backends.hemispheres.HemisphereModel`
with :class:`HemisphereBody` as its bodies. Each body is the unit quarter hemisphere
meshed once (:func:`~rbbench_plugins.backends.hemisphere_mesh.quarter_hemisphere`,
``MeshTet``; P1 ``ElementTetP1`` or P2 ``ElementTetP2`` on straight tetrahedra) and mapped
by a similarity ``x = s(mu) x_hat + c(mu)``. Strains scale by ``1 / s`` and volumes by
``s^3``, so the stiffness on the mapped body is ``s`` times the reference one: each body's
two Lame terms are assembled once and ``A(mu) = sum_b s_b(mu) (lambda_b K_div,b + mu_b
K_eps,b)``.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from rbbench_plugins.backends import hemispheres as hs
from rbbench_plugins.backends.hemisphere_mesh import (
    TetMesh,
    boundary_triangles,
    edge_lookup,
    mirror_z,
)
from skfem import Basis, BilinearForm, ElementTetP1, ElementTetP2, ElementVector, MeshTet, asm
from skfem.models.elasticity import linear_elasticity

from rbbench.hf.geometry.surface_stress import TET_EDGES
from rbbench.scene.loading import Scene


@BilinearForm
def _vector_h1(u, v, w):
    return (u * v).sum(axis=0) + (u.grad * v.grad).sum(axis=(0, 1))


def skfem_hemisphere_model(scene: Scene, degree: int, h_contact: float, h_max: float,
                           grading: float) -> hs.HemisphereModel:
    """The :class:`~rbbench_plugins.backends.hemispheres.HemisphereModel` on scikit-fem
    bodies."""
    return hs.HemisphereModel(scene, degree, h_contact, h_max, grading, HemisphereBody)


class HemisphereBody:
    """One body: its reference ``MeshTet``, vector basis, and nodes (vertices, then for
    P2 the edge midpoints) with their global dofs."""

    def __init__(self, spec: hs.HemisphereBody, mesh: TetMesh, degree: int, offset: int):
        self.spec, self.name, self.offset = spec, spec.name, offset
        if spec.mirrored:
            mesh = mirror_z(mesh)
        self.mesh = MeshTet(np.ascontiguousarray(mesh.points.T),
                            np.ascontiguousarray(mesh.tets.T))
        elem = ElementTetP1() if degree == 1 else ElementTetP2()
        self.basis = Basis(self.mesh, ElementVector(elem))
        self.ndofs = self.basis.N
        m, b = self.mesh, self.basis
        points, dofs = [m.p.T], [b.nodal_dofs.T]
        if degree == 2:
            points.append(m.p[:, m.edges].mean(axis=1).T)
            dofs.append(b.edge_dofs.T)
        self.node_points = np.concatenate(points)
        self.node_dofs = np.concatenate(dofs) + offset
        self.degree = degree

    def surface_triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """``(triangles, curved)``: the boundary triangles as node numbers ((n, 3), P2:
        (n, 6) with the edge nodes of edges (0, 1), (1, 2), (0, 2)) and which are on the
        sphere."""
        m = self.mesh
        tri = boundary_triangles(m.t.T)
        on_plane = [np.all(m.p[k, tri] == 0.0, axis=1) for k in range(3)]
        curved = ~(on_plane[0] | on_plane[1] | on_plane[2])
        if self.degree == 2:
            lookup = edge_lookup(m.edges.T, m.nvertices)
            mids = [lookup(tri[:, a], tri[:, b]) + m.nvertices
                    for a, b in ((0, 1), (1, 2), (0, 2))]
            tri = np.column_stack([tri, *mids])
        return tri, curved

    def tet_nodes(self) -> np.ndarray:
        """(m, 4) vertex numbers of each tetrahedron; P2: (m, 10), then the edge nodes of
        :data:`~rbbench.hf.geometry.surface_stress.TET_EDGES` (numbered as ``node_points``)."""
        m = self.mesh
        t = m.t.T
        if self.degree == 1:
            return np.ascontiguousarray(t)
        lookup = edge_lookup(m.edges.T, m.nvertices)
        mids = [lookup(t[:, a], t[:, b]) + m.nvertices for a, b in TET_EDGES]
        return np.column_stack([t, *mids])

    def node_groups(self) -> dict[str, np.ndarray]:
        """Masks of the nodes on the flat face and on the symmetry planes."""
        return hs.node_groups(self.node_points)

    def lame_terms(self) -> tuple[sp.csr_matrix, sp.csr_matrix]:
        """``(K_div, K_eps)`` of the reference body, local numbering
        (``linear_elasticity(1, 0)`` and ``(0, 1)``)."""
        return tuple(asm(linear_elasticity(*lame), self.basis).tocsr()
                     for lame in ((1.0, 0.0), (0.0, 1.0)))

    def h1(self) -> sp.csr_matrix:
        """The vector H1 product of the reference body, local numbering."""
        return asm(_vector_h1, self.basis).tocsr()

    @property
    def vertices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(points (n, 3), tetrahedra (m, 4), global dofs (n, 3))`` of the vertices."""
        return self.mesh.p.T, self.mesh.t.T, self.basis.nodal_dofs.T + self.offset

"""NGSolve bodies of a ``hemispheres`` scene (3D Hertz contact), P1 and P2.

:class:`NGSolveBackend <rbbench_plugins.backends.ngsolve.backend.NGSolveBackend>` hands a
``hemispheres`` scene to :class:`~rbbench_plugins.backends.hemispheres.HemisphereModel`
with :class:`NGSolveHemisphereBody` as its bodies: the same Netgen reference mesh as the
scikit-fem backend (:func:`~rbbench_plugins.backends.hemisphere_mesh.quarter_hemisphere`),
handed to NGSolve as arrays, and ``VectorH1`` of order 1 or 2 (dofs blockwise: all x, then
all y, then all z). NGSolve's order-2 basis is hierarchical (vertex hats and one edge bubble
per edge); the contact geometry works on nodal P2 (values at the vertices and the edge
midpoints, as scikit-fem's ``ElementTetP2``), so the P2 operators are assembled in NGSolve's
basis and transformed to the nodal one: ``c_e = (u_mid - (u_a + u_b) / 2) / beta_e``, with
``beta_e`` the edge bubble's value at its midpoint (evaluated, not assumed), i.e.
``u_hier = T u_nodal`` and ``K_nodal = T^T K_hier T``.
"""

from __future__ import annotations

import netgen.meshing as ngm
import ngsolve as ngs
import numpy as np
import scipy.sparse as sp
from rbbench_plugins.backends import hemispheres as hs
from rbbench_plugins.backends.hemisphere_mesh import (
    TetMesh,
    boundary_triangles,
    edge_lookup,
    mirror_z,
)

from rbbench.scene.loading import Scene, SceneError


def ngsolve_hemisphere_model(scene: Scene, degree: int, h_contact: float, h_max: float,
                             grading: float) -> hs.HemisphereModel:
    """The :class:`~rbbench_plugins.backends.hemispheres.HemisphereModel` on NGSolve bodies
    (P1 or P2: another ``[discretization] degree`` raises a :class:`SceneError`)."""
    if degree not in (1, 2):
        raise SceneError(f"{scene.path}: [discretization] degree = {degree}: the ngsolve "
                         "backend builds the 3D hemispheres with P1 or P2 (degree = 1 or 2)")
    return hs.HemisphereModel(scene, degree, h_contact, h_max, grading, NGSolveHemisphereBody)


def _tet_mesh(points: np.ndarray, tets: np.ndarray) -> ngs.Mesh:
    """An NGSolve mesh from arrays (vertex ``i`` = row ``i``), boundary triangles included."""
    m = ngm.Mesh(dim=3)
    m.AddPoints(np.ascontiguousarray(points, dtype=float))
    m.Add(ngm.FaceDescriptor(bc=1, domin=1, domout=0, surfnr=1))
    m.AddElements(dim=3, index=1, data=np.ascontiguousarray(tets, dtype=np.int32), base=0)
    m.AddElements(dim=2, index=1, base=0,
                  data=np.ascontiguousarray(boundary_triangles(tets), dtype=np.int32))
    return ngs.Mesh(m)


def _nodal_to_hierarchical(ngmesh: ngs.Mesh, edges: np.ndarray, nv: int,
                           mids: np.ndarray) -> sp.csr_matrix:
    """Scalar ``T`` with ``u_hier = T u_nodal`` for NGSolve's order-2 ``H1`` on ``ngmesh``
    (dofs: vertices, then one bubble per edge; checked): vertex rows the identity, edge
    ``e = (a, b)``: ``(u_mid - (u_a + u_b) / 2) / beta_e``, ``beta_e`` the value of the
    bubble at its own midpoint (every other bubble vanishes there)."""
    fes = ngs.H1(ngmesh, order=2)
    ne = edges.shape[0]
    e_dofs = [fes.GetDofNrs(ngs.NodeId(ngs.EDGE, e))[0] for e in range(ne)]
    if fes.ndof != nv + ne or not np.array_equal(e_dofs, nv + np.arange(ne)):
        raise RuntimeError("ngsolve hemispheres: unexpected order-2 dof numbering")
    g = ngs.GridFunction(fes)
    g.vec[:] = 0.0
    g.vec.FV().NumPy()[nv:] = 1.0
    beta = np.asarray(g(ngmesh(mids[:, 0], mids[:, 1], mids[:, 2]))).ravel()
    if np.any(np.abs(beta) < 1e-8):
        raise RuntimeError("ngsolve hemispheres: an edge bubble vanishes at its midpoint")
    rows = np.concatenate([np.arange(nv), np.repeat(nv + np.arange(ne), 3)])
    cols = np.concatenate([np.arange(nv),
                           np.column_stack([nv + np.arange(ne), edges]).ravel()])
    vals = np.concatenate([np.ones(nv),
                           (np.array([1.0, -0.5, -0.5])[None, :] / beta[:, None]).ravel()])
    return sp.csr_matrix((vals, (rows, cols)), shape=(nv + ne, nv + ne))


def _csr(form: ngs.BilinearForm, n: int) -> sp.csr_matrix:
    form.Assemble()
    rows, cols, vals = form.mat.COO()
    return sp.csr_matrix((np.array(vals), (np.array(rows), np.array(cols))), shape=(n, n))


class NGSolveHemisphereBody:
    """One body: an NGSolve mesh of the reference body and ``VectorH1`` (P1 or P2); nodes
    (vertices, then for P2 the edge midpoints in NGSolve's edge order) with their global
    dofs, nodal for P2 (:data:`T`, the module docstring)."""

    def __init__(self, spec: hs.HemisphereBody, mesh: TetMesh, degree: int, offset: int):
        if degree not in (1, 2):
            raise ValueError("ngsolve hemispheres: degree 1 or 2 only")
        if spec.mirrored:
            mesh = mirror_z(mesh)
        self.spec, self.name, self.offset, self.degree = spec, spec.name, offset, degree
        self.points, self.tets = mesh.points, mesh.tets
        ngmesh = _tet_mesh(self.points, self.tets)
        self.fes = ngs.VectorH1(ngmesh, order=degree)
        nv = self.points.shape[0]
        self.edges = (np.array([[v.nr for v in e.vertices] for e in ngmesh.edges], dtype=int)
                      if degree == 2 else np.zeros((0, 2), dtype=int))
        n = nv + self.edges.shape[0]  # scalar nodes: vertices, then edge midpoints
        if self.fes.ndof != 3 * n:
            raise RuntimeError(f"ngsolve hemispheres: VectorH1 has {self.fes.ndof} dofs, "
                               f"expected 3 x {n} nodes")
        self.ndofs = self.fes.ndof
        mids = self.points[self.edges].mean(axis=1)
        self.node_points = np.concatenate([self.points, mids]) if degree == 2 else self.points
        self.node_dofs = np.arange(n)[:, None] + n * np.arange(3)[None, :] + offset
        #: hierarchical = T nodal (identity for P1)
        self.T = sp.identity(self.ndofs, format="csr") if degree == 1 else \
            sp.kron(sp.identity(3), _nodal_to_hierarchical(ngmesh, self.edges, nv, mids),
                    format="csr")

    def surface_triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """``(triangles, curved)``: the boundary triangles as node numbers ((n, 3), P2:
        (n, 6) with the edge nodes of edges (0, 1), (1, 2), (0, 2)) and which are on the
        sphere (not on one of the planes x, y, z = 0)."""
        tri = boundary_triangles(self.tets)
        on_plane = [np.all(self.points[tri, k] == 0.0, axis=1) for k in range(3)]
        curved = ~(on_plane[0] | on_plane[1] | on_plane[2])
        if self.degree == 2:
            nv = self.points.shape[0]
            lookup = edge_lookup(self.edges, nv)
            tri = np.column_stack([tri, *(lookup(tri[:, a], tri[:, b]) + nv
                                          for a, b in ((0, 1), (1, 2), (0, 2)))])
        return tri, curved

    def tet_nodes(self) -> np.ndarray:
        """(m, 4) vertex numbers of each tetrahedron (P1: the nodes are the vertices)."""
        return np.asarray(self.tets)

    def node_groups(self) -> dict[str, np.ndarray]:
        return hs.node_groups(self.node_points)

    def lame_terms(self) -> tuple[sp.csr_matrix, sp.csr_matrix]:
        """``(K_div, K_eps)``: ``int div u div v`` and ``int 2 eps(u) : eps(v)`` on the
        reference body (the terms of lambda and of the shear modulus)."""
        u, v = self.fes.TnT()

        def eps(w):
            return 0.5 * (ngs.Grad(w) + ngs.Grad(w).trans)

        k_div = ngs.BilinearForm(self.fes)
        k_div += ngs.div(u) * ngs.div(v) * ngs.dx
        k_eps = ngs.BilinearForm(self.fes)
        k_eps += 2.0 * ngs.InnerProduct(eps(u), eps(v)) * ngs.dx
        return self._nodal(k_div), self._nodal(k_eps)

    def h1(self) -> sp.csr_matrix:
        u, v = self.fes.TnT()
        form = ngs.BilinearForm(self.fes)
        form += (u * v + ngs.InnerProduct(ngs.Grad(u), ngs.Grad(v))) * ngs.dx
        return self._nodal(form)

    def _nodal(self, form: ngs.BilinearForm) -> sp.csr_matrix:
        """The assembled ``form`` in the nodal basis: ``T^T K T``."""
        K = _csr(form, self.ndofs)
        return K if self.degree == 1 else (self.T.T @ K @ self.T).tocsr()

    @property
    def vertices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(points (n, 3), tetrahedra (m, 4), global dofs (n, 3))`` of the vertices."""
        return self.points, self.tets, self.node_dofs[:self.points.shape[0]]

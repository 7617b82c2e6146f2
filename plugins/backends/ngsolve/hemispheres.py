"""NGSolve bodies of a ``hemispheres`` scene (3D Hertz contact), P1.

:class:`NGSolveBackend <rbbench_plugins.backends.ngsolve.backend.NGSolveBackend>` hands a
``hemispheres`` scene to :class:`~rbbench_plugins.backends.hemispheres.HemisphereModel`
with :class:`NGSolveHemisphereBody` as its bodies: the same Netgen reference mesh as the
scikit-fem backend (:func:`~rbbench_plugins.backends.hemisphere_mesh.quarter_hemisphere`),
handed to NGSolve as arrays, and ``VectorH1`` of order 1 (dofs blockwise: all x, then all
y, then all z). P2 (NGSolve's hierarchical edge bubbles) is not offered in 3D yet.
"""

from __future__ import annotations

import netgen.meshing as ngm
import ngsolve as ngs
import numpy as np
import scipy.sparse as sp
from rbbench_plugins.backends import hemispheres as hs
from rbbench_plugins.backends.hemisphere_mesh import TetMesh, boundary_triangles, mirror_z

from rbbench.scene.loading import Scene, SceneError


def ngsolve_hemisphere_model(scene: Scene, degree: int, h_contact: float, h_max: float,
                             grading: float) -> hs.HemisphereModel:
    """The :class:`~rbbench_plugins.backends.hemispheres.HemisphereModel` on NGSolve bodies
    (P1 only: ``[discretization] degree = 2`` raises a :class:`SceneError`)."""
    if degree != 1:
        raise SceneError(f"{scene.path}: [discretization] degree = {degree}: the ngsolve "
                         "backend builds the 3D hemispheres with P1 (degree = 1) only; use "
                         "the skfem backend for P2")
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


def _csr(form: ngs.BilinearForm, n: int) -> sp.csr_matrix:
    form.Assemble()
    rows, cols, vals = form.mat.COO()
    return sp.csr_matrix((np.array(vals), (np.array(rows), np.array(cols))), shape=(n, n))


class NGSolveHemisphereBody:
    """One body: an NGSolve mesh of the reference body and ``VectorH1`` (P1)."""

    def __init__(self, spec: hs.HemisphereBody, mesh: TetMesh, degree: int, offset: int):
        if degree != 1:
            raise ValueError("ngsolve hemispheres: degree 1 only")
        if spec.mirrored:
            mesh = mirror_z(mesh)
        self.spec, self.name, self.offset, self.degree = spec, spec.name, offset, degree
        self.points, self.tets = mesh.points, mesh.tets
        self.fes = ngs.VectorH1(_tet_mesh(self.points, self.tets), order=1)
        nv = self.points.shape[0]
        if self.fes.ndof != 3 * nv:
            raise RuntimeError(f"ngsolve hemispheres: VectorH1 has {self.fes.ndof} dofs, "
                               f"expected 3 x {nv} vertices")
        self.ndofs = self.fes.ndof
        self.node_points = self.points
        self.node_dofs = np.arange(nv)[:, None] + nv * np.arange(3)[None, :] + offset

    def surface_triangles(self) -> tuple[np.ndarray, np.ndarray]:
        """``(triangles (n, 3), curved)``: the boundary triangles and which are on the
        sphere (not on one of the planes x, y, z = 0)."""
        tri = boundary_triangles(self.tets)
        on_plane = [np.all(self.points[tri, k] == 0.0, axis=1) for k in range(3)]
        return tri, ~(on_plane[0] | on_plane[1] | on_plane[2])

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
        return _csr(k_div, self.ndofs), _csr(k_eps, self.ndofs)

    def h1(self) -> sp.csr_matrix:
        u, v = self.fes.TnT()
        form = ngs.BilinearForm(self.fes)
        form += (u * v + ngs.InnerProduct(ngs.Grad(u), ngs.Grad(v))) * ngs.dx
        return _csr(form, self.ndofs)

    @property
    def vertices(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(points (n, 3), tetrahedra (m, 4), global dofs (n, 3))`` of the vertices."""
        return self.points, self.tets, self.node_dofs

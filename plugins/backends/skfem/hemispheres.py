"""scikit-fem HF operators of a ``hemispheres`` scene (3D Hertz contact).

:class:`SkfemBackend <rbbench_plugins.backends.skfem.backend.SkfemBackend>` hands a
``hemispheres`` scene to :class:`HemisphereModel`. Each body is the unit quarter hemisphere
meshed once (:func:`~rbbench_plugins.backends.hemisphere_mesh.quarter_hemisphere`,
``MeshTet``; P1 ``ElementTetP1`` or P2 ``ElementTetP2`` on straight tetrahedra) and mapped
by a similarity ``x = s(mu) x_hat + c(mu)``. Strains scale by ``1 / s`` and volumes by
``s^3``, so the stiffness on the mapped body is ``s`` times the reference one: each body's
two Lame terms are assembled once and ``A(mu) = sum_b s_b(mu) (lambda_b K_div,b + mu_b
K_eps,b)``.
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
from rbbench_plugins.backends import hemispheres as hs
from rbbench_plugins.backends.hemisphere_mesh import (
    TetMesh,
    boundary_triangles,
    mirror_z,
    quarter_hemisphere,
)
from skfem import Basis, BilinearForm, ElementTetP1, ElementTetP2, ElementVector, MeshTet, asm
from skfem.models.elasticity import lame_parameters, linear_elasticity

from rbbench.hf.geometry.surface import SurfaceLayout
from rbbench.interfaces import BodyMesh, Discretization
from rbbench.scene.loading import Scene


@BilinearForm
def _vector_h1(u, v, w):
    return (u * v).sum(axis=0) + (u.grad * v.grad).sum(axis=(0, 1))


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
            lookup = _edge_lookup(m.edges.T, m.nvertices)
            mids = [lookup(tri[:, a], tri[:, b]) + m.nvertices
                    for a, b in ((0, 1), (1, 2), (0, 2))]
            tri = np.column_stack([tri, *mids])
        return tri, curved

    def node_groups(self) -> dict[str, np.ndarray]:
        """Masks of the nodes on the flat face and on the symmetry planes."""
        p = self.node_points
        return {"sym_x": p[:, 0] == 0.0, "sym_y": p[:, 1] == 0.0, "flat": p[:, 2] == 0.0}


def _edge_lookup(edges: np.ndarray, n_vertices: int):
    """``f(a, b)``: the index of the edge with vertices ``a``, ``b`` (either order)."""
    key = np.sort(edges, axis=1) @ np.array([n_vertices, 1])
    order = np.argsort(key)

    def index(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        k = np.minimum(a, b) * n_vertices + np.maximum(a, b)
        pos = np.searchsorted(key, k, sorter=order)
        found = order[np.minimum(pos, key.size - 1)]
        if not np.array_equal(key[found], k):
            raise RuntimeError("skfem hemispheres: a boundary triangle edge is not a mesh edge")
        return found

    return index


class HemisphereModel:
    """The reference bodies, their stiffness terms, Dirichlet data and contact layout of a
    ``hemispheres`` scene; :meth:`discretize` gives the operators at mu."""

    def __init__(self, scene: Scene, degree: int, h_contact: float, h_max: float,
                 grading: float):
        self.scene, self.degree = scene, degree
        mesh = quarter_hemisphere(hs.mesh_cap(scene), h_contact, h_max, grading)
        self.bodies: list[HemisphereBody] = []
        offset = 0
        for spec in hs.hemisphere_bodies(scene):
            body = HemisphereBody(spec, mesh, degree, offset)
            self.bodies.append(body)
            offset += body.ndofs
        self.ndofs = offset
        self.maps = hs.hemisphere_maps(scene)
        fixed, moving = [], []
        for body in self.bodies:
            d = hs.dirichlet_data(body.node_groups(), body.name == "upper")
            fixed.append(body.node_dofs[d["fixed"]])
            moving.append(body.node_dofs[d["moving"]])
        self.dirichlet = np.concatenate(fixed)
        self.moving = np.isin(self.dirichlet, np.concatenate(moving))
        self._k_ref: list[tuple[sp.csr_matrix, sp.csr_matrix]] | None = None
        self._layout: SurfaceLayout | None = None

    # -------------------------------------------------------------- stiffness
    def reference_stiffness(self) -> list[tuple[sp.csr_matrix, sp.csr_matrix]]:
        """``[(K_div, K_eps) per body]`` on the unit reference body, in global numbering
        (``linear_elasticity(1, 0)`` and ``(0, 1)``), assembled once."""
        if self._k_ref is None:
            self._k_ref = []
            for body in self.bodies:
                terms = []
                for lame in ((1.0, 0.0), (0.0, 1.0)):
                    k = asm(linear_elasticity(*lame), body.basis).tocoo()
                    terms.append(sp.csr_matrix((k.data, (k.row + body.offset,
                                                         k.col + body.offset)),
                                               shape=(self.ndofs, self.ndofs)))
                self._k_ref.append(tuple(terms))
        return self._k_ref

    def lame(self, mu) -> list[tuple[float, float]]:
        """``(lambda, mu)`` of each body at mu (3D)."""
        return [lame_parameters(*self.scene.material(b.name, mu)) for b in self.bodies]

    def stiffness(self, mu) -> sp.csr_matrix:
        """``A(mu) = sum_b s_b(mu) (lambda_b K_div,b + mu_b K_eps,b)`` (the 3D similarity
        scaling; equal to the assembly on the mapped mesh up to round-off)."""
        A = sp.csr_matrix((self.ndofs, self.ndofs))
        for body, (k_div, k_eps), (lam, mu_l) in zip(self.bodies, self.reference_stiffness(),
                                                     self.lame(mu), strict=True):
            s = self.maps[body.name].at(mu)[0]
            A = A + s * (lam * k_div + mu_l * k_eps)
        return A.tocsr()

    def inner_product(self, which: str) -> sp.csr_matrix:
        """The energy product at the scene's default mu, or the vector H1 product of the
        reference bodies (``[discretization] inner_product``)."""
        if which == "energy":
            return self.stiffness(self.scene.default_mu)
        return sp.block_diag([asm(_vector_h1, b.basis) for b in self.bodies]).tocsr()

    # ---------------------------------------------------------------- contact
    def contact_layout(self) -> SurfaceLayout:
        """The slave cap of the upper body and the master cap of the lower one (or the
        rigid plane), built once."""
        if self._layout is None:
            surfaces = []
            for body in self.bodies:
                tri, curved = body.surface_triangles()
                cap = hs.cap_triangles(body.node_points, tri, curved, body.spec)
                surfaces.append(hs.tri_surface(body.node_points, tri[cap], body.node_dofs,
                                               body.spec, self.maps[body.name]))
            master = surfaces[1] if len(surfaces) > 1 else None
            self._layout = hs.surface_layout(self.scene, surfaces[0], master, self.degree,
                                             self.ndofs)
        return self._layout

    def discretize(self, mu, backend: str, inner_product: sp.csr_matrix) -> Discretization:
        """The operators at mu (frictionless: no tangential or stress operators yet)."""
        t0 = time.perf_counter()
        A = self.stiffness(mu)
        t_asm = time.perf_counter() - t0
        d = float(self.scene.value("load", "displacement", mu))
        values = np.where(self.moving, -d, 0.0)
        contact = hs.surface_contact(self.scene, self.contact_layout(), mu)
        bodies = []
        for body in self.bodies:
            E, nu = self.scene.material(body.name, mu)
            x = self.maps[body.name](mu, body.mesh.p.T)
            bodies.append(BodyMesh(body.name, x, body.mesh.t.T.copy(),
                                   body.basis.nodal_dofs.T + body.offset, E, nu))
        info = {"geometry": hs.hemisphere_geometry(self.scene, self.maps, mu),
                "t_assemble_s": t_asm, "n_facets_slave": self.contact_layout().slave.n_tri,
                "degree": self.degree, "backend": backend}
        return Discretization(mu=mu, A=A, F=np.zeros(self.ndofs),
                              dirichlet_dofs=self.dirichlet, dirichlet_values=values,
                              X=inner_product, contact=contact, bodies=bodies,
                              physics="elasticity", info=info)

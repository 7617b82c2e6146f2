"""Backend-neutral pieces of a ``hemispheres`` scene (3D Hertz; numpy only).

* the reference bodies and their mu-maps (:func:`hemisphere_maps`,
  :func:`hemisphere_geometry`): the upper quarter hemisphere (pole down, radius
  ``upper_radius``) above the lower one (pole up, radius ``lower_radius``, flat face
  ``z = 0`` clamped) or the rigid plane ``z = 0``;
* the potential contact surface of a body from its boundary triangles
  (:func:`cap_triangles`, :func:`tri_surface`), handed to
  :func:`rbbench.hf.geometry.surface.contact_operators_3d` through a
  :class:`~rbbench.hf.geometry.surface.SurfaceLayout` (:func:`surface_layout`);
* the slave body's tetrahedra under its contact triangles (:func:`slave_solid`), for the
  normal stress ``Snn`` of Nitsche's method;
* the Dirichlet data (:func:`dirichlet_data`): the upper flat face moves by
  ``(0, 0, -d)``, the lower flat face is clamped, the symmetry planes ``x = 0`` / ``y = 0``
  hold the normal displacement at zero.

Every body is meshed once on the unit quarter hemisphere
(:func:`rbbench_plugins.backends.hemisphere_mesh.quarter_hemisphere`, pole at
``(0, 0, -1)``); the lower body is its mirror ``z -> -z``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
from rbbench_plugins.backends.common import body_maps, is_rigid
from rbbench_plugins.backends.hemisphere_mesh import quarter_hemisphere

from rbbench.hf.geometry.chains import AffineMap
from rbbench.hf.geometry.pairing import PairingError
from rbbench.hf.geometry.surface import SurfaceLayout, TriSurface, contact_operators_3d
from rbbench.hf.geometry.surface_stress import SlaveSolid, contact_operators_3d_stress
from rbbench.interfaces import BodyMesh, ContactOperators, Discretization
from rbbench.scene.loading import Scene, SceneError

#: The symmetry planes of ``[geometry] symmetry`` (names of :class:`SurfaceLayout`).
SYMMETRY_PLANES = {"quarter": ("x", "y")}


@dataclass(frozen=True)
class HemisphereBody:
    """One reference body: ``"upper"`` (pole ``(0, 0, -1)``, as meshed) or ``"lower"``
    (the mirror ``z -> -z``, pole ``(0, 0, 1)``); ``cap`` is the polar angle / pi of its
    potential contact surface about the pole."""

    name: str
    cap: float
    mirrored: bool

    @property
    def pole(self) -> np.ndarray:
        return np.array([0.0, 0.0, 1.0 if self.mirrored else -1.0])

    @property
    def inside(self) -> np.ndarray:
        """A reference point inside the body, on the axis (normals point away from it)."""
        return -0.5 * self.pole


def hemisphere_bodies(scene: Scene) -> list[HemisphereBody]:
    """The upper body, then (two elastic bodies) the lower one."""
    g = scene.data["geometry"]
    bodies = [HemisphereBody("upper", float(g["contact_cap"]), False)]
    if not is_rigid(scene):
        bodies.append(HemisphereBody("lower", float(g["master_cap"]), True))
    return bodies


def mesh_cap(scene: Scene) -> float:
    """The cap toward which the one reference mesh of both bodies is graded:
    ``contact_cap`` (one mesh, meshed once, serves both; the master cap beyond it only
    holds pairing candidates)."""
    return float(scene.data["geometry"]["contact_cap"])


def hemisphere_maps(scene: Scene) -> dict[str, AffineMap]:
    """The mu-map of each body: upper ``R1 x_hat + (0, 0, top + g0 + R1)`` with ``top = R2``
    (two bodies) or ``0`` (rigid flat), lower ``R2 x_hat`` (:func:`body_maps` in 3D)."""
    return body_maps(scene, dim=3)


def hemisphere_geometry(scene: Scene, maps: dict[str, AffineMap], mu: np.ndarray) -> dict:
    """Radii, initial gap, upper centre and symmetry at mu (``Discretization.info``)."""
    r1, centre1 = maps["upper"].at(mu)
    r2 = maps["lower"].at(mu)[0] if "lower" in maps else None
    return {"R1": r1, "R2": r2, "g0": float(scene.value("geometry", "initial_gap", mu)),
            "centre1": centre1, "dim": 3,
            "symmetry": SYMMETRY_PLANES[scene.data["geometry"]["symmetry"]]}


def cap_triangles(points: np.ndarray, triangles: np.ndarray, curved: np.ndarray,
                  body: HemisphereBody) -> np.ndarray:
    """Indices of the curved boundary triangles whose centroid lies within the polar angle
    ``cap pi`` of the body's pole (reference coordinates)."""
    c = points[triangles[:, :3]].mean(axis=1)
    cosang = c @ body.pole / np.linalg.norm(c, axis=1)
    return np.flatnonzero(curved & (cosang >= np.cos(np.pi * body.cap)))


def tri_surface(points: np.ndarray, triangles: np.ndarray, node_dofs: np.ndarray,
                body: HemisphereBody, amap: AffineMap) -> TriSurface:
    """The :class:`TriSurface` of triangles given by global node numbers.

    Parameters
    ----------
    points : (n, 3)
        Reference coordinates of every node that ``triangles`` names.
    triangles : (n_tri, 3) or (n_tri, 6)
        Global node numbers (P2: then the edge midpoints of edges (0, 1), (1, 2), (0, 2)).
    node_dofs : (n, 3)
        Global x, y, z dofs of each node.
    """
    nodes, local = np.unique(triangles, return_inverse=True)
    return TriSurface(points=np.asarray(points[nodes], float),
                      triangles=local.reshape(triangles.shape),
                      dofs=np.asarray(node_dofs[nodes]), inside=body.inside, map=amap)


def surface_layout(scene: Scene, slave: TriSurface, master: TriSurface | None, degree: int,
                   n_dofs: int) -> SurfaceLayout:
    """The :class:`SurfaceLayout` of a ``hemispheres`` scene. ``[discretization]
    quadrature`` is the exact degree of the slave triangle rule here (0: ``2 degree``)."""
    disc = scene.data["discretization"]
    order = int(disc["quadrature"]) or 2 * degree
    try:
        return SurfaceLayout(slave=slave, master=master, degree=degree, quad_order=order,
                             multiplier=disc["multiplier"], patch=int(disc["lac_patch"]),
                             n_dofs=n_dofs,
                             symmetry=SYMMETRY_PLANES[scene.data["geometry"]["symmetry"]])
    except ValueError as exc:
        raise SceneError(f"{scene.path}: [discretization]: {exc}") from None


def surface_contact(scene: Scene, layout: SurfaceLayout, mu: np.ndarray,
                    solid: SlaveSolid | None = None) -> ContactOperators:
    """The contact operators at mu, with ``Snn`` and ``facet_length`` when the slave
    ``solid`` is given (:func:`~rbbench.hf.geometry.surface_stress.contact_operators_3d_stress`);
    a slave point missing the master cap becomes a :class:`SceneError` naming
    ``[geometry] master_cap``."""
    try:
        if solid is None:
            return contact_operators_3d(layout, mu)
        return contact_operators_3d_stress(layout, solid, mu)
    except PairingError as exc:
        raise SceneError(
            f"{scene.path}: [geometry] master_cap: {exc.n_missed} slave quadrature point(s) "
            f"(e.g. x = {np.asarray(exc.example).round(4).tolist()}) miss the master cap "
            f"{scene.data['geometry']['master_cap']} (polar angle / pi); widen it") from None


def tets_of_faces(tets: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    """The tetrahedron (row of ``tets`` (m, 4), vertex numbers) having each boundary
    triangle (``triangles`` (n, 3), vertex numbers) as a face; a triangle that is no face
    raises a ``ValueError``."""
    faces = np.sort(tets[:, [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]], axis=2)
    n = np.int64(max(int(tets.max()), int(triangles.max())) + 1)
    weights = np.array([n * n, n, 1], dtype=np.int64)
    key = faces.reshape(-1, 3).astype(np.int64) @ weights
    want = np.sort(triangles, axis=1).astype(np.int64) @ weights
    order = np.argsort(key, kind="stable")
    pos = np.minimum(np.searchsorted(key, want, sorter=order), key.size - 1)
    found = order[pos]
    if not np.array_equal(key[found], want):
        raise ValueError("a contact triangle is not a face of any tetrahedron of its body")
    return found // 4


def slave_solid(scene: Scene, body: Any, triangles: np.ndarray) -> SlaveSolid:
    """The :class:`~rbbench.hf.geometry.surface_stress.SlaveSolid` of the slave
    ``triangles`` (node numbers of ``body``, first 3 columns the vertices): the
    tetrahedron under each (:func:`tets_of_faces`), its reference vertices and the global
    dofs of its nodes (``body.tet_nodes()``: vertices, then for P2 the midpoints of the
    edges :data:`~rbbench.hf.geometry.surface_stress.TET_EDGES`), the body's material."""
    nodes = body.tet_nodes()
    owner = tets_of_faces(nodes[:, :4], triangles[:, :3])
    table = scene.data["material"][body.name]
    return SlaveSolid(tets=np.asarray(body.node_points, float)[nodes[owner, :4]],
                      dofs=np.asarray(body.node_dofs)[nodes[owner]],
                      E=scene.affine(table["E"]), nu=scene.affine(table["nu"]))


def node_groups(points: np.ndarray) -> dict[str, np.ndarray]:
    """Masks of the nodes on the flat face ``z = 0`` and the symmetry planes ``x = 0``,
    ``y = 0`` (exact zeros: the mesh snaps its planes)."""
    return {"sym_x": points[:, 0] == 0.0, "sym_y": points[:, 1] == 0.0,
            "flat": points[:, 2] == 0.0}


def dirichlet_data(groups: dict[str, np.ndarray], upper: bool) -> dict[str, np.ndarray]:
    """Which nodes of a body carry which Dirichlet condition.

    Parameters
    ----------
    groups : dict
        Boolean masks over the body's nodes: ``"flat"`` (z = 0), ``"sym_x"`` (x = 0),
        ``"sym_y"`` (y = 0).
    upper : bool
        The upper body (its flat face moves by ``(0, 0, -d)``) or the lower one (clamped).

    Returns
    -------
    dict
        ``"fixed"`` (n, 3) boolean: the components held; ``"moving"`` (n, 3) boolean: the
        held components that take ``-d`` (the z component of the upper flat face).
    """
    flat = groups["flat"]
    fixed = np.zeros((flat.size, 3), dtype=bool)
    fixed[flat] = True
    fixed[groups["sym_x"], 0] = True
    fixed[groups["sym_y"], 1] = True
    moving = np.zeros_like(fixed)
    if upper:
        moving[flat, 2] = True
    return {"fixed": fixed, "moving": moving}


class HemisphereModel:
    """The reference bodies, their stiffness terms, Dirichlet data and contact layout of a
    ``hemispheres`` scene; :meth:`discretize` gives the operators at mu.

    ``make_body(spec, mesh, degree, offset)`` builds one body in a backend's numbering: it
    has ``name``, ``spec``, ``offset``, ``ndofs``, ``node_points`` (n, 3) and
    ``node_dofs`` (n, 3) (vertices, then P2 edge nodes), ``surface_triangles()``,
    ``tet_nodes()`` (m, 4 or 10: the node numbers of each tetrahedron, vertices then P2
    edge midpoints in the order of
    :data:`~rbbench.hf.geometry.surface_stress.TET_EDGES`), ``node_groups()``,
    ``lame_terms()`` and ``h1()`` (local matrices) and ``vertices``.
    With the same mesh, two backends give the same operators up to dof numbering."""

    def __init__(self, scene: Scene, degree: int, h_contact: float, h_max: float,
                 grading: float, make_body: Callable[..., Any]):
        self.scene, self.degree = scene, degree
        mesh = quarter_hemisphere(mesh_cap(scene), h_contact, h_max, grading)
        self.bodies: list[Any] = []
        offset = 0
        for spec in hemisphere_bodies(scene):
            body = make_body(spec, mesh, degree, offset)
            self.bodies.append(body)
            offset += body.ndofs
        self.ndofs = offset
        self.maps = hemisphere_maps(scene)
        fixed, moving = [], []
        for body in self.bodies:
            d = dirichlet_data(body.node_groups(), body.name == "upper")
            fixed.append(body.node_dofs[d["fixed"]])
            moving.append(body.node_dofs[d["moving"]])
        self.dirichlet = np.concatenate(fixed)
        self.moving = np.isin(self.dirichlet, np.concatenate(moving))
        self._k_ref: list[tuple[sp.csr_matrix, sp.csr_matrix]] | None = None
        self._layout: SurfaceLayout | None = None
        self._slave_triangles: np.ndarray | None = None
        self._solid: SlaveSolid | None = None

    # -------------------------------------------------------------- stiffness
    def _global(self, body: Any, k: sp.spmatrix) -> sp.csr_matrix:
        k = k.tocoo()
        return sp.csr_matrix((k.data, (k.row + body.offset, k.col + body.offset)),
                             shape=(self.ndofs, self.ndofs))

    def reference_stiffness(self) -> list[tuple[sp.csr_matrix, sp.csr_matrix]]:
        """``[(K_div, K_eps) per body]`` on the unit reference body, in global numbering
        (the terms of lambda and of the shear modulus), assembled once."""
        if self._k_ref is None:
            self._k_ref = [tuple(self._global(b, k) for k in b.lame_terms())
                           for b in self.bodies]
        return self._k_ref

    def lame(self, mu) -> list[tuple[float, float]]:
        """``(lambda, mu)`` of each body at mu (3D)."""
        out = []
        for b in self.bodies:
            E, nu = self.scene.material(b.name, mu)
            out.append((E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))))
        return out

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
        return sp.block_diag([b.h1() for b in self.bodies]).tocsr()

    # ---------------------------------------------------------------- contact
    def contact_layout(self) -> SurfaceLayout:
        """The slave cap of the upper body and the master cap of the lower one (or the
        rigid plane), built once."""
        if self._layout is None:
            surfaces = []
            for body in self.bodies:
                tri, curved = body.surface_triangles()
                cap = cap_triangles(body.node_points, tri, curved, body.spec)
                surfaces.append(tri_surface(body.node_points, tri[cap], body.node_dofs,
                                               body.spec, self.maps[body.name]))
                if body is self.bodies[0]:
                    self._slave_triangles = tri[cap]
            master = surfaces[1] if len(surfaces) > 1 else None
            self._layout = surface_layout(self.scene, surfaces[0], master, self.degree,
                                             self.ndofs)
        return self._layout

    def slave_solid(self) -> SlaveSolid:
        """The upper (slave) body's tetrahedra under its contact triangles, in the order of
        the layout's slave triangles (:func:`slave_solid`), built once."""
        if self._solid is None:
            self.contact_layout()
            self._solid = slave_solid(self.scene, self.bodies[0], self._slave_triangles)
        return self._solid

    def discretize(self, mu, backend: str, inner_product: sp.csr_matrix,
                   stress: bool = False) -> Discretization:
        """The operators at mu; ``stress``: with the slave normal stress ``Snn`` and the
        triangle diameters ``facet_length`` (Nitsche's method). Frictionless: no
        tangential operators."""
        t0 = time.perf_counter()
        A = self.stiffness(mu)
        t_asm = time.perf_counter() - t0
        d = float(self.scene.value("load", "displacement", mu))
        values = np.where(self.moving, -d, 0.0)
        contact = surface_contact(self.scene, self.contact_layout(), mu,
                                  self.slave_solid() if stress else None)
        bodies = []
        for body in self.bodies:
            E, nu = self.scene.material(body.name, mu)
            points, tets, vertex_dofs = body.vertices
            bodies.append(BodyMesh(body.name, self.maps[body.name](mu, points),
                                   np.array(tets), np.array(vertex_dofs), E, nu))
        info = {"geometry": hemisphere_geometry(self.scene, self.maps, mu),
                "t_assemble_s": t_asm, "n_facets_slave": self.contact_layout().slave.n_tri,
                "degree": self.degree, "backend": backend}
        return Discretization(mu=mu, A=A, F=np.zeros(self.ndofs),
                              dirichlet_dofs=self.dirichlet, dirichlet_values=values,
                              X=inner_product, contact=contact, bodies=bodies,
                              physics="elasticity", info=info)

"""Backend-neutral pieces of the built-in HF backends (numpy only, no FEM library).

What every backend of the built-in scenes computes the same way, whatever its
mesh and dof numbering:

* the reference bodies of a ``halfdisks`` scene and their mu-maps
  (:func:`halfdisk_bodies`, :func:`body_maps`, :func:`halfdisk_geometry`);
* boundary facets of a triangle mesh given as arrays, the facets of a potential
  contact zone ordered along the arc (:func:`zone_facets`), the facets of the
  flat (Dirichlet) face (:func:`flat_facets`), and the
  :class:`~rbbench.hf.geometry.operators.FacetChain` built from them
  (:func:`facet_chain`);
* the contact operators at mu with the scene-level error message
  (:func:`halfdisk_contact`), the slave elements behind the normal stress
  ``Snn`` (:func:`slave_stress`), the layout and operators of a backend's
  ``halfdisks`` scenes (the mixin :class:`HalfDiskContact`), and the
  collocation operators of the scalar obstacle problem (:func:`obstacle_contact`);
* what a scene requires of ``discretize`` (:func:`scene_needs`: the tangential
  operators of a friction scene) and the Dirichlet values of its load steps
  (:func:`dirichlet_loads`).

Meshes are arrays: ``points`` (n, 2) in reference coordinates, ``facets``
(n_f, 2) vertex indices of edges, ``triangles`` (n_t, 3).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from rbbench.hf.geometry.chains import AffineMap, FacetChain, SlaveStress, with_vertex_normals
from rbbench.hf.geometry.operators import contact_operators
from rbbench.hf.geometry.pairing import ContactLayout, PairingError
from rbbench.interfaces import ContactOperators
from rbbench.scene.friction import friction_of, tangential_displacement
from rbbench.scene.loading import Scene, SceneError

#: Relative tolerance (to the unit reference radius) of the flat-face test.
FLAT_TOL = 1e-9


# ---------------------------------------------------------------------------
# halfdisks scenes: reference bodies and their mu-maps
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class HalfDiskBody:
    """One reference body of a ``halfdisks`` scene.

    Attributes
    ----------
    name : str
        ``"upper"`` or ``"lower"`` (the material table and map of the body).
    mesh_zone : (float, float)
        Angular zone (radians) on the unit *lower* half-disk toward which its
        mesh is graded (the potential contact arc).
    chain_zone : (float, float)
        Angular zone (radians) of the contact chain in the body's own
        reference coordinates.
    mirrored : bool
        The body is the mirror image ``y -> -y`` of the graded lower half-disk
        (the lower body, curved side up); triangles are reoriented.
    """

    name: str
    mesh_zone: tuple[float, float]
    chain_zone: tuple[float, float]
    mirrored: bool


def discretization_settings(scene: Scene) -> dict:
    """The scene's ``[discretization]`` as backend attributes: ``degree``, ``h_contact`` and
    ``h_max`` (scaled by ``2**-level``), ``grading``, ``n_gauss`` (0: degree + 1),
    ``multiplier``; and the geometry ``kind``."""
    disc = scene.data["discretization"]
    scale = 2.0 ** (-int(disc["level"]))
    degree = int(disc["degree"])
    return {"degree": degree, "h_contact": float(disc["h_contact"]) * scale,
            "h_max": float(disc["h_max"]) * scale, "grading": float(disc["grading"]),
            "n_gauss": int(disc["quadrature"]) or degree + 1,
            "multiplier": disc["multiplier"], "kind": scene.data["geometry"]["kind"]}


def is_rigid(scene: Scene) -> bool:
    """The lower body is the rigid plane ``y = 0`` (``geometry.lower = "rigid_flat"``)."""
    return scene.data["geometry"]["lower"] == "rigid_flat"


def halfdisk_bodies(scene: Scene) -> list[HalfDiskBody]:
    """The reference bodies of a ``halfdisks`` scene: the upper one, then the lower one.

    Upper: the unit lower half-disk graded toward ``contact_zone``. Lower (absent
    on a rigid flat): the unit upper half-disk, the mirror of a lower half-disk
    graded toward the mirrored ``master_zone``.
    """
    g = scene.data["geometry"]
    zone = tuple(np.pi * np.asarray(g["contact_zone"]))
    bodies = [HalfDiskBody("upper", zone, zone, False)]
    if not is_rigid(scene):
        mzone = np.pi * np.asarray(g["master_zone"])
        bodies.append(HalfDiskBody("lower", (-mzone[1], -mzone[0]), tuple(mzone), True))
    return bodies


def mirror_y(points: np.ndarray, triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mirror image ``y -> -y`` of a mesh ``(points (n, 2), triangles (m, 3))``,
    triangles reoriented (vertex order 0, 2, 1)."""
    return points * np.array([1.0, -1.0]), triangles[:, [0, 2, 1]]


def body_maps(scene: Scene, dim: int = 2) -> dict[str, AffineMap]:
    """The mu-map of each body, the one source of the geometry of a ``halfdisks`` (``dim =
    2``) or ``hemispheres`` (``dim = 3``) scene.

    The upper body is ``R1 x_hat + (0, [0,] top + g0 + R1)`` with ``top = R2`` (two bodies)
    or ``0`` (rigid flat), the lower one ``R2 x_hat``: the vertical axis is the last.
    Coefficients on ``theta(mu) = [1, mu]``
    (:meth:`rbbench.scene.loading.Scene.affine_coefficients`).
    """
    coef = scene.affine_coefficients
    rigid = is_rigid(scene)
    r1 = coef("geometry", "upper_radius")
    zero = np.zeros_like(r1)
    top = zero if rigid else coef("geometry", "lower_radius")
    shift = [zero] * (dim - 1) + [top + coef("geometry", "initial_gap") + r1]
    maps = {"upper": AffineMap(r1, np.stack(shift))}
    if not rigid:
        r2 = coef("geometry", "lower_radius")
        maps["lower"] = AffineMap(r2, np.zeros((dim, r2.size)))
    return maps


def halfdisk_geometry(scene: Scene, maps: dict[str, AffineMap], mu: np.ndarray) -> dict:
    """Radii, initial gap and upper centre at mu (``Discretization.info["geometry"]``)."""
    r1, centre1 = maps["upper"].at(mu)
    r2 = maps["lower"].at(mu)[0] if "lower" in maps else None
    return {"R1": r1, "R2": r2, "g0": float(scene.value("geometry", "initial_gap", mu)),
            "centre1": centre1}


# ---------------------------------------------------------------------------
# facets from arrays
# ---------------------------------------------------------------------------
def boundary_facets(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Boundary edges of a triangle mesh: ``(facets (n_b, 2), element (n_b,))``.

    Each boundary edge keeps the vertex order of its triangle (counter-clockwise
    triangles give the domain on the left); ``element`` is the adjacent triangle.
    Sorted by (smaller, larger) vertex index.
    """
    t = np.asarray(triangles)
    local = np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]])
    elem = np.tile(np.arange(t.shape[0]), 3)
    key = np.sort(local, axis=1)
    _, first, inverse, count = np.unique(key, axis=0, return_index=True,
                                         return_inverse=True, return_counts=True)
    once = np.flatnonzero(count == 1)
    idx = first[once]
    return local[idx], elem[idx]


def zone_facets(points: np.ndarray, facets: np.ndarray, zone: tuple[float, float]
                ) -> tuple[np.ndarray, np.ndarray]:
    """Boundary facets of a unit (half-)circle arc whose midpoint angle lies in ``zone``.

    Parameters
    ----------
    points : (n, 2)
        Reference vertex coordinates (unit radius, centre at the origin).
    facets : (n_f, 2)
        Vertex indices of the boundary facets.
    zone : (float, float)
        Angular interval (radians).

    Returns
    -------
    order : (n_z,) int
        Rows of ``facets`` in the zone, ordered by increasing midpoint angle.
    flip : (n_z,) bool
        Whether ``facets[order, 1]`` (not ``[order, 0]``) is the vertex of smaller
        angle, i.e. the start of the facet along the chain.

    Midpoints are tested on the angle and on ``|r - 1| < 0.1`` (chord midpoints
    of a polygonal circle lie strictly inside it: pitfalls.md, scikit-fem).
    """
    mid = points[facets].mean(axis=1).T
    ang = np.arctan2(mid[1], mid[0])
    on_arc = np.abs(np.linalg.norm(mid, axis=0) - 1.0) < 0.1
    keep = on_arc & (ang >= zone[0]) & (ang <= zone[1])
    order = np.flatnonzero(keep)[np.argsort(ang[keep])]
    a0 = np.arctan2(*points[facets[order, 0]].T[::-1])
    a1 = np.arctan2(*points[facets[order, 1]].T[::-1])
    return order, a0 > a1


def flat_facets(points: np.ndarray, facets: np.ndarray, y: float = 0.0) -> np.ndarray:
    """Rows of ``facets`` whose midpoint lies on the line ``y`` (reference coordinates).

    The flat face of a reference half-disk is ``y = 0``: the Dirichlet boundary
    of both bodies (the test of the scikit-fem backend on the mapped face,
    ``|y - y_face| < 1e-9 R``, pulled back to the unit reference body).
    """
    mid_y = points[facets, 1].mean(axis=1)
    return np.flatnonzero(np.abs(mid_y - y) < FLAT_TOL)


def facet_chain(points: np.ndarray, triangles: np.ndarray, facets: np.ndarray,
                elements: np.ndarray, zone: tuple[float, float],
                facet_dofs: Callable[[np.ndarray, np.ndarray], np.ndarray],
                amap: AffineMap) -> FacetChain:
    """The :class:`~rbbench.hf.geometry.operators.FacetChain` of the boundary facets in ``zone``.

    Parameters
    ----------
    points, triangles : (n, 2), (n_t, 3)
        The body's reference mesh.
    facets, elements : (n_f, 2), (n_f,)
        Its boundary facets (vertex indices) and their adjacent triangles.
    zone : (float, float)
        Angular zone (radians), see :func:`zone_facets`.
    facet_dofs : callable
        ``facet_dofs(rows, flip)`` -> (n_z, degree + 1, 2) global dofs of the facets
        ``facets[rows]``, ``[start, end, (mid)] x component`` with the start vertex
        ``facets[rows, 1]`` where ``flip`` (the backend's dof numbering).
    amap : AffineMap
        The body's mu-map.

    ``a``, ``b`` are the facet ends by increasing angle; ``inner`` the centroid of
    the adjacent triangle.
    """
    rows, flip = zone_facets(points, facets, zone)
    f = facets[rows]
    n0 = np.where(flip, f[:, 1], f[:, 0])
    n1 = np.where(flip, f[:, 0], f[:, 1])
    inner = points[triangles[elements[rows]]].mean(axis=1)
    return FacetChain(a=points[n0], b=points[n1], inner=inner, dofs=facet_dofs(rows, flip),
                      map=amap, ids=np.arange(rows.size))


def edge_lookup(edges: np.ndarray, n_vertices: int) -> Callable[[np.ndarray], np.ndarray]:
    """``index(pairs (k, 2)) -> (k,)``: rows of ``edges`` (n_e, 2) with these vertex pairs
    (either order). Raises ``ValueError`` for a pair that is not an edge."""
    key = np.sort(np.asarray(edges), axis=1) @ np.array([n_vertices, 1])
    order = np.argsort(key)
    sorted_key = key[order]

    def index(pairs: np.ndarray) -> np.ndarray:
        q = np.sort(np.asarray(pairs), axis=1) @ np.array([n_vertices, 1])
        pos = np.minimum(np.searchsorted(sorted_key, q), key.size - 1)
        if np.any(sorted_key[pos] != q):
            raise ValueError("a vertex pair is not an edge of the mesh")
        return order[pos]

    return index


def slave_stress(scene: Scene, points: np.ndarray, triangles: np.ndarray,
                 facets: np.ndarray, elements: np.ndarray, zone: tuple[float, float],
                 vertex_dofs: Callable[[np.ndarray], np.ndarray],
                 edge_dofs: Callable[[np.ndarray], np.ndarray] | None,
                 body: str = "upper") -> SlaveStress:
    """The :class:`~rbbench.hf.geometry.operators.SlaveStress` of the chain facets in ``zone``.

    Parameters
    ----------
    points, triangles, facets, elements, zone
        As in :func:`facet_chain` (the same facets, in the same chain order).
    vertex_dofs : callable
        ``vertex_dofs(v (k,))`` -> (k, 2) global dofs of vertices ``v``.
    edge_dofs : callable or None
        ``edge_dofs(pairs (k, 2))`` -> (k, 2) global dofs of the midpoints of the
        edges with those vertex pairs (P2); ``None`` for P1.
    body : str
        The body whose material is used (the slave, ``"upper"``).
    """
    rows, _ = zone_facets(points, facets, zone)
    tri = np.asarray(triangles)[elements[rows]]  # (nf, 3) vertex indices
    nf = tri.shape[0]
    dofs = [vertex_dofs(tri.ravel()).reshape(nf, 3, 2)]
    if edge_dofs is not None:
        pairs = np.stack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]], axis=1)
        dofs.append(edge_dofs(pairs.reshape(-1, 2)).reshape(nf, 3, 2))
    table = scene.data["material"][body]
    return SlaveStress(tri=np.asarray(points, dtype=float)[tri],
                       dofs=np.concatenate(dofs, axis=1), E=scene.affine(table["E"]),
                       nu=scene.affine(table["nu"]))


def halfdisk_layout(scene: Scene, slave: FacetChain, master: FacetChain | None,
                    degree: int, n_gauss: int, n_dofs: int,
                    stress: SlaveStress | None = None) -> ContactLayout:
    """The :class:`~rbbench.hf.geometry.operators.ContactLayout` of a ``halfdisks`` scene
    (``[discretization] normals = "smooth"``: the slave chain gets vertex normals,
    :func:`~rbbench.hf.geometry.operators.with_vertex_normals`; ``contact_integration``:
    :attr:`~rbbench.hf.geometry.operators.ContactLayout.integration`)."""
    disc = scene.data["discretization"]
    if disc["normals"] == "smooth":
        slave = with_vertex_normals(slave)
    return ContactLayout(slave=slave, master=master, degree=degree, n_gauss=n_gauss,
                         multiplier=disc["multiplier"], patch=int(disc["lac_patch"]),
                         n_facets=slave.n, n_dofs=n_dofs, stress=stress,
                         integration=disc["contact_integration"])


def check_multiplier(scene: Scene) -> None:
    """``nodal`` multipliers are for obstacle problems: raise :class:`SceneError` otherwise."""
    if scene.data["discretization"]["multiplier"] == "nodal":
        raise SceneError(f"{scene.path}: [discretization] multiplier: 'nodal' is for "
                         "obstacle problems; use 'lac', 'p0' or 'p1' for two-body contact")


#: Optional operators a backend builds on request (``Backend.discretize(mu, needs=...)``).
NEEDS = ("tangential", "stress")


def scene_needs(scene: Scene, needs: frozenset[str]) -> frozenset[str]:
    """``needs`` and what the scene requires: ``"tangential"`` when it declares friction
    (``[friction] law != "none"``); a frictionless scene adds nothing."""
    if friction_of(scene).active:
        return frozenset(needs) | {"tangential"}
    return frozenset(needs)


def dirichlet_loads(scene: Scene, mu: np.ndarray, down: np.ndarray, along: np.ndarray
                    ) -> tuple[np.ndarray, list[np.ndarray] | None]:
    """Dirichlet values of a ``halfdisks`` scene and, with friction, those of each load step.

    The upper flat face moves by ``(t, -d)``: ``-d`` on the Dirichlet entries ``down``
    (its y dofs), the tangential displacement ``t`` (``[load] tangential_displacement``,
    0 if not given) on ``along`` (its x dofs), 0 elsewhere. A load step ``(a, b)``
    (:attr:`rbbench.scene.friction.Friction.steps`) moves it by ``(b t, -a d)``.

    Returns
    -------
    values : the full load; steps : the values per load step, ``None`` without friction.
    """
    d = float(scene.value("load", "displacement", mu))
    values = np.where(down, -d, 0.0)
    friction = friction_of(scene)
    if not friction.active:
        return values, None
    t = tangential_displacement(scene, mu)
    steps = [np.where(down, -a * d, 0.0) + np.where(along, b * t, 0.0)
             for a, b in friction.steps]
    return values + np.where(along, t, 0.0), steps


def check_needs(backend: str, scene: Scene, needs: frozenset[str]) -> None:
    """Validate ``needs`` of ``Backend.discretize`` (:data:`NEEDS`: ``"tangential"``,
    ``"stress"``)."""
    unknown = set(needs) - set(NEEDS)
    if unknown:
        raise ValueError(f"{backend} backend: unknown needs {sorted(unknown)}; "
                         f"valid: {', '.join(map(repr, NEEDS))}")
    if needs and scene.data["geometry"]["kind"] == "unit_square":
        raise ValueError(f"{backend} backend: a scalar obstacle problem has no tangential "
                         "or stress operators")


def halfdisk_contact(scene: Scene, layout: ContactLayout, mu: np.ndarray,
                     tangential: bool = False, stress: bool = False) -> ContactOperators:
    """The contact operators at mu (:func:`rbbench.hf.geometry.operators.contact_operators`:
    Gauss-point-to-segment, or segment-to-segment with ``contact_integration``).

    A slave point missing the master zone becomes a :class:`SceneError` naming
    ``[geometry] master_zone``.
    """
    try:
        return contact_operators(layout, mu, tangential, stress)
    except PairingError as exc:
        zone = [float(z) for z in scene.data["geometry"]["master_zone"]]
        raise SceneError(
            f"{scene.path}: [geometry] master_zone: {exc.n_missed} slave "
            f"quadrature point(s) (e.g. x = {exc.example.round(4).tolist()}) project "
            f"outside the master zone {zone} (theta/pi); widen it") from None


class HalfDiskContact:
    """Mixin: the contact of a backend's ``halfdisks`` scenes, whatever its dof numbering.

    The mu-maps (:func:`body_maps`) and the :class:`~rbbench.hf.geometry.operators.ContactLayout`
    (:func:`halfdisk_layout`) are built once, on first use; the operators at mu come
    from the layout (:func:`halfdisk_contact`). The backend has ``name``, ``scene``,
    ``kind``, ``degree``, ``n_gauss``, ``ndofs``, the bodies ``upper`` and ``lower``
    (``None`` on a rigid flat), and builds, in its own dof numbering, a body's contact
    chain, ``_chain(body, amap)`` (:func:`facet_chain`), and the slave elements behind
    ``Snn``, ``_stress(body)`` (:func:`slave_stress`).
    """

    _maps: dict[str, AffineMap] | None = None
    _layout: ContactLayout | None = None

    def _body_maps(self) -> dict[str, AffineMap]:
        """The mu-map of each body (:func:`body_maps`)."""
        if self._maps is None:
            self._maps = body_maps(self.scene)
        return self._maps

    def contact_layout(self) -> ContactLayout:
        """Reference contact data and the mu-maps (see :mod:`rbbench.hf.geometry.operators`)."""
        if self.kind != "halfdisks":
            raise NotImplementedError(f"{self.name} backend: a contact layout exists for "
                                      "two-body (halfdisks) scenes only")
        if self._layout is None:
            maps = self._body_maps()
            slave = self._chain(self.upper, maps["upper"])
            master = None if self.lower is None else self._chain(self.lower, maps["lower"])
            self._layout = halfdisk_layout(self.scene, slave, master, self.degree,
                                           self.n_gauss, self.ndofs,
                                           stress=self._stress(self.upper))
        return self._layout

    def _contact(self, mu: np.ndarray, needs: frozenset[str]) -> ContactOperators:
        """The contact operators at mu (:func:`halfdisk_contact`), ``Ut`` / ``Snn`` when
        ``needs`` holds ``"tangential"`` / ``"stress"``."""
        return halfdisk_contact(self.scene, self.contact_layout(), mu,
                                tangential="tangential" in needs, stress="stress" in needs)


# ---------------------------------------------------------------------------
# obstacle problem
# ---------------------------------------------------------------------------
def obstacle_contact(scene: Scene, mu: np.ndarray, xy: np.ndarray, free: np.ndarray,
                     lumped: np.ndarray, n_dofs: int) -> ContactOperators:
    """Collocation contact operators of the scalar obstacle problem at mu.

    One nodal multiplier per free dof: ``Un = -u(x_i)``, gap ``-psi(x_i)`` with the
    paraboloid ``psi = height - curvature |x - centre|^2``, weights the lumped
    mass ``lumped`` (row sums of the mass matrix at the free dofs).

    Parameters
    ----------
    xy : (n_free, 2)
        Coordinates of the free dofs.
    free : (n_free,)
        Their global numbers.
    """
    h = float(scene.value("obstacle", "height", mu))
    c = float(scene.value("obstacle", "curvature", mu))
    x0 = np.asarray(scene.data["obstacle"]["centre"])
    psi = h - c * np.sum((xy - x0) ** 2, axis=1)
    nq = free.size
    Un = sp.csr_matrix((-np.ones(nq), (np.arange(nq), free)), shape=(nq, n_dofs))
    return ContactOperators(
        Un=Un, gap=-psi, weights=lumped, points=xy, normals=np.tile([0.0, -1.0], (nq, 1)),
        Mlam=sp.identity(nq, format="csr"), multiplier="nodal", mult_points=xy,
        mult_extent=np.stack([xy[:, 0], xy[:, 0]], axis=1))


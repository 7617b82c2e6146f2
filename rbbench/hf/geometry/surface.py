"""3D contact geometry on triangulated surfaces: Gauss-point-to-triangle pairing of the slave
surface with the master surface (or the rigid plane ``z = 0``) at mu, and the contact
operators ``Un``, gap, weights and multipliers (:class:`~rbbench.interfaces.ContactOperators`).

The 3D counterpart of :mod:`rbbench.hf.geometry.pairing`, with the same choices (docs,
"Contact operators in 3D"):

* **Geometry** is subparametric: each slave and master triangle is the flat triangle of its
  3 vertices (mapped by the body's similarity ``x = s(mu) x_hat + c(mu)``), whatever the
  displacement degree; P2 midpoint nodes carry displacement dofs only.
* **Quadrature** on each slave triangle: a symmetric Gauss rule exact to degree
  ``quad_order`` (Dunavant 1985, :func:`~rbbench.hf.geometry.surface_rules.triangle_rule`);
  physical weights are the rule's weights times the mapped area (``s(mu)^2`` times the
  reference area).
* **Normals**: the unit normal of each flat slave triangle, oriented away from the body's
  ``inside`` point (convex bodies).
* **Pairing**: the line through each slave point along its normal is cast onto the master
  triangles (Moller & Trumbore, "Fast, minimum storage ray-triangle intersection",
  J. Graphics Tools 2 (1997) 21-28), the candidates coming from k-d trees on the master
  triangle centroids (:func:`ray_cast_triangles`); of the hits, the one nearest the slave
  point is kept (the gap is the signed line parameter, so a penetrating point has a
  negative gap).
* **Jump**: ``Un`` row q is ``(u_1(x_q) - u_2(y_q)) . n_1(x_q)`` with the slave and master
  Lagrange bases at the point and at its hit ``y_q``; ``Un u <= gap`` is the constraint.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy import spatial

from rbbench.hf.geometry.chains import AffineMap
from rbbench.hf.geometry.pairing import PairingError
from rbbench.hf.geometry.surface_patches import lac_patches, radial_range
from rbbench.hf.geometry.surface_rules import RULE_DEGREES, triangle_rule, triangle_shape
from rbbench.interfaces import ContactOperators

__all__ = ["SurfaceLayout", "SurfacePairing", "TriSurface", "contact_operators_3d",
           "operators_from_pairing", "pair_surfaces", "ray_cast_pairs", "ray_cast_triangles",
           "surface_rows", "tangent_frames", "tangential_jumps"]

#: (point, triangle) pairs per block of :func:`ray_cast_triangles` (bounds its work arrays)
RAY_BLOCK = 1 << 15


@dataclass
class TriSurface:
    """One body's potential contact surface, reference coordinates (small arrays only).

    Attributes
    ----------
    points : (n_nodes, 3)
        Reference coordinates of the surface nodes.
    triangles : (n_tri, 3) or (n_tri, 6)
        P1: the 3 vertices; P2: the 3 vertices, then the midpoint nodes of edges (0, 1),
        (1, 2), (0, 2) (indices into ``points``).
    dofs : (n_nodes, 3)
        Global dof of the x, y, z displacement of each node.
    inside : (3,)
        A reference point inside the body: outward normals point away from it (convex
        bodies).
    map : AffineMap
        The body's similarity map at mu (``shift`` is (3, p + 1)).
    """

    points: np.ndarray
    triangles: np.ndarray
    dofs: np.ndarray
    inside: np.ndarray
    map: AffineMap

    @property
    def n_tri(self) -> int:
        return int(self.triangles.shape[0])

    def vertices(self, mu: np.ndarray, tris: np.ndarray | slice = slice(None)
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Mapped vertices ``(v0, v1, v2)``, each (n, 3), of triangles ``tris``."""
        t = self.triangles[tris, :3]
        s, c = self.map.at(mu)
        return tuple(s * self.points[t[:, i]] + c for i in range(3))

    def outward_normals(self, mu: np.ndarray, tris: np.ndarray | slice = slice(None)
                        ) -> tuple[np.ndarray, np.ndarray]:
        """``(normals (n, 3), areas (n,))`` of the mapped flat triangles ``tris``; the
        normals point away from the mapped ``inside`` point."""
        v0, v1, v2 = self.vertices(mu, tris)
        cr = np.cross(v1 - v0, v2 - v0)
        area2 = np.linalg.norm(cr, axis=1)
        s, c = self.map.at(mu)
        side = np.einsum("ij,ij->i", cr, (v0 + v1 + v2) / 3.0 - (s * self.inside + c))
        if np.any(area2 == 0.0) or np.any(side == 0.0):
            bad = np.flatnonzero((area2 == 0.0) | (side == 0.0))[0]
            raise ValueError(f"surface triangle {bad}: zero area or its plane passes through "
                             "the body's inside point; cannot orient its normal")
        return np.sign(side)[:, None] * cr / area2[:, None], 0.5 * area2


@dataclass
class SurfaceLayout:
    """What the 3D pairing needs (the 3D counterpart of
    :class:`~rbbench.hf.geometry.pairing.ContactLayout`).

    ``master = None`` is the rigid plane ``z = 0`` (outward normal ``+z``). ``degree`` (1 or
    2) is the displacement degree on the surface triangles, ``quad_order`` the exact degree
    of the slave triangle rule, ``multiplier`` one of ``"p1"`` (continuous nodal hats on
    slave vertices), ``"p0"`` (one per slave triangle), ``"lac"`` (P0 on patches, each the
    star of a vertex, of at least ``ceil(patch / 2)`` slave triangles,
    :func:`~rbbench.hf.geometry.surface_patches.lac_patches`).
    ``symmetry`` names the planes (``"x"``: ``x = 0``, ``"y"``: ``y = 0``) that cut the
    bodies; the weights are those of the part modelled.
    """

    slave: TriSurface
    master: TriSurface | None
    degree: int
    quad_order: int
    multiplier: str
    patch: int
    n_dofs: int
    symmetry: tuple[str, ...] = ()
    _columns: np.ndarray | None = field(default=None, init=False, repr=False, compare=False)

    def __post_init__(self):
        if self.degree not in (1, 2):
            raise ValueError(f"SurfaceLayout: degree = {self.degree!r}; valid: 1, 2")
        for name, surf in (("slave", self.slave), ("master", self.master)):
            if surf is not None and surf.triangles.shape[1] != (3 if self.degree == 1 else 6):
                raise ValueError(f"SurfaceLayout: {name} triangles have "
                                 f"{surf.triangles.shape[1]} nodes; degree {self.degree} "
                                 f"needs {3 if self.degree == 1 else 6}")
        if self.quad_order not in RULE_DEGREES:
            raise ValueError(f"SurfaceLayout: quad_order = {self.quad_order!r}; valid: "
                             f"{list(RULE_DEGREES)}")
        if self.multiplier not in ("p1", "p0", "lac"):
            raise ValueError(f"SurfaceLayout: multiplier = {self.multiplier!r}; valid: "
                             "'p1', 'p0', 'lac'")
        if int(self.patch) != self.patch or self.patch < 1:
            raise ValueError(f"SurfaceLayout: patch = {self.patch!r}; valid: an integer >= 1")
        bad = [s for s in self.symmetry if s not in ("x", "y")]
        if bad:
            raise ValueError(f"SurfaceLayout: symmetry plane(s) {bad}; valid: 'x', 'y'")

    @property
    def n_points_per_triangle(self) -> int:
        return int(triangle_rule(self.quad_order)[1].size)

    @property
    def n_quad(self) -> int:
        return self.slave.n_tri * self.n_points_per_triangle

    def multiplier_columns(self) -> np.ndarray:
        """Column of each slave triangle (p0, lac: (n_tri,)) or of each triangle vertex
        (p1: (n_tri, 3), the slave vertices numbered in increasing node order); fixed by
        the reference surface, so computed once."""
        if self._columns is None:
            tri = self.slave.triangles[:, :3]
            if self.multiplier == "p0":
                cols = np.arange(tri.shape[0])
            elif self.multiplier == "lac":
                cen = self.slave.points[tri].mean(axis=1)
                cols = lac_patches(tri, cen, int(self.patch))
            else:
                verts, inv = np.unique(tri, return_inverse=True)
                cols = inv.reshape(tri.shape)
            self._columns = cols
        return self._columns

    @property
    def n_mult(self) -> int:
        return int(self.multiplier_columns().max()) + 1


def _moller_trumbore(x: np.ndarray, n: np.ndarray, v0: np.ndarray, e1: np.ndarray,
                     e2: np.ndarray, pi: np.ndarray, ti: np.ndarray, tol: float
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Intersections of the lines ``x[pi] + t n[pi]`` with the triangles ``ti`` (pairs):
    ``(ok, u, v, t)`` with ``x + t n = v0 + u e1 + v e2`` where ``ok``."""
    E1, E2, d = e1[ti], e2[ti], n[pi]
    p = np.cross(d, E2)
    det = np.einsum("ij,ij->i", E1, p)
    s = x[pi] - v0[ti]
    q = np.cross(s, E1)
    ok = np.abs(det) > 1e-12 * np.linalg.norm(E1, axis=1) * np.linalg.norm(E2, axis=1)
    inv = np.divide(1.0, det, out=np.zeros_like(det), where=ok)
    u = np.einsum("ij,ij->i", s, p) * inv
    v = np.einsum("ij,ij->i", d, q) * inv
    t = np.einsum("ij,ij->i", E2, q) * inv
    ok &= (u >= -tol) & (v >= -tol) & (u + v <= 1.0 + tol)
    return ok, u, v, t


class _Nearest:
    """The hit with the smallest ``|t|`` found so far for each line; pairs whose line misses
    the triangle's bounding sphere (centroid ``cen``, radius ``rad``) are skipped."""

    def __init__(self, x, n, v0, v1, v2, tol):
        nq = x.shape[0]
        self.tri = np.full(nq, -1, dtype=np.int64)
        self.u, self.v, self.t = np.zeros(nq), np.zeros(nq), np.full(nq, np.nan)
        self.abs = np.full(nq, np.inf)
        self.args = (x, n, v0, v1 - v0, v2 - v0)
        self.tol = tol
        self.cen = (v0 + v1 + v2) / 3.0
        self.rad = np.sqrt(np.max([((v - self.cen) ** 2).sum(axis=1) for v in (v0, v1, v2)],
                                  axis=0)) if v0.shape[0] else np.zeros(0)
        self.slack = self.rad * (1.0 + 1e-6) + 1e-12 * (self.rad.max() if nq else 0.0)
        self.unit = n / np.linalg.norm(n, axis=1, keepdims=True) if nq else n

    def test(self, pi: np.ndarray, ti: np.ndarray) -> None:
        """Intersect the pairs (line ``pi``, triangle ``ti``) in blocks; keep better hits."""
        x = self.args[0]
        for i in range(0, pi.size, RAY_BLOCK):
            p, tr = pi[i:i + RAY_BLOCK], ti[i:i + RAY_BLOCK]
            cr = np.cross(self.cen[tr] - x[p], self.unit[p])
            near = np.einsum("ij,ij->i", cr, cr) <= self.slack[tr] ** 2
            p, tr = p[near], tr[near]
            ok, u, v, t = _moller_trumbore(*self.args, p, tr, self.tol)
            idx = np.flatnonzero(ok)
            if idx.size == 0:
                continue
            idx = idx[np.lexsort((np.abs(t[idx]), p[idx]))]
            idx = idx[np.r_[True, p[idx][1:] != p[idx][:-1]]]  # per line, the smallest |t|
            idx = idx[np.abs(t[idx]) < self.abs[p[idx]]]
            q = p[idx]
            self.tri[q], self.u[q], self.v[q], self.t[q] = tr[idx], u[idx], v[idx], t[idx]
            self.abs[q] = np.abs(t[idx])


def _knn_search(best: _Nearest, x: np.ndarray, tree: spatial.cKDTree, ids: np.ndarray,
                todo: np.ndarray, k: int, k_max: int, radius: float | None) -> np.ndarray:
    """Try the ``k`` nearest triangles ``ids`` (by centroid, ``tree``) of the lines
    ``todo``, ``k`` doubling up to ``k_max``, until a line has a hit (``radius`` None) or
    its nearest hit cannot lie in a triangle not tried (``radius``: the largest
    centroid-to-vertex distance of ``ids``). Returns the lines left undecided."""
    k = min(k, ids.size)
    while todo.size:
        dist, loc = tree.query(x[todo], k=k)
        dist, loc = dist.reshape(todo.size, k), loc.reshape(todo.size, k)
        best.test(np.repeat(todo, k), ids[loc].ravel())
        if k == ids.size:
            return todo[:0]
        if radius is None:
            done = best.tri[todo] >= 0
        else:
            done = dist[:, -1] > best.abs[todo] + radius
        todo = todo[~done]
        if k >= k_max:
            return todo
        k = min(2 * k, ids.size, k_max)
    return todo


def _capsule_search(best: _Nearest, x: np.ndarray, n: np.ndarray, cen: np.ndarray,
                    ids: np.ndarray, radius: float, lines: np.ndarray,
                    reach: np.ndarray | None = None) -> None:
    """Try, for each line of ``lines``, every triangle ``ids`` (centroids ``cen``, largest
    centroid-to-vertex distance ``radius``) that can hold a hit at ``|t| <= reach``
    (default: nearer than the line's best): the centroid lies within ``radius`` of the
    segment ``x + s n``, ``|s| <= reach``. The
    segment is sampled every ``radius``; the centroids within ``1.12 radius`` of a sample
    (``sqrt(1 + 1/4)``: the balls cover the capsule) come from a k-d tree pair query
    (duplicates are harmless)."""
    if lines.size == 0:
        return
    reach = best.abs[lines] if reach is None else reach
    m = np.ceil(2.0 * reach / radius).astype(np.int64) + 1
    owner = np.repeat(lines, m)
    first = np.repeat(np.cumsum(m) - m, m)
    step = np.repeat(2.0 * reach / np.maximum(m - 1, 1), m)
    s = np.repeat(-reach, m) + (np.arange(owner.size) - first) * step
    samples = x[owner] + s[:, None] * n[owner]
    pairs = spatial.cKDTree(samples).sparse_distance_matrix(
        spatial.cKDTree(cen), 1.12 * radius * (1.0 + 1e-6), output_type="ndarray")
    if pairs.size == 0:
        return
    best.test(owner[pairs["i"]], ids[pairs["j"]])


def ray_cast_triangles(x: np.ndarray, n: np.ndarray, v0: np.ndarray, v1: np.ndarray,
                       v2: np.ndarray, tol: float = 1e-9, k0: int = 16
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Cast the lines ``x + t n`` (points and directions (nq, 3)) onto the triangles
    ``(v0, v1, v2)`` (each (nt, 3)); of the hits, the one with the smallest ``|t|``.

    Returns ``(tri, bary, t)``: the triangle hit (-1 for none), the barycentric coordinates
    (nq, 3) of the hit point in it and the line parameter (``nan`` for none). ``tol`` is
    the barycentric tolerance (a line through an edge hits).

    1. A first hit: the ``k`` triangles with the nearest centroids (k-d tree), ``k``
       doubling from ``k0`` up to 32; lines still without a hit try the triangles near
       the line within a reach that doubles until a hit or past the triangles' bounding
       box (:func:`_capsule_search`). Only triangles whose bounding sphere (centroid,
       largest centroid-to-vertex distance ``r_T``) the line crosses are intersected.
    2. The nearest hit: a triangle holding a hit at ``|t| <= |t_best|`` has its centroid
       within ``r_T`` of the segment ``x + s n``, ``|s| <= |t_best|``. The triangles are
       grouped by ``r_T`` (classes of ratio 2, so a graded mesh's coarse triangles do not
       widen the search near its fine ones) and, in each class, every triangle whose
       centroid is that close to the segment is tried (:func:`_capsule_search`).
    """
    x, n = np.asarray(x, dtype=float), np.asarray(n, dtype=float)
    nq, nt = x.shape[0], v0.shape[0]
    best = _Nearest(x, n, v0, v1, v2, tol)
    if nq and nt:
        cen, rad = best.cen, best.rad
        every = np.arange(nt)
        left = _knn_search(best, x, spatial.cKDTree(cen), every, np.arange(nq),
                           max(int(k0), 1), 32, None)
        # lines without a hit among the 32 nearest: the capsule of reach R around the line,
        # R doubling until a hit or R passes the master's bounding box
        lo, hi = np.min([v0, v1, v2], axis=(0, 1)), np.max([v0, v1, v2], axis=(0, 1))
        far = np.linalg.norm(x[left] - 0.5 * (lo + hi), axis=1) + 0.5 * np.linalg.norm(hi - lo)
        reach = np.full(left.size, 4.0 * rad.max())
        while left.size:
            _capsule_search(best, x, n, cen, every, rad.max(), left, reach)
            done = (best.tri[left] >= 0) | (reach >= far)
            left, reach, far = left[~done], 2.0 * reach[~done], far[~done]
        found = np.flatnonzero(best.tri >= 0)
        cls = np.floor(np.log2(rad / rad.min())).astype(np.int64)
        for c in np.unique(cls):
            ids = np.flatnonzero(cls == c)
            _capsule_search(best, x, n, cen[ids], ids, rad[ids].max(), found)
    b = np.clip(np.stack([1.0 - best.u - best.v, best.u, best.v], axis=1), 0.0, None)
    hit = best.tri >= 0
    bary = np.where(hit[:, None], b / np.maximum(b.sum(axis=1, keepdims=True), 1e-300), 0.0)
    return best.tri, bary, best.t


def ray_cast_pairs(x: np.ndarray, n: np.ndarray, v0: np.ndarray, v1: np.ndarray,
                   v2: np.ndarray, pi: np.ndarray, ti: np.ndarray, tol: float = 1e-9
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`ray_cast_triangles` restricted to the candidate pairs (line ``pi``, triangle
    ``ti``) given by the caller (e.g. a hyper-reduced evaluation's windows sampled
    offline): of each line's hits among its candidates, the one with the smallest ``|t|``."""
    x, n = np.asarray(x, dtype=float), np.asarray(n, dtype=float)
    best = _Nearest(x, n, v0, v1, v2, tol)
    if x.shape[0] and v0.shape[0]:
        best.test(np.asarray(pi, dtype=np.int64), np.asarray(ti, dtype=np.int64))
    b = np.clip(np.stack([1.0 - best.u - best.v, best.u, best.v], axis=1), 0.0, None)
    hit = best.tri >= 0
    bary = np.where(hit[:, None], b / np.maximum(b.sum(axis=1, keepdims=True), 1e-300), 0.0)
    return best.tri, bary, best.t


@dataclass
class SurfacePairing:
    """Slave quadrature points at mu and their master hits (rows of the contact operators)."""

    x: np.ndarray  # (nq, 3) physical points
    nrm: np.ndarray  # (nq, 3) slave outward normals
    w: np.ndarray  # (nq,) physical area weights
    tq: np.ndarray  # (nq,) slave triangle of each point
    bary: np.ndarray  # (nq, 3) barycentric coordinates in it
    gap: np.ndarray  # (nq,)
    mtri: np.ndarray | None  # (nq,) master triangle hit (None: rigid plane)
    mbary: np.ndarray | None  # (nq, 3) barycentric coordinates of the hit

    def jump(self, layout: SurfaceLayout, direction: np.ndarray | None = None
             ) -> sp.csr_matrix:
        """Rows q: ``(u_1(x_q) - u_2(y_q)) . direction_q`` (nq x n_dofs); default direction:
        the slave normals (``Un``)."""
        d = self.nrm if direction is None else direction
        nq = self.w.size
        coef = [(triangle_shape(self.bary, layout.degree)[:, :, None] * d[:, None, :])
                .reshape(nq, -1)]
        dofs = [layout.slave.dofs[layout.slave.triangles[self.tq]].reshape(nq, -1)]
        if self.mtri is not None:
            coef.append(-(triangle_shape(self.mbary, layout.degree)[:, :, None]
                          * d[:, None, :]).reshape(nq, -1))
            dofs.append(layout.master.dofs[layout.master.triangles[self.mtri]].reshape(nq, -1))
        rows = np.repeat(np.arange(nq), coef[0].shape[1])
        return sp.csr_matrix((np.concatenate([c.ravel() for c in coef]),
                              (np.tile(rows, len(coef)),
                               np.concatenate([c.ravel() for c in dofs]))),
                             shape=(nq, layout.n_dofs))


def pair_surfaces(layout: SurfaceLayout, mu: np.ndarray, rows: np.ndarray | None = None,
                  master_tris: np.ndarray | None = None,
                  candidates: tuple[np.ndarray, np.ndarray] | None = None) -> SurfacePairing:
    """The slave quadrature points at mu (all, or the points ``rows``, numbered triangle by
    triangle: point ``q`` is rule point ``q % n_g`` of slave triangle ``q // n_g``) and their
    hits on the master (module docstring), among the master triangles ``master_tris``
    (default: all; a hyper-reduced evaluation passes the few its rows can hit), or only the
    pairs ``candidates = (point, master triangle)`` (:func:`ray_cast_pairs`). Raises
    :class:`PairingError` with the number of misses and an example point when a line hits
    no master triangle."""
    bary_g, w_g = triangle_rule(layout.quad_order)
    ng = w_g.size
    if rows is None:
        tq = np.repeat(np.arange(layout.slave.n_tri), ng)
        kq = np.tile(np.arange(ng), layout.slave.n_tri)
    else:
        rows = np.asarray(rows, dtype=np.int64)
        if rows.size and (rows.min() < 0 or rows.max() >= layout.n_quad):
            raise ValueError(f"rows must lie in [0, {layout.n_quad}) (the slave quadrature "
                             "points)")
        tq, kq = rows // ng, rows % ng
    tris, inv = np.unique(tq, return_inverse=True)
    nrm_t, area_t = layout.slave.outward_normals(mu, tris)
    v0, v1, v2 = layout.slave.vertices(mu, tris)
    b = bary_g[kq]
    x = b[:, :1] * v0[inv] + b[:, 1:2] * v1[inv] + b[:, 2:] * v2[inv]
    nrm, w = nrm_t[inv], w_g[kq] * area_t[inv]
    mtri = mbary = None
    if layout.master is None:  # rigid plane z = 0
        with np.errstate(divide="ignore", invalid="ignore"):
            gap = -x[:, 2] / nrm[:, 2]
        miss = ~np.isfinite(gap) | (np.abs(nrm[:, 2]) < 1e-12)
    else:
        keep = (np.arange(layout.master.n_tri) if master_tris is None
                else np.asarray(master_tris, dtype=np.int64))
        if candidates is None:
            mtri, mbary, gap = ray_cast_triangles(x, nrm, *layout.master.vertices(mu, keep))
        else:
            mtri, mbary, gap = ray_cast_pairs(x, nrm, *layout.master.vertices(mu, keep),
                                              *candidates)
        miss = mtri < 0
        mtri = np.where(miss, -1, keep[np.maximum(mtri, 0)])
    if np.any(miss):
        raise PairingError(int(miss.sum()), x[miss][0])
    return SurfacePairing(x=x, nrm=nrm, w=w, tq=tq, bary=b, gap=gap, mtri=mtri, mbary=mbary)


def _multiplier_matrix(layout: SurfaceLayout, p: SurfacePairing) -> sp.csr_matrix:
    """``Mlam`` (nq x n_mult): the multiplier basis at the points of ``p``."""
    cols, nq = layout.multiplier_columns(), p.w.size
    if layout.multiplier == "p1":
        rows = np.repeat(np.arange(nq), 3)
        return sp.csr_matrix((p.bary.ravel(), (rows, cols[p.tq].ravel())),
                             shape=(nq, layout.n_mult))
    return sp.csr_matrix((np.ones(nq), (np.arange(nq), cols[p.tq])),
                         shape=(nq, layout.n_mult))


def contact_operators_3d(layout: SurfaceLayout, mu: np.ndarray) -> ContactOperators:
    """The 3D contact operators at mu: ``Un`` (n_q x n_dofs), gap, physical area weights,
    points and slave normals (n_q, 3), ``Mlam`` (n_q x n_mult), ``mult_points`` (the
    weighted centroid of each multiplier's support) and ``mult_extent`` (n_mult, 2): the
    radial extent ``[r_min, r_max]``, ``r = sqrt(x^2 + y^2)``, of each multiplier's
    support (the slave triangles where it is nonzero)."""
    return operators_from_pairing(layout, pair_surfaces(layout, mu), mu)


def operators_from_pairing(layout: SurfaceLayout, p: SurfacePairing, mu: np.ndarray
                           ) -> ContactOperators:
    """:func:`contact_operators_3d` from the pairing ``p`` of all slave points at mu."""
    Mlam = _multiplier_matrix(layout, p)
    mw = np.asarray(Mlam.T @ p.w).ravel()
    mpts = np.asarray(Mlam.T @ (p.w[:, None] * p.x)) / mw[:, None]
    r_lo, r_hi = radial_range(*layout.slave.vertices(mu))
    coo = Mlam.tocoo()
    ext = np.empty((Mlam.shape[1], 2))
    ext[:, 0], ext[:, 1] = np.inf, -np.inf
    np.minimum.at(ext[:, 0], coo.col, r_lo[p.tq[coo.row]])
    np.maximum.at(ext[:, 1], coo.col, r_hi[p.tq[coo.row]])
    return ContactOperators(Un=p.jump(layout), gap=p.gap, weights=p.w, points=p.x,
                            normals=p.nrm, Mlam=Mlam, multiplier=layout.multiplier,
                            mult_points=mpts, mult_extent=ext)


def surface_rows(layout: SurfaceLayout, mu: np.ndarray, rows: np.ndarray,
                 master_tris: np.ndarray | None = None) -> tuple[sp.csr_matrix, np.ndarray]:
    """``(Un[rows], gap[rows])`` at mu, pairing only the slave points ``rows`` (numbered as
    in :func:`pair_surfaces`) with the master triangles ``master_tris`` (default: all): the
    rows a hyper-reduced (EIM) evaluation needs. With a subset, the result equals the full
    rows' when the subset holds every triangle the full pairing hits and none nearer."""
    p = pair_surfaces(layout, mu, rows, master_tris)
    return p.jump(layout), p.gap


def tangent_frames(nrm: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unit tangents ``(t1, t2)`` (each (n, 3)) of unit normals ``nrm``: ``t1`` the
    projection of ``e_x`` on the tangent plane, normalised (``e_y`` where ``n`` is within
    1e-6 rad of ``+-e_x``), ``t2 = n x t1``, so ``(t1, t2, n)`` is right-handed. The frame
    depends continuously on ``n`` away from ``+-e_x``, so it does not flip between
    parameter values for contact normals near ``+-e_z`` (the later 3D friction)."""
    e = np.where((1.0 - np.abs(nrm[:, :1]) < 5e-13), [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    t1 = e - np.einsum("ij,ij->i", e, nrm)[:, None] * nrm
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return t1, np.cross(nrm, t1)


def tangential_jumps(layout: SurfaceLayout, p: SurfacePairing
                     ) -> tuple[sp.csr_matrix, sp.csr_matrix]:
    """``(Ut1, Ut2)`` (each n_q x n_dofs): ``(u_1(x_q) - u_2(y_q)) . t_k`` along the frame
    of :func:`tangent_frames` at the points of ``p``."""
    t1, t2 = tangent_frames(p.nrm)
    return p.jump(layout, t1), p.jump(layout, t2)

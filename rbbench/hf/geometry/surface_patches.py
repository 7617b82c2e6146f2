"""Supports of the 3D contact multipliers on a slave triangulation: the LAC patches of
triangles and the radial extent of triangles about the z axis
(:mod:`rbbench.hf.geometry.surface`); numpy / scipy only."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order

__all__ = ["lac_patches", "radial_range", "triangle_adjacency"]


def triangle_adjacency(tri: np.ndarray) -> sp.csr_matrix:
    """(n_tri x n_tri) boolean adjacency of triangles ``tri`` (n_tri, 3) sharing an edge."""
    n = tri.shape[0]
    edges = np.sort(np.vstack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [0, 2]]]), axis=1)
    _, eid = np.unique(edges, axis=0, return_inverse=True)
    inc = sp.csr_matrix((np.ones(3 * n), (np.tile(np.arange(n), 3), eid.ravel())))
    adj = (inc @ inc.T).tolil()
    adj.setdiag(0)
    adj = adj.tocsr()
    adj.eliminate_zeros()
    return adj.astype(bool)


def lac_patches(tri: np.ndarray, centroids: np.ndarray, size: int) -> np.ndarray:
    """Patch label (n_tri,) of each triangle: connected patches, each holding the whole
    star (all triangles) of one vertex, of at least ``ceil(size / 2)`` triangles (LAC
    multipliers; Abbas, Drouet & Hild, "The local average contact (LAC) method", CMAME 339
    (2018) 646-666: P0 on patches; in 2D a patch of two facets is the star of a node).

    The vertices are visited breadth first from the vertex nearest the z axis (the centre
    of the contact zone); a vertex whose star is still free makes that star a patch (so
    the seeds are about every other vertex, each patch is round, of diameter about 2 h).
    Every triangle left over joins the smallest patch it shares an edge with; patches of
    fewer than ``ceil(size / 2)`` triangles (at the rim) join their smallest neighbour.
    The star's vertex is interior to its patch: its hat function, supported in the patch,
    gives the Fortin argument of inf-sup stability with P1 (and P2) displacement traces,
    which P0 per triangle lacks. ``size = 1`` is P0 per triangle.
    """
    n = tri.shape[0]
    if size <= 1 or n == 0:
        return np.arange(n)
    adj = triangle_adjacency(tri)
    ptr, nbr = adj.indptr, adj.indices
    n_v = int(tri.max()) + 1
    star = sp.csr_matrix((np.ones(3 * n), (tri.ravel(), np.repeat(np.arange(n), 3))),
                         shape=(n_v, n))
    vgraph = star @ star.T
    used = np.unique(tri)
    pos = np.zeros((n_v, 3))
    np.add.at(pos, tri.ravel(), np.repeat(centroids, 3, axis=0))
    radial = np.hypot(pos[:, 0], pos[:, 1]) / np.maximum(np.diff(star.indptr), 1)
    order, seen = [], np.zeros(n_v, dtype=bool)
    for start in used[np.argsort(radial[used], kind="stable")]:
        if not seen[start]:
            comp = breadth_first_order(vgraph, start, directed=False, return_predecessors=False)
            seen[comp] = True
            order.append(comp)
    label = np.full(n, -1, dtype=np.int64)
    count: list[int] = []
    for v in np.concatenate(order):
        mine = star.indices[star.indptr[v]:star.indptr[v + 1]]
        if mine.size and np.all(label[mine] < 0):
            label[mine] = len(count)
            count.append(int(mine.size))
    while np.any(label < 0):  # leftovers join the smallest neighbouring patch
        progress = False
        for i in np.flatnonzero(label < 0):
            others = {int(label[j]) for j in nbr[ptr[i]:ptr[i + 1]] if label[j] >= 0}
            if others:
                q = min(others, key=lambda o: (count[o], o))
                label[i] = q
                count[q] += 1
                progress = True
        if not progress:  # a component without a free star
            for i in np.flatnonzero(label < 0):
                label[i] = len(count)
                count.append(1)
    small = int(np.ceil(size / 2))
    for p in range(len(count)):
        if 0 < count[p] < small:
            mine = np.flatnonzero(label == p)
            others = {int(label[j]) for i in mine for j in nbr[ptr[i]:ptr[i + 1]]} - {p}
            if others:
                q = min(others, key=lambda o: (count[o], o))
                label[mine] = q
                count[q] += count[p]
                count[p] = 0
    return np.unique(label, return_inverse=True)[1].ravel()


def radial_range(v0: np.ndarray, v1: np.ndarray, v2: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray]:
    """``(r_min, r_max)`` (n,) of ``r = sqrt(x^2 + y^2)`` over each triangle ``(v0, v1, v2)``
    (each (n, 3)): r_max at a vertex, r_min the distance from the z axis to the triangle's
    projection on the xy plane (0 when the projection holds the axis)."""
    P = [v[:, :2] for v in (v0, v1, v2)]
    r_hi = np.max([np.hypot(p[:, 0], p[:, 1]) for p in P], axis=0)
    d_edge, cross = [], []
    for a, b in ((P[0], P[1]), (P[1], P[2]), (P[2], P[0])):
        e = b - a
        ee = np.einsum("ij,ij->i", e, e)
        with np.errstate(divide="ignore", invalid="ignore"):
            s = np.clip(np.where(ee > 0, -np.einsum("ij,ij->i", a, e) / ee, 0.0), 0.0, 1.0)
        d_edge.append(np.linalg.norm(a + s[:, None] * e, axis=1))
        cross.append(a[:, 0] * e[:, 1] - a[:, 1] * e[:, 0])  # sign of the origin's side
    cross = np.array(cross)
    holds = (np.all(cross >= 0, axis=0) | np.all(cross <= 0, axis=0)) & np.any(cross != 0,
                                                                                axis=0)
    return np.where(holds, 0.0, np.min(d_edge, axis=0)), r_hi

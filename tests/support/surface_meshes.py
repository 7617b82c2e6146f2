"""Structured triangulated surfaces for the 3D contact-geometry tests: a square grid in
(x, y) lifted to a height field, P1 or P2 (contract node order)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from rbbench.hf.geometry.chains import AffineMap
from rbbench.hf.geometry.surface import TriSurface

IDENTITY = AffineMap(scale=np.array([1.0, 0.0]), shift=np.zeros((3, 2)))


def grid(n: int, lo: tuple[float, float], hi: tuple[float, float], height: Callable,
         degree: int, inside: np.ndarray, first_node: int = 0, map: AffineMap = IDENTITY,
         curved: bool = False) -> TriSurface:
    """An ``n x n``-cell grid on [lo, hi], each cell cut into two triangles, lifted to
    ``z = height(x, y)``. P2 midpoints sit on the height field (``curved``) or at the
    chord midpoints. Node k has dofs ``3 (first_node + k) + (0, 1, 2)``."""
    xs, ys = np.linspace(lo[0], hi[0], n + 1), np.linspace(lo[1], hi[1], n + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    pts = np.stack([X.ravel(), Y.ravel(), height(X.ravel(), Y.ravel())], axis=1)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), \
        idx[:-1, 1:].ravel()
    tri = np.vstack([np.stack([a, b, c], axis=1), np.stack([a, c, d], axis=1)])
    if degree == 2:
        edges = np.sort(np.vstack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [0, 2]]]), axis=1)
        uniq, inv = np.unique(edges, axis=0, return_inverse=True)
        mid = 0.5 * (pts[uniq[:, 0]] + pts[uniq[:, 1]])
        if curved:
            mid[:, 2] = height(mid[:, 0], mid[:, 1])
        mid_ids = pts.shape[0] + inv.ravel().reshape(3, -1).T
        pts = np.vstack([pts, mid])
        tri = np.hstack([tri, mid_ids])
    nodes = first_node + np.arange(pts.shape[0])
    dofs = 3 * nodes[:, None] + np.arange(3)[None, :]
    return TriSurface(points=pts, triangles=tri, dofs=dofs, inside=np.asarray(inside, float),
                      map=map)


def sphere_cap(n: int, radius: float, centre_z: float, half_width: float, degree: int,
               lower: bool = True, first_node: int = 0, curved: bool = False) -> TriSurface:
    """The lower (``lower``) or upper cap of the sphere of ``radius`` centred at
    ``(0, 0, centre_z)`` over the square ``|x|, |y| <= half_width``."""
    sign = -1.0 if lower else 1.0

    def height(x, y):
        return centre_z + sign * np.sqrt(radius**2 - x**2 - y**2)

    return grid(n, (-half_width, -half_width), (half_width, half_width), height, degree,
                np.array([0.0, 0.0, centre_z]), first_node, curved=curved)

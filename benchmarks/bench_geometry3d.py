"""asv: the 3D contact geometry (:func:`rbbench.hf.geometry.surface.contact_operators_3d`)
on structured sphere caps: all operators at one mu, and 40 rows (the contact EIM's use)."""

from __future__ import annotations

import numpy as np

from rbbench.hf.geometry.chains import AffineMap
from rbbench.hf.geometry.surface import (
    SurfaceLayout,
    TriSurface,
    contact_operators_3d,
    surface_rows,
)

IDENTITY = AffineMap(scale=np.array([1.0, 0.0]), shift=np.zeros((3, 2)))


def sphere_cap(n: int, radius: float, centre_z: float, half_width: float, lower: bool,
               first_node: int = 0) -> TriSurface:
    """P2 triangulation (midpoints on the chords) of the lower / upper cap of a sphere over
    the square ``|x|, |y| <= half_width``: ``2 n^2`` triangles."""
    xs = np.linspace(-half_width, half_width, n + 1)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    Z = centre_z + (-1.0 if lower else 1.0) * np.sqrt(radius**2 - X**2 - Y**2)
    pts = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    idx = np.arange((n + 1) ** 2).reshape(n + 1, n + 1)
    a, b, c, d = (idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(),
                  idx[:-1, 1:].ravel())
    tri = np.vstack([np.stack([a, b, c], axis=1), np.stack([a, c, d], axis=1)])
    edges = np.sort(np.vstack([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [0, 2]]]), axis=1)
    uniq, inv = np.unique(edges, axis=0, return_inverse=True)
    mids = pts.shape[0] + inv.ravel().reshape(3, -1).T
    pts = np.vstack([pts, 0.5 * (pts[uniq[:, 0]] + pts[uniq[:, 1]])])
    dofs = 3 * (first_node + np.arange(pts.shape[0]))[:, None] + np.arange(3)
    return TriSurface(points=pts, triangles=np.hstack([tri, mids]), dofs=dofs,
                      inside=np.array([0.0, 0.0, centre_z]), map=IDENTITY)


def layout(n_slave: int, multiplier: str = "lac") -> SurfaceLayout:
    """Slave: lower cap (R = 1, 1e-3 above the master's pole, ``2 n_slave^2`` triangles);
    master: upper cap (R = 1.2, twice as many triangles); P2, rule of degree 4."""
    s = sphere_cap(n_slave, 1.0, 1.001, 0.3, lower=True)
    m = sphere_cap(int(round(n_slave * np.sqrt(2))), 1.2, -1.2, 0.8, lower=False,
                   first_node=s.points.shape[0])
    return SurfaceLayout(s, m, 2, 4, multiplier, 4,
                         3 * (s.points.shape[0] + m.points.shape[0]))


class ContactGeometry3D:
    """The 3D contact operators at mu = 1 (pairing, ``Un``, multipliers) and 40 rows."""

    params = ([2500, 10000],)
    param_names = ["slave_triangles"]
    timeout = 300
    repeat = (1, 3, 30.0)

    def setup(self, n_tri):
        self.layout = layout(int(round(np.sqrt(n_tri / 2))))
        self.mu = np.array([1.0])
        self.layout.multiplier_columns()  # the patches, built once per layout
        self.rows = np.random.default_rng(0).choice(self.layout.n_quad, 40, replace=False)

    def time_contact_operators_3d(self, n_tri):
        """Wall time (s) of all the 3D contact operators at one mu."""
        contact_operators_3d(self.layout, self.mu)

    def time_surface_rows_40(self, n_tri):
        """Wall time (s) of 40 rows of ``Un`` and the gap at one mu."""
        surface_rows(self.layout, self.mu, self.rows)

"""The magic rows of the 3D contact constraint: ``B(mu)`` and ``G(mu)`` rows on triangulated
surfaces, HF-size independent, for the contact EIM (:mod:`rbbench.rb.hyper.contact_eim`).

The 3D counterpart of :class:`~rbbench.rb.hyper.contact_eim.RowEvaluator`: a multiplier row
``i`` of ``B = Mlam^T diag(w) Un`` integrates the normal jump over the slave triangles of
its support (Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods:
parametric variational inequalities" (talk), slide "EIM"). Offline, the slave points of the
magic rows are paired with the whole master cap over a dense sample of D; their hits, widened
by ``margin`` rings of edge-neighbouring triangles, are each point's candidates. Online,
only those slave triangles are paired, each point against its candidates
(:func:`~rbbench.hf.geometry.surface.pair_surfaces` on a restricted
:class:`~rbbench.hf.geometry.surface.SurfaceLayout`), on local dofs; a point leaving the window
raises :class:`~rbbench.rb.hyper.contact_eim.HyperReductionError`. This is the reference of
the compiled online path (:mod:`rbbench.rb.kernels.surface_pairing`, the same pairing per
point on a plan tabulated by :mod:`rbbench.rb.kernels.surface_plan`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from rbbench.hf.geometry.pairing import PairingError
from rbbench.hf.geometry.surface import SurfaceLayout, SurfacePairing, TriSurface, pair_surfaces
from rbbench.rb.hyper.contact_eim import HyperReductionError

__all__ = ["ROW_THRESHOLD", "SurfaceRowEvaluator", "build_surface_row_evaluator",
           "master_window"]

#: The relative pivot threshold of the row-aware selection of the 3D contact EIM's magic
#: entries (:func:`rbbench.rb.algorithms.eim.deim` ``groups``, ``threshold``): an entry in
#: a multiplier row already evaluated (its slave points paired) is taken when its residual
#: is at least this fraction of the largest. Sparse LU's threshold pivoting uses 0.1 (Duff,
#: Erisman & Reid, 1986); on ``hertz_sphere`` at mesh level 1, 0.25 cut the rows to pair
#: from 57 to 20 at the same EIM size and validation error within 1.4x, 0.1 to 16 rows at a
#: fivefold validation error of ``B_N``.
ROW_THRESHOLD = 0.25


@dataclass
class SurfaceRowEvaluator:
    """Rows ``rows`` of ``B(mu)`` (on the local dofs) and of ``G(mu)`` in 3D.

    Attributes
    ----------
    layout : SurfaceLayout
        Restricted: the slave triangles of the rows, the master window, dofs renumbered to
        ``0 .. n_local - 1``.
    rows : (M,)
        Global multiplier indices (sorted, unique).
    windows : (points, triangles) or None
        Candidate pairs: each restricted slave point with the master triangles it hit over
        a dense sample of D, widened by rings of neighbours (indices into the restricted
        master); None for the rigid plane.
    local_dofs : (n_local,)
        Global dofs behind the local numbering.
    Mrows : (M, nq)
        Multiplier basis of the rows at the restricted slave points (mu-independent).
    """

    layout: SurfaceLayout
    rows: np.ndarray
    windows: tuple[np.ndarray, np.ndarray] | None
    local_dofs: np.ndarray
    Mrows: np.ndarray

    def pairing(self, mu: np.ndarray) -> SurfacePairing:
        """The pairing of the rows' slave points at mu, against the master window."""
        try:
            return pair_surfaces(self.layout, mu, candidates=self.windows)
        except PairingError as exc:
            raise HyperReductionError(
                f"mu = {np.atleast_1d(mu).tolist()}: a magic row's quadrature point left "
                f"the master window sampled offline ({exc})") from None

    def __call__(self, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(B(mu)[rows][:, local_dofs] (M x n_local) dense, G(mu)[rows] (M,))``."""
        p = self.pairing(mu)
        Mw = self.Mrows * p.w
        return np.asarray(sp.csr_matrix(Mw) @ p.jump(self.layout).toarray()), Mw @ p.gap

    def support(self, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rows ``rows[pos]`` as ``(positions (E, 1), ones (E, 1))``, the arguments
        :meth:`entries` takes."""
        pos = np.asarray(pos, dtype=np.int64)
        return pos[:, None], np.ones((pos.size, 1))

    def entries(self, mu: np.ndarray, Z_loc: np.ndarray, pts: np.ndarray, vals: np.ndarray,
                cols: np.ndarray, pos_G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Entries ``(B(mu) Z)[rows[pts[e, 0]], cols[e]]`` and ``G(mu)[rows[pos_G]]`` from the
        local basis ``Z_loc`` (work: entries x local dofs)."""
        p = self.pairing(mu)
        Mw = self.Mrows * p.w
        brows = (sp.csr_matrix(Mw[pts[:, 0]]) @ p.jump(self.layout)).toarray()
        C = np.einsum("ed,de->e", brows, Z_loc[:, np.asarray(cols)])
        return C, Mw[np.asarray(pos_G)] @ p.gap

    @property
    def n_local(self) -> int:
        return int(self.local_dofs.size)

    @property
    def window_max_width(self) -> int:
        """The most candidate master triangles of one slave point (0 for a rigid plane)."""
        return 0 if self.windows is None else int(np.bincount(self.windows[0]).max())

    @property
    def n_master(self) -> int:
        """Master triangles of the restricted layout (0 for a rigid plane)."""
        return 0 if self.layout.master is None else self.layout.master.n_tri


def _row_triangles(layout: SurfaceLayout, rows: np.ndarray) -> np.ndarray:
    """Slave triangles where a multiplier of ``rows`` is nonzero (sorted)."""
    cols = layout.multiplier_columns()
    hit = np.isin(cols, rows)
    return np.flatnonzero(hit.any(axis=1) if hit.ndim == 2 else hit)


def master_window(layout: SurfaceLayout, tris: np.ndarray, mus: np.ndarray,
                  margin: int = 1) -> sp.csr_matrix:
    """Candidate master triangles of the slave points of triangles ``tris`` (boolean
    (points x master triangles), points triangle by triangle): those each point hits over
    ``mus`` (a dense sample of D), widened by ``margin`` rings of edge neighbours. A point
    moving continuously from one hit to the next between two samples crosses edges, so
    with samples much closer than a triangle's size its hit stays among these."""
    ng = layout.n_points_per_triangle
    pts = (tris[:, None] * ng + np.arange(ng)[None, :]).ravel()
    tri = layout.master.triangles[:, :3]
    hits = np.stack([pair_surfaces(layout, mu, rows=pts).mtri for mu in mus], axis=1)
    q = np.repeat(np.arange(pts.size), hits.shape[1])
    W = sp.csr_matrix((np.ones(q.size), (q, hits.ravel())), shape=(pts.size, tri.shape[0]))
    inc = sp.csr_matrix((np.ones(tri.size), (np.repeat(np.arange(tri.shape[0]), 3),
                                              tri.ravel())))
    shared = (inc @ inc.T).tocsr()
    adj = (shared >= 2).astype(float)  # triangles sharing an edge (and each itself)
    for _ in range(margin):
        W = W @ adj
    return (W > 0).astype(bool).tocsr()


def _subset(surf: TriSurface, tris: np.ndarray) -> TriSurface:
    """The triangles ``tris`` of ``surf``, nodes renumbered (global dofs kept)."""
    nodes, inv = np.unique(surf.triangles[tris], return_inverse=True)
    return replace(surf, points=surf.points[nodes],
                   triangles=inv.reshape(-1, surf.triangles.shape[1]), dofs=surf.dofs[nodes])


def build_surface_row_evaluator(layout: SurfaceLayout, rows: np.ndarray, mus: np.ndarray,
                                margin: int = 1) -> SurfaceRowEvaluator:
    """Restrict ``layout`` to the multiplier ``rows`` and the master window of their slave
    points over ``mus`` (:func:`master_window`)."""
    rows = np.unique(np.asarray(rows, dtype=np.int64))
    tris = _row_triangles(layout, rows)
    slave = _subset(layout.slave, tris)
    master, windows = None, None
    if layout.master is not None:
        W = master_window(layout, tris, mus, margin)
        keep = np.flatnonzero(np.asarray(W.sum(axis=0)).ravel() > 0)
        master = _subset(layout.master, keep)
        pi, ti = W.nonzero()
        windows = (pi, np.searchsorted(keep, ti))
    local = np.unique(np.concatenate([s.dofs.ravel() for s in (slave, master)
                                      if s is not None]))

    def renumber(s):
        return None if s is None else replace(s, dofs=np.searchsorted(local, s.dofs))

    small = replace(layout, slave=renumber(slave), master=renumber(master), n_dofs=local.size)
    # multiplier basis of the rows at the small layout's points (triangle by triangle)
    p = pair_surfaces(small, mus[0], candidates=windows)
    cols = layout.multiplier_columns()[tris][p.tq]  # (nq,) or (nq, 3)
    if cols.ndim == 1:
        Mrows = (cols[None, :] == rows[:, None]).astype(float)
    else:
        Mrows = np.einsum("iqk,qk->iq", (cols[None] == rows[:, None, None]), p.bary)
    return SurfaceRowEvaluator(small, rows, windows, local, Mrows)

"""The offline side of the compiled 3D contact EIM: what a plan of
:mod:`rbbench.rb.kernels.surface_pairing` tabulates.

The 3D counterpart of :func:`rbbench.rb.kernels.plan.reference_points`,
:func:`~rbbench.rb.kernels.plan.slave_terms` and :func:`~rbbench.rb.kernels.plan.master_plan`,
from a :class:`~rbbench.rb.hyper.surface_eim.SurfaceRowEvaluator` (its restricted layout
and master windows): the slave Gauss points, unit outward normals and weights on the
reference surface (:func:`reference_surface_points`), the rows' points and multiplier
values per magic entry (:func:`point_support`), the slave half of every magic entry
(:func:`surface_slave_terms`) and the master window: its reference vertices, triangles,
candidate lists and ``Z^T`` on its dofs (:func:`surface_master_plan`);
:func:`surface_eim_arrays` assembles them. numpy only.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rbbench.hf.geometry.surface_rules import triangle_rule, triangle_shape

__all__ = ["point_support", "reference_surface_points", "surface_eim_arrays",
           "surface_master_plan", "surface_slave_terms"]


def reference_surface_points(lay: Any) -> tuple[np.ndarray, ...]:
    """``(x_hat, n_hat, w_hat, sphi)`` of the slave Gauss points of ``lay`` (a
    :class:`~rbbench.hf.geometry.surface.SurfaceLayout`) on the reference surface (the
    identity map), numbered triangle by triangle as in
    :func:`~rbbench.hf.geometry.surface.pair_surfaces`: points (nq, 3), unit normals of the
    flat triangles oriented away from the body's ``inside`` point (nq, 3), weights (rule
    weight times area, nq) and slave shape values (nq, 3 or 6). Under ``x = s x_hat + c``
    the physical values are ``s x_hat + c``, ``sign(s) n_hat``, ``s^2 w_hat`` and ``sphi``."""
    sl = lay.slave
    bary, wg = triangle_rule(lay.quad_order)
    ng = wg.size
    v0, v1, v2 = (sl.points[sl.triangles[:, i]] for i in range(3))
    x = (bary[None, :, 0, None] * v0[:, None] + bary[None, :, 1, None] * v1[:, None]
         + bary[None, :, 2, None] * v2[:, None]).reshape(-1, 3)
    cr = np.cross(v1 - v0, v2 - v0)
    area2 = np.linalg.norm(cr, axis=1)
    side = np.einsum("ij,ij->i", cr, (v0 + v1 + v2) / 3.0 - sl.inside)
    if np.any(area2 == 0.0) or np.any(side == 0.0):
        raise ValueError("a slave triangle has zero area or its plane passes through the "
                         "body's inside point")
    nrm = np.sign(side)[:, None] * cr / area2[:, None]
    n_hat = np.repeat(nrm, ng, axis=0)
    w_hat = (wg[None, :] * 0.5 * area2[:, None]).ravel()
    sphi = triangle_shape(np.tile(bary, (sl.n_tri, 1)), lay.degree)
    return np.ascontiguousarray(x), n_hat, w_hat, sphi


def point_support(Mrows: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The slave points of the rows ``pos`` of ``Mrows`` (rows x points, the multiplier
    basis at the points), padded: ``(points, values)``, each (len(pos), P), with
    ``values`` the multiplier basis there (0 on padding)."""
    M = Mrows[np.asarray(pos, dtype=np.int64)]
    P = max(int((M != 0).sum(axis=1).max()), 1) if M.size else 1
    pts = np.zeros((M.shape[0], P), dtype=np.int64)
    vals = np.zeros((M.shape[0], P))
    for i, row in enumerate(M):
        nz = np.flatnonzero(row)
        pts[i, :nz.size], vals[i, :nz.size] = nz, row[nz]
    return pts, vals


def surface_slave_terms(lay: Any, Z_loc: np.ndarray, cols: np.ndarray, sphi: np.ndarray,
                        n_hat: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """``S[e, p] = sum_(a, d) sphi[q, a] n_hat[q, d] Z[dofs(a, d), cols[e]]`` at ``q =
    pts[e, p]`` on slave triangle ``q // n_g`` (its nodes ``a``, components ``d``): the
    slave half of the normal jump of every magic entry on the reference surface
    (:func:`rbbench.rb.kernels.surface_pairing.surface_jump_values`)."""
    ng = triangle_rule(lay.quad_order)[1].size
    sl = lay.slave
    dofs = sl.dofs[sl.triangles[pts // ng]]  # (E, P, nodes, 3)
    z = Z_loc[dofs, np.asarray(cols)[:, None, None, None]]
    return np.einsum("epa,epd,epad->ep", sphi[pts], n_hat[pts], z)


def surface_master_plan(ev: Any, Z_loc: np.ndarray) -> dict[str, np.ndarray]:
    """The master window of ``ev`` (a
    :class:`~rbbench.rb.hyper.surface_eim.SurfaceRowEvaluator`): reference vertices
    ``m_v`` (the window triangles' vertices only), triangles ``m_tri`` into them, each
    point's candidates as lists ``w_tri[w_ptr[q]:w_ptr[q + 1]]`` (in the order the
    reference tests them, which breaks ties alike), ``Z^T`` on the window's master dofs
    (``zt_m``) and ``m_dofs`` (triangle, node x component) numbered into it. A rigid plane:
    one-entry placeholders."""
    ms = ev.layout.master
    N = Z_loc.shape[1]
    if ms is None:
        return {"m_v": np.zeros((1, 3)), "zt_m": np.zeros((N, 1)),
                "m_dofs": np.zeros((1, 3), dtype=np.int64),
                "m_tri": np.zeros((1, 3), dtype=np.int64),
                "w_ptr": np.zeros(2, dtype=np.int64), "w_tri": np.zeros(1, dtype=np.int64)}
    pi, ti = (np.asarray(a, dtype=np.int64) for a in ev.windows)
    order = np.argsort(pi, kind="stable")  # grouped by point, each point's order kept
    nq = ev.Mrows.shape[1]
    ptr = np.concatenate([[0], np.cumsum(np.bincount(pi, minlength=nq))])
    verts, inv = np.unique(ms.triangles[:, :3], return_inverse=True)
    dofs = ms.dofs[ms.triangles].reshape(ms.n_tri, -1)  # (tri, nodes x 3)
    used, m_dofs = np.unique(dofs, return_inverse=True)
    return {"m_v": ms.points[verts], "m_tri": inv.reshape(-1, 3).astype(np.int64),
            "w_ptr": ptr.astype(np.int64), "w_tri": ti[order],
            "zt_m": np.ascontiguousarray(Z_loc[used].T),
            "m_dofs": m_dofs.reshape(dofs.shape).astype(np.int64)}


def surface_eim_arrays(ceim: Any) -> dict[str, np.ndarray]:
    """The pairing and magic-entry arrays of a 3D
    :class:`~rbbench.rb.hyper.contact_eim.ContactEIM` (its evaluator a
    :class:`~rbbench.rb.hyper.surface_eim.SurfaceRowEvaluator`) in the plan's names
    (:data:`rbbench.rb.kernels.layout.FLOATS`, ``INTS``): the bodies' maps, the reference
    slave points, the magic entries' points, values and slave terms, the magic rows of
    ``G``, the master window and ``dims = [degree, has_master, 0, 3]``. The 2D-only arrays
    are one-entry placeholders; the caller adds the parameter box and the EIM maps."""
    ev = ceim.evaluator
    lay = ev.layout
    sl, ms = lay.slave, lay.master
    x_hat, n_hat, w_hat, sphi = reference_surface_points(lay)
    pts_b, vals_b = point_support(ev.Mrows, ceim.pos_B[ceim.entry_row])
    pts_g, vals_g = point_support(ev.Mrows, ceim.pos_G)
    cols = np.asarray(ceim.entry_col, dtype=np.int64)
    out = {"s_scale": sl.map.scale, "s_shift": sl.map.shift,
           "m_scale": sl.map.scale if ms is None else ms.map.scale,
           "m_shift": sl.map.shift if ms is None else ms.map.shift,
           "x_hat": x_hat, "n_hat": n_hat, "w_hat": w_hat,
           "slave_b": surface_slave_terms(lay, ceim.Z_loc, cols, sphi, n_hat, pts_b),
           "vals_b": vals_b, "vals_g": vals_g, "pts_b": pts_b, "cols_b": cols,
           "order_b": np.argsort(cols, kind="stable"), "pts_g": pts_g,
           "dims": np.array([lay.degree, ms is not None, 0, 3]),
           "m_a": np.zeros((1, 2)), "m_b": np.zeros((1, 2)),
           "mono": np.zeros((1, 2), dtype=np.int64), "lo": np.zeros(1, dtype=np.int64),
           "hi": np.zeros(1, dtype=np.int64)}
    out.update(surface_master_plan(ev, ceim.Z_loc))
    return out

"""The offline side of the compiled 3D contact EIM: what a plan of
:mod:`rbbench.rb.kernels.surface_pairing` tabulates.

The 3D counterpart of :func:`rbbench.rb.kernels.plan.reference_points`,
:func:`~rbbench.rb.kernels.plan.slave_terms` and :func:`~rbbench.rb.kernels.plan.master_plan`,
from a :class:`~rbbench.rb.hyper.surface_eim.SurfaceRowEvaluator` (its restricted layout
and master windows): the slave Gauss points, unit outward normals and weights on the
reference surface (:func:`reference_surface_points`), the rows' points and multiplier
values per magic entry (:func:`~rbbench.hf.geometry.facets.point_support`), the slave
half of every magic entry (:func:`surface_slave_terms`) and the master window: its
reference vertices, triangles, candidate lists and ``Z^T`` on its dofs
(:func:`surface_master_plan`);
:func:`surface_eim_arrays` assembles them. numpy only.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rbbench.hf.geometry.facets import point_support
from rbbench.hf.geometry.surface_rules import triangle_rule, triangle_shape

__all__ = ["TABLE_GRID", "no_table", "pairing_table", "reference_surface_points",
           "surface_eim_arrays", "surface_master_plan", "surface_slave_terms"]

#: grid points over D of :func:`pairing_table`
TABLE_GRID = 2049


def no_table(nq: int) -> dict[str, np.ndarray]:
    """No pairing table (every point searched): empty runs for ``nq`` points."""
    return {"t_mu": np.zeros(1), "t_ptr": np.zeros(nq + 1, dtype=np.int64),
            "t_tri": np.zeros(1, dtype=np.int64)}


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


def surface_master_plan(ev: Any, Z_loc: np.ndarray, x_hat: np.ndarray | None = None,
                        n_hat: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """The master window of ``ev`` (a :class:`~rbbench.rb.hyper.surface_eim.SurfaceRowEvaluator`):
    each point's candidates as rows ``w_tri[w_ptr[q]:w_ptr[q + 1]]`` of
    ``[triangle, rank]`` (``rank``: the position in the order the reference tests them,
    which breaks ties alike), sorted by ``w_key = e_q . centroid`` along the axis ``e_q``
    (:func:`_trace_axes`; ``w_axis[q] = [e_q, the largest bounding radius of q's candidates,
    with the reference's slack]``), the master triangles in the reference frame (``m_geo``,
    :func:`_triangle_rows`; ``m_v`` and ``m_tri``, the 2D layout's vertex slots, are
    placeholders), ``Z^T`` on the window's master dofs (``zt_m``) and ``m_dofs``
    (triangle, node x component) numbered into it. ``x_hat``, ``n_hat``: the reference
    points (:func:`reference_surface_points`, computed when not given). A rigid plane:
    one-entry placeholders."""
    ms = ev.layout.master
    N = Z_loc.shape[1]
    if ms is None:
        return {"m_v": np.zeros((1, 3)), "zt_m": np.zeros((N, 1)),
                "m_dofs": np.zeros((1, 3), dtype=np.int64),
                "m_tri": np.zeros((1, 3), dtype=np.int64),
                "w_ptr": np.zeros(2, dtype=np.int64),
                "w_tri": np.zeros((1, 2), dtype=np.int64), "w_axis": np.zeros((1, 4)),
                "w_key": np.zeros(1), "m_geo": np.zeros((1, 14)),
                **no_table(int(ev.Mrows.shape[1]))}
    pi, ti = (np.asarray(a, dtype=np.int64) for a in ev.windows)
    rank = np.arange(pi.size)  # the reference's order of the pairs (its ties)
    axis = _trace_axes(ev.layout, n_hat if n_hat is not None
                       else reference_surface_points(ev.layout)[1], x_hat)
    corners = ms.points[ms.triangles[:, :3]]
    cen = corners.mean(axis=1)
    rad = np.sqrt(((corners - cen[:, None]) ** 2).sum(axis=2).max(axis=1))
    key = np.einsum("kd,kd->k", axis[pi], cen[ti])
    slack = rad * (1.0 + 1e-6) + 1e-12 * rad.max()  # the reference's (surface._Nearest)
    r_max = np.zeros(ev.Mrows.shape[1])
    np.maximum.at(r_max, pi, slack[ti])
    order = np.lexsort((key, pi))  # by point, then by the key along its axis
    nq = ev.Mrows.shape[1]
    ptr = np.concatenate([[0], np.cumsum(np.bincount(pi, minlength=nq))])
    dofs = ms.dofs[ms.triangles].reshape(ms.n_tri, -1)  # (tri, nodes x 3)
    used, m_dofs = np.unique(dofs, return_inverse=True)
    return {"m_v": np.zeros((1, 3)), "m_tri": np.zeros((1, 3), dtype=np.int64),  # unread in 3D
            "m_geo": _triangle_rows(corners, cen, slack),
            "w_ptr": ptr.astype(np.int64),
            "w_tri": np.stack([ti[order], rank[order]], axis=1),
            "w_axis": np.column_stack([axis, r_max]), "w_key": key[order], **no_table(nq),
            "zt_m": np.ascontiguousarray(Z_loc[used].T),
            "m_dofs": m_dofs.reshape(dofs.shape).astype(np.int64)}


def _triangle_rows(corners: np.ndarray, cen: np.ndarray, slack: np.ndarray) -> np.ndarray:
    """Rows ``[v0, e1 = v1 - v0, e2 = v2 - v0, 1e-12 |e1| |e2|, centroid, bounding radius
    with slack]`` of triangles ``corners`` (T, 3, 3) on the reference surface: what the
    ray-triangle test of :func:`rbbench.rb.kernels.surface_pairing.pair_surface_points`
    reads (the reference's degenerate-determinant threshold,
    :func:`rbbench.hf.geometry.surface._moller_trumbore`)."""
    e1, e2 = corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]
    det = 1e-12 * np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
    return np.ascontiguousarray(np.column_stack([corners[:, 0], e1, e2, det, cen, slack]))


def _trace_axes(lay: Any, n_hat: np.ndarray, x_hat: np.ndarray | None) -> np.ndarray:
    """A unit axis ``e_q`` normal to each point's line direction ``n_hat[q]``: the
    direction in which the line moves with mu (the slave map is affine in mu, so the line's
    trace on the plane normal to ``n_hat[q]`` is straight), or any normal axis where it
    does not move. Candidates sorted by ``e_q . centroid`` are searched by bisection
    online, in the master's reference frame (the point ``y``, the line still along
    ``n_hat[q]``): ``|e_q . (centroid - y)|`` is at most the distance from the centroid to
    the line, so every triangle the reference's bounding-sphere test keeps lies in the range
    searched, whatever the axis normal to the line
    (:func:`rbbench.rb.kernels.surface_pairing.pair_surface_points`)."""
    sl = lay.slave
    x = reference_surface_points(lay)[0] if x_hat is None else x_hat
    scale, shift = np.asarray(sl.map.scale, float), np.asarray(sl.map.shift, float)
    # x(mu) = s(mu) x_hat + c(mu): d/dmu_1 (one direction; several parameters: the first)
    move = scale[1] * x + shift[:, 1][None, :] if scale.size > 1 else np.zeros_like(x)
    move = move - np.einsum("qd,qd->q", move, n_hat)[:, None] * n_hat
    norm = np.linalg.norm(move, axis=1)
    e = np.where(np.abs(n_hat[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    e = e - np.einsum("qd,qd->q", e, n_hat)[:, None] * n_hat
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    big = norm > 1e-12 * max(float(norm.max(initial=0.0)), 1e-300)
    e[big] = move[big] / norm[big, None]
    return np.ascontiguousarray(e)


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
    out.update(surface_master_plan(ev, ceim.Z_loc, x_hat, n_hat))
    return out


def pairing_table(arrays: dict[str, np.ndarray], n_grid: int = TABLE_GRID
                  ) -> dict[str, np.ndarray]:
    """The table of :func:`rbbench.rb.kernels.surface_pairing.pair_surface_points` for a
    plan's ``arrays`` (with ``mu_lo``, ``mu_hi``): per slave point, the triangle its search
    chooses at ``n_grid`` equispaced parameters of D, as runs (``t_tri``, the run's first
    parameter ``t_mu``, a change between two grid points put at their midpoint;
    ``t_ptr[q]:t_ptr[q + 1]`` the runs of point ``q``). Online a run only names the
    triangle to cast first: hit well inside, it is the search's answer; else the search
    runs. A grid point where the search fails (a point outside its window) is left out.
    No table (:func:`no_table`) with several parameters, a rigid plane, an unbounded D, or
    where the search fails at every grid point."""
    from rbbench.rb.kernels import layout
    from rbbench.rb.kernels.plan import pack
    from rbbench.rb.kernels.surface_pairing import pair_surface_points

    nq = int(np.asarray(arrays["x_hat"]).shape[0])
    lo, hi = np.atleast_1d(arrays["mu_lo"]), np.atleast_1d(arrays["mu_hi"])
    if lo.size != 1 or not int(arrays["dims"][1]) or not np.all(np.isfinite([lo, hi])):
        return no_table(nq)
    unread = {**dict.fromkeys(layout.FLOATS, np.zeros((1, 1))),  # what pairing does not read
              **dict.fromkeys(layout.INTS, np.zeros((1, 1), dtype=np.int64))}
    fb, ib, meta = pack({**unread, **arrays, **no_table(nq)})
    grid = np.linspace(float(lo[0]), float(hi[0]), n_grid)
    tri = np.empty((n_grid, nq), dtype=np.int64)
    w, gap, mphi = np.empty(nq), np.empty(nq), np.zeros((nq, 3 * int(arrays["dims"][0])))
    ok = np.zeros(n_grid, dtype=bool)
    for g, mu in enumerate(grid):
        status, _ = pair_surface_points(np.array([1.0, mu]), fb, ib, meta, w, gap, mphi,
                                        tri[g])
        ok[g] = status == layout.OK
    if not ok.any():
        return no_table(nq)
    grid, tri = grid[ok], tri[ok]  # where some point left its window: no sample there
    change = np.vstack([np.ones((1, nq), bool), tri[1:] != tri[:-1]]).T  # a run starts
    q_idx, g_idx = np.nonzero(change)  # point by point, then along the grid
    start = np.where(g_idx == 0, grid[0], 0.5 * (grid[g_idx] + grid[np.maximum(g_idx - 1, 0)]))
    ptr = np.concatenate([[0], np.cumsum(np.bincount(q_idx, minlength=nq))])
    return {"t_mu": start, "t_ptr": ptr.astype(np.int64), "t_tri": tri[g_idx, q_idx]}

"""numba kernels of the 3D contact pairing and the magic entries of a contact EIM on
triangulated surfaces, on a packed plan (:mod:`rbbench.rb.kernels.layout`; offline side:
:mod:`rbbench.rb.kernels.surface_plan`).

The 3D counterpart of :mod:`rbbench.rb.kernels.pairing`.
:func:`pair_surface_points` pairs the EIM magic rows' slave Gauss points with the master
triangles of their windows (sampled offline,
:func:`rbbench.rb.hyper.surface_eim.master_window`) at one mu, by the ray-triangle test of
Moller & Trumbore ("Fast, minimum storage ray-triangle intersection", J. Graphics Tools 2
(1997) 21-28), as :func:`rbbench.hf.geometry.surface.pair_surfaces` with candidates does;
:func:`surface_jump_values` gives the magic entries of ``B(mu) Z`` and
:func:`surface_magic_values` both steps and the magic rows of ``G(mu)``. Under the
similarity maps ``x = s(mu) x_hat + c(mu)`` of the bodies, the slave points, normals and
weights are ``s x_hat + c``, ``sign(s) n_hat`` and ``s^2 w_hat`` (tabulated once on the
reference surface); the master surface is never mapped: each line is cast in the master's
reference frame, on triangles tabulated once. The formulas are the reference's, written
per point; only the summation order and the frame of the ray-triangle test differ
(round-off). The module imports numba at the top: import it only when numba is installed.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbbench.rb.kernels import layout, pairing
from rbbench.rb.kernels.layout import (
    COLS_B,
    DIMS,
    M_DOFS,
    M_GEO,
    M_SCALE,
    M_SHIFT,
    N_HAT,
    NO_HIT,
    OK,
    ORDER_B,
    PTS_B,
    PTS_G,
    S_SCALE,
    S_SHIFT,
    SLAVE_B,
    T_MU,
    T_PTR,
    T_TRI,
    VALS_B,
    VALS_G,
    W_AXIS,
    W_HAT,
    W_KEY,
    W_PTR,
    W_TRI,
    X_HAT,
    ZT_M,
    flat_floats,
    flat_ints,
    float_rows,
    int_rows,
)
from rbbench.runtime.numba_cache import stale_cache_dropper, use_user_cache

use_user_cache()  # before any @njit(cache=True): the cache lives in the user's cache dir

#: the reference's barycentric tolerance (a line through an edge hits,
#: :func:`rbbench.hf.geometry.surface.ray_cast_pairs`)
_TOL = 1e-9
#: the barycentric margin inside which the table's triangle is taken without the search
#: (:func:`pair_surface_points`): far from every edge, where no neighbour can be hit
_INSIDE = 1e-6


@njit(cache=True)
def _map3(th, scale, shift):
    """``(s, c)`` of a 3D :class:`~rbbench.hf.geometry.chains.AffineMap` at ``th = [1,
    mu]`` (``shift``: 3 rows of ``p + 1`` coefficients, flat)."""
    p1 = th.size
    s = 0.0
    c = np.zeros(3)
    for j in range(p1):
        s += scale[j] * th[j]
        for d in range(3):
            c[d] += shift[d * p1 + j] * th[j]
    return s, c


@njit(cache=True)
def _tri_shape(l0, l1, l2, degree, out, q):
    """:func:`~rbbench.hf.geometry.surface_rules.triangle_shape` at one point, into row
    ``q`` of ``out`` (P2: vertices, then the midpoints of edges (0, 1), (1, 2), (0, 2))."""
    if degree == 1:
        out[q, 0], out[q, 1], out[q, 2] = l0, l1, l2
    else:
        out[q, 0] = l0 * (2 * l0 - 1)
        out[q, 1] = l1 * (2 * l1 - 1)
        out[q, 2] = l2 * (2 * l2 - 1)
        out[q, 3] = 4 * l0 * l1
        out[q, 4] = 4 * l1 * l2
        out[q, 5] = 4 * l0 * l2


@njit(cache=True)
def _cast(y0, y1, y2, n0, n1, n2, geo, j):
    """The line ``y + t n`` against window triangle ``j`` in the master's reference frame
    (row ``j`` of ``geo``: ``[v0, e1 = v1 - v0, e2 = v2 - v0, 1e-12 |e1| |e2|, centroid,
    bounding radius with the reference's slack]``, tabulated offline,
    :func:`rbbench.rb.kernels.surface_plan.surface_master_plan`): ``(ok, u, v, t)`` with
    ``y + t n = v0 + u e1 + v e2``. A line missing the triangle's bounding sphere is skipped
    first, as the reference does; then the Moller-Trumbore test with the reference's
    operations in its order (:func:`rbbench.hf.geometry.surface._moller_trumbore`). Under
    the master map ``x = s_m y + c_m`` the physical line ``x + t' n`` is ``y + (t' / s_m)
    n``: the same barycentric coordinates, ``t' = s_m t``, and the tests are relative (the
    slack and the determinant's threshold scale with the triangle)."""
    r0, r1, r2 = geo[j, 10] - y0, geo[j, 11] - y1, geo[j, 12] - y2
    c0, c1, c2 = r1 * n2 - r2 * n1, r2 * n0 - r0 * n2, r0 * n1 - r1 * n0
    if c0 * c0 + c1 * c1 + c2 * c2 > geo[j, 13] * geo[j, 13]:
        return False, 0.0, 0.0, 0.0
    e10, e11, e12 = geo[j, 3], geo[j, 4], geo[j, 5]
    e20, e21, e22 = geo[j, 6], geo[j, 7], geo[j, 8]
    p0 = n1 * e22 - n2 * e21  # p = n x e2
    p1 = n2 * e20 - n0 * e22
    p2 = n0 * e21 - n1 * e20
    det = e10 * p0 + e11 * p1 + e12 * p2
    if not abs(det) > geo[j, 9]:
        return False, 0.0, 0.0, 0.0
    inv = 1.0 / det
    s0, s1, s2 = y0 - geo[j, 0], y1 - geo[j, 1], y2 - geo[j, 2]
    q0 = s1 * e12 - s2 * e11  # q = s x e1
    q1 = s2 * e10 - s0 * e12
    q2 = s0 * e11 - s1 * e10
    u = (s0 * p0 + s1 * p1 + s2 * p2) * inv
    v = (n0 * q0 + n1 * q1 + n2 * q2) * inv
    t = (e20 * q0 + e21 * q1 + e22 * q2) * inv
    ok = (u >= -_TOL) and (v >= -_TOL) and (u + v <= 1.0 + _TOL)
    return ok, u, v, t


@njit(cache=True)
def _first_at_least(key, first, last, value):
    """The first ``k`` in ``first .. last`` with ``key[k] >= value`` (``key`` sorted there;
    ``last`` when none): bisection."""
    while first < last:
        mid = (first + last) // 2
        if key[mid] < value:
            first = mid + 1
        else:
            last = mid
    return first


@njit(cache=True)
def _run(t_mu, first, last, mu):
    """The run of a point's table holding ``mu``: the last ``k`` in ``first .. last - 1``
    with ``t_mu[k] <= mu`` (``first`` when none; ``t_mu`` sorted there)."""
    k = _first_at_least_above(t_mu, first + 1, last, mu)
    return k - 1


@njit(cache=True)
def _first_at_least_above(key, first, last, value):
    """The first ``k`` in ``first .. last`` with ``key[k] > value`` (``last`` when none)."""
    while first < last:
        mid = (first + last) // 2
        if key[mid] <= value:
            first = mid + 1
        else:
            last = mid
    return first


@njit(cache=True)
def _search(y0, y1, y2, n0, n1, n2, q, ptr, cand, axis, key, geo):
    """The reference's choice for point ``q`` (line ``y + t n`` in the master's reference
    frame) among its candidates whose key lies in range (:func:`pair_surface_points`):
    ``(triangle, u, v, t)``, triangle -1 when none is hit."""
    a = axis[q, 0] * y0 + axis[q, 1] * y1 + axis[q, 2] * y2
    half = 1.001 * axis[q, 3]
    last, hi = ptr[q + 1], a + half
    best, bj, bu, bv, bt, br = np.inf, -1, 0.0, 0.0, np.nan, 0
    for k in range(_first_at_least(key, ptr[q], last, a - half), last):
        if key[k] > hi:
            break
        j = cand[k, 0]
        ok, u, v, t = _cast(y0, y1, y2, n0, n1, n2, geo, j)
        if ok and (abs(t) < best or (abs(t) == best and cand[k, 1] < br)):
            best, bj, bu, bv, bt, br = abs(t), j, u, v, t, cand[k, 1]
    return bj, bu, bv, bt


@njit(cache=True)
def pair_surface_points(th, fb, ib, meta, w, gap, mphi, mtri):
    """The pairing at ``th = [1, mu]`` of the plan's slave points: weights ``w``, gaps ``gap``,
    master shape values ``mphi`` (row per point) and master triangles ``mtri`` (rows of the
    plan's ``m_geo``; -1 for the rigid plane), written in place. Returns
    ``(status, s)``, ``s`` the slave map's scale (the normals are ``sign(s) n_hat``).

    Per point, the line along its normal is cast on the candidate triangles of its window
    (``w_tri[w_ptr[q]:w_ptr[q + 1]]``, sorted by the key ``e_q . centroid_hat`` along an
    axis ``e_q`` normal to the line,
    :func:`rbbench.rb.kernels.surface_plan.surface_master_plan`) whose key lies within the
    largest bounding radius of the point's candidates (``w_axis[q, 3]``, with the
    reference's slack) of ``e_q . y`` (``y = (x - c_m) / s_m``, the point in the master's
    reference frame): found by bisection, a superset of the triangles the reference's
    bounding-sphere test keeps, and a few per point whatever the mesh size (the window of a
    point is a band along its trace; the key range cuts the band across). Of the hits, the
    smallest ``|t|``, on ties the first in the reference's order (``rank``); its clipped,
    renormalised barycentric coordinates give the master shape values. The lines are cast in
    the master's reference frame on triangles tabulated offline (``m_geo``, :func:`_cast`):
    nothing is mapped per window triangle, so the work per point does not grow with the
    window (which grows with the mesh level). First, with one parameter, the point's table
    (``t_tri[t_ptr[q]:t_ptr[q + 1]]``, runs starting at ``t_mu``: the triangle the search
    chose over a grid of D, :func:`rbbench.rb.kernels.surface_plan.pairing_table`) names a
    triangle; cast on it, it is kept when hit at least ``_INSIDE`` (barycentric) away from
    its edges, where a neighbour cannot be hit, with the numbers the search would give;
    otherwise (near an edge or a change of triangle) the search runs. Then the work per
    point is one cast and a bisection whatever the mesh. The rigid plane ``z = 0``:
    ``gap = -x_z / n_z``. ``NO_HIT`` when a point hits no candidate (it left its window),
    meets the plane at a grazing angle, or a body's map is degenerate: the reference then
    decides."""
    xh, nh = float_rows(fb, meta, X_HAT), float_rows(fb, meta, N_HAT)
    wh = flat_floats(fb, meta, W_HAT)
    dims = flat_ints(ib, meta, DIMS)
    s, c = _map3(th, flat_floats(fb, meta, S_SCALE), flat_floats(fb, meta, S_SHIFT))
    if not s != 0.0:  # a degenerate (or NaN) map: the reference decides
        return NO_HIT, s
    sign = 1.0 if s > 0 else -1.0
    nq = xh.shape[0]
    for q in range(nq):
        w[q] = s * s * wh[q]
    if not dims[1]:  # rigid plane z = 0, outward normal +z
        for q in range(nq):
            nz = sign * nh[q, 2]
            g = -(s * xh[q, 2] + c[2]) / nz
            if not (abs(nz) >= 1e-12 and np.isfinite(g)):
                return NO_HIT, s
            gap[q] = g
            mtri[q] = -1
        return OK, s
    sm, cm = _map3(th, flat_floats(fb, meta, M_SCALE), flat_floats(fb, meta, M_SHIFT))
    if not (sm != 0.0 and np.isfinite(sm)):  # a degenerate master map: the reference decides
        return NO_HIT, s
    ptr, cand = flat_ints(ib, meta, W_PTR), int_rows(ib, meta, W_TRI)
    axis, key = float_rows(fb, meta, W_AXIS), flat_floats(fb, meta, W_KEY)
    geo = float_rows(fb, meta, M_GEO)
    t_ptr, t_tri = flat_ints(ib, meta, T_PTR), flat_ints(ib, meta, T_TRI)
    t_mu = flat_floats(fb, meta, T_MU)
    for q in range(nq):
        # the point in the master's reference frame: y = (x - c_m) / s_m
        y0 = (s * xh[q, 0] + c[0] - cm[0]) / sm
        y1 = (s * xh[q, 1] + c[1] - cm[1]) / sm
        y2 = (s * xh[q, 2] + c[2] - cm[2]) / sm
        n0, n1, n2 = sign * nh[q, 0], sign * nh[q, 1], sign * nh[q, 2]
        bj, bu, bv, bt = -1, 0.0, 0.0, np.nan
        if t_ptr[q + 1] > t_ptr[q]:  # the table's triangle, kept when hit well inside
            j = t_tri[_run(t_mu, t_ptr[q], t_ptr[q + 1], th[1])]
            ok, u, v, t = _cast(y0, y1, y2, n0, n1, n2, geo, j)
            if ok and u > _INSIDE and v > _INSIDE and 1.0 - u - v > _INSIDE:
                bj, bu, bv, bt = j, u, v, t
        if bj < 0:
            bj, bu, bv, bt = _search(y0, y1, y2, n0, n1, n2, q, ptr, cand, axis, key, geo)
        if bj < 0:
            return NO_HIT, s
        l0, l1, l2 = max(1.0 - bu - bv, 0.0), max(bu, 0.0), max(bv, 0.0)
        tot = max(l0 + l1 + l2, 1e-300)
        _tri_shape(l0 / tot, l1 / tot, l2 / tot, dims[0], mphi, q)
        mtri[q], gap[q] = bj, sm * bt
    return OK, s


@njit(cache=True)
def surface_jump_values(s, nh, wh, zt, m_dofs, has_master, slave, vals, pts, cols, order,
                        mphi, mtri, c):
    """Entries ``c[e]`` of ``B(mu) Z`` (the normal jump ``sign(s) n_hat``) at the points of
    :func:`pair_surface_points`, written in place.

    Entry ``e`` sums over its row's points ``q = pts[e, p]``: ``vals[e, p] w_q`` times the
    jump ``(u_1(x_q) - u_2(y_q)) . n_q`` of column ``cols[e]`` of ``Z``
    (:meth:`~rbbench.hf.geometry.surface.SurfacePairing.jump`). With ``w = s^2 w_hat`` and
    ``n = sign(s) n_hat`` the entry is ``s |s| sum_p vals w_hat (slave[e, p] - master
    term)``: the slave term (``slave``) is mu-independent and tabulated offline; the master
    term reads ``Z^T`` (``zt``: the window's master dofs only, ``m_dofs`` (triangle, node x
    component) numbered into it) on the triangle hit. Entries in the order of their columns
    (``order``), so that a row of ``Z^T`` stays in cache."""
    k = mphi.shape[1]
    for i in range(order.size):
        e = order[i]
        col = cols[e]
        acc_e = 0.0
        for p in range(pts.shape[1]):
            q = pts[e, p]
            acc = slave[e, p]
            if has_master:
                f = mtri[q]
                for a in range(k):
                    jump = nh[q, 0] * zt[col, m_dofs[f, 3 * a]]
                    jump += nh[q, 1] * zt[col, m_dofs[f, 3 * a + 1]]
                    jump += nh[q, 2] * zt[col, m_dofs[f, 3 * a + 2]]
                    acc -= mphi[q, a] * jump
            acc_e += vals[e, p] * wh[q] * acc
        c[e] = s * abs(s) * acc_e


@njit(cache=True)
def surface_magic_values(th, fb, ib, meta, c, g):
    """The magic entries ``c`` of ``B(mu) Z`` and magic rows ``g`` of ``G(mu)`` at ``th``
    (:meth:`~rbbench.rb.hyper.surface_eim.SurfaceRowEvaluator.entries`), written in place:
    :func:`pair_surface_points`, :func:`surface_jump_values`, then the weighted gaps
    (:func:`rbbench.rb.kernels.pairing.gap_values`). Returns the pairing's status."""
    dims = flat_ints(ib, meta, DIMS)
    nq = meta[X_HAT, 1]
    w, gap = np.empty(nq), np.empty(nq)
    mphi = np.zeros((nq, 3 * dims[0]))
    mtri = np.zeros(nq, dtype=np.int64)
    status, s = pair_surface_points(th, fb, ib, meta, w, gap, mphi, mtri)
    if status != OK:
        return status
    surface_jump_values(s, float_rows(fb, meta, N_HAT), flat_floats(fb, meta, W_HAT),
                        float_rows(fb, meta, ZT_M), int_rows(ib, meta, M_DOFS), dims[1],
                        float_rows(fb, meta, SLAVE_B), float_rows(fb, meta, VALS_B),
                        int_rows(ib, meta, PTS_B), flat_ints(ib, meta, COLS_B),
                        flat_ints(ib, meta, ORDER_B), mphi, mtri, c)
    pairing.gap_values(w, gap, float_rows(fb, meta, VALS_G), int_rows(ib, meta, PTS_G), g)
    return OK


#: the modules whose kernels this one's compile in (numba's cache checks only this file)
DEPENDENCIES = (layout.__file__, pairing.__file__)


# forget this module's cached kernels made against other dependencies' contents
drop_stale_cache = stale_cache_dropper(__name__, DEPENDENCIES)
drop_stale_cache()

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
reference surface); only the window's master vertices are mapped per mu, never the mesh.
The formulas are the reference's, written per point; only the summation order differs
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
    M_SCALE,
    M_SHIFT,
    M_TRI,
    M_V,
    N_HAT,
    NO_HIT,
    OK,
    ORDER_B,
    PTS_B,
    PTS_G,
    S_SCALE,
    S_SHIFT,
    SLAVE_B,
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

#: the reference's barycentric tolerance (a line through an edge hits) and its test of a
#: degenerate determinant (:func:`rbbench.hf.geometry.surface.ray_cast_pairs`)
_TOL, _DET = 1e-9, 1e-12


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
def _window_triangles(th, fb, ib, meta):
    """The window's master triangles at ``th``, one row each: ``[v0 (3), e1 = v1 - v0 (3),
    e2 = v2 - v0 (3), 1e-12 |e1| |e2|, centroid (3), bounding radius with its slack]``
    (the reference's, :class:`rbbench.hf.geometry.surface._Nearest`): only the window's
    vertices ``m_v`` are mapped, once per call."""
    sm, cm = _map3(th, flat_floats(fb, meta, M_SCALE), flat_floats(fb, meta, M_SHIFT))
    mvh, tri = float_rows(fb, meta, M_V), int_rows(ib, meta, M_TRI)
    nv, nt = mvh.shape[0], tri.shape[0]
    mv = np.empty((nv, 3))
    for i in range(nv):
        for d in range(3):
            mv[i, d] = sm * mvh[i, d] + cm[d]
    out = np.empty((nt, 14))
    rad_max = 0.0
    for j in range(nt):
        a, b, c = tri[j, 0], tri[j, 1], tri[j, 2]
        r2 = 0.0
        for d in range(3):
            out[j, d] = mv[a, d]
            out[j, 3 + d] = mv[b, d] - mv[a, d]
            out[j, 6 + d] = mv[c, d] - mv[a, d]
            out[j, 10 + d] = (mv[a, d] + mv[b, d] + mv[c, d]) / 3.0
        for v in (a, b, c):
            dv = 0.0
            for d in range(3):
                dv += (mv[v, d] - out[j, 10 + d]) ** 2
            r2 = max(r2, dv)
        out[j, 13] = np.sqrt(r2)
        rad_max = max(rad_max, out[j, 13])
        n1 = np.sqrt(out[j, 3] ** 2 + out[j, 4] ** 2 + out[j, 5] ** 2)
        n2 = np.sqrt(out[j, 6] ** 2 + out[j, 7] ** 2 + out[j, 8] ** 2)
        out[j, 9] = _DET * n1 * n2
    for j in range(nt):
        out[j, 13] = out[j, 13] * (1.0 + 1e-6) + 1e-12 * rad_max
    return out


@njit(cache=True)
def _cast(x0, x1, x2, n0, n1, n2, T, j):
    """The line ``x + t n`` against window triangle ``j`` (row ``j`` of ``T``,
    :func:`_window_triangles`): ``(ok, u, v, t)`` with ``x + t n = v0 + u e1 + v e2``. A
    line missing the triangle's bounding sphere is skipped first, as the reference does;
    then the Moller-Trumbore test with the reference's operations in its order
    (:func:`rbbench.hf.geometry.surface._moller_trumbore`)."""
    r0, r1, r2 = T[j, 10] - x0, T[j, 11] - x1, T[j, 12] - x2
    c0, c1, c2 = r1 * n2 - r2 * n1, r2 * n0 - r0 * n2, r0 * n1 - r1 * n0
    if c0 * c0 + c1 * c1 + c2 * c2 > T[j, 13] * T[j, 13]:
        return False, 0.0, 0.0, 0.0
    e10, e11, e12 = T[j, 3], T[j, 4], T[j, 5]
    e20, e21, e22 = T[j, 6], T[j, 7], T[j, 8]
    p0 = n1 * e22 - n2 * e21  # p = n x e2
    p1 = n2 * e20 - n0 * e22
    p2 = n0 * e21 - n1 * e20
    det = e10 * p0 + e11 * p1 + e12 * p2
    if not abs(det) > T[j, 9]:
        return False, 0.0, 0.0, 0.0
    inv = 1.0 / det
    s0, s1, s2 = x0 - T[j, 0], x1 - T[j, 1], x2 - T[j, 2]
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
def pair_surface_points(th, fb, ib, meta, w, gap, mphi, mtri):
    """The pairing at ``th = [1, mu]`` of the plan's slave points: weights ``w``, gaps
    ``gap``, master shape values ``mphi`` (row per point) and master triangles ``mtri``
    (into the plan's window triangles ``m_tri``; -1 for the rigid plane), written in place.
    Returns ``(status, s)``, ``s`` the slave map's scale (the normals are ``sign(s)
    n_hat``).

    Per point, the line along its normal is cast on the candidate triangles of its window
    (``w_tri[w_ptr[q]:w_ptr[q + 1]]``, sorted by the key ``e_q . centroid_hat`` along an
    axis ``e_q`` normal to the line,
    :func:`rbbench.rb.kernels.surface_plan.surface_master_plan`)
    whose mapped key ``sm key + e_q . cm`` lies within the largest bounding radius of the
    point's candidates (``w_axis[q, 3]``, mapped, with the reference's slack) of
    ``e_q . x``: found by bisection, a superset of the triangles the reference's
    bounding-sphere test keeps, and a few per point whatever the mesh size (the window of a
    point is a band along its trace; the key range cuts the band across). Of the hits, the
    smallest ``|t|``, on ties the first in the reference's order (``rank``); its clipped,
    renormalised barycentric coordinates give the master shape values. The window's
    triangles are mapped once per call (:func:`_window_triangles`). The rigid plane ``z =
    0``: ``gap = -x_z / n_z``. ``NO_HIT`` when a point hits no candidate (it left its
    window), meets the plane at a grazing angle, or the slave map is degenerate: the
    reference then decides."""
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
    T = _window_triangles(th, fb, ib, meta)
    r_all = 0.0  # the largest bounding radius (the reference's slack has 1e-12 of it)
    for j in range(T.shape[0]):
        r_all = max(r_all, T[j, 13])
    sm, cm = _map3(th, flat_floats(fb, meta, M_SCALE), flat_floats(fb, meta, M_SHIFT))
    ptr, cand = flat_ints(ib, meta, W_PTR), int_rows(ib, meta, W_TRI)
    axis, key = float_rows(fb, meta, W_AXIS), flat_floats(fb, meta, W_KEY)
    for q in range(nq):
        x0, x1, x2 = s * xh[q, 0] + c[0], s * xh[q, 1] + c[1], s * xh[q, 2] + c[2]
        n0, n1, n2 = sign * nh[q, 0], sign * nh[q, 1], sign * nh[q, 2]
        first, last = ptr[q], ptr[q + 1]
        if sm != 0.0:  # the candidates whose key can pass the bounding-sphere test
            half = 1.001 * (abs(sm) * axis[q, 3] * (1.0 + 1e-6) + 1e-12 * r_all)
            a = axis[q, 0] * (x0 - cm[0]) + axis[q, 1] * (x1 - cm[1]) + axis[q, 2] * (x2 - cm[2])
            lo, hi = (a - half) / sm, (a + half) / sm
            if sm < 0:
                lo, hi = hi, lo
            first = _first_at_least(key, first, last, lo)
        else:
            hi = np.inf
        best, bj, bu, bv, bt, br = np.inf, -1, 0.0, 0.0, np.nan, 0
        for k in range(first, last):
            if key[k] > hi:
                break
            j = cand[k, 0]
            ok, u, v, t = _cast(x0, x1, x2, n0, n1, n2, T, j)
            if ok and (abs(t) < best or (abs(t) == best and cand[k, 1] < br)):
                best, bj, bu, bv, bt, br = abs(t), j, u, v, t, cand[k, 1]
        if bj < 0:
            return NO_HIT, s
        l0, l1, l2 = max(1.0 - bu - bv, 0.0), max(bu, 0.0), max(bv, 0.0)
        tot = max(l0 + l1 + l2, 1e-300)
        _tri_shape(l0 / tot, l1 / tot, l2 / tot, dims[0], mphi, q)
        mtri[q], gap[q] = bj, bt
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

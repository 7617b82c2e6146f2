"""numba kernels of the 2D contact pairing and the magic entries of a contact EIM, on a
packed plan (:mod:`rbbench.rb.kernels.layout`).

:func:`pair_points` pairs the EIM magic rows' quadrature points in their master windows
(:func:`rbbench.hf.geometry.pairing.pair`, :func:`rbbench.hf.geometry.facets.ray_cast_window`)
at one mu; :func:`jump_values` and :func:`gap_values` give the magic entries of ``J(mu) Z``
for a jump ``J`` (normal or tangential) and the magic rows of ``G(mu)``
(:meth:`rbbench.rb.hyper.contact_eim.RowEvaluator.entries`); :func:`slave_points` tabulates
the reference slave points offline. The formulas are the reference's, written per point;
only the summation order differs (round-off). Used by the frictionless model's compiled
online path (:mod:`rbbench.rb.mixed.compiled`), its error bound and the wedge friction
model's (:mod:`rbbench.rb.friction.wedge.compiled`). The module imports numba at the top:
import it only when numba is installed.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbbench.rb.kernels import layout
from rbbench.rb.kernels.layout import (
    DIMS,
    HI,
    LO,
    M_A,
    M_B,
    M_SCALE,
    M_SHIFT,
    M_V,
    MONO,
    N_HAT,
    NO_HIT,
    OK,
    S_SCALE,
    S_SHIFT,
    W_HAT,
    X_HAT,
    flat_floats,
    flat_ints,
    float_rows,
    int_rows,
)
from rbbench.runtime.numba_cache import stale_cache_dropper, use_user_cache

use_user_cache()  # before any @njit(cache=True): the cache lives in the user's cache dir
_TOL = 1e-10  # ray_cast's tolerance on the facet coordinate


@njit(cache=True)
def _map(th, scale, shift):
    """``(s, cx, cy)`` of :class:`~rbbench.hf.geometry.chains.AffineMap` at ``th = [1, mu]``."""
    s, cx, cy = 0.0, 0.0, 0.0
    p1 = th.size
    for j in range(p1):
        s += scale[j] * th[j]
        cx += shift[j] * th[j]
        cy += shift[p1 + j] * th[j]
    return s, cx, cy


@njit(cache=True)
def _shape(s, degree, out, q):
    """:func:`~rbbench.hf.geometry.facets.facet_shape` at one point, into row ``q`` of ``out``."""
    if degree == 1:
        out[q, 0], out[q, 1] = 1.0 - s, s
    else:
        out[q, 0] = (1 - s) * (1 - 2 * s)
        out[q, 1] = s * (2 * s - 1)
        out[q, 2] = 4 * s * (1 - s)


@njit(cache=True)
def slave_points(sa, sb, inner, na, nb, sg, wg, degree, vertex_normals, x, nrm, w, sphi):
    """Points, unit outward normals, weights and slave shape values of the Gauss rule on
    every facet of the reference slave chain (:func:`~rbbench.hf.geometry.pairing.pair`,
    :meth:`~rbbench.hf.geometry.chains.FacetChain.normals_at`), computed once offline.

    The slave map is a similarity ``s x + c`` (:class:`~rbbench.hf.geometry.chains.AffineMap`),
    so at mu the points are ``s x + c``, the normals ``sign(s) n`` (the orientation test
    against the inner point scales by ``|s|``), the weights ``|s| w`` and the shape values
    unchanged: the online kernel only maps."""
    ng = sg.size
    for f in range(sa.shape[0]):
        ax, ay, bx, by = sa[f, 0], sa[f, 1], sb[f, 0], sb[f, 1]
        dx, dy = bx - ax, by - ay
        length = np.sqrt(dx * dx + dy * dy)
        fnx, fny = dy / length, -dx / length
        if fnx * (inner[f, 0] - 0.5 * (ax + bx)) + fny * (inner[f, 1] - 0.5 * (ay + by)) > 0:
            fnx, fny = -fnx, -fny
        for g in range(ng):
            q = f * ng + g
            sq = sg[g]
            x[q, 0], x[q, 1] = ax + sq * dx, ay + sq * dy
            if vertex_normals:
                vx = (1.0 - sq) * na[f, 0] + sq * nb[f, 0]
                vy = (1.0 - sq) * na[f, 1] + sq * nb[f, 1]
                nv = np.sqrt(vx * vx + vy * vy)
                nrm[q, 0], nrm[q, 1] = vx / nv, vy / nv
            else:
                nrm[q, 0], nrm[q, 1] = fnx, fny
            w[q] = wg[g] * length
            _shape(sq, degree, sphi, q)


@njit(cache=True)
def _cast(x0, x1, n0, n1, ax, ay, bx, by):
    """One ray-segment test of :func:`~rbbench.hf.geometry.facets.ray_cast`: ``(ok, s, |t|, t)``."""
    d0, d1 = bx - ax, by - ay
    det = n0 * (-d1) - n1 * (-d0)
    r0, r1 = ax - x0, ay - x1
    if not abs(det) > 1e-14:
        return False, 0.0, np.inf, 0.0
    s = (n0 * r1 - n1 * r0) / det
    if not ((s >= -_TOL) and (s <= 1 + _TOL)):  # a miss: its t is never read
        return False, s, np.inf, 0.0
    t = (r0 * (-d1) - r1 * (-d0)) / det
    return True, s, abs(t), t


@njit(cache=True)
def _best(x0, x1, n0, n1, ma, mb, sm, cx, cy, first, last, lo, hi):
    """Best hit (smallest ``|t|``, first on ties) over the master facets ``first .. last``
    kept in ``lo .. hi``, each mapped as it is tested (``sm x + c``; mapping the whole
    chain per solve was O(HF)): ``(facet or -1, s clipped to [0, 1], t)``."""
    seg, best, bs, bt = -1, np.inf, 0.0, np.nan
    for j in range(max(first, lo), min(last, hi) + 1):
        ok, s, at, t = _cast(x0, x1, n0, n1, sm * ma[j, 0] + cx, sm * ma[j, 1] + cy,
                             sm * mb[j, 0] + cx, sm * mb[j, 1] + cy)
        if ok and at < best:
            seg, best, bs, bt = j, at, s, t
    return seg, min(max(bs, 0.0), 1.0), bt


@njit(inline="always")
def _side(mv, j, sm, n0, n1, k):
    """The sign (-1, 0, 1) of ``cross(n, P_j - x)``, the side of the ray line of chain
    vertex ``P_j = sm P_hat_j + m``: ``sm cross(n, P_hat_j) + k`` with the point's constant
    ``k = cross(n, m - x)`` (:func:`pair_points`). Tested on the reference vertices
    ``mv`` (plan array ``m_v``), nothing mapped per test: ~6 ns per point's search
    instead of 41 with a mapped vertex per test, the pairing of 272 points 6.7 us instead
    of 15.6 (level 0, measured side by side)."""
    v = sm * (n0 * mv[j, 1] - n1 * mv[j, 0]) + k
    return (v > 0.0) - (v < 0.0)


@njit(inline="always")
def _last_same(mv, sm, n0, n1, k, lo, hi, guess):
    """The bisection of :func:`~rbbench.hf.geometry.facets.ray_cast_window` on a monotone window:
    the last vertex ``L`` in ``lo .. hi`` whose side (:func:`_side`) has the sign of vertex
    ``lo`` (those vertices are a prefix of the window, the side being monotone; vertex
    ``hi + 1`` is never tested). Found by galloping from ``guess`` (the previous point's
    vertex: the points follow the chains), then bisecting: the same ``L`` in a few side
    tests (3.5 per point on average at level 0), not ~2 log2(width)."""
    f = _side(mv, lo, sm, n0, n1, k)
    g = min(max(guess, lo), hi)
    step = 1
    if _side(mv, g, sm, n0, n1, k) == f:  # L >= g
        left, right = g, hi + 1
        while left + step <= hi:
            j = left + step
            if _side(mv, j, sm, n0, n1, k) != f:
                right = j
                break
            left = j
            step *= 2
    else:  # L < g
        left, right = lo, g
        while right - step > lo:
            j = right - step
            if _side(mv, j, sm, n0, n1, k) == f:
                left = j
                break
            right = j
            step *= 2
    while right - left > 1:
        mid = (left + right) // 2
        if _side(mv, mid, sm, n0, n1, k) == f:
            left = mid
        else:
            right = mid
    return left


@njit(cache=True)
def pair_points(th, fb, ib, meta, w, gap, mphi, seg):
    """The pairing at mu of the plan's quadrature points: weights ``w``, gaps ``gap``,
    master shape values ``mphi`` and master facets ``seg`` (written in place), as
    :func:`~rbbench.hf.geometry.pairing.pair` with
    :func:`~rbbench.hf.geometry.facets.ray_cast_window`. Returns ``(status, s)``, ``s`` the slave
    map's scale (the normals are ``sign(s) n_hat``, :func:`slave_points`).

    Per point: its facet by :func:`_last_same` and an exact cast on it and its two
    neighbours where the window's facet directions are monotone along the ray (``mono``,
    the reference's test, computed offline for both signs of ``s``: it depends on the
    normal only), else (or without a hit) brute force over the window. The search starts
    from the previous point's vertex (a per-point start at the centre of D, shifted as
    the previous point's was, measured no faster with the earlier side test: 17.1 against
    17.2 us)."""
    xh, nh = float_rows(fb, meta, X_HAT), float_rows(fb, meta, N_HAT)
    wh = flat_floats(fb, meta, W_HAT)
    dims = flat_ints(ib, meta, DIMS)
    s, cx, cy = _map(th, flat_floats(fb, meta, S_SCALE), flat_floats(fb, meta, S_SHIFT))
    if not s != 0.0:  # a degenerate (or NaN) map: the reference decides
        return NO_HIT, s
    sign = 1.0 if s > 0 else -1.0
    for q in range(xh.shape[0]):
        w[q] = abs(s) * wh[q]
    if not dims[1]:  # rigid plane y = 0
        for q in range(xh.shape[0]):
            gap[q] = -(s * xh[q, 1] + cy) / (sign * nh[q, 1])
        return OK, s
    sm, mx, my = _map(th, flat_floats(fb, meta, M_SCALE), flat_floats(fb, meta, M_SHIFT))
    ma, mb, mv = float_rows(fb, meta, M_A), float_rows(fb, meta, M_B), float_rows(fb, meta, M_V)
    lo, hi, mono = flat_ints(ib, meta, LO), flat_ints(ib, meta, HI), int_rows(ib, meta, MONO)
    col = 0 if s > 0 else 1
    guess = lo[0] if lo.size else 0
    for q in range(xh.shape[0]):
        x0, x1 = s * xh[q, 0] + cx, s * xh[q, 1] + cy
        n0, n1 = sign * nh[q, 0], sign * nh[q, 1]
        j = -1
        if mono[q, col]:
            k = n0 * (my - x1) - n1 * (mx - x0)
            guess = _last_same(mv, sm, n0, n1, k, lo[q], hi[q], guess)
            j, s2, t = _best(x0, x1, n0, n1, ma, mb, sm, mx, my, guess - 1, guess + 1,
                             lo[q], hi[q])
        if j < 0:
            j, s2, t = _best(x0, x1, n0, n1, ma, mb, sm, mx, my, lo[q], hi[q], lo[q], hi[q])
        if j < 0:
            return NO_HIT, s
        seg[q], gap[q] = j, t
        _shape(s2, dims[0], mphi, q)
    return OK, s


@njit(cache=True)
def jump_values(s, dh, wh, zt, m_dofs, has_master, slave, vals, pts, cols, order, mphi,
                seg, c):
    """Entries ``c[e]`` of ``J(mu) Z`` for the jump ``J`` along the direction ``sign(s)
    dh[q]`` at every point (``dh``: the reference normals ``n_hat`` give ``B Z``, the
    tangents ``(-n_y, n_x)`` of them ``Bt Z``), written in place.

    Entry ``e`` sums over its row's points ``q = pts[e, p]``: ``vals[e, p] w_q`` times the
    jump ``sum_j coef[q, j] Z[dof[q, j], cols[e]]``
    (:meth:`~rbbench.hf.geometry.pairing.Pairing.jump_terms`). With ``w = |s| w_hat`` and
    the direction ``sign(s) dh`` (:func:`slave_points`) the entry is ``s sum_p vals w_hat
    (slave[e, p] - master term)``: the slave term (``slave``) is mu-independent and
    tabulated offline; the master term reads ``Z^T`` on the master facet ``seg[q]``
    (``zt``: the master dofs of the windows only, ``m_dofs`` numbered into it; entries in
    the order of their columns, ``order``, so that a row of ``Z^T`` stays in cache)."""
    k = mphi.shape[1]
    for i in range(order.size):
        e = order[i]
        col = cols[e]
        acc_e = 0.0
        for p in range(pts.shape[1]):
            q = pts[e, p]
            acc = slave[e, p]
            if has_master:
                f = seg[q]
                for a in range(k):
                    jump = dh[q, 0] * zt[col, m_dofs[f, 2 * a]]
                    jump += dh[q, 1] * zt[col, m_dofs[f, 2 * a + 1]]
                    acc -= mphi[q, a] * jump
            acc_e += vals[e, p] * wh[q] * acc
        c[e] = s * acc_e


@njit(cache=True)
def gap_values(w, gap, vals_g, pts_g, g):
    """Rows ``g[r] = sum_p vals_g[r, p] w_q gap_q`` (``q = pts_g[r, p]``) of ``G(mu)``."""
    for r in range(pts_g.shape[0]):
        acc = 0.0
        for p in range(pts_g.shape[1]):
            q = pts_g[r, p]
            acc += vals_g[r, p] * w[q] * gap[q]
        g[r] = acc



#: the modules whose kernels this one's compile in (numba's cache checks only this file)
DEPENDENCIES = (layout.__file__,)


# forget this module's cached kernels made against other dependencies' contents
drop_stale_cache = stale_cache_dropper(__name__, DEPENDENCIES)
drop_stale_cache()

"""numba kernels of the compiled online stage (:mod:`rbbench.rb.mixed.compiled`).

One call of :func:`online_qp` does, for one mu, what the Python reference does in about 500
Python calls: the pairing of the EIM magic rows' quadrature points in their master windows
(:func:`rbbench.hf.geometry.pairing.pair`, :func:`rbbench.hf.geometry.facets.ray_cast_window`), the
magic entries of ``C(mu) = B(mu) Z`` and the magic rows of ``G(mu)``
(:meth:`rbbench.rb.hyper.contact_eim.RowEvaluator.entries`), the EIM coefficient solves, the
reduced ``B_N``, ``G_N``, ``A_N``, ``F_N`` (:class:`rbbench.rb.hyper.contact_eim.ContactEIM`) and
the scaled QP data of :func:`rbbench.rb.mixed.model._solve_daqp`. The formulas are the
reference's, written per point; only the summation order differs (round-off).

Arguments are packed into two flat buffers (``fb`` float64, ``ib`` int64) and a table
``meta`` (one row ``[offset, s0, s1, s2]`` per array, in the order of :data:`FLOATS` then
:data:`INTS`): a numba call costs ~0.2 us per array argument, so five arguments instead of
thirty. The module imports numba at the top: import it only when numba is installed.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbbench.runtime.numba_cache import use_user_cache

use_user_cache()  # before any @njit(cache=True): the cache lives in the user's cache dir

#: float arrays of the plan, in buffer order (shapes: see ``compiled_online.plan_arrays``)
FLOATS = ("mu_lo", "mu_hi", "s_scale", "s_shift", "m_scale", "m_shift", "x_hat", "n_hat",
          "w_hat", "m_a", "m_b", "m_v", "zt_m", "slave_b", "vals_b", "vals_g", "w_b", "w_g",
          "a_terms", "f_terms", "vt", "lam_a")
#: int arrays of the plan: ``dims = [degree, has_master, affine]`` (``affine``: an exact
#: affine constraint, whose terms are ``w_b``, ``w_g``: no pairing)
INTS = ("dims", "mono", "m_dofs", "lo", "hi", "pts_b", "cols_b", "order_b", "pts_g")

(MU_LO, MU_HI, S_SCALE, S_SHIFT, M_SCALE, M_SHIFT, X_HAT, N_HAT, W_HAT, M_A, M_B, M_V, ZT_M,
 SLAVE_B, VALS_B, VALS_G, W_B, W_G, A_TERMS, F_TERMS, VT, LAM_A) = range(22)
(DIMS, MONO, M_DOFS, LO, HI, PTS_B, COLS_B, ORDER_B, PTS_G) = range(22, 31)

#: statuses of :func:`online_qp` (anything but OK: the caller reruns the Python path,
#: which raises the reference's error)
OK, OUTSIDE_D, NO_HIT = 0, 1, 2

_TOL = 1e-10  # ray_cast's tolerance on the facet coordinate


@njit(cache=True)
def _f(fb, meta, k):
    o = meta[k, 0]
    return fb[o:o + meta[k, 1] * meta[k, 2] * meta[k, 3]]


@njit(cache=True)
def _f2(fb, meta, k):
    return _f(fb, meta, k).reshape((meta[k, 1], meta[k, 2] * meta[k, 3]))


@njit(cache=True)
def _i(ib, meta, k):
    o = meta[k, 0]
    return ib[o:o + meta[k, 1] * meta[k, 2] * meta[k, 3]]


@njit(cache=True)
def _i2(ib, meta, k):
    return _i(ib, meta, k).reshape((meta[k, 1], meta[k, 2] * meta[k, 3]))


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
    xh, nh, wh = _f2(fb, meta, X_HAT), _f2(fb, meta, N_HAT), _f(fb, meta, W_HAT)
    dims = _i(ib, meta, DIMS)
    s, cx, cy = _map(th, _f(fb, meta, S_SCALE), _f(fb, meta, S_SHIFT))
    if not s != 0.0:  # a degenerate (or NaN) map: the reference decides
        return NO_HIT, s
    sign = 1.0 if s > 0 else -1.0
    for q in range(xh.shape[0]):
        w[q] = abs(s) * wh[q]
    if not dims[1]:  # rigid plane y = 0
        for q in range(xh.shape[0]):
            gap[q] = -(s * xh[q, 1] + cy) / (sign * nh[q, 1])
        return OK, s
    sm, mx, my = _map(th, _f(fb, meta, M_SCALE), _f(fb, meta, M_SHIFT))
    ma, mb, mv = _f2(fb, meta, M_A), _f2(fb, meta, M_B), _f2(fb, meta, M_V)
    lo, hi, mono = _i(ib, meta, LO), _i(ib, meta, HI), _i2(ib, meta, MONO)
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
def magic_values(fb, ib, meta, s, w, gap, mphi, seg, c, g):
    """The magic entries ``c`` of ``C(mu)`` and magic rows ``g`` of ``G(mu)``
    (:meth:`~rbbench.rb.hyper.contact_eim.RowEvaluator.entries`), written in place: the
    normal jump of the plan's entries (:func:`jump_values` along ``n_hat``) and the
    weighted gaps of its rows (:func:`gap_values`)."""
    jump_values(s, _f2(fb, meta, N_HAT), _f(fb, meta, W_HAT), _f2(fb, meta, ZT_M),
                _i2(ib, meta, M_DOFS), _i(ib, meta, DIMS)[1], _f2(fb, meta, SLAVE_B),
                _f2(fb, meta, VALS_B), _i2(ib, meta, PTS_B), _i(ib, meta, COLS_B),
                _i(ib, meta, ORDER_B), mphi, seg, c)
    gap_values(w, gap, _f2(fb, meta, VALS_G), _i2(ib, meta, PTS_G), g)


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


@njit(cache=True)
def _combine(coef, terms, out):
    """``out = sum_k coef[k] terms[k]`` (terms flattened per k), summed in the order of k
    as one pass per term would (the same round-off), but eight terms per pass over
    ``out``: the sum is bound by reading the terms (81 x 1200 doubles: 14 us one term per
    pass, 9.4 us eight, measured warm)."""
    out[:] = 0.0
    n, kk = out.size, coef.size
    k = 0
    while k + 8 <= kk:
        c0, c1, c2, c3 = coef[k], coef[k + 1], coef[k + 2], coef[k + 3]
        c4, c5, c6, c7 = coef[k + 4], coef[k + 5], coef[k + 6], coef[k + 7]
        for i in range(n):
            acc = out[i] + c0 * terms[k, i]
            acc += c1 * terms[k + 1, i]
            acc += c2 * terms[k + 2, i]
            acc += c3 * terms[k + 3, i]
            acc += c4 * terms[k + 4, i]
            acc += c5 * terms[k + 5, i]
            acc += c6 * terms[k + 6, i]
            out[i] = acc + c7 * terms[k + 7, i]
        k += 8
    for j in range(k, kk):
        cj = coef[j]
        for i in range(n):
            out[i] += cj * terms[j, i]


@njit(cache=True)
def theta(mu, fb, meta):
    """``(status, th)``: ``th = [1, mu]`` when mu is in D (:data:`OK`), else
    :data:`OUTSIDE_D` (wrong size, not finite or outside the bounds)."""
    lo_mu, hi_mu = _f(fb, meta, MU_LO), _f(fb, meta, MU_HI)
    th = np.empty(mu.size + 1)
    if mu.size != lo_mu.size:
        return OUTSIDE_D, th
    for j in range(mu.size):
        if not (np.isfinite(mu[j]) and lo_mu[j] <= mu[j] <= hi_mu[j]):
            return OUTSIDE_D, th
    th[0] = 1.0
    th[1:] = mu
    return OK, th


@njit(cache=True)
def constraint_rows(th, fb, ib, meta, b, gn):
    """The reduced constraint at ``th``: ``b = sum_e c_e W_B[e]`` (flat, in the layout of
    the plan's ``w_b``) and ``gn = sum_r g_r W_G[r]`` from the pairing and the magic
    entries ``c``, rows ``g`` (:func:`pair_points`, :func:`magic_values`; an exact affine
    constraint: ``c = g = th``). Returns a status (:data:`NO_HIT`: a point left its master
    window, or a degenerate map)."""
    if _i(ib, meta, DIMS)[2]:  # exact affine: B_N = sum_k theta_k B_k, G_N likewise
        _combine(th, _f2(fb, meta, W_B), b)
        _combine(th, _f2(fb, meta, W_G), gn)
        return OK
    nq = meta[X_HAT, 1]
    w, gap = np.empty(nq), np.empty(nq)
    mphi, seg = np.zeros((nq, _i(ib, meta, DIMS)[0] + 1)), np.zeros(nq, dtype=np.int64)
    status, s = pair_points(th, fb, ib, meta, w, gap, mphi, seg)
    if status != OK:
        return status
    c, g = np.empty(meta[PTS_B, 1]), np.empty(meta[PTS_G, 1])
    magic_values(fb, ib, meta, s, w, gap, mphi, seg, c, g)
    _combine(c, _f2(fb, meta, W_B), b)  # sum_j theta_j T_B[j], theta = B^-1 c
    _combine(g, _f2(fb, meta, W_G), gn)
    return OK


@njit(cache=True)
def online_qp(mu, fb, ib, meta, qp):
    """The scaled QP data of one online solve at ``mu``, written into ``qp``.

    ``qp`` holds ``[H (n x n), f (n), A (m x n), b_upper (m), row norms of B_N (m), |F_N|]``
    with ``H = A_N``, ``f = -F_N / |F_N|``, ``A = B_N / rows``, ``b_upper = G_N / rows /
    |F_N|`` (:func:`rbbench.rb.mixed.model._solve_daqp`). Returns a status: :data:`OK`,
    :data:`OUTSIDE_D` (mu is not in D: wrong size, not finite or outside the bounds) or
    :data:`NO_HIT` (a point left its master window, or a degenerate map).
    """
    status, th = theta(mu, fb, meta)
    if status != OK:
        return status
    n = meta[A_TERMS, 2]
    m = meta[W_G, 2]
    b = qp[n * n + n:n * n + n + m * n]
    gn = np.empty(m)
    status = constraint_rows(th, fb, ib, meta, b, gn)
    if status != OK:
        return status
    _combine(th, _f2(fb, meta, A_TERMS), qp[:n * n])
    f = np.empty(n)
    _combine(th, _f2(fb, meta, F_TERMS), f)
    _scale(f, b.reshape((m, n)), gn, qp[n * n:], n, m)
    return OK


@njit(cache=True)
def _scale(f, b, gn, out, n, m):
    """Row and load scaling of :func:`rbbench.rb.mixed.model._solve_daqp` into ``out`` =
    ``[f (n), A (m x n, in place: b is its storage), b_upper (m), rows (m), |F|]``."""
    fs = np.sqrt(np.sum(f * f))
    if fs == 0.0:
        fs = 1.0
    for i in range(n):
        out[i] = -f[i] / fs
    o = n + m * n
    for r in range(m):
        rn = np.sqrt(np.sum(b[r] * b[r]))
        if rn == 0.0:
            rn = 1.0
        b[r] /= rn
        out[o + r] = gn[r] / rn / fs
        out[o + m + r] = rn
    out[o + 2 * m] = fs


@njit(cache=True)
def unscale(y, lam, qp, n, m):
    """``(c, alpha, finite, rel_min)`` from daqp's ``(y, lam)``: ``c = y |F|``, raw
    multipliers ``lam |F| / rows``, ``alpha = max(raw, 0)``, ``min(raw) / max|raw|``."""
    o = n + n * n + m * n + m
    fs = qp[o + m]
    c = y * fs
    raw = lam * fs / qp[o:o + m]
    alpha = np.maximum(raw, 0.0)
    finite = np.all(np.isfinite(c)) and np.all(np.isfinite(alpha))
    top = np.max(np.abs(raw)) if raw.size else 0.0
    rel = np.min(raw) / top if top > 0 else 0.0
    return c, alpha, finite, rel

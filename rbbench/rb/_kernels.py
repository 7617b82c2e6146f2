"""numba kernels of the compiled online stage (:mod:`rbbench.rb.compiled_online`).

One call of :func:`online_qp` does, for one mu, what the Python reference does in about 500
Python calls: the pairing of the EIM magic rows' quadrature points in their master windows
(:func:`rbbench.hf.pairing.pair`, :func:`rbbench.hf.facets.ray_cast_window`), the magic
entries of ``C(mu) = B(mu) Z`` and the magic rows of ``G(mu)``
(:meth:`rbbench.rb.contact_eim.RowEvaluator.entries`), the EIM coefficient solves, the
reduced ``B_N``, ``G_N``, ``A_N``, ``F_N`` (:class:`rbbench.rb.contact_eim.ContactEIM`) and
the scaled QP data of :func:`rbbench.rb.mixed_model._solve_daqp`. The formulas are the
reference's, written per point; only the summation order differs (round-off).

Arguments are packed into two flat buffers (``fb`` float64, ``ib`` int64) and a table
``meta`` (one row ``[offset, s0, s1, s2]`` per array, in the order of :data:`FLOATS` then
:data:`INTS`): a numba call costs ~0.2 us per array argument, so five arguments instead of
thirty. The module imports numba at the top: import it only when numba is installed.
"""

from __future__ import annotations

import numpy as np
from numba import njit

#: float arrays of the plan, in buffer order (shapes: see ``compiled_online.plan_arrays``)
FLOATS = ("mu_lo", "mu_hi", "s_scale", "s_shift", "m_scale", "m_shift", "s_a", "s_b",
          "s_inner", "s_na", "s_nb", "m_a", "m_b", "ranges", "sg", "wg", "zt_loc", "vals_b",
          "vals_g", "w_b", "w_g", "a_terms", "f_terms")
#: int arrays of the plan: ``dims = [degree, has_master, vertex_normals]``
INTS = ("dims", "s_dofs", "m_dofs", "lo", "hi", "pts_b", "cols_b", "order_b", "pts_g")

(MU_LO, MU_HI, S_SCALE, S_SHIFT, M_SCALE, M_SHIFT, S_A, S_B, S_INNER, S_NA, S_NB, M_A, M_B,
 RANGES, SG, WG, ZT_LOC, VALS_B, VALS_G, W_B, W_G, A_TERMS, F_TERMS) = range(23)
(DIMS, S_DOFS, M_DOFS, LO, HI, PTS_B, COLS_B, ORDER_B, PTS_G) = range(23, 32)

#: statuses of :func:`online_qp` (anything but OK: the caller reruns the Python path,
#: which raises the reference's error)
OK, OUTSIDE_D, NO_HIT = 0, 1, 2

_TOL = 1e-10  # ray_cast's tolerance on the facet coordinate
_EPS = 1e-9  # ray_cast_window's margin on the angles


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
    """``(s, cx, cy)`` of :class:`~rbbench.hf.facet_chains.AffineMap` at ``th = [1, mu]``."""
    s, cx, cy = 0.0, 0.0, 0.0
    p1 = th.size
    for j in range(p1):
        s += scale[j] * th[j]
        cx += shift[j] * th[j]
        cy += shift[p1 + j] * th[j]
    return s, cx, cy


@njit(cache=True)
def _shape(s, degree, out, q):
    """:func:`~rbbench.hf.facets.facet_shape` at one point, into row ``q`` of ``out``."""
    if degree == 1:
        out[q, 0], out[q, 1] = 1.0 - s, s
    else:
        out[q, 0] = (1 - s) * (1 - 2 * s)
        out[q, 1] = s * (2 * s - 1)
        out[q, 2] = 4 * s * (1 - s)


@njit(cache=True)
def slave_points(th, fb, ib, meta, x, nrm, w, sphi):
    """Points, unit outward normals, weights and slave shape values of the Gauss rule on
    every slave facet at mu (:func:`~rbbench.hf.pairing.pair`,
    :meth:`~rbbench.hf.facet_chains.FacetChain.normals_at`)."""
    sa, sb, inner = _f2(fb, meta, S_A), _f2(fb, meta, S_B), _f2(fb, meta, S_INNER)
    na, nb = _f2(fb, meta, S_NA), _f2(fb, meta, S_NB)
    sg, wg = _f(fb, meta, SG), _f(fb, meta, WG)
    dims = _i(ib, meta, DIMS)
    s, cx, cy = _map(th, _f(fb, meta, S_SCALE), _f(fb, meta, S_SHIFT))
    ng = sg.size
    sign = 1.0 if s > 0 else (-1.0 if s < 0 else 0.0)
    for f in range(sa.shape[0]):
        ax, ay = s * sa[f, 0] + cx, s * sa[f, 1] + cy
        bx, by = s * sb[f, 0] + cx, s * sb[f, 1] + cy
        dx, dy = bx - ax, by - ay
        length = np.sqrt(dx * dx + dy * dy)
        fnx, fny = dy / length, -dx / length
        ix, iy = s * inner[f, 0] + cx, s * inner[f, 1] + cy
        if fnx * (ix - 0.5 * (ax + bx)) + fny * (iy - 0.5 * (ay + by)) > 0:
            fnx, fny = -fnx, -fny
        for g in range(ng):
            q = f * ng + g
            sq = sg[g]
            x[q, 0], x[q, 1] = ax + sq * dx, ay + sq * dy
            if dims[2]:
                vx = (1.0 - sq) * na[f, 0] + sq * nb[f, 0]
                vy = (1.0 - sq) * na[f, 1] + sq * nb[f, 1]
                nv = np.sqrt(vx * vx + vy * vy)
                nrm[q, 0], nrm[q, 1] = sign * vx / nv, sign * vy / nv
            else:
                nrm[q, 0], nrm[q, 1] = fnx, fny
            w[q] = wg[g] * length
            _shape(sq, dims[0], sphi, q)


@njit(cache=True)
def _cast(x0, x1, n0, n1, ax, ay, bx, by):
    """One ray-segment test of :func:`~rbbench.hf.facets.ray_cast`: ``(ok, s, |t|, t)``."""
    d0, d1 = bx - ax, by - ay
    det = n0 * (-d1) - n1 * (-d0)
    r0, r1 = ax - x0, ay - x1
    if not abs(det) > 1e-14:
        return False, 0.0, np.inf, 0.0
    t = (r0 * (-d1) - r1 * (-d0)) / det
    s = (n0 * r1 - n1 * r0) / det
    return (s >= -_TOL) and (s <= 1 + _TOL), s, abs(t), t


@njit(cache=True)
def _best(x0, x1, n0, n1, segs, first, last, lo, hi):
    """Best hit (smallest ``|t|``, first on ties) over facets ``first .. last`` kept in
    ``lo .. hi`` (``segs[j] = [a_j, b_j]``): ``(segment or -1, s clipped to [0, 1], t)``."""
    seg, best, bs, bt = -1, np.inf, 0.0, np.nan
    for j in range(max(first, lo), min(last, hi) + 1):
        ok, s, at, t = _cast(x0, x1, n0, n1, segs[j, 0], segs[j, 1], segs[j, 2], segs[j, 3])
        if ok and at < best:
            seg, best, bs, bt = j, at, s, t
    return seg, min(max(bs, 0.0), 1.0), bt


@njit(cache=True)
def _sign_side(x0, x1, n0, n1, px, py):
    """The sign of ``cross(n, P - x)`` (the side of chain vertex P of the ray line)."""
    return np.sign(n0 * (py - x1) - n1 * (px - x0))


@njit(cache=True)
def _last_same(x0, x1, n0, n1, verts, lo, hi, guess):
    """The bisection of :func:`~rbbench.hf.facets.ray_cast_window` on a monotone window:
    the last vertex ``L`` in ``lo .. hi`` whose side has the sign of vertex ``lo`` (those
    vertices are a prefix of the window, the side being monotone; vertex ``hi + 1`` is
    never tested). Found by galloping from ``guess`` (the previous point's vertex: the
    points follow the chains), then bisecting: the same ``L`` in ~4 side tests, not ~8."""
    f = _sign_side(x0, x1, n0, n1, verts[lo, 0], verts[lo, 1])
    g = min(max(guess, lo), hi)
    step = 1
    if _sign_side(x0, x1, n0, n1, verts[g, 0], verts[g, 1]) == f:  # L >= g
        left, right = g, hi + 1
        while left + step <= hi:
            j = left + step
            if _sign_side(x0, x1, n0, n1, verts[j, 0], verts[j, 1]) != f:
                right = j
                break
            left = j
            step *= 2
    else:  # L < g
        left, right = lo, g
        while right - step > lo:
            j = right - step
            if _sign_side(x0, x1, n0, n1, verts[j, 0], verts[j, 1]) == f:
                left = j
                break
            right = j
            step *= 2
    while right - left > 1:
        mid = (left + right) // 2
        if _sign_side(x0, x1, n0, n1, verts[mid, 0], verts[mid, 1]) == f:
            left = mid
        else:
            right = mid
    return left


@njit(cache=True)
def ray_cast_window(x, nrm, segs, verts, lo, hi, ranges, seg, s2, gap):
    """:func:`~rbbench.hf.facets.ray_cast_window` per point: where the window's facet
    directions are monotone along the ray, its facet by :func:`_last_same` and an exact
    cast on it and its two neighbours; else (or without a hit) brute force over the
    window. ``segs[j] = [a_j, b_j]``, ``verts``: the chain's vertices (``a``, then the
    last ``b``). Returns False when a point hits no facet."""
    guess = lo[0] if lo.size else 0
    for q in range(x.shape[0]):
        x0, x1, n0, n1 = x[q, 0], x[q, 1], nrm[q, 0], nrm[q, 1]
        th = np.arctan2(n1, n0)
        monotone = (np.floor((ranges[q, 0] - th - _EPS) / np.pi)
                    == np.floor((ranges[q, 1] - th + _EPS) / np.pi))
        j = -1
        if monotone:
            guess = _last_same(x0, x1, n0, n1, verts, lo[q], hi[q], guess)
            j, s, t = _best(x0, x1, n0, n1, segs, guess - 1, guess + 1, lo[q], hi[q])
        if j < 0:
            j, s, t = _best(x0, x1, n0, n1, segs, lo[q], hi[q], lo[q], hi[q])
        if j < 0:
            return False
        seg[q], s2[q], gap[q] = j, s, t
    return True


@njit(cache=True)
def magic_values(fb, ib, meta, nrm, w, gap, sphi, mphi, seg, has_master):
    """The magic entries of ``C(mu)`` and magic rows of ``G(mu)``
    (:meth:`~rbbench.rb.contact_eim.RowEvaluator.entries`).

    Entry ``e`` sums over its row's points ``q``: ``vals[e, p] w_q`` times the normal jump
    ``sum_j coef[q, j] Z[dof[q, j], col_e]`` (:meth:`~rbbench.hf.pairing.Pairing.jump_terms`:
    slave term, then master term on facet ``seg[q]``), from ``Z^T`` (entries in the order
    of their columns, ``order_b``, so that a row of ``Z^T`` stays in cache). Written out
    in one loop nest: a helper function per point cost 3x (measured).
    """
    zt = _f2(fb, meta, ZT_LOC)
    vals_b, pts_b, cols = _f2(fb, meta, VALS_B), _i2(ib, meta, PTS_B), _i(ib, meta, COLS_B)
    s_dofs, m_dofs, order = _i2(ib, meta, S_DOFS), _i2(ib, meta, M_DOFS), _i(ib, meta, ORDER_B)
    ng, k = _f(fb, meta, SG).size, sphi.shape[1]
    c = np.zeros(pts_b.shape[0])
    for i in range(order.size):
        e = order[i]
        col = cols[e]
        for p in range(pts_b.shape[1]):
            q = pts_b[e, p]
            f = q // ng
            acc = 0.0
            for a in range(k):
                for d in range(2):
                    acc += sphi[q, a] * nrm[q, d] * zt[col, s_dofs[f, 2 * a + d]]
            if has_master:
                s = seg[q]
                for a in range(k):
                    for d in range(2):
                        acc += -(mphi[q, a] * nrm[q, d]) * zt[col, m_dofs[s, 2 * a + d]]
            c[e] += vals_b[e, p] * w[q] * acc
    vals_g, pts_g = _f2(fb, meta, VALS_G), _i2(ib, meta, PTS_G)
    g = np.zeros(pts_g.shape[0])
    for r in range(pts_g.shape[0]):
        for p in range(pts_g.shape[1]):
            q = pts_g[r, p]
            g[r] += vals_g[r, p] * w[q] * gap[q]
    return c, g


@njit(cache=True)
def _combine(coef, terms, out):
    """``out = sum_k coef[k] terms[k]`` (terms flattened per k)."""
    out[:] = 0.0
    for k in range(coef.size):
        ck = coef[k]
        for i in range(out.size):
            out[i] += ck * terms[k, i]


@njit(cache=True)
def pair_points(th, fb, ib, meta, nq, k):
    """The pairing of the plan's quadrature points at mu: ``(status, nrm, w, gap, sphi,
    mphi, seg)`` (shape values on the slave and master facets, master facet per point)."""
    dims = _i(ib, meta, DIMS)
    x, nrm = np.empty((nq, 2)), np.empty((nq, 2))
    w, gap, sphi = np.empty(nq), np.empty(nq), np.empty((nq, k))
    slave_points(th, fb, ib, meta, x, nrm, w, sphi)
    mphi, seg = np.zeros((nq, k)), np.zeros(nq, dtype=np.int64)
    if not dims[1]:  # rigid plane y = 0
        for q in range(nq):
            gap[q] = -x[q, 1] / nrm[q, 1]
        return OK, nrm, w, gap, sphi, mphi, seg
    s, cx, cy = _map(th, _f(fb, meta, M_SCALE), _f(fb, meta, M_SHIFT))
    ma, mb = _f2(fb, meta, M_A), _f2(fb, meta, M_B)
    nm = ma.shape[0]
    segs, verts = np.empty((nm, 4)), np.empty((nm + 1, 2))
    for j in range(nm):  # the map of AffineMap.__call__: s x_hat + c
        segs[j, 0], segs[j, 1] = s * ma[j, 0] + cx, s * ma[j, 1] + cy
        segs[j, 2], segs[j, 3] = s * mb[j, 0] + cx, s * mb[j, 1] + cy
        verts[j, 0], verts[j, 1] = segs[j, 0], segs[j, 1]
    verts[nm, 0], verts[nm, 1] = segs[nm - 1, 2], segs[nm - 1, 3]
    s2 = np.empty(nq)
    if not ray_cast_window(x, nrm, segs, verts, _i(ib, meta, LO), _i(ib, meta, HI),
                           _f2(fb, meta, RANGES), seg, s2, gap):
        return NO_HIT, nrm, w, gap, sphi, mphi, seg
    for q in range(nq):
        _shape(s2[q], dims[0], mphi, q)
    return OK, nrm, w, gap, sphi, mphi, seg


@njit(cache=True)
def online_qp(mu, fb, ib, meta, qp):
    """The scaled QP data of one online solve at ``mu``, written into ``qp``.

    ``qp`` holds ``[H (n x n), f (n), A (m x n), b_upper (m), row norms of B_N (m), |F_N|]``
    with ``H = A_N``, ``f = -F_N / |F_N|``, ``A = B_N / rows``, ``b_upper = G_N / rows /
    |F_N|`` (:func:`rbbench.rb.mixed_model._solve_daqp`). Returns a status: :data:`OK`,
    :data:`OUTSIDE_D` (mu is not in D: wrong size, not finite or outside the bounds) or
    :data:`NO_HIT` (a point left its master window).
    """
    lo_mu, hi_mu = _f(fb, meta, MU_LO), _f(fb, meta, MU_HI)
    if mu.size != lo_mu.size:
        return OUTSIDE_D
    for j in range(mu.size):
        if not (np.isfinite(mu[j]) and lo_mu[j] <= mu[j] <= hi_mu[j]):
            return OUTSIDE_D
    th = np.empty(mu.size + 1)
    th[0] = 1.0
    th[1:] = mu
    dims = _i(ib, meta, DIMS)
    k = dims[0] + 1
    nq = _f(fb, meta, SG).size * meta[S_A, 1]
    status, nrm, w, gap, sphi, mphi, seg = pair_points(th, fb, ib, meta, nq, k)
    if status != OK:
        return status
    c, g = magic_values(fb, ib, meta, nrm, w, gap, sphi, mphi, seg, dims[1])
    a_terms = _f2(fb, meta, A_TERMS)
    n = meta[A_TERMS, 2]
    m = meta[W_B, 2]
    _combine(th, a_terms, qp[:n * n])
    f = np.empty(n)
    _combine(th, _f2(fb, meta, F_TERMS), f)
    b = qp[n * n + n:n * n + n + m * n]
    _combine(c, _f2(fb, meta, W_B), b)  # sum_j theta_j T_B[j], theta = B^-1 c
    gn = np.empty(m)
    _combine(g, _f2(fb, meta, W_G), gn)
    _scale(f, b.reshape((m, n)), gn, qp[n * n:], n, m)
    return OK


@njit(cache=True)
def _scale(f, b, gn, out, n, m):
    """Row and load scaling of :func:`rbbench.rb.mixed_model._solve_daqp` into ``out`` =
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

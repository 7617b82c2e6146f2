"""numba kernel of the hyper-reduced wedge model's online solve
(:mod:`rbbench.rb.friction.wedge.compiled`).

One call of :func:`wedge_online` does for one mu what
:meth:`rbbench.rb.friction.wedge.hyper.WedgeHyperModel.solve` does on the Python path:

1. the pairing of the magic rows' quadrature points in their master windows and the magic
   entries of ``Bn(mu) Z``, ``Bt(mu) Z``, the magic rows of ``Gn(mu)`` and the slip rows
   ``(Bt(mu) Z)[I]`` (the shared kernels :func:`rbbench.rb.kernels.pairing.pair_points`,
   :func:`~rbbench.rb.kernels.pairing.jump_values` along the normals and the tangents,
   :func:`~rbbench.rb.kernels.pairing.gap_values`);
2. the EIM coefficient solves folded offline into the terms and the reduced ``B``, ``g``,
   ``A_N``, ``F_N`` (:func:`rbbench.rb.kernels.layout.combine_terms`), written in a common
   eigenbasis ``V`` of ``A_N``'s affine terms, ``A_N(mu) = V^-T diag(s(mu)) V^-1``
   (:func:`rbbench.rb.kernels.plan.eigenbasis`), so that the condensation on ``c``
   needs no factorisation (:func:`rbbench.rb.kernels.nnls.condense`)::

       D = Bv diag(1/s) Bv^T,  q = g - Bv (Fv / s),  a = V (Fv - Bv^T c) / s,

   ``Bv = B V``, ``Fv = V^T F_N``; the slip rows come out in the same coordinates (their
   entries are linear in the basis: the plan holds ``Z V`` for them), so the nodal
   tangential gap is ``t0 + T c`` with ``t0 = -Rv (Fv / s)``, ``T = Rv diag(1/s) Bv^T``
   (applied as two products, ``T`` never formed);
3. De Saxce's fixed point (:func:`rbbench.rb.friction.wedge.model.desaxce_coulomb`, the same
   stop rule and tolerance): each bound-constrained QP ``min 1/2 c^T D c + g^T c``,
   ``c >= 0``, by Lawson and Hanson's active set in Bro and de Jong's Gram form
   (:func:`rbbench.rb.kernels.nnls.nnls_gram`, warm-started from the previous
   iterate as daqp is on the Python path), on the Jacobi-scaled problem (daqp's scaling),
   accepted when its natural residual is below :data:`TOL`; the first iterate is the
   nearest training solution.

Any deviation (mu outside D, a point leaving its window, ``A_N(mu)`` not positive definite,
a QP the active set does not solve to :data:`TOL`, non-finite numbers) returns a status
other than :data:`OK` and the caller reruns the Python path. The module imports numba at
the top: import it only when numba is installed.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbbench.rb.kernels import layout as K
from rbbench.rb.kernels import nnls as NN
from rbbench.rb.kernels import pairing as KP
from rbbench.runtime.numba_cache import stale_cache_dropper, use_user_cache

use_user_cache()  # before any @njit(cache=True): the cache lives in the user's cache dir

#: the wedge arrays of the plan (a second buffer beside the frictionless plan's), in order
FLOATS = ("t_hat", "slave_t", "vals_t", "slave_s", "vals_s", "z_s", "pq_t", "mus_train",
          "x_train", "settings", "w_u")
#: ``sizes = [M_s, max_iter, k]``, ``k`` the rank of the compressed EIM map (``w_u``,
#: E x k: ``B = (c^T w_u) w_b``; 0: ``B = c^T w_b``)
INTS = ("pts_t", "cols_t", "order_t", "pts_s", "sizes")
(T_HAT, SLAVE_T, VALS_T, SLAVE_S, VALS_S, Z_S, PQ_T, MUS_TRAIN, X_TRAIN, SETTINGS,
 W_U) = range(11)
(PTS_T, COLS_T, ORDER_T, PTS_S, SIZES) = range(11, 16)

#: statuses: :mod:`rbbench.rb.kernels.layout`'s ``OK``, ``OUTSIDE_D``, ``NO_HIT``, and these
OK = K.OK
NOT_SPD, QP_FAILED, NOT_FINITE = 3, 4, 5
#: stop reasons of the fixed point (:func:`rbbench.rb.friction.qp.increment_stop`)
STOPS = ("converged", "max_iterations", "diverged")
#: warm start: the nearest training solution, the ``x0`` given, none (``c = 0``)
NEAREST, GIVEN, COLD = 0, 1, 2
#: the natural residual each QP must reach, and the passive-set solves it may take
TOL, QP_MAX_ITER = 1e-10, 500


@njit(cache=True)
def _master_rows(row, zs, dofs, cm, k):
    """``row -= sum_a cm[a] zs[dofs[a]]`` over the ``2 k`` dofs of one master facet, one
    pass over the columns (a three-node facet unrolled)."""
    n = row.size
    if k == 3:
        z0, z1, z2, z3, z4, z5 = (zs[dofs[0]], zs[dofs[1]], zs[dofs[2]], zs[dofs[3]],
                                  zs[dofs[4]], zs[dofs[5]])
        c0, c1, c2, c3, c4, c5 = cm[0], cm[1], cm[2], cm[3], cm[4], cm[5]
        for j in range(n):
            row[j] -= (c0 * z0[j] + c1 * z1[j] + c2 * z2[j] + c3 * z3[j] + c4 * z4[j]
                       + c5 * z5[j])
    else:
        for a in range(2 * k):
            ca, za = cm[a], zs[dofs[a]]
            for j in range(n):
                row[j] -= ca * za[j]


@njit(cache=True)
def jump_rows(s, dh, wh, zs, m_dofs, has_master, slave_rows, vals, pts, mphi, seg, out):
    """Whole rows ``out[r] = (J(mu) Z)[row r]`` (the slip rows), as
    :func:`rbbench.rb.kernels.pairing.jump_values` does entry by entry but a row at a time:
    ``s slave_rows[r]`` the slave part (its points' terms summed offline,
    :func:`rbbench.rb.friction.wedge.compiled.slave_row_sums`), then the master part, the
    coefficients of consecutive points on the same master facet summed before one pass over
    the columns; ``zs`` the basis on the master dofs of the windows, one contiguous row per
    dof (``out`` zeroed by the caller)."""
    k, n = mphi.shape[1], out.shape[1]
    cm = np.zeros(2 * k)
    for r in range(pts.shape[0]):
        row = out[r]
        for j in range(n):
            row[j] += s * slave_rows[r, j]
        if not has_master:
            continue
        open_facet = -1
        for p in range(pts.shape[1]):
            coef = vals[r, p]
            if coef == 0.0:  # padding
                continue
            q = pts[r, p]
            f = seg[q]
            if f != open_facet:
                if open_facet >= 0:
                    _master_rows(row, zs, m_dofs[open_facet], cm, k)
                open_facet = f
                cm[:] = 0.0
            coef *= s * wh[q]
            for a in range(k):
                cm[2 * a] += coef * mphi[q, a] * dh[q, 0]
                cm[2 * a + 1] += coef * mphi[q, a] * dh[q, 1]
        if open_facet >= 0:
            _master_rows(row, zs, m_dofs[open_facet], cm, k)


@njit(cache=True)
def _nearest(mu, mus, xs, c):
    """``c = xs[j]`` for the row ``j`` of ``mus`` nearest to ``mu`` (Euclidean, the first
    on ties: :func:`rbbench.rb.friction.qp.nearest_training`)."""
    best, j = np.inf, 0
    for i in range(mus.shape[0]):
        d = 0.0
        for k in range(mu.size):
            d += (mus[i, k] - mu[k]) ** 2
        if d < best:
            best, j = d, i
    c[:] = xs[j]


@njit(cache=True)
def _slip(t0, rv_t, kt_t, c, y, slip):
    """``slip = |t0 + Rv (Kt c)|`` from the transposes ``rv_t = Rv^T`` (n x ms) and
    ``kt_t = Kt^T`` (r x n) (``y``: work array of A_N's size): the slip rows applied to the
    displacement's ``c`` part as two sums of rows (vectorised, the zero entries of ``c``
    skipped) instead of forming ``Rv Kt`` (ms x n x r) once per solve."""
    y[:] = 0.0
    for i in range(c.size):
        ci = c[i]
        if ci != 0.0:
            for k in range(y.size):
                y[k] += ci * kt_t[i, k]
    slip[:] = t0
    for k in range(y.size):
        yk = y[k]
        for j in range(slip.size):
            slip[j] += yk * rv_t[k, j]
    for j in range(slip.size):
        slip[j] = abs(slip[j])


@njit(cache=True)
def _linear_term(q, pq_t, slip, g):
    """``g = q + P slip`` from ``pq_t = P^T`` (ms x r), as a sum of rows."""
    g[:] = q
    for j in range(slip.size):
        sj = slip[j]
        for i in range(g.size):
            g[i] += sj * pq_t[j, i]


@njit(cache=True)
def _qp(ds, sc, g, c, warm, y):
    """``c = argmin_{c >= 0} 1/2 c^T D c + g^T c`` from the scaled ``ds = S D S``
    (``S = diag(sc)``): ``c = S y |S g|_inf``, ``y`` the NNLS solution of the unit-scaled
    problem, warm-started from ``c`` when ``warm``. Returns ``(ok, passive-set solves)``."""
    r = g.size
    gs = np.empty(r)
    gm = 0.0
    for i in range(r):
        gs[i] = sc[i] * g[i]
        gm = max(gm, abs(gs[i]))
    if gm == 0.0:
        c[:] = 0.0
        return True, 0
    for i in range(r):
        gs[i] /= gm
        y[i] = c[i] / (sc[i] * gm) if warm else 0.0
    status, it = NN.nnls_gram(ds, gs, y, QP_MAX_ITER, warm)
    if status != NN.NNLS_OK or not NN.natural_residual(ds, gs, y) <= TOL:
        return False, it
    for i in range(r):
        c[i] = sc[i] * y[i] * gm
    return True, it


@njit(cache=True)
def _reduced_arrays(th, fb, ib, meta, fw, iw, mw, n, r, ms, n_map):
    """Steps 1 and 2 of :func:`wedge_online`: the pairing, the magic entries (normal,
    tangential), Gn's rows and the slip rows, then ``B`` (n x r, in A_N's eigenbasis) and
    ``gn`` (r): ``(status, B, gn, slip rows (ms x n))``."""
    bt, gn, rv = np.empty(n * r), np.empty(r), np.zeros((ms, n))
    nq = meta[K.X_HAT, 1]
    dims = K.flat_ints(ib, meta, K.DIMS)
    w, gap = np.empty(nq), np.empty(nq)
    mphi, seg = np.zeros((nq, dims[0] + 1)), np.zeros(nq, dtype=np.int64)
    status, s = KP.pair_points(th, fb, ib, meta, w, gap, mphi, seg)
    if status != K.OK:
        return status, bt.reshape((n, r)), gn, rv
    mn, mt = meta[K.PTS_B, 1], mw[PTS_T, 1]
    wh, zt = K.flat_floats(fb, meta, K.W_HAT), K.float_rows(fb, meta, K.ZT_M)
    m_dofs = K.int_rows(ib, meta, K.M_DOFS)
    nh, tangent = K.float_rows(fb, meta, K.N_HAT), K.float_rows(fw, mw, T_HAT)
    vals = np.empty(mn + mt)
    KP.jump_values(s, nh, wh, zt, m_dofs, dims[1], K.float_rows(fb, meta, K.SLAVE_B),
                   K.float_rows(fb, meta, K.VALS_B), K.int_rows(ib, meta, K.PTS_B),
                   K.flat_ints(ib, meta, K.COLS_B), K.flat_ints(ib, meta, K.ORDER_B), mphi,
                   seg, vals[:mn])
    KP.jump_values(s, tangent, wh, zt, m_dofs, dims[1], K.float_rows(fw, mw, SLAVE_T),
                   K.float_rows(fw, mw, VALS_T), K.int_rows(iw, mw, PTS_T),
                   K.flat_ints(iw, mw, COLS_T), K.flat_ints(iw, mw, ORDER_T), mphi, seg,
                   vals[mn:])
    gvals = np.empty(meta[K.PTS_G, 1])
    KP.gap_values(w, gap, K.float_rows(fb, meta, K.VALS_G), K.int_rows(ib, meta, K.PTS_G),
                  gvals)
    jump_rows(s, tangent, wh, K.float_rows(fw, mw, Z_S), m_dofs, dims[1],
              K.float_rows(fw, mw, SLAVE_S),
              K.float_rows(fw, mw, VALS_S), K.int_rows(iw, mw, PTS_S), mphi, seg, rv)
    if n_map > 0:  # the compressed map: B = (c^T U) W_k
        wu = K.float_rows(fw, mw, W_U)
        y = np.zeros(n_map)
        for e in range(vals.size):
            ce = vals[e]
            for j in range(y.size):
                y[j] += ce * wu[e, j]
        K.combine_terms(y, K.float_rows(fb, meta, K.W_B), bt)
    else:
        K.combine_terms(vals, K.float_rows(fb, meta, K.W_B), bt)
    K.combine_terms(gvals, K.float_rows(fb, meta, K.W_G), gn)
    return K.OK, bt.reshape((n, r)), gn, rv


@njit(cache=True)
def _condense_wedge(bt2, ft, sd, gn, rv, d, q, a0, kt_t, t0, sc, ds):
    """Step 2 of :func:`wedge_online`: the condensation on ``c`` (``d``, ``q``), ``u = a0 -
    Kt c`` in the eigenbasis (written as ``kt_t = Kt^T``, r x n), the slip rows' constant
    part ``t0 = -Rv a0`` (their ``c`` part is applied by :func:`_slip`) and the
    Jacobi-scaled ``ds`` (``sc`` its scaling); False when ``d`` has a non-positive
    diagonal."""
    n, r = bt2.shape
    NN.condense(bt2, ft, sd, d, q, gn)
    for k in range(n):
        a0[k] = ft[k] / sd[k]
        for i in range(r):
            kt_t[i, k] = bt2[k, i] / sd[k]
    for j in range(t0.size):
        v = 0.0
        for k in range(n):
            v -= rv[j, k] * a0[k]
        t0[j] = v
    for i in range(r):
        if not d[i, i] > 0.0:
            return False
        sc[i] = 1.0 / np.sqrt(d[i, i])
    for i in range(r):
        for j in range(r):
            ds[i, j] = sc[i] * d[i, j] * sc[j]
    return True


@njit(cache=True)
def _desaxce(ds, sc, q, pq_t, t0, rv, kt_t, c, tol, warm, hist):
    """Step 3 of :func:`wedge_online`: De Saxce's fixed point from ``c`` (updated in place),
    the stop rule of :func:`rbbench.rb.friction.wedge.model.desaxce_coulomb`:
    ``(qp ok, iterations, stop index, qp iterations)``."""
    r, ms = c.size, t0.size
    slip, g, g_new, y = np.empty(ms), np.empty(r), np.empty(r), np.empty(r)
    work, rv_t = np.empty(kt_t.shape[1]), rv.T.copy()
    _slip(t0, rv_t, kt_t, c, work, slip)
    _linear_term(q, pq_t, slip, g)
    it, inner, stop, low = 0, 0, 1, np.inf
    while it < hist.size:
        it += 1
        ok, k_it = _qp(ds, sc, g, c, warm or it > 1, y)
        inner += k_it
        if not ok:
            return False, it, 0, inner
        _slip(t0, rv_t, kt_t, c, work, slip)
        _linear_term(q, pq_t, slip, g_new)
        num, den = 0.0, 0.0
        for i in range(r):
            num = max(num, abs(g_new[i] - g[i]))
            den = max(den, abs(g_new[i]))
            g[i] = g_new[i]
        h = num / max(den, np.finfo(np.float64).tiny)
        hist[it - 1] = h
        low = min(low, h)
        if h <= tol:
            return True, it, 0, inner
        if h > 1e6 * low:
            return True, it, 2, inner
    return True, it, stop, inner


@njit(cache=True)
def wedge_online(mu, fb, ib, meta, fw, iw, mw, x0, start):
    """One online solve at ``mu`` (module docstring): ``(status, iterations, stop,
    qp_iterations, a, c, history)``, ``stop`` an index of :data:`STOPS`, ``history`` the
    relative increments of the linear term; ``start`` one of :data:`NEAREST`,
    :data:`GIVEN` (``x0``), :data:`COLD`.

    ``fb, ib, meta``: the frictionless plan (:mod:`rbbench.rb.kernels.layout`) with the normal
    magic entries in its ``b`` arrays, ``w_b`` the combined normal and tangential EIM maps
    (``(W_e V)^T``), ``w_g`` Gn's, ``f_terms``, ``vt``, ``lam_a`` those of
    :func:`rbbench.rb.mixed.dual_kernels.online_nnls`; ``fw, iw, mw``: the wedge arrays
    (:data:`FLOATS`, :data:`INTS`)."""
    sizes = K.flat_ints(iw, mw, SIZES)
    n, r, ms, max_iter = meta[K.VT, 1], meta[K.W_G, 2], sizes[0], sizes[1]
    a, c = np.zeros(n), np.zeros(r)
    hist = np.zeros(max_iter)
    status, th = K.theta(mu, fb, meta)
    if status != K.OK:
        return status, 0, 0, 0, a, c, hist[:0]
    # 1. magic entries, Gn rows, slip rows; 2. reduced arrays and condensation
    status, bt2, gn, rv = _reduced_arrays(th, fb, ib, meta, fw, iw, mw, n, r, ms, sizes[2])
    if status != K.OK:
        return status, 0, 0, 0, a, c, hist[:0]
    sd, ft = np.empty(n), np.empty(n)
    K.combine_terms(th, K.float_rows(fb, meta, K.LAM_A), sd)
    K.combine_terms(th, K.float_rows(fb, meta, K.F_TERMS), ft)
    for k in range(n):
        if not sd[k] > 0.0:  # A_N(mu) not positive definite: the reference decides
            return NOT_SPD, 0, 0, 0, a, c, hist[:0]
    d, q, a0, kt_t = np.empty((r, r)), np.empty(r), np.empty(n), np.empty((r, n))
    t0, sc, ds = np.empty(ms), np.empty(r), np.empty((r, r))
    if not _condense_wedge(bt2, ft, sd, gn, rv, d, q, a0, kt_t, t0, sc, ds):
        return NOT_SPD, 0, 0, 0, a, c, hist[:0]
    # 3. De Saxce's fixed point
    if start == NEAREST:
        _nearest(mu, K.float_rows(fw, mw, MUS_TRAIN), K.float_rows(fw, mw, X_TRAIN), c)
    elif start == GIVEN:
        c[:] = x0
    for i in range(r):
        c[i] = max(c[i], 0.0)
    ok, it, stop, inner = _desaxce(ds, sc, q, K.float_rows(fw, mw, PQ_T), t0, rv, kt_t, c,
                                   K.flat_floats(fw, mw, SETTINGS)[0], start != COLD, hist)
    if not ok:
        return QP_FAILED, it, 0, inner, a, c, hist[:it]
    av = a0.copy()
    for k in range(n):
        for i in range(r):
            av[k] -= kt_t[i, k] * c[i]
    vt = K.float_rows(fb, meta, K.VT)
    for k in range(n):
        for j in range(n):
            a[j] += vt[k, j] * av[k]
    for j in range(n):
        if not np.isfinite(a[j]):
            return NOT_FINITE, it, stop, inner, a, c, hist[:it]
    return K.OK, it, stop, inner, a, c, hist[:it]


#: the modules whose kernels :func:`wedge_online` compiles in (numba's cache checks only
#: this file)
DEPENDENCIES = (K.__file__, KP.__file__, NN.__file__)


# forget this module's cached kernels made against other dependencies' contents
drop_stale_cache = stale_cache_dropper(__name__, DEPENDENCIES)
drop_stale_cache()

"""numba kernels of the frictionless model's compiled online stage
(:mod:`rbbench.rb.mixed.compiled`).

One call of :func:`online_qp` does, for one mu, what the Python reference does in about 500
Python calls: the pairing of the EIM magic rows' quadrature points in their master windows
and the magic entries of ``C(mu) = B(mu) Z`` and the magic rows of ``G(mu)`` (the shared
kernels :func:`rbbench.rb.kernels.pairing.pair_points`, :func:`magic_values`; in 3D
:func:`rbbench.rb.kernels.surface_pairing.surface_magic_values`), the EIM
coefficient solves, the reduced ``B_N``, ``G_N``, ``A_N``, ``F_N``
(:class:`rbbench.rb.hyper.contact_eim.ContactEIM`) and the scaled QP data of
:func:`rbbench.rb.mixed.model._solve_daqp`. The formulas are the reference's, written per
point; only the summation order differs (round-off). The arguments are a packed plan
(:mod:`rbbench.rb.kernels.layout`). The module imports numba at the top: import it only
when numba is installed.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbbench.rb.kernels import layout, pairing, surface_pairing
from rbbench.rb.kernels.layout import (
    A_TERMS,
    COLS_B,
    DIMS,
    F_TERMS,
    M_DOFS,
    N_HAT,
    OK,
    ORDER_B,
    PTS_B,
    PTS_G,
    SLAVE_B,
    VALS_B,
    VALS_G,
    W_B,
    W_G,
    W_HAT,
    X_HAT,
    ZT_M,
    coefficients,
    combine_terms,
    flat_floats,
    flat_ints,
    float_rows,
    int_rows,
    is_surface,
    theta,
)
from rbbench.rb.kernels.pairing import gap_values, jump_values, pair_points
from rbbench.rb.kernels.surface_pairing import surface_magic_values
from rbbench.runtime.numba_cache import stale_cache_dropper, use_user_cache

use_user_cache()  # before any @njit(cache=True): the cache lives in the user's cache dir


@njit(cache=True)
def magic_values(fb, ib, meta, s, w, gap, mphi, seg, c, g):
    """The magic entries ``c`` of ``C(mu)`` and magic rows ``g`` of ``G(mu)``
    (:meth:`~rbbench.rb.hyper.contact_eim.RowEvaluator.entries`), written in place: the
    normal jump of the plan's entries (:func:`jump_values` along ``n_hat``) and the
    weighted gaps of its rows (:func:`gap_values`)."""
    jump_values(s, float_rows(fb, meta, N_HAT), flat_floats(fb, meta, W_HAT),
                float_rows(fb, meta, ZT_M), int_rows(ib, meta, M_DOFS),
                flat_ints(ib, meta, DIMS)[1], float_rows(fb, meta, SLAVE_B),
                float_rows(fb, meta, VALS_B), int_rows(ib, meta, PTS_B),
                flat_ints(ib, meta, COLS_B), flat_ints(ib, meta, ORDER_B), mphi, seg, c)
    gap_values(w, gap, float_rows(fb, meta, VALS_G), int_rows(ib, meta, PTS_G), g)


@njit(cache=True)
def constraint_rows(th, fb, ib, meta, b, gn):
    """The reduced constraint at ``th``: ``b = sum_e c_e W_B[e]`` (flat, in the layout of
    the plan's ``w_b``) and ``gn = sum_r g_r W_G[r]`` from the pairing and the magic
    entries ``c``, rows ``g`` (:func:`pair_points`, :func:`magic_values`; on triangulated
    surfaces :func:`~rbbench.rb.kernels.surface_pairing.surface_magic_values`; an exact
    affine constraint: ``c = g`` = the terms' coefficients,
    :func:`~rbbench.rb.kernels.layout.coefficients`). Returns a status
    (:data:`~rbbench.rb.kernels.layout.NO_HIT`: a point left its master window, or a
    degenerate map)."""
    if flat_ints(ib, meta, DIMS)[2]:  # exact affine: B_N = sum_k theta_k B_k, G_N likewise
        coef = coefficients(th, meta)
        combine_terms(coef, float_rows(fb, meta, W_B), b)
        combine_terms(coef, float_rows(fb, meta, W_G), gn)
        return OK
    if is_surface(ib, meta):  # 3D: triangulated surfaces
        c, g = np.empty(meta[PTS_B, 1]), np.empty(meta[PTS_G, 1])
        status = surface_magic_values(th, fb, ib, meta, c, g)
        if status != OK:
            return status
        combine_terms(c, float_rows(fb, meta, W_B), b)
        combine_terms(g, float_rows(fb, meta, W_G), gn)
        return OK
    nq = meta[X_HAT, 1]
    w, gap = np.empty(nq), np.empty(nq)
    mphi, seg = np.zeros((nq, flat_ints(ib, meta, DIMS)[0] + 1)), np.zeros(nq, dtype=np.int64)
    status, s = pair_points(th, fb, ib, meta, w, gap, mphi, seg)
    if status != OK:
        return status
    c, g = np.empty(meta[PTS_B, 1]), np.empty(meta[PTS_G, 1])
    magic_values(fb, ib, meta, s, w, gap, mphi, seg, c, g)
    combine_terms(c, float_rows(fb, meta, W_B), b)  # sum_j theta_j T_B[j], theta = B^-1 c
    combine_terms(g, float_rows(fb, meta, W_G), gn)
    return OK


@njit(cache=True)
def online_qp(mu, fb, ib, meta, qp):
    """The scaled QP data of one online solve at ``mu``, written into ``qp``.

    ``qp`` holds ``[H (n x n), f (n), A (m x n), b_upper (m), row norms of B_N (m), |F_N|]``
    with ``H = A_N``, ``f = -F_N / |F_N|``, ``A = B_N / rows``, ``b_upper = G_N / rows /
    |F_N|`` (:func:`rbbench.rb.mixed.model._solve_daqp`). Returns a status
    (:mod:`rbbench.rb.kernels.layout`): ``OK``, ``OUTSIDE_D`` (mu is not in D: wrong size,
    not finite or outside the bounds) or ``NO_HIT`` (a point left its master window, or a
    degenerate map).
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
    coef = coefficients(th, meta)
    combine_terms(coef, float_rows(fb, meta, A_TERMS), qp[:n * n])
    f = np.empty(n)
    combine_terms(coef, float_rows(fb, meta, F_TERMS), f)
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


#: the modules whose kernels this one's compile in (numba's cache checks only this file)
DEPENDENCIES = (layout.__file__, pairing.__file__, surface_pairing.__file__)


# forget this module's cached kernels made against other dependencies' contents
drop_stale_cache = stale_cache_dropper(__name__, DEPENDENCIES)
drop_stale_cache()

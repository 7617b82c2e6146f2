"""The packed plan of the compiled online kernels: its layout and compiled accessors.

A plan's arrays are packed into two flat buffers (``fb`` float64, ``ib`` int64) and a
table ``meta`` (one row ``[offset, s0, s1, s2]`` per array, in the order of :data:`FLOATS`
then :data:`INTS`; :func:`rbbench.rb.kernels.plan.pack`): a numba call costs ~0.2 us per
array argument, so five arguments instead of thirty. A kernel reads array ``k`` back with
:func:`flat_floats`, :func:`float_rows`, :func:`flat_ints`, :func:`int_rows`. Also here:
``theta = [1, mu]`` on the box D (:func:`theta`), the coefficients of the affine terms
(:func:`coefficients`: ``theta`` or the powers of one parameter) and the affine or EIM
combination of terms (:func:`combine_terms`). The module imports numba at the top: import
it only when numba is installed.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbbench.runtime.numba_cache import use_user_cache

use_user_cache()  # before any @njit(cache=True): the cache lives in the user's cache dir

#: float arrays of the plan, in buffer order (shapes: see
#: :func:`rbbench.rb.mixed.compiled.plan_arrays`)
FLOATS = ("mu_lo", "mu_hi", "s_scale", "s_shift", "m_scale", "m_shift", "x_hat", "n_hat",
          "w_hat", "m_a", "m_b", "m_v", "zt_m", "slave_b", "vals_b", "vals_g", "w_b", "w_g",
          "a_terms", "f_terms", "vt", "lam_a", "w_axis", "w_key", "m_geo", "t_mu")
#: int arrays of the plan: ``dims = [degree, has_master, affine(, space)]`` (``affine``: an
#: exact affine constraint, whose terms are ``w_b``, ``w_g``: no pairing; ``space``: 3 for
#: triangulated contact surfaces (:mod:`rbbench.rb.kernels.surface_pairing`), 2 or absent
#: for facet chains). ``m_tri``, ``w_ptr``, ``w_tri`` (and the floats ``w_axis``,
#: ``w_key``, ``m_geo``): the 3D master window; ``t_ptr``, ``t_tri`` (and ``t_mu``): its
#: table of the triangle hit against the parameter (one-entry placeholders in 2D plans,
#: :func:`rbbench.rb.kernels.plan.master_plan`)
INTS = ("dims", "mono", "m_dofs", "lo", "hi", "pts_b", "cols_b", "order_b", "pts_g",
        "m_tri", "w_ptr", "w_tri", "t_ptr", "t_tri")

(MU_LO, MU_HI, S_SCALE, S_SHIFT, M_SCALE, M_SHIFT, X_HAT, N_HAT, W_HAT, M_A, M_B, M_V, ZT_M,
 SLAVE_B, VALS_B, VALS_G, W_B, W_G, A_TERMS, F_TERMS, VT, LAM_A, W_AXIS, W_KEY, M_GEO,
 T_MU) = range(26)
(DIMS, MONO, M_DOFS, LO, HI, PTS_B, COLS_B, ORDER_B, PTS_G, M_TRI, W_PTR, W_TRI, T_PTR,
 T_TRI) = range(26, 40)

#: statuses of the kernels on a plan (anything but OK: the caller reruns the Python path,
#: which raises the reference's error)
OK, OUTSIDE_D, NO_HIT = 0, 1, 2


@njit(cache=True)
def flat_floats(fb, meta, k):
    """Float array ``k`` of the plan, flat."""
    o = meta[k, 0]
    return fb[o:o + meta[k, 1] * meta[k, 2] * meta[k, 3]]


@njit(cache=True)
def float_rows(fb, meta, k):
    """Float array ``k`` of the plan as rows (first axis kept, the others flattened)."""
    return flat_floats(fb, meta, k).reshape((meta[k, 1], meta[k, 2] * meta[k, 3]))


@njit(cache=True)
def flat_ints(ib, meta, k):
    """Int array ``k`` of the plan, flat."""
    o = meta[k, 0]
    return ib[o:o + meta[k, 1] * meta[k, 2] * meta[k, 3]]


@njit(cache=True)
def int_rows(ib, meta, k):
    """Int array ``k`` of the plan as rows (first axis kept, the others flattened)."""
    return flat_ints(ib, meta, k).reshape((meta[k, 1], meta[k, 2] * meta[k, 3]))


@njit(cache=True)
def _add_block(coef, terms, out, k, b):
    """``out += sum_{k <= j < k + b} coef[j] terms[j]`` in one pass over ``out``, each
    entry summed in the order of j (as one pass per term would)."""
    for i in range(out.size):
        acc = out[i]
        for j in range(k, k + b):
            acc += coef[j] * terms[j, i]
        out[i] = acc


@njit(cache=True)
def combine_terms(coef, terms, out):
    """``out = sum_k coef[k] terms[k]`` (terms flattened per k), summed in the order of k
    as one pass per term would (the same round-off), but sixteen, then eight terms per pass
    over ``out``: the sum is bound by reading the terms (81 x 1200 doubles: 14 us one term
    per pass, 9.4 us eight, measured warm; 322 x 2800 side by side: 99 us eight, 93 us
    sixteen, bit-identical)."""
    out[:] = 0.0
    kk = coef.size
    k = 0
    while k + 16 <= kk:
        _add_block(coef, terms, out, k, 16)
        k += 16
    while k + 8 <= kk:
        _add_block(coef, terms, out, k, 8)
        k += 8
    for j in range(k, kk):
        cj = coef[j]
        for i in range(out.size):
            out[i] += cj * terms[j, i]


@njit(cache=True)
def is_surface(ib, meta):
    """Whether the plan pairs triangulated 3D contact surfaces (``dims[3] == 3``)."""
    dims = flat_ints(ib, meta, DIMS)
    return dims.size > 3 and dims[3] == 3


@njit(cache=True)
def coefficients(th, meta):
    """The coefficients of the affine terms (``a_terms``, ``f_terms``, ``lam_a``, and the
    terms of an exact affine constraint) at ``th = [1, mu]`` (:func:`theta`): ``th``
    itself when there are ``p + 1`` terms (:class:`~rbbench.rb.algorithms.affine.LinearInMu`),
    else, one parameter and K terms, ``[1, mu, ..., mu^(K-1)]``
    (:class:`~rbbench.rb.algorithms.affine.PolynomialInMu`: a 3D similarity map is cubic).
    The maps of the bodies (``s_scale``, ``m_shift``, ...) always take ``th``."""
    k = meta[A_TERMS, 1]
    if k == th.size:
        return th
    out = np.empty(k)
    out[0] = 1.0
    for j in range(1, k):
        out[j] = out[j - 1] * th[1]
    return out


@njit(cache=True)
def theta(mu, fb, meta):
    """``(status, th)``: ``th = [1, mu]`` when mu is in D (:data:`OK`), else
    :data:`OUTSIDE_D` (wrong size, not finite or outside the bounds)."""
    lo_mu, hi_mu = flat_floats(fb, meta, MU_LO), flat_floats(fb, meta, MU_HI)
    th = np.empty(mu.size + 1)
    if mu.size != lo_mu.size:
        return OUTSIDE_D, th
    for j in range(mu.size):
        if not (np.isfinite(mu[j]) and lo_mu[j] <= mu[j] <= hi_mu[j]):
            return OUTSIDE_D, th
    th[0] = 1.0
    th[1:] = mu
    return OK, th


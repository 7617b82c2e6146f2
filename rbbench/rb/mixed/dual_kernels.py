"""numba kernel of the condensed online solve (``method = "nnls"``, ``compiled_online``).

One call of :func:`online_nnls` condenses the reduced saddle point on the cone coefficients
through a common eigenbasis of ``A_N``'s affine terms and solves ``LCP(q, D)`` by
Lawson-Hanson's active set (the shared kernels :func:`rbbench.rb.kernels.nnls.condense`,
:func:`rbbench.rb.kernels.nnls.nnls_gram`, whose module docstring has the formulas), after
the pairing and magic entries of :func:`rbbench.rb.mixed.kernels.constraint_rows`. Any
numerical trouble (a dependent row, too many steps, a natural residual above the tolerance)
returns a failure status and the caller reruns the Python path. The module imports numba at
the top: import it only when numba is installed.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbbench.rb.kernels import layout as L
from rbbench.rb.kernels import nnls, pairing, surface_pairing
from rbbench.rb.kernels.nnls import (
    NNLS_DEPENDENT,
    NNLS_OK,
    NNLS_RESIDUAL,
    condense,
    natural_residual,
    nnls_gram,
)
from rbbench.rb.mixed import kernels as K
from rbbench.runtime.numba_cache import stale_cache_dropper, use_user_cache

use_user_cache()  # before any @njit(cache=True): the cache lives in the user's cache dir

#: passive-set solves before :func:`online_nnls` gives up (the reference then decides) and
#: the natural residual it must reach (the PDAS tolerance of :func:`rbbench.hf.solvers.lcp.pdas`)
MAX_ITER, TOL = 200, 1e-10


@njit(cache=True)
def online_nnls(mu, fb, ib, meta):
    """One condensed online solve at ``mu`` (module docstring): ``(status, iterations,
    min(alpha) / max(alpha), c, alpha)``.

    The plan's ``w_b`` holds ``(W_B[e] V)^T`` (n x R per term), ``f_terms`` ``V^T F_k``,
    ``vt`` ``V^T`` and ``lam_a`` the diagonals ``diag(V^T A_k V)``. ``D`` and ``q`` are
    scaled by ``max diag D`` and ``max |q|`` before :func:`nnls_gram` (a relative tolerance
    then means the same on every scene). The status is a :mod:`rbbench.rb.kernels.layout` one,
    :data:`NNLS_OK`, another NNLS status (at most :data:`MAX_ITER` passive-set solves), or
    :data:`NNLS_RESIDUAL` when the natural residual exceeds :data:`TOL`."""
    status, th = L.theta(mu, fb, meta)
    n, r = meta[L.VT, 1], meta[L.W_G, 2]
    c, alpha = np.zeros(n), np.zeros(r)
    if status != L.OK:
        return status, 0, 0.0, c, alpha
    bt, gn = np.empty(n * r), np.empty(r)
    status = K.constraint_rows(th, fb, ib, meta, bt, gn)
    if status != L.OK:
        return status, 0, 0.0, c, alpha
    bt2 = bt.reshape((n, r))
    s, ft = np.empty(n), np.empty(n)
    coef = L.coefficients(th, meta)
    L.combine_terms(coef, L.float_rows(fb, meta, L.LAM_A), s)
    L.combine_terms(coef, L.float_rows(fb, meta, L.F_TERMS), ft)
    for k in range(n):
        if not s[k] > 0.0:  # A_N(mu) not positive definite: the reference decides
            return NNLS_DEPENDENT, 0, 0.0, c, alpha
    d, q = np.empty((r, r)), np.empty(r)
    condense(bt2, ft, s, d, q, gn)
    dm, qm = 0.0, 0.0
    for i in range(r):
        dm = max(dm, d[i, i])
        qm = max(qm, abs(q[i]))
    it = 0
    if dm == 0.0 and qm > 0.0:  # B_N = 0: bounded only if q >= 0
        for i in range(r):
            if q[i] < 0.0:
                return NNLS_DEPENDENT, 0, 0.0, c, alpha
    if qm > 0.0 and dm > 0.0:
        ds, qs = d / dm, q / qm
        status, it = nnls_gram(ds, qs, alpha, MAX_ITER)
        if status != NNLS_OK:
            return status, it, 0.0, c, alpha
        if not natural_residual(ds, qs, alpha) <= TOL:
            return NNLS_RESIDUAL, it, 0.0, c, alpha
        alpha *= qm / dm
    y = np.empty(n)
    for k in range(n):
        v = ft[k]
        for i in range(r):
            v -= bt2[k, i] * alpha[i]
        y[k] = v / s[k]
    vt = L.float_rows(fb, meta, L.VT)
    for k in range(n):
        yk = y[k]
        row = vt[k]
        for a in range(n):
            c[a] += row[a] * yk
    lo, top = 0.0, 0.0
    for i in range(r):
        lo, top = min(lo, alpha[i]), max(top, alpha[i])
    return NNLS_OK, it, (lo / top if top > 0 else 0.0), c, alpha


#: the modules whose kernels :func:`online_nnls` compiles in (numba's cache checks only
#: this file)
DEPENDENCIES = (K.__file__, L.__file__, pairing.__file__, surface_pairing.__file__,
                nnls.__file__)


# forget this module's cached kernels made against other dependencies' contents
drop_stale_cache = stale_cache_dropper(__name__, DEPENDENCIES)
drop_stale_cache()

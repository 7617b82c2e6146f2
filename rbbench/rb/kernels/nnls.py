"""numba kernels of the condensed online solve: the condensation on the cone coefficients
and the Gram-form NNLS.

With the reduced stiffness written ``A_N(mu) = V^-T diag(s(mu)) V^-1`` (a common eigenbasis
``V`` of its affine terms, computed offline: :func:`rbbench.rb.kernels.plan.eigenbasis`), a
reduced saddle point condenses on its cone coefficients without any factorisation online
(:func:`rbbench.rb.mixed.model.condense_dense`)::

    Bt = B_N V,  Ft = V^T F_N,  D = Bt diag(1/s) Bt^T,  q = G_N - Bt (Ft / s),
    alpha = argmin_{alpha >= 0} 1/2 alpha^T D alpha + q^T alpha   (LCP(q, D)),
    c = V (Ft - Bt^T alpha) / s.

:func:`condense` forms ``D`` and ``q``. The bound-constrained QP is solved by the active set
of Lawson and Hanson (1974, ch. 23) in the Gram form of Bro and de Jong (1997, "A fast
non-negativity-constrained least squares algorithm"), :func:`nnls_gram`: it works on ``D``
and ``q`` directly, keeps the Cholesky factor of ``D`` on the passive set and updates it by
one row per added index. It terminates after finitely many steps in exact arithmetic; here
any numerical trouble (a dependent row, too many steps) returns a failure status and the
caller reruns the Python path; :func:`natural_residual` checks the answer. Used by the
frictionless model's condensed solve (:func:`rbbench.rb.mixed.dual_kernels.online_nnls`)
and the wedge friction model's fixed point (:mod:`rbbench.rb.friction.wedge.kernels`). The
module imports numba at the top: import it only when numba is installed.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbbench.runtime.numba_cache import use_user_cache

use_user_cache()  # before any @njit(cache=True): the cache lives in the user's cache dir

#: statuses of :func:`nnls_gram` (anything but NNLS_OK: the caller reruns the Python path)
NNLS_OK, NNLS_DEPENDENT, NNLS_MAX_ITER, NNLS_RESIDUAL = 0, 3, 4, 5

_EPS = np.finfo(np.float64).eps


@njit(cache=True, fastmath={"reassoc", "contract"})
def condense(bt, ft, s, d, q, g):
    """``D = Bt diag(1/s) Bt^T`` and ``q = G - Bt (Ft / s)`` (module docstring) into ``d``
    and ``q``, from ``bt`` = ``Bt^T`` (n x R, the layout of the EIM combination), ``ft``
    and ``s > 0`` (n), as dot products of the rows of ``Bt diag(s)^-1/2``. The reductions
    may be reassociated (vectorised): round-off only, no assumption on NaN or inf; 1.8 us
    against 3.0 us for the row-update form at n = 60, R = 20."""
    n, r = bt.shape
    b = np.empty((r, n))
    fs = np.empty(n)
    for k in range(n):
        inv = 1.0 / np.sqrt(s[k])
        fs[k] = ft[k] * inv
        for i in range(r):
            b[i, k] = bt[k, i] * inv
    for i in range(r):
        bi = b[i]
        acc = 0.0
        for k in range(n):
            acc += bi[k] * fs[k]
        q[i] = g[i] - acc
        for j in range(i + 1):
            bj = b[j]
            acc = 0.0
            for k in range(n):
                acc += bi[k] * bj[k]
            d[i, j] = acc
            d[j, i] = acc


@njit(cache=True)
def _add_row(d, idx, k, lf, j):
    """Append index ``j`` to the Cholesky factor ``lf`` of ``d[idx[:k], idx[:k]]``:
    ``False`` when its pivot is not positive (``j`` depends on the passive set)."""
    for a in range(k):
        v = d[idx[a], j]
        for b in range(a):
            v -= lf[a, b] * lf[k, b]
        lf[k, a] = v / lf[a, a]
    v = d[j, j]
    for b in range(k):
        v -= lf[k, b] * lf[k, b]
    if not v > 1e3 * _EPS * d[j, j]:
        return False
    lf[k, k] = np.sqrt(v)
    idx[k] = j
    return True


@njit(cache=True)
def _solve_passive(lf, idx, k, q, z):
    """``z = -D_PP^-1 q_P`` by the factor ``lf`` (forward and backward substitution)."""
    for a in range(k):
        v = -q[idx[a]]
        for b in range(a):
            v -= lf[a, b] * z[b]
        z[a] = v / lf[a, a]
    for a in range(k - 1, -1, -1):
        v = z[a]
        for b in range(a + 1, k):
            v -= lf[b, a] * z[b]
        z[a] = v / lf[a, a]


@njit(cache=True)
def _gradient(d, q, x, idx, k, w):
    """``w = -(q + D x)`` with ``x`` supported on ``idx[:k]``."""
    for i in range(q.size):
        w[i] = -q[i]
    for a in range(k):
        j = idx[a]
        xj = x[j]
        for i in range(q.size):
            w[i] -= d[i, j] * xj


@njit(cache=True)
def _interpolate(x, idx, k, z, inp):
    """Lawson-Hanson's step back to the feasible set: ``x += t (z - x)`` on the passive set
    with the largest ``t`` keeping ``x >= 0``; the index that limits ``t`` is set to 0 and
    leaves the passive set with any other that reached 0. Returns the new passive count
    (``idx`` compacted, ``inp`` updated)."""
    t, hit = 1.0, -1
    for a in range(k):
        if z[a] <= 0.0:
            xa = x[idx[a]]
            ta = xa / (xa - z[a])
            if ta < t or hit < 0:
                t, hit = ta, a
    kept = 0
    for a in range(k):
        j = idx[a]
        xj = x[j] + t * (z[a] - x[j])
        if a == hit or xj <= 0.0:
            x[j] = 0.0
            inp[j] = False
        else:
            x[j] = xj
            idx[kept] = j
            kept += 1
    return kept


@njit(cache=True)
def _refactor(d, idx, k, lf):
    """The Cholesky factor of ``d[idx[:k], idx[:k]]`` from scratch (after removals)."""
    order = idx[:k].copy()
    for a in range(k):
        if not _add_row(d, idx, a, lf, order[a]):
            return False
    return True


@njit(cache=True)
def nnls_gram(d, q, x, max_iter, warm=False):
    """``x = argmin_{x >= 0} 1/2 x^T d x + q^T x`` for a symmetric positive definite
    ``d`` (module docstring: Lawson-Hanson / Bro-de Jong). Writes ``x``; returns
    ``(status, iterations)``, iterations = passive-set solves.

    ``warm``: start from the ``x >= 0`` given (Bro and de Jong's warm start): its positive
    entries are the first passive set (an entry dependent on the others starts at 0), the
    first passive solve and the steps back to the feasible set make it optimal on that
    set, then the active-set loop goes on as from 0. Without ``warm``, ``x`` starts at 0."""
    r = q.size
    idx = np.empty(r, np.int64)
    inp = np.zeros(r, np.bool_)
    lf = np.zeros((r, r))
    z, w = np.empty(r), np.empty(r)
    k, it = 0, 0
    for i in range(r):
        if warm and x[i] > 0.0 and _add_row(d, idx, k, lf, i):
            inp[i] = True
            k += 1
        else:
            x[i] = 0.0
    scale = 0.0
    for i in range(r):
        scale = max(scale, abs(q[i]))
    tol = 1e3 * _EPS * max(scale, 1e-300)
    if k > 0:
        status, k, it = _passive_steps(d, q, x, idx, inp, lf, k, z, it, max_iter)
        if status != NNLS_OK:
            return status, it
    _gradient(d, q, x, idx, k, w)
    while True:
        j, best = -1, tol
        for i in range(r):
            if not inp[i] and w[i] > best:
                j, best = i, w[i]
        if j < 0:
            return NNLS_OK, it
        if not _add_row(d, idx, k, lf, j):
            return NNLS_DEPENDENT, it
        inp[j] = True
        k += 1
        status, k, it = _passive_steps(d, q, x, idx, inp, lf, k, z, it, max_iter)
        if status != NNLS_OK:
            return status, it
        _gradient(d, q, x, idx, k, w)


@njit(cache=True)
def _passive_steps(d, q, x, idx, inp, lf, k, z, it, max_iter):
    """Lawson-Hanson's inner loop: solve on the passive set ``idx[:k]``, step back to the
    feasible set (:func:`_interpolate`) until the passive solution is positive, which
    becomes ``x`` there. Returns ``(status, k, iterations)``."""
    while True:
        it += 1
        if it > max_iter:
            return NNLS_MAX_ITER, k, it
        _solve_passive(lf, idx, k, q, z)
        positive = True
        for a in range(k):
            if not z[a] > 0.0:
                positive = False
        if positive:
            for a in range(k):
                x[idx[a]] = z[a]
            return NNLS_OK, k, it
        k = _interpolate(x, idx, k, z, inp)
        if not _refactor(d, idx, k, lf):
            return NNLS_DEPENDENT, k, it


@njit(cache=True)
def natural_residual(d, q, x):
    """``||min(x, c s)|| / ||c q||``, ``s = q + D x``, ``c = 1 / mean(diag D)``
    (:func:`rbbench.hf.solvers.lcp.natural_residual`)."""
    r = q.size
    tr = 0.0
    for i in range(r):
        tr += d[i, i]
    c = r / tr if tr > 0 else 1.0
    num, den = 0.0, 0.0
    for i in range(r):
        si = q[i]
        for j in range(r):
            si += d[i, j] * x[j]
        v = min(x[i], c * si)
        num += v * v
        den += (c * q[i]) ** 2
    return np.sqrt(num) / max(np.sqrt(den), 1e-300)


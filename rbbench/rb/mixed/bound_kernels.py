"""numba kernels of the online error bounds (:meth:`rbbench.rb.mixed.bounds.MixedBound.terms`;
with a moving contact :meth:`rbbench.rb.mixed.contact_bound.ContactBound.terms`).

The same formulas as the numpy reference, written as loops: one call instead of a dozen
numpy calls (each ~1-10 us of overhead on arrays this small). Imports numba at the top:
import it only when numba is installed.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbbench.rb.kernels import layout, pairing
from rbbench.runtime.numba_cache import stale_cache_dropper, use_user_cache

use_user_cache()  # before any @njit(cache=True)


@njit(cache=True)
def bound_terms(mu, T, qF, qA, qB, C, qC, Gq, qG, Vg, c, a, ip, ix, dv, L, sparse):
    """``(rho, sigma, kappa, lam_norm)`` of :class:`rbbench.rb.algorithms.bounds.BoundTerms`
    (``ip``, ``ix``, ``dv``: CSR of ``D^{-1}`` when ``sparse``, else ``L`` the lower
    Cholesky factor of D; ``theta = [1, mu]``)."""
    th = np.empty(mu.size + 1)
    th[0] = 1.0
    th[1:] = mu
    N = c.size
    R = a.size
    q = T.shape[1]
    w = np.empty(q)
    k = 0
    for i in range(qF.size):
        w[k] = th[qF[i]]
        k += 1
    for i in range(qA.size):
        for j in range(N):
            w[k] = -th[qA[i]] * c[j]
            k += 1
    b0 = k
    for i in range(qB.size):
        for j in range(R):
            w[k] = -th[qB[i]] * a[j]
            k += 1
    rho2 = 0.0
    l2 = 0.0
    for r in range(T.shape[0]):
        s = 0.0
        sb = 0.0
        for j in range(q):
            s += T[r, j] * w[j]
        for j in range(b0, q):
            sb += T[r, j] * w[j]
        rho2 += s * s
        l2 += sb * sb
    m = Gq.shape[1]
    d = np.zeros(m)
    for i in range(qC.size):
        t = th[qC[i]]
        for r in range(m):
            s = 0.0
            for j in range(N):
                s += C[i, r, j] * c[j]
            d[r] += t * s
    for i in range(qG.size):
        t = th[qG[i]]
        for r in range(m):
            d[r] -= t * Gq[i, r]
    kappa = 0.0
    for r in range(m):
        lam = 0.0
        for j in range(R):
            lam += Vg[r, j] * a[j]
        if d[r] < 0.0:
            kappa -= lam * d[r]
            d[r] = 0.0
    sig2 = 0.0
    if sparse:
        for r in range(m):
            if d[r] == 0.0:
                continue
            s = 0.0
            for p in range(ip[r], ip[r + 1]):
                s += dv[p] * d[ix[p]]
            sig2 += d[r] * s
    else:
        y = np.zeros(m)
        for r in range(m):
            s = d[r]
            for j in range(r):
                s -= L[r, j] * y[j]
            y[r] = s / L[r, r]
            sig2 += y[r] * y[r]
    return np.sqrt(rho2), np.sqrt(max(sig2, 0.0)), max(kappa, 0.0), np.sqrt(l2)


@njit(cache=True)
def contact_jumps(s, w, gap, mphi, seg, sphi, n_hat, sdofs, mdofs, rows, uz, lam, d, b):
    """The constraint residual ``d = B(mu) uz - G(mu)`` (m rows) and ``b = B(mu)^T lam`` (on
    the contact dofs), written in place, from the pairing at mu
    (:func:`rbbench.rb.kernels.pairing.pair_points`: weights ``w``, gaps, master shape values
    ``mphi`` and facets ``seg``, slave scale ``s``): the normal jump ``(u1 - u2 o pi) .
    n`` at each point, ``n = sign(s) n_hat``, of the slave shape values ``sphi`` on the slave
    facet's dofs ``sdofs[q]`` and the master ones on ``mdofs[seg[q]]`` (each ``(k, 2)``);
    ``rows[q]``: the multiplier row of point q (P0 / LAC multipliers: one per point)."""
    sign = 1.0 if s > 0 else -1.0
    d[:] = 0.0
    b[:] = 0.0
    for q in range(w.size):
        n0, n1 = sign * n_hat[q, 0], sign * n_hat[q, 1]
        j = 0.0
        for a in range(sphi.shape[1]):
            j += sphi[q, a] * (n0 * uz[sdofs[q, a, 0]] + n1 * uz[sdofs[q, a, 1]])
        f = seg[q]
        for a in range(mphi.shape[1]):
            j -= mphi[q, a] * (n0 * uz[mdofs[f, a, 0]] + n1 * uz[mdofs[f, a, 1]])
        r = rows[q]
        d[r] += w[q] * (j - gap[q])
        lw = w[q] * lam[r]
        for a in range(sphi.shape[1]):
            b[sdofs[q, a, 0]] += lw * sphi[q, a] * n0
            b[sdofs[q, a, 1]] += lw * sphi[q, a] * n1
        for a in range(mphi.shape[1]):
            b[mdofs[f, a, 0]] -= lw * mphi[q, a] * n0
            b[mdofs[f, a, 1]] -= lw * mphi[q, a] * n1


@njit(cache=True, fastmath={"reassoc", "contract"})
def _slave_terms(sr, Vg, a, Cs, c, d):
    """The multipliers ``lam = Vg a`` and the slave part ``d = s_r Cs c``."""
    m, N, R = Cs.shape[0], c.size, a.size
    lam = np.zeros(m)
    for r in range(m):
        v = 0.0
        for j in range(R):
            v += Vg[r, j] * a[j]
        lam[r] = v
        v = 0.0
        for j in range(N):
            v += Cs[r, j] * c[j]
        d[r] = sr * v
    return lam


@njit(cache=True, fastmath={"reassoc", "contract"})
def _master_terms(s, n_hat, mdofs, rows, Zl, c, U, w, gap, mphi, seg, mark, uz, b, touched,
                  lam, d):
    """Add the master part of ``d`` (``uz = Zl c`` at the paired facets' dofs only) and
    return ``(||b_M||^2, g = U^T b_M)`` with ``b_M = B_M(mu)^T lam`` on ``lam``'s support;
    ``mark`` and ``b`` are left zero."""
    N = c.size
    sign = 1.0 if s > 0 else -1.0
    nt = 0
    k = mphi.shape[1]
    for q in range(w.size):
        n0, n1 = sign * n_hat[q, 0], sign * n_hat[q, 1]
        f = seg[q]
        jm = 0.0
        for e in range(k):
            for t in range(2):
                dof = mdofs[f, e, t]
                if mark[dof] == 0:
                    mark[dof] = 1
                    touched[nt] = dof
                    nt += 1
                    v = 0.0
                    for j in range(N):
                        v += Zl[dof, j] * c[j]
                    uz[dof] = v
            jm += mphi[q, e] * (n0 * uz[mdofs[f, e, 0]] + n1 * uz[mdofs[f, e, 1]])
        r = rows[q]
        d[r] += w[q] * (-jm - gap[q])
        lw = w[q] * lam[r]
        if lw != 0.0:
            for e in range(k):
                b[mdofs[f, e, 0]] -= lw * mphi[q, e] * n0
                b[mdofs[f, e, 1]] -= lw * mphi[q, e] * n1
                mark[mdofs[f, e, 0]] = 2
                mark[mdofs[f, e, 1]] = 2
    K = U.shape[1]
    g = np.zeros(K)
    bb = 0.0
    for i in range(nt):
        dof = touched[i]
        if mark[dof] == 2:
            bd = b[dof]
            bb += bd * bd
            for j in range(K):
                g[j] += U[dof, j] * bd
            b[dof] = 0.0
        mark[dof] = 0
    return bb, g


@njit(cache=True, fastmath={"reassoc", "contract"})
def _residual_norms(T, kj, j_lam, sr, c, a, g):
    """``(||T w||, ||T_lam w_lam||)`` for ``w = [1, -c, -s_r a, -g]``, ``T`` used on rows
    ``< kj[j]`` of column ``j`` (upper trapezoidal), the multiplier part from ``j_lam``."""
    N, R = c.size, a.size
    y = np.zeros(T.shape[0])
    yl = np.zeros(T.shape[0])
    for j in range(T.shape[1]):
        if j == 0:
            wj = 1.0
        elif j <= N:
            wj = -c[j - 1]
        elif j <= N + R:
            wj = -sr * a[j - 1 - N]
        else:
            wj = -g[j - 1 - N - R]
        if j >= j_lam:
            for i in range(kj[j]):
                tw = T[i, j] * wj
                y[i] += tw
                yl[i] += tw
        else:
            for i in range(kj[j]):
                y[i] += T[i, j] * wj
    rho2 = 0.0
    l2 = 0.0
    for i in range(y.size):
        rho2 += y[i] * y[i]
        l2 += yl[i] * yl[i]
    return np.sqrt(rho2), np.sqrt(l2)


@njit(cache=True, fastmath={"reassoc", "contract"})
def _violation_terms(Linv, d, lam):
    """``(||Linv d_+||, kappa = -sum_{d < 0} lam d)``, kappa clipped at 0."""
    m = d.size
    v = np.zeros(m)
    kappa = 0.0
    for r in range(m):
        if d[r] > 0.0:
            for i in range(r, m):
                v[i] += Linv[i, r] * d[r]
        elif d[r] < 0.0:
            kappa -= lam[r] * d[r]
    sig2 = 0.0
    for i in range(m):
        sig2 += v[i] * v[i]
    return np.sqrt(sig2), max(kappa, 0.0)


@njit(cache=True, fastmath={"reassoc", "contract"})  # SIMD sums: round-off only
def moving_contact_terms(mu, fb, ib, meta, n_hat, mdofs, rows, s_terms, Vg, a, Cs, Zl, c, U,
                         T, kj, j_lam, Linv, w, gap, mphi, seg, mark, uz, b, touched, d, out):
    """The terms of :meth:`rbbench.rb.mixed.contact_bound.ContactBound.terms` in one call,
    touching only the data the pairing at mu needs. Returns the pairing's status (``out``
    is valid when it is ``OK``): ``out = [||T w||, ||T_lam w_lam||, ||b_M||^2, ||g||^2,
    sigma, kappa]``.

    The slave part of ``d`` is ``s_r(mu) Cs c`` (``s_r = [1, mu] . s_terms``), the master
    part sums over the points with ``uz = Zl c`` evaluated only at the master dofs of the
    paired facets; ``b_M = B_M(mu)^T lam`` only where ``lam`` is non-zero, and ``g = U^T
    b_M`` over that support; ``T`` (Fortran order) is used on rows ``< kj[j]`` of column
    ``j`` (it is upper trapezoidal: Gram-Schmidt); ``w = [1, -c, -s_r a, -g]``, its
    multiplier part from column ``j_lam``. ``mark``, ``b`` must be zero on entry (left so).
    """
    status, th = layout.theta(mu, fb, meta)
    if status != layout.OK:
        return status
    status, s = pairing.pair_points(th, fb, ib, meta, w, gap, mphi, seg)
    if status != layout.OK:
        return status
    sr = s_terms[0]
    for i in range(mu.size):
        sr += s_terms[i + 1] * mu[i]
    lam = _slave_terms(sr, Vg, a, Cs, c, d)
    bb, g = _master_terms(s, n_hat, mdofs, rows, Zl, c, U, w, gap, mphi, seg, mark, uz, b,
                          touched, lam, d)
    out[0], out[1] = _residual_norms(T, kj, j_lam, sr, c, a, g)
    out[2] = bb
    out[3] = float(np.sum(g * g))
    out[4], out[5] = _violation_terms(Linv, d, lam)
    out[4] /= abs(sr)
    return layout.OK


#: the modules whose kernels this one's compile in (numba's cache checks only this file)
DEPENDENCIES = (layout.__file__, pairing.__file__)


# forget this module's cached kernels made against other dependencies' contents
drop_stale_cache = stale_cache_dropper(__name__, DEPENDENCIES)
drop_stale_cache()

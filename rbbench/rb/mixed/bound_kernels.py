"""numba kernel of the online error bound (:meth:`rbbench.rb.mixed.bounds.MixedBound.terms`).

The same formulas as the numpy reference, written as loops: one call instead of a dozen
numpy calls (each ~1-10 us of overhead on arrays this small). Imports numba at the top:
import it only when numba is installed.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from rbbench.runtime.numba_cache import use_user_cache

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

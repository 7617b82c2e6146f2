"""Condensed LCP solvers: properties on random problems (hypothesis, fixed seeds)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import lsq_linear

from rbbench.hf.condensation.dense import condense
from rbbench.hf.solvers import lcp


def _random_lcp(seed: int, m: int):
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((m, m))
    D = M @ M.T + 0.1 * m * np.eye(m)
    q = rng.standard_normal(m)
    return D, q


def _reference(D, q):
    """Dual QP min 1/2 l^T D l + q^T l, l >= 0, by BVLS on the Cholesky factor."""
    L = np.linalg.cholesky(D)
    rhs = -np.linalg.solve(L, q)
    return lsq_linear(L.T, rhs, bounds=(0, np.inf), method="bvls", tol=1e-15).x


@settings(max_examples=40, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), m=st.integers(1, 40))
def test_pdas_solves_the_lcp(seed, m):
    D, q = _random_lcp(seed, m)
    lam, it, reason, res, _ = lcp.pdas(D, q)
    assert reason == "converged"
    s = q + D @ lam
    scale = np.abs(q).max()
    assert lam.min() >= 0.0
    assert s.min() >= -1e-10 * scale
    assert abs(lam @ s) <= 1e-10 * scale * max(1.0, np.abs(lam).max())
    ref = _reference(D, q)
    assert np.allclose(lam, ref, atol=1e-8 * max(1.0, np.abs(ref).max()))


@settings(max_examples=15, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), m=st.integers(1, 20))
def test_uzawa_matches_pdas(seed, m):
    D, q = _random_lcp(seed, m)
    lam_u, _, reason, _, _ = lcp.uzawa(D, q, tol=1e-12)
    lam_p = lcp.pdas(D, q)[0]
    assert reason == "converged"
    assert np.allclose(lam_u, lam_p, atol=1e-8 * max(1.0, np.abs(lam_p).max()))


def test_nnls_dual_matches_reference():
    D, q = _random_lcp(3, 25)
    assert np.allclose(lcp.nnls_dual(D, q), _reference(D, q), atol=1e-9)


def test_solvers_always_stop_with_a_reason():
    D, q = _random_lcp(1, 30)
    assert lcp.pdas(D, q, max_iter=1)[2] in ("max_iterations", "converged")
    assert lcp.uzawa(D, q, max_iter=3)[2] == "max_iterations"
    bad = q.copy()
    bad[0] = np.nan
    assert lcp.uzawa(D, bad)[2] == "nan"
    assert lcp.pdas(D, bad)[2] == "nan"


def test_uzawa_rejects_divergent_step():
    D, q = _random_lcp(1, 5)
    try:
        lcp.uzawa(D, q, omega=2.5)
    except ValueError as exc:
        assert "omega" in str(exc)
    else:  # pragma: no cover
        raise AssertionError("omega >= 2 must be refused")


def test_condense_reproduces_full_solution():
    rng = np.random.default_rng(0)
    n, m = 40, 6
    M = rng.standard_normal((n, n))
    A = M @ M.T + n * np.eye(n)
    B = rng.standard_normal((m, n))
    F = rng.standard_normal(n)
    G = rng.standard_normal(m)
    import scipy.sparse as sp

    c = condense(sp.csr_matrix(A), F, sp.csr_matrix(B), G)
    lam = lcp.pdas(c.D, c.q)[0]
    u = c.displacement(lam)
    assert np.allclose(A @ u + B.T @ lam, F, atol=1e-10 * np.abs(F).max())
    assert np.all(G - B @ u >= -1e-10)

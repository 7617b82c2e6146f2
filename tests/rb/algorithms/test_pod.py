"""POD and the ideal / weak greedy (rbbench.rb.algorithms.pod)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from rbbench.rb.algorithms.pod import gram_schmidt_add, pod, projection_errors, weak_greedy


def _smooth_family(n=80, P=30):
    x = np.linspace(0, 1, n)[:, None]
    mu = np.linspace(0.5, 3.0, P)[None, :]
    return np.exp(-mu * x) * np.sin(2 * mu * x + 0.3)


def _laplace_mass(n: int) -> sp.csr_matrix:
    """SPD inner product: 1-D stiffness + mass on a uniform mesh (an H1 Gram matrix)."""
    h = 1.0 / (n + 1)
    K = sp.diags([-np.ones(n - 1), 2 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1]) / h
    M = sp.diags([np.ones(n - 1), 4 * np.ones(n), np.ones(n - 1)], [-1, 0, 1]) * h / 6
    return (K + M).tocsr()


def _low_rank(n=60, P=25, r=6, seed=0, decay=0.3):
    rng = np.random.default_rng(seed)
    return rng.standard_normal((n, r)) @ np.diag(decay ** np.arange(r)) @ \
        rng.standard_normal((r, P))


def _xsqrt(X):
    w, V = np.linalg.eigh(X.toarray())
    return V @ np.diag(np.sqrt(w)) @ V.T


# ---------------------------------------------------------------------------
# POD
# ---------------------------------------------------------------------------
def test_pod_exact_with_rank():
    U, X = _low_rank(), _laplace_mass(60)
    r = pod(U, X)
    assert r.N == r.rank == 6
    assert projection_errors(U, r.Z, X).max() <= 1e-10 * np.abs(U).max()
    np.testing.assert_allclose(r.Z.T @ X @ r.Z, np.eye(6), atol=1e-12)


def test_pod_singular_values_match_svd():
    U, X = _smooth_family(), _laplace_mass(80)
    r = pod(U, X)
    s_ref = np.linalg.svd(_xsqrt(X) @ U, compute_uv=False)
    k = r.rank
    assert k >= 5
    # absolute accuracy sqrt(eps) * s_1 at worst; much better for the leading ones
    np.testing.assert_allclose(r.s, s_ref[:k], rtol=1e-8, atol=1e-9 * s_ref[0])
    np.testing.assert_allclose(r.modes.T @ X @ r.modes, np.eye(k), atol=1e-12)
    assert r.total_energy == pytest.approx(np.sum(s_ref**2), rel=1e-12)


@pytest.mark.parametrize("tol", [1e-1, 1e-3, 1e-6])
def test_pod_tolerance_criterion(tol):
    U, X = _smooth_family(), _laplace_mass(80)
    r = pod(U, X, tol=tol)
    s2 = r.s**2
    total = r.total_energy
    assert np.sum(s2[r.N:]) <= tol**2 * total * (1 + 1e-12)  # honoured
    assert np.sum(s2[r.N - 1:]) > tol**2 * total  # and N is the smallest such
    R = U - r.Z @ (r.Z.T @ (X @ U))
    assert np.einsum("ij,ij->", R, X @ R) <= tol**2 * total * (1 + 1e-8)


def test_pod_cap_and_identity_inner_product():
    U = _low_rank(n=30, P=10, r=4)
    r = pod(U, n=2)
    assert r.N == 2 and r.Z.shape == (30, 2)
    np.testing.assert_allclose(r.s, np.linalg.svd(U, compute_uv=False)[:4], rtol=1e-10)


# ---------------------------------------------------------------------------
# greedy
# ---------------------------------------------------------------------------
def test_ideal_greedy_properties():
    U, X = _low_rank(r=6), _laplace_mass(60)
    g = weak_greedy(U, X, tol=1e-12)
    assert g.ideal and g.N == 6 and len(g.sigma) == g.N + 1
    # first pick: the largest snapshot (Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order
    # reduction methods: parametric variational inequalities" (talk): mu_1 in argmax ||u(mu)||_V)
    norms = np.sqrt(np.einsum("ij,ij->j", U, X @ U))
    assert g.picks[0] == int(np.argmax(norms))
    assert g.sigma[0] == pytest.approx(norms.max())
    assert np.all(np.diff(g.sigma) <= 1e-12 * g.sigma[0])  # non-increasing (nested spaces)
    assert g.sigma[-1] <= 1e-10 * g.sigma[0]  # ~0 at N = rank
    np.testing.assert_allclose(g.Z.T @ X @ g.Z, np.eye(6), atol=1e-12)
    assert len(set(g.picks)) == g.N


def test_greedy_errors_and_dpw_check():
    U, X = _smooth_family(), _laplace_mass(80)
    g = weak_greedy(U, X, tol=1e-7)
    assert g.sigma[-1] <= 1e-7 * g.sigma[0] < g.sigma[-2]
    # sigma[k] is the true max projection error with k vectors
    for k in range(g.N + 1):
        assert g.sigma[k] == pytest.approx(projection_errors(U, g.Z[:, :k], X).max(),
                                           rel=1e-6, abs=1e-12 * g.sigma[0])
    assert np.all(np.diff(g.sigma) <= 1e-12 * g.sigma[0])
    # DeVore-Petrova-Wojtaszczyk on the training set, with the POD width proxy
    for k in range(1, len(g.d_pod)):
        if 2 * k < len(g.sigma):
            assert g.sigma[2 * k] <= g.dpw_bound[k] * (1 + 1e-10)
    assert g.d_pod[0] == pytest.approx(g.sigma[0])  # no basis: the largest norm
    assert np.all(np.diff(g.d_pod) <= 1e-12 * g.sigma[0])


def test_greedy_with_indicator_and_cap():
    U, X = _smooth_family(), _laplace_mass(80)
    calls = []

    def indicator(Z, i):
        calls.append(Z.shape[1])
        return float(projection_errors(U[:, [i]], Z, X)[0])

    ideal = weak_greedy(U, X, tol=1e-6)
    g = weak_greedy(U, X, indicator=indicator, tol=1e-6)
    assert not g.ideal and g.picks == ideal.picks
    np.testing.assert_allclose(g.sigma, ideal.sigma, rtol=1e-6, atol=1e-12 * g.sigma[0])
    capped = weak_greedy(U, X, tol=0.0, n_max=3)
    assert capped.N == 3 and capped.picks == ideal.picks[:3]


def test_gram_schmidt_add_rejects_dependent_vector():
    X = _laplace_mass(20)
    rng = np.random.default_rng(1)
    Z = np.zeros((20, 0))
    for _ in range(3):
        Z, _ = gram_schmidt_add(Z, rng.standard_normal(20), X)
    Z2, rel = gram_schmidt_add(Z, Z @ np.array([1.0, -2.0, 0.5]), X)
    assert Z2.shape[1] == 3 and rel < 1e-12


# ---------------------------------------------------------------------------
# matrix EIM
# ---------------------------------------------------------------------------
N_ROWS, N_COLS = 30, 40



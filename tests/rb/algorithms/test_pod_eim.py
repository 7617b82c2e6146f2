"""POD, the ideal / weak greedy (rbbench.rb.algorithms.pod) and EIM / DEIM
(rbbench.rb.algorithms.eim)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from rbbench.rb.algorithms.eim import deim, eim_error, matrix_eim
from rbbench.rb.algorithms.pod import gram_schmidt_add, pod, projection_errors, weak_greedy


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


def _smooth_family(n=80, P=30):
    x = np.linspace(0, 1, n)[:, None]
    mu = np.linspace(0.5, 3.0, P)[None, :]
    return np.exp(-mu * x) * np.sin(2 * mu * x + 0.3)


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
    # first pick: the largest snapshot (seed: mu_1 in argmax ||u(mu)||_V)
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
# EIM / DEIM (vectors)
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("method", ["eim", "deim"])
def test_eim_interpolation_property(method):
    S = _smooth_family(n=120, P=40)
    r = deim(S, tol=1e-8, method=method)
    assert 3 <= r.m < 40 and r.errors[-1] <= 1e-8
    approx = r.approximate(S)
    scale = np.abs(S).max()
    # exact at the magic points, for every training snapshot
    assert np.abs(approx[r.magic] - S[r.magic]).max() <= 1e-12 * scale
    assert eim_error(r, S) == pytest.approx(r.errors[-1], rel=1e-6, abs=1e-14)
    assert len(np.unique(r.magic)) == r.m


def test_greedy_eim_structure():
    S = _smooth_family(n=120, P=40)
    r = deim(S, m_max=6)
    assert r.m == 6 and len(r.picks) == 6
    Qm = r.Q[r.magic]
    np.testing.assert_array_equal(np.diag(Qm), 1.0)  # residual normalised at its magic point
    np.testing.assert_array_equal(np.triu(Qm, 1), 0.0)  # vanishes at earlier magic points
    # the k-th error is the true interpolation error with k + 1 terms
    for k in (0, 2, 5):
        sub = deim(S, m_max=k + 1)
        assert sub.errors[-1] == pytest.approx(r.errors[k])
        assert eim_error(sub, S) == pytest.approx(r.errors[k], rel=1e-8)


@pytest.mark.parametrize("method", ["eim", "deim"])
def test_eim_exact_in_span(method):
    rng = np.random.default_rng(2)
    basis = rng.standard_normal((70, 5))
    S = basis @ rng.standard_normal((5, 30))
    r = deim(S, method=method)
    assert r.m == 5
    assert eim_error(r, S) <= 1e-12
    new = basis @ rng.standard_normal((5, 4))  # not in the training set, in the span
    assert eim_error(r, new) <= 1e-11
    theta = r.coefficients(new[r.magic])
    np.testing.assert_allclose(r.Q @ theta, r.interpolate(new[r.magic]))


def test_eim_zero_and_bad_method():
    assert deim(np.zeros((5, 3))).m == 0
    with pytest.raises(ValueError, match="method"):
        deim(np.ones((5, 3)), method="qdeim")


# ---------------------------------------------------------------------------
# matrix EIM
# ---------------------------------------------------------------------------
N_ROWS, N_COLS = 30, 40


def _banded(mu: float) -> sp.csr_matrix:
    """Diagonal with smooth values plus an off-diagonal band whose position jumps with mu
    (like a contact pairing): rank <= 2 + 2 * 4 over mu in [0, 1)."""
    i = np.arange(N_ROWS)
    k = int(4 * mu)  # band shift 0..3
    rows = np.concatenate([i, i])
    cols = np.concatenate([i, i + 5 + k])
    vals = np.concatenate([1.0 + mu * np.sin(i), np.cos(mu) * (i + 1) / N_ROWS + mu**2])
    return sp.csr_matrix((vals, (rows, cols)), shape=(N_ROWS, N_COLS))


def test_matrix_eim_changing_pattern():
    train = np.linspace(0.0, 0.99, 40)
    mats = [_banded(m) for m in train]
    res = matrix_eim(mats, tol=1e-12)
    assert res.m <= 10
    assert res.shape == (N_ROWS, N_COLS) and len(res.basis) == res.m
    assert all(B.shape == (N_ROWS, N_COLS) for B in res.basis)
    # union pattern: the diagonal plus 4 shifted bands
    assert res.rows.size == 5 * N_ROWS
    for M in mats:
        M = M.tocoo()
        keys = set(zip(res.rows.tolist(), res.cols.tolist(), strict=True))
        assert set(zip(M.row.tolist(), M.col.tolist(), strict=True)) <= keys
    assert eim_error(res, mats) <= 1e-12
    # exact at the magic entries, from those entries only
    for M in mats:
        E = res.approximate(M)
        got = np.asarray(E.tocsr()[res.magic_rows, res.magic_cols]).ravel()
        want = np.asarray(M[res.magic_rows, res.magic_cols]).ravel()
        assert np.abs(got - want).max() <= 1e-12 * np.abs(M).max()
    # new parameters with a known band position
    valid = [_banded(m) for m in np.random.default_rng(0).uniform(0, 0.99, 10)]
    assert eim_error(res, valid) <= 1e-11
    theta = res.coefficients(res.entries(valid[0]))
    np.testing.assert_allclose(res.assemble(theta).toarray(),
                               sum(t * B for t, B in zip(theta, res.basis, strict=True)).toarray(),
                               rtol=1e-12, atol=1e-14)


def test_matrix_eim_tolerance_and_unseen_pattern():
    x = np.arange(N_ROWS)[:, None]
    y = np.arange(N_COLS)[None, :]

    def smooth(mu):
        full = np.exp(-mu * ((x - y) / 10.0) ** 2)
        full[np.abs(x - y) > 3] = 0.0
        return sp.csr_matrix(full)

    train = [smooth(m) for m in np.linspace(0.5, 2.0, 30)]
    res = matrix_eim(train, tol=1e-6)
    assert res.errors[-1] <= 1e-6
    assert eim_error(res, train) == pytest.approx(res.errors[-1], rel=1e-6, abs=1e-15)
    # an entry outside the training union is not represented: the error shows it
    outside = smooth(1.0).tolil()
    outside[0, N_COLS - 1] = 5.0
    assert eim_error(res, [outside.tocsr()]) == pytest.approx(1.0)

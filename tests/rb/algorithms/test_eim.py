"""EIM / DEIM and the matrix EIM (rbbench.rb.algorithms.eim): interpolation at the magic
points, exactness in the span, greedy structure, changing sparsity patterns."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from rbbench.rb.algorithms.eim import deim, eim_error, matrix_eim


def _smooth_family(n=80, P=30):
    x = np.linspace(0, 1, n)[:, None]
    mu = np.linspace(0.5, 3.0, P)[None, :]
    return np.exp(-mu * x) * np.sin(2 * mu * x + 0.3)


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


# ---------------------------------------------------------------------------
# row-aware selection (groups, threshold)
# ---------------------------------------------------------------------------
def _grouped_family(seed: int, n_groups: int = 12, per: int = 6, P: int = 25) -> np.ndarray:
    """Smooth snapshots of n_groups x per entries (a matrix C(mu) flattened by rows)."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(0.0, 1.0, n_groups * per)[:, None]
    a = rng.uniform(0.5, 2.0, n_groups * per)[:, None]
    mu = np.linspace(0.2, 2.0, P)[None, :]
    return a * np.exp(-mu * x) * np.cos(3.0 * mu * x + a)


def _residual(S, Q, magic, k, p):
    """The residual of snapshot p after the first k terms, by solving the interpolation
    system (independent of the BMNP recursion the greedy loop uses)."""
    if k == 0:
        return S[:, p].copy()
    theta = np.linalg.solve(Q[magic[:k], :k], S[magic[:k], p])
    return S[:, p] - Q[:, :k] @ theta


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), threshold=st.floats(0.05, 1.0))
def test_row_aware_eim_interpolates_and_keeps_the_threshold(seed, threshold):
    per = 6
    S = _grouped_family(seed, per=per)
    groups = np.arange(S.shape[0]) // per
    r = deim(S, tol=1e-9, groups=groups, threshold=threshold)
    assert r.m >= 3 and len(np.unique(r.magic)) == r.m
    scale = np.abs(S).max()
    # exact at the magic entries for every training snapshot
    assert np.abs(r.approximate(S)[r.magic] - S[r.magic]).max() <= 1e-10 * scale
    Qm = r.Q[r.magic]
    np.testing.assert_array_equal(np.diag(Qm), 1.0)
    np.testing.assert_array_equal(np.triu(Qm, 1), 0.0)
    paid: set[int] = set()
    for k in range(r.m):
        res = _residual(S, r.Q, r.magic, k, r.picks[k])
        i, top = r.magic[k], np.abs(res).max()
        # the pivot is within the threshold of the largest residual entry ...
        assert abs(res[i]) >= threshold * top * (1 - 1e-9)
        # ... so the basis vector is bounded by 1 / threshold (the Lebesgue bound's input)
        assert np.abs(r.Q[:, k]).max() <= (1 + 1e-9) / threshold
        in_paid = np.isin(groups, list(paid))
        best_paid = np.abs(res[in_paid]).max(initial=0.0)
        if groups[i] in paid:  # the largest entry among the paid groups
            assert abs(res[i]) == pytest.approx(best_paid, rel=1e-9)
        else:  # a new group only when no paid entry reaches the threshold: the largest
            assert best_paid < threshold * top * (1 + 1e-9)
            assert abs(res[i]) == pytest.approx(top, rel=1e-9)
        paid.add(int(groups[i]))


def test_row_aware_eim_touches_fewer_groups_and_threshold_one_is_plain():
    per = 6
    S = _grouped_family(3, per=per)
    groups = np.arange(S.shape[0]) // per
    plain = deim(S, tol=1e-8)
    same = deim(S, tol=1e-8, groups=groups, threshold=1.0)
    np.testing.assert_array_equal(same.magic, plain.magic)
    aware = deim(S, tol=1e-8, groups=groups, threshold=0.1)
    assert aware.errors[-1] <= 1e-8
    n_plain = np.unique(groups[plain.magic]).size
    n_aware = np.unique(groups[aware.magic]).size
    assert n_aware < n_plain
    # groups paid before the first step are preferred from the start
    pre = deim(S, tol=1e-8, groups=groups, threshold=0.1, paid=np.array([0, 1]))
    assert groups[pre.magic[1]] in (0, 1, groups[pre.magic[0]])


def test_row_aware_eim_refuses_bad_input():
    S = _grouped_family(0)
    with pytest.raises(ValueError, match="threshold"):
        deim(S, groups=np.zeros(S.shape[0], dtype=int), threshold=0.0)
    with pytest.raises(ValueError, match="groups"):
        deim(S, groups=np.zeros(3, dtype=int), threshold=0.5)
    with pytest.raises(ValueError, match="method"):
        deim(S, groups=np.zeros(S.shape[0], dtype=int), threshold=0.5, method="deim")

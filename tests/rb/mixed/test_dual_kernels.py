"""The compiled NNLS of the condensed online solve (rbbench.rb.mixed.dual_kernels) on its own.

Against an independent reference: on small problems every active set is enumerated and the
unique one satisfying the KKT conditions of LCP(q, D) gives the exact solution; on larger
ones the KKT conditions are checked on the raw output (no clipping before the test).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("numba")

from rbbench.rb.mixed import dual_kernels as dk  # noqa: E402


def _problem(seed: int, r: int, spread: float) -> tuple[np.ndarray, np.ndarray]:
    """A random SPD ``D`` (eigenvalues over ``10**spread``) and load ``q``."""
    rng = np.random.default_rng(seed)
    Q = np.linalg.qr(rng.standard_normal((r, r)))[0]
    D = Q @ np.diag(np.logspace(0, -spread, r)) @ Q.T
    return 0.5 * (D + D.T), rng.standard_normal(r)


def _brute_force(D: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The LCP solution by enumerating the active sets (r <= 8)."""
    r = q.size
    for mask in itertools.product((False, True), repeat=r):
        a = np.array(mask)
        x = np.zeros(r)
        if a.any():
            x[a] = np.linalg.solve(D[np.ix_(a, a)], -q[a])
        s = q + D @ x
        tol = 1e-9 * (1 + np.abs(q).max())
        if (x >= -tol).all() and (s[~a] >= -tol).all():
            return x
    raise AssertionError("no active set satisfies the KKT conditions")


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), r=st.integers(1, 8), spread=st.sampled_from([0, 2, 5]))
def test_nnls_gram_equals_the_enumerated_solution(seed, r, spread):
    D, q = _problem(seed, r, spread)
    x = np.empty(r)
    status, it = dk.nnls_gram(D, q, x, 100)
    assert status == dk.NNLS_OK and it >= (1 if (q < 0).any() else 0)
    ref = _brute_force(D, q)
    assert np.abs(x - ref).max() <= 1e-8 * 10.0 ** spread * max(np.abs(ref).max(), 1e-300)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), r=st.integers(1, 40), spread=st.sampled_from([0, 3, 6]))
def test_nnls_gram_satisfies_kkt(seed, r, spread):
    """Raw output: x >= 0 exactly (the active set sets leaving entries to 0), s = q + D x
    >= 0 and complementarity to round-off, the natural residual below 1e-10."""
    D, q = _problem(seed, r, spread)
    x = np.empty(r)
    status, _ = dk.nnls_gram(D, q, x, 200)
    assert status == dk.NNLS_OK
    s = q + D @ x
    scale = np.abs(q).max()
    assert x.min() >= 0.0
    assert s.min() >= -1e-10 * scale
    assert np.abs(x * s).max() <= 1e-10 * scale * max(np.abs(x).max(), 1e-300)
    assert dk._natural_residual(D, q, x) <= 1e-10


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), r=st.integers(1, 8), spread=st.sampled_from([0, 2, 5]),
       start=st.sampled_from(["random", "solution", "zero"]))
def test_warm_started_nnls_gram_equals_the_enumerated_solution(seed, r, spread, start):
    """From any x >= 0 (random sparse, the solution itself, 0) the warm start reaches the
    enumerated solution; started at the solution it takes one passive-set solve."""
    D, q = _problem(seed, r, spread)
    ref = _brute_force(D, q)
    rng = np.random.default_rng(seed + 1)
    x = {"random": np.abs(rng.standard_normal(r)) * (rng.random(r) < 0.5),
         "solution": ref.copy(), "zero": np.zeros(r)}[start]
    status, it = dk.nnls_gram(D, q, x, 100, True)
    assert status == dk.NNLS_OK
    assert np.abs(x - ref).max() <= 1e-8 * 10.0 ** spread * max(np.abs(ref).max(), 1e-300)
    if start == "solution" and (ref > 0).any():
        assert it == 1


def test_nnls_gram_reports_dependent_rows_and_too_many_steps():
    """A singular D with a load pushing along its kernel (D [1, 1] = 0, q . [1, 1] < 0: the
    QP is unbounded below): the dependent row is refused (the caller then reruns the Python
    path); max_iter = 1 stops a longer solve."""
    D = np.array([[1.0, -1.0], [-1.0, 1.0]])
    status, _ = dk.nnls_gram(D, np.array([-1.0, -1.0]), np.empty(2), 50)
    assert status == dk.NNLS_DEPENDENT
    D, q = _problem(1, 12, 3)
    q = -np.abs(q)  # everything pushes: several passive-set steps
    assert dk.nnls_gram(D, q, np.empty(12), 1)[0] == dk.NNLS_MAX_ITER


def test_condense_equals_the_dense_formula():
    rng = np.random.default_rng(0)
    n, r = 9, 4
    bt, ft, g = rng.standard_normal((n, r)), rng.standard_normal(n), rng.standard_normal(r)
    s = rng.uniform(0.5, 2.0, n)
    d, q = np.empty((r, r)), np.empty(r)
    dk.condense(bt, ft, s, d, q, g)
    np.testing.assert_allclose(d, bt.T @ np.diag(1 / s) @ bt, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(q, g - bt.T @ (ft / s), rtol=1e-14, atol=1e-14)


def test_eigenbasis_one_term_and_commuting_terms():
    """``V^T A_k V = diag(lam[k])`` and ``V^T A(theta_ref) V = I``: one constant term
    (V = L^-T), and three terms that are polynomials of one SPD matrix (they commute, so a
    common eigenbasis exists although there are two parameters)."""
    from rbbench.rb.mixed.compiled import eigenbasis

    rng = np.random.default_rng(5)
    X = rng.standard_normal((7, 7))
    S = X @ X.T + 7 * np.eye(7)
    poly = np.stack([S, 0.1 * S @ S / 7, 0.01 * np.eye(7)])
    for terms, th in ((S[None], np.array([1.0])), (poly, np.array([1.0, 0.5, 2.0]))):
        V, lam = eigenbasis(terms, th)
        for k in range(terms.shape[0]):
            np.testing.assert_allclose(V.T @ terms[k] @ V, np.diag(lam[k]), atol=1e-12)
        np.testing.assert_allclose(V.T @ np.tensordot(th, terms, 1) @ V, np.eye(7), atol=1e-12)
    bad = eigenbasis(np.stack([S, -10 * S]), np.array([1.0, 1.0]))  # A(theta_ref) = -9 S
    assert isinstance(bad, str) and "not positive definite" in bad


def test_a_cache_older_than_the_kernels_it_inlines_is_dropped(tmp_path):
    """numba would keep running the cached online_nnls after a change to _kernels.py alone
    (it checks only _dual_kernels.py): the index is compared with _kernels.py's time."""
    import os

    index, source = tmp_path / "k.nbi", tmp_path / "k.py"
    index.write_text("")
    source.write_text("")
    os.utime(index, (1000, 1000))
    os.utime(source, (2000, 2000))
    assert dk.is_stale(index, source) and not dk.is_stale(source, index)
    assert not dk.is_stale(tmp_path / "missing.nbi", source)
    # the numba internals it reads exist in this numba
    assert str(dk.online_nnls._cache._cache_file._index_path).endswith(".nbi")
    assert dk.drop_stale_cache() is False  # just imported: nothing stale left

"""The Gram-form NNLS and the condensation of the compiled online solves, on their own.

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

from rbbench.rb.kernels import nnls as dk  # noqa: E402


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
    assert dk.natural_residual(D, q, x) <= 1e-10


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

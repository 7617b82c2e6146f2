"""The certified bound of a saddle-point VI: holds for any reduced pair (property), vanishes at
the HF solution, and a coercivity constant that is not a lower bound is caught."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from hypothesis import given, settings
from hypothesis import strategies as st

from rbbench.rb.algorithms.bounds import (
    BoundTerms,
    coercivity_constants,
    hf_bound_terms,
    natural_dual,
    riesz_factor,
    vi_bound,
)


def _spd(rng, n, cond=50.0):
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    return (Q * np.geomspace(1.0, cond, n)) @ Q.T


def _case(seed, n=12, m=5):
    """A random SPD A, X, a full-rank B, and the HF VI solution by brute force over the
    active sets (independent of rbbench's solvers)."""
    rng = np.random.default_rng(seed)
    A, X = _spd(rng, n), _spd(rng, n, 5.0)
    B = rng.standard_normal((m, n))
    F = 3.0 * rng.standard_normal(n)
    G = rng.standard_normal(m)
    best = None
    for mask in range(1 << m):
        act = np.array([(mask >> i) & 1 for i in range(m)], dtype=bool)
        K = np.block([[A, B[act].T], [B[act], np.zeros((act.sum(), act.sum()))]])
        sol = np.linalg.solve(K, np.concatenate([F, G[act]]))
        u, lam = sol[:n], np.zeros(m)
        lam[act] = sol[n:]
        if lam.min() >= -1e-10 and (B @ u - G).max() <= 1e-10:
            best = (u, np.maximum(lam, 0.0))
            break
    assert best is not None
    return rng, A, X, B, F, G, *best


def _solver(X):
    cho = sla.cho_factor(X)
    return lambda r: sla.cho_solve(cho, r)


def _errors(A, X, B, u, lam, u_N, lam_N, xs):
    e = u - u_N
    el = B.T @ (lam - lam_N)
    return float(np.sqrt(e @ X @ e)), float(np.sqrt(el @ xs(el)))


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10_000), scale=st.floats(1e-4, 1.0),
       lam_scale=st.floats(0.0, 2.0))
def test_bound_holds_for_any_reduced_pair(seed, scale, lam_scale):
    """Delta_u >= ||u - u_N||_X and Delta_lam >= ||lam - lam_N||_* for any u_N and any
    lam_N >= 0 (the theorem needs no Galerkin property)."""
    rng, A, X, B, F, G, u, lam = _case(seed)
    xs = _solver(X)
    u_N = u + scale * rng.standard_normal(u.size)
    lam_N = np.maximum(lam + lam_scale * rng.standard_normal(lam.size), 0.0)
    alpha, gamma = coercivity_constants(A, X)
    b = vi_bound(hf_bound_terms(A, F, B, G, xs, natural_dual(B, xs), u_N, lam_N), alpha,
                 gamma)
    err_u, err_lam = _errors(A, X, B, u, lam, u_N, lam_N, xs)
    assert b.delta_u >= err_u * (1 - 1e-10)
    assert b.delta_lam >= err_lam * (1 - 1e-10)
    # never above HSW's own form: sigma (l_N + rho) + max(0, lam_N . (G - B u_N))
    t = b.terms
    d1 = (t.rho + gamma * t.sigma) / (2 * alpha)
    hsw = d1 + np.sqrt(d1 * d1 + (t.sigma * (t.lam_norm + t.rho)
                                  + max(0.0, lam_N @ (G - B @ u_N))) / alpha)
    assert b.delta_u <= hsw * (1 + 1e-12)


def test_bound_vanishes_at_the_hf_solution():
    _, A, X, B, F, G, u, lam = _case(3)
    assert lam.max() > 0  # an active constraint
    xs = _solver(X)
    alpha, gamma = coercivity_constants(A, X)
    b = vi_bound(hf_bound_terms(A, F, B, G, xs, natural_dual(B, xs), u, lam), alpha, gamma)
    t, norm = b.terms, np.sqrt(u @ X @ u)
    assert t.rho <= 1e-13 * t.lam_norm and t.sigma <= 1e-13 * norm and t.kappa <= 1e-13
    # zero in exact arithmetic; the active rows' round-off (B u - G ~ eps) enters through
    # sqrt(sigma l_N / alpha): the floor is sqrt(eps), not eps
    assert b.delta_u <= 1e-6 * norm


def test_a_coercivity_constant_that_is_not_a_lower_bound_is_caught():
    """The check (bound >= error) fails when alpha is twice the true coercivity constant: a
    perturbation along the softest mode, no active constraint."""
    rng = np.random.default_rng(1)
    n, m = 10, 3
    A, X = _spd(rng, n), _spd(rng, n, 5.0)
    B = rng.standard_normal((m, n))
    F = rng.standard_normal(n)
    u = np.linalg.solve(A, F)
    G = B @ u + 10.0  # inactive: lam = 0
    w, V = sla.eigh(A, X)
    u_N = u + 1e-3 * V[:, 0] / np.sqrt(V[:, 0] @ X @ V[:, 0])
    xs = _solver(X)
    terms = hf_bound_terms(A, F, B, G, xs, natural_dual(B, xs), u_N, np.zeros(m))
    err = float(np.sqrt((u - u_N) @ X @ (u - u_N)))
    alpha, gamma = coercivity_constants(A, X)
    assert alpha == pytest.approx(w[0], rel=1e-7) and alpha <= w[0]
    assert vi_bound(terms, alpha, gamma).delta_u >= err
    assert vi_bound(terms, 2.0 * w[0], gamma).delta_u < err  # the violated assumption


def test_quadratic_root():
    """(5) is the larger root of alpha e^2 - (rho + gamma sigma) e - (sigma rho + kappa)."""
    t = BoundTerms(rho=0.3, sigma=0.2, kappa=0.05, lam_norm=1.5)
    alpha, gamma = 0.7, 1.3
    e = vi_bound(t, alpha, gamma).delta_u
    q = alpha * e * e - (t.rho + gamma * t.sigma) * e - (t.sigma * t.rho + t.kappa)
    assert abs(q) < 1e-12
    assert vi_bound(BoundTerms(0.3, 0.0, 0.0, 9.0), alpha, gamma).delta_u == \
        pytest.approx(0.3 / alpha)  # no violation: the linear bound rho / alpha


@pytest.mark.parametrize("block", [1, 3, 64])
def test_riesz_factor_matches_the_dual_norm(block):
    rng = np.random.default_rng(4)
    n = 30
    X = _spd(rng, n)
    P = rng.standard_normal((n, 10))
    P[:, 5] = P[:, 0] - 2 * P[:, 1]  # a dependent piece
    P[:, 8] = 3 * P[:, 6] + P[:, 2]  # one more, within a later block
    xs = _solver(X)
    T, ranks = riesz_factor(P, X, xs, block=block, return_ranks=True)
    assert T.shape[0] == 8
    assert ranks.tolist() == [1, 2, 3, 4, 5, 8, 6, 7, 8, 8]  # dropped pieces: all rows
    # upper trapezoidal: the rows below ranks[j] are round-off
    Tcut = T.copy()
    for j, r in enumerate(ranks):
        Tcut[r:, j] = 0.0
    for _ in range(5):
        w = rng.standard_normal(10)
        r = P @ w
        exact = np.sqrt(r @ xs(r))
        assert np.linalg.norm(T @ w) == pytest.approx(exact, rel=1e-10)
        assert np.linalg.norm(Tcut @ w) == pytest.approx(exact, rel=1e-10)


def test_natural_dual_refuses_a_dependent_b():
    rng = np.random.default_rng(0)
    X = _spd(rng, 6)
    B = rng.standard_normal((3, 6))
    B[2] = B[0] + B[1]
    with pytest.raises(ValueError, match="not injective"):
        natural_dual(B, _solver(X))

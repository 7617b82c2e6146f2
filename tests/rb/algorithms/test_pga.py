"""Projected Greedy Algorithm (Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction
methods: parametric variational inequalities" (talk), slides "Approximation of S_R" to
"Some details")."""

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from rbbench.rb.algorithms.infsup import (
    boundedness_constant,
    infsup_cone,
    infsup_span,
    make_solver,
    quotient_matrices,
    supremizer_operator,
)
from rbbench.rb.algorithms.pga import (
    pga,
    projection_defect,
    riesz_lower_bound,
    supremizers,
    theorem_lower_bound,
    x_orthonormalize,
)


def _instance(seed, n=60, m=8, R=3, N=4, P=5, affine=False):
    """Sparse SPD X, P parameters with B(mu) of full row rank (B0 + mu B1 when affine,
    else an independent random perturbation per mu), diagonal W, non-negative Vg."""
    rng = np.random.default_rng(seed)
    L = sp.diags([2 * np.ones(n), -np.ones(n - 1), -np.ones(n - 1)], [0, 1, -1])
    Rn = sp.random(n, n, density=0.03, random_state=seed)
    X = (L + 0.3 * (Rn @ Rn.T) + sp.diags(rng.uniform(0.05, 1.0, n))).tocsr()
    B0 = sp.random(m, n, density=0.15, random_state=seed + 1) + sp.eye(m, n, k=2)
    if affine:
        B1 = sp.random(m, n, density=0.15, random_state=seed + 2)
        Bs = [(B0 + mu * B1).tocsr() for mu in np.linspace(0.5, 1.5, P)]
    else:
        Bs = [(B0 + 0.5 * sp.random(m, n, density=0.1, random_state=seed + 10 + p)).tocsr()
              for p in range(P)]
    W = rng.uniform(0.5, 2.0, m)
    Vg = np.abs(rng.standard_normal((m, R)))
    Z = rng.standard_normal((n, N))
    solve = make_solver(X)
    T = [supremizers(B, solve, Vg) for B in Bs]
    return X, Bs, W, Vg, Z, T, solve


def _check_basis(res, Z, X):
    K = res.basis
    assert np.allclose(K.T @ (X @ K), np.eye(K.shape[1]), atol=1e-10)
    assert np.abs(Z.T @ (X @ K)).max() <= 1e-10 * np.linalg.norm(Z)


def test_exhausts_generic():
    X, _, _, _, Z, T, _ = _instance(0)
    res = pga(T, Z, X, delta=0.0)
    assert res.stop_reason == "exhausted"
    assert res.dim == 5 * 3  # sum of the S_R(mu): P R = 15 generic dimensions
    assert res.sigma_max[-1] <= 1e-10 and np.all(res.sigma <= 1e-10)
    assert len(res.sigma_max) == res.dim + 1 and len(res.picks) == res.dim
    assert all(0 <= p < len(T) for p in res.picks)
    assert np.all(np.diff(res.sigma_max) <= 1e-12)
    assert 0 < res.sigma_max[0] <= 1 + 1e-12
    _check_basis(res, Z, X)


def test_exhausts_affine_at_q_times_r():
    """B(mu) = B0 + mu B1: sum_mu S_R(mu) = span(X^-1 B0^T Vg, X^-1 B1^T Vg), dim 2R."""
    X, _, _, _, Z, T, _ = _instance(1, P=7, affine=True)
    res = pga(T, Z, X, delta=0.0)
    assert res.stop_reason == "exhausted" and res.dim == 2 * 3
    _check_basis(res, Z, X)


def test_history_matches_independent_recomputation():
    """sigma_max[i] = max_mu sigma_{S^i}(mu), recomputed from scratch for each prefix."""
    X, _, _, _, Z, T, _ = _instance(2)
    res = pga(T, Z, X, delta=0.0)
    for i in range(res.dim + 1):
        S = res.basis[:, :i]
        sig = [projection_defect(Tp, Z, S, X) for Tp in T]
        assert max(sig) == pytest.approx(res.sigma_max[i], rel=1e-8, abs=1e-11)
        if i < res.dim:  # greedy: the pick is an argmax
            assert sig[res.picks[i]] == pytest.approx(max(sig), rel=1e-8)
    assert res.sigma == pytest.approx([projection_defect(Tp, Z, res.basis, X) for Tp in T],
                                      abs=1e-11)


def test_tolerance_and_max_dim_stops():
    X, _, _, _, Z, T, _ = _instance(3)
    full = pga(T, Z, X, delta=0.0)
    res = pga(T, Z, X, delta=0.5)
    assert res.stop_reason == "tolerance"
    assert res.sigma_max[-1] <= 0.5 < res.sigma_max[-2]
    assert np.allclose(res.sigma_max, full.sigma_max[: res.dim + 1])
    res = pga(T, Z, X, delta=0.0, max_dim=4)
    assert res.stop_reason == "max_dim" and res.dim == 4 and len(res.sigma_max) == 5
    assert res.picks == full.picks[:4]


def test_rank_deficiency():
    """Duplicate / dependent generators and a supremizer already inside V_N."""
    X, _, _, Vg, Z, T, _ = _instance(4)
    T = [np.column_stack([Tp, Tp[:, 0] + 2 * Tp[:, 1], Tp[:, 0]]) for Tp in T]
    Z = np.column_stack([Z, T[0][:, 0], Z[:, 0] + Z[:, 1]])  # V_N holds one supremizer
    res = pga(T, Z, X, delta=0.0)
    assert res.stop_reason == "exhausted" and res.dim == 5 * 3 - 1
    _check_basis(res, Z, X)
    Q, XQ = x_orthonormalize(T[0], X)
    assert Q.shape[1] == 3 and np.allclose(XQ, X @ Q)
    assert np.allclose(Q.T @ XQ, np.eye(3), atol=1e-12)


def test_x_orthonormalize_paths_agree():
    """Blocked CholeskyQR2 (well-conditioned input) and pivoted Gram-Schmidt (forced by a
    dependent column) span the same space; near-dependence above rtol is kept, below dropped."""
    X, _, _, _, Z, T, _ = _instance(9)
    V = T[0]
    Q1, XQ1 = x_orthonormalize(V, X)  # fast path
    Q2, _ = x_orthonormalize(np.column_stack([V, V[:, 0] - V[:, 1]]), X)  # fallback path
    P1, P2 = Q1 @ XQ1.T, Q2 @ (X @ Q2).T  # X-orthogonal projectors
    assert Q1.shape[1] == Q2.shape[1] == 3 and np.allclose(P1, P2, atol=1e-10)
    a, b = V[:, 0], V[:, 1]
    assert x_orthonormalize(np.column_stack([a, a + 1e-6 * b]), X)[0].shape[1] == 2
    assert x_orthonormalize(np.column_stack([a, a + 1e-14 * b]), X)[0].shape[1] == 1
    Zo, XZo = x_orthonormalize(Z, X)
    Q3, _ = x_orthonormalize(V, X, U=Zo, XU=XZo)
    assert np.abs(Zo.T @ (X @ Q3)).max() < 1e-12
    assert np.allclose(Q3.T @ (X @ Q3), np.eye(3), atol=1e-12)


def test_empty_inputs():
    X, _, _, _, Z, T, _ = _instance(5)
    res = pga([], Z, X, delta=0.1)
    assert res.dim == 0 and res.stop_reason == "exhausted"
    res = pga([np.zeros((60, 2))], Z, X, delta=0.1)
    assert res.dim == 0 and res.sigma_max[0] == 0.0
    assert projection_defect(T[0], Z, None, X) == pytest.approx(
        pga(T[:1], Z, X, 0.0).sigma_max[0])


def _constants(B, X, solve, W, Vg, Zs):
    """beta_on (cone, span), c_HF (V x W), beta over span([Z, S]) (cone, span)."""
    T = supremizers(B, solve, Vg)
    H_hf = supremizer_operator(B, solve)
    S_on, M = quotient_matrices(B, X, Vg, W, Z=np.hstack([Zs[0], T]))
    S_all, M_all = quotient_matrices(B, X, np.eye(B.shape[0]), W, H=H_hf)
    c_hf = boundedness_constant(S_all, M_all)
    offs = []
    for Zoff in Zs[1:]:
        S_off, _ = quotient_matrices(B, X, Vg, W, Z=Zoff)
        offs.append((infsup_cone(S_off, M).value, infsup_span(S_off, M)))
    return infsup_cone(S_on, M).value, infsup_span(S_on, M), c_hf, T, offs


@settings(derandomize=True, max_examples=8, deadline=None)
@given(seed=st.integers(0, 10**5))
def test_main_result(seed):
    """Benaceur et al.'s "Main result": sigma_S(mu) < beta_on / c_HF  =>  beta_off(mu) >=
    (beta_on - c_HF sigma) / (1 + sigma), for every PGA prefix S^i, on training and
    validation parameters (the bound holds for any mu), cone and span values alike."""
    X, Bs, W, Vg, Z, T, solve = _instance(seed, n=50, m=6, R=3, N=3, P=6)
    train, valid = Bs[:4], Bs[4:]
    res = pga(T[:4], Z, X, delta=0.0)
    assert np.all(np.diff(res.sigma_max) <= 1e-12)
    prefixes = [res.basis[:, :i] for i in range(res.dim + 1)]
    hits = 0
    for B in train + valid:
        b_on, b_on_span, c, Tmu, offs = _constants(
            B, X, solve, W, Vg, [Z] + [np.hstack([Z, S]) for S in prefixes])
        assert b_on_span <= b_on + 1e-12
        sig = [projection_defect(Tmu, Z, S, X) for S in prefixes]
        assert np.all(np.diff(sig) <= 1e-12)  # basic property 1: S grows -> sigma decreases
        for s, (off_cone, off_span) in zip(sig, offs, strict=True):
            # sharper, condition-free bound (rbbench.rb.algorithms.pga.riesz_lower_bound); nearly
            # tight
            assert off_cone >= riesz_lower_bound(b_on, s) * (1 - 1e-9)
            assert off_span >= riesz_lower_bound(b_on_span, s) * (1 - 1e-9)
            if s < b_on_span / c:
                hits += 1
                assert off_span >= theorem_lower_bound(b_on_span, c, s) - 1e-10
            if s < b_on / c:
                assert off_cone >= theorem_lower_bound(b_on, c, s) - 1e-10
                assert theorem_lower_bound(b_on, c, s) > 0
    assert hits > 0


def test_main_result_tolerance_gives_stable_training_set():
    """delta_PGA < min_train beta_on / c_HF  =>  beta_off > 0 on every training mu."""
    X, Bs, W, Vg, Z, T, solve = _instance(7, n=50, m=6, R=3, N=3, P=5)
    ratios = []
    for B in Bs:
        b_on, _, c, _, _ = _constants(B, X, solve, W, Vg, [Z])
        ratios.append(b_on / c)
    delta = 0.9 * min(ratios)
    res = pga(T, Z, X, delta=delta)
    assert res.stop_reason in ("tolerance", "exhausted") and res.sigma_max[-1] <= delta
    Zoff = np.hstack([Z, res.basis])
    for B, r in zip(Bs, ratios, strict=True):
        b_on, _, c, _, offs = _constants(B, X, solve, W, Vg, [Z, Zoff])
        sigma = projection_defect(supremizers(B, solve, Vg), Z, res.basis, X)
        assert sigma <= delta < r
        assert offs[0][0] >= theorem_lower_bound(b_on, c, sigma) - 1e-10 > 0


def test_riesz_bound_is_attained_for_a_single_generator():
    """R = 1: the cone and span are one ray, beta_off = ||Pi T||/||T|| beta_on exactly, and
    sigma = ||(I - Pi) T|| / ||T||: the sharper bound holds with equality."""
    X, Bs, W, Vg, Z, _, solve = _instance(8, R=1)
    B = Bs[0]
    T = supremizers(B, solve, Vg)
    S = pga([T], Z, X, delta=0.0).basis[:, :0]
    sigma = projection_defect(T, Z, S, X)
    b_on = infsup_span(*quotient_matrices(B, solve, Vg, W))
    b_off = infsup_span(*quotient_matrices(B, X, Vg, W, Z=Z))
    assert 0 < sigma < 1
    assert b_off == pytest.approx(riesz_lower_bound(b_on, sigma), rel=1e-9)


def test_theorem_lower_bound_formula():
    assert theorem_lower_bound(0.5, 2.0, 0.1) == pytest.approx(0.3 / 1.1)
    assert theorem_lower_bound(0.5, 2.0, 0.25) == pytest.approx(0.0)
    out = theorem_lower_bound(np.array([0.5, 0.5]), 2.0, np.array([0.0, 0.5]))
    assert np.allclose(out, [0.5, -0.5 / 1.5])
    assert riesz_lower_bound(2.0, 0.6) == pytest.approx(1.6)
    assert riesz_lower_bound(2.0, 0.6) >= theorem_lower_bound(2.0, 2.0, 0.6)

"""Dual compressors (rbbench.rb.algorithms.cones): exact cone projection, greedy invariants,
baselines."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import nnls

from rbbench.rb.algorithms import cones

FAST = settings(max_examples=50, deadline=None, derandomize=True)


# ----------------------------------------------------------------------- fixtures
def _metric(kind: str, n: int, rng: np.random.Generator):
    if kind == "diag":
        return sp.diags(rng.uniform(0.5, 2.0, n))
    if kind == "diag1d":
        return rng.uniform(0.5, 2.0, n)
    if kind == "tridiag":  # consistent P1 boundary mass on a uniform 1-D grid
        h = 1.0 / max(n - 1, 1)
        main = np.full(n, 4 * h / 6)
        main[[0, -1]] = 2 * h / 6
        off = np.full(n - 1, h / 6)
        return sp.diags([off, main, off], [-1, 0, 1], format="csr")
    A = rng.standard_normal((n, n))
    return A @ A.T + n * np.eye(n)  # dense SPD


def _bumps(seed: int, n: int, Q: int):
    """Hertz-like pressure bumps of random centre, width and height, lumped-mass W."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.0, n)
    h = x[1] - x[0]
    w = np.full(n, h)
    w[[0, -1]] = h / 2
    c = rng.uniform(0.3, 0.7, Q)
    a = rng.uniform(0.05, 0.25, Q)
    p = rng.uniform(0.5, 2.0, Q)
    T = p * np.sqrt(np.maximum(0.0, 1.0 - ((x[:, None] - c) / a) ** 2))
    return T, sp.diags(w)


def _random_nonneg(seed: int, n: int, Q: int):
    rng = np.random.default_rng(seed)
    T = rng.random((n, Q)) * (rng.random((n, Q)) < 0.6)
    T[rng.integers(0, n), :] += 0.1  # no all-zero column
    return T, sp.diags(rng.uniform(0.5, 2.0, n))


@st.composite
def families(draw, max_q: int = 10):
    seed = draw(st.integers(0, 10_000))
    Q = draw(st.integers(2, max_q))
    if draw(st.booleans()):
        return _bumps(seed, draw(st.integers(30, 80)), Q)
    return _random_nonneg(seed, draw(st.integers(4, 25)), Q)


# ------------------------------------------------------------------ cone projection
def _brute_force(theta, V, W):
    """Enumerate all faces: unconstrained W-least squares on each support, keep feasible."""
    Wd = W.toarray() if sp.issparse(W) else (np.diag(W) if np.ndim(W) == 1 else W)
    L = np.linalg.cholesky(Wd)
    C = L.T
    R = V.shape[1]
    best = (np.zeros(R), float(np.linalg.norm(C @ theta)))
    for k in range(1, R + 1):
        for S in itertools.combinations(range(R), k):
            S = list(S)
            aS = np.linalg.lstsq(C @ V[:, S], C @ theta, rcond=None)[0]
            if np.all(aS >= 0):
                a = np.zeros(R)
                a[S] = aS
                e = float(np.linalg.norm(C @ (theta - V @ a)))
                if e < best[1] - 1e-14:
                    best = (a, e)
    return best, Wd


@FAST
@given(seed=st.integers(0, 10_000), R=st.integers(1, 4), extra=st.integers(0, 6),
       kind=st.sampled_from(["diag", "diag1d", "tridiag", "dense"]), nonneg=st.booleans())
def test_cone_projection_matches_brute_force_and_kkt(seed, R, extra, kind, nonneg):
    rng = np.random.default_rng(seed)
    n = R + extra + 1
    V = rng.standard_normal((n, R))
    theta = rng.standard_normal(n)
    if nonneg:
        V, theta = np.abs(V), np.abs(theta)
    W = _metric(kind, n, rng)
    alpha, proj, err = cones.cone_projection(theta, V, W)
    (a_ref, e_ref), Wd = _brute_force(theta, V, W)
    scale = max(1.0, float(np.abs(a_ref).max()))
    assert np.all(alpha >= 0)
    assert abs(err - e_ref) <= 1e-10 * max(1.0, e_ref)
    assert np.allclose(alpha, a_ref, atol=1e-10 * scale, rtol=0)
    assert np.allclose(proj, V @ alpha, atol=1e-12 * scale)
    # obtuse-angle (KKT) characterisation of the projection onto a closed convex cone
    res = theta - proj
    tol = 1e-10 * np.sqrt(theta @ Wd @ theta) * np.sqrt(np.diag(V.T @ Wd @ V)).max()
    assert np.all(res @ Wd @ V <= tol)
    assert abs(res @ Wd @ proj) <= tol * max(1.0, np.abs(alpha).sum())


def test_cone_projection_batch_empty_and_gram_reuse():
    rng = np.random.default_rng(3)
    n, R, k = 40, 6, 7
    V = np.abs(rng.standard_normal((n, R)))
    Th = rng.standard_normal((n, k))
    W = _metric("tridiag", n, rng)
    gram = cones.cone_gram(V, W)
    A, P, E = cones.cone_projection(Th, gram=gram)
    assert A.shape == (R, k) and P.shape == (n, k) and E.shape == (k,)
    for j in range(k):
        a, p, e = cones.cone_projection(Th[:, j], V, W)
        assert np.allclose(A[:, j], a, atol=1e-12) and np.isclose(E[j], e, rtol=1e-12)
    # trivial cone {0}: the error is the W-norm
    a0, p0, e0 = cones.cone_projection(Th, np.zeros((n, 0)), W)
    assert a0.shape == (0, k) and np.all(p0 == 0)
    assert np.allclose(e0, np.sqrt(np.einsum("ij,ij->j", Th, W @ Th)))


def test_metric_variants_agree():
    rng = np.random.default_rng(0)
    n = 9
    d = rng.uniform(0.5, 2.0, n)
    x = rng.standard_normal(n)
    ref = np.sqrt(x @ (d * x))
    for W in (d, np.diag(d), sp.diags(d), sp.csr_matrix(np.diag(d))):
        M = cones.as_metric(W)
        assert M.is_diagonal and np.isclose(M.norm(x), ref, rtol=1e-14)
    Wt = _metric("tridiag", n, rng)
    M = cones.as_metric(Wt)
    assert not M.is_diagonal
    assert np.isclose(M.norm(x), np.sqrt(x @ (Wt @ x)), rtol=1e-13)
    assert np.allclose(M.unfactor(M.factor(x)), x)
    with pytest.raises(ValueError):
        cones.as_metric(-np.eye(3))


# ------------------------------------------------------------------ mCPG sub-problem
def _kkt_residual(theta, V, Wd, alpha):
    """Optimality certificate of the mCPG QP: multipliers by NNLS on the active constraints.

    min 1/2 ||theta - V a||_W^2 s.t. a >= 0, V a <= theta is solved iff
    grad = -V^T W (theta - V a) = lam - V^T mu with lam >= 0 on {a = 0}, mu >= 0 on
    {V a = theta}: returns the relative residual of that NNLS.
    """
    R = V.shape[1]
    g = -V.T @ Wd @ (theta - V @ alpha)
    act_b = np.where(alpha <= 1e-12 * max(1.0, alpha.max()))[0]
    act_c = np.where(theta - V @ alpha <= 1e-9 * theta.max())[0]
    A = np.hstack([np.eye(R)[:, act_b], -V[act_c].T])
    if A.shape[1] == 0:
        return np.linalg.norm(g) / max(1.0, np.linalg.norm(V.T @ Wd @ theta))
    _, r = nnls(A, g)
    return r / max(1.0, np.linalg.norm(V.T @ Wd @ theta))


@FAST
@given(seed=st.integers(0, 10_000), R=st.integers(1, 5), n=st.integers(3, 25),
       kind=st.sampled_from(["diag", "tridiag", "dense"]))
def test_mcpg_split_feasible_in_cone_and_optimal(seed, R, n, kind):
    rng = np.random.default_rng(seed)
    V = rng.random((n, R)) * (rng.random((n, R)) < 0.7)
    theta = rng.random(n) * (rng.random(n) < 0.8) + 0.3 * V[:, 0]
    W = _metric(kind, n, rng)
    Wd = W.toarray() if sp.issparse(W) else W
    alpha, tt, nu, status = cones.mcpg_split(theta, V, W)
    scale = np.abs(theta).max()
    assert status["ok"] and status["flag"] == 1 and status["shrink"] >= 1 - 1e-6
    assert status["alpha_raw_min"] >= -1e-10  # daqp's raw coefficients, before the clip
    assert status["nu_raw_min"] >= -1e-12  # the raw residual is in W+ to round-off
    assert np.all(alpha >= 0)  # theta_tilde in the previous cone ...
    assert np.allclose(tt, V @ alpha, atol=1e-14 * scale)
    assert np.all(nu >= 0)  # ... and the residual in W+
    assert np.all(theta - tt >= -1e-12 * scale)
    assert np.allclose(theta - tt, nu, atol=1e-12 * scale)
    # optimal: KKT multipliers exist (independent NNLS certificate) ...
    assert _kkt_residual(theta, V, Wd, alpha) <= 1e-9
    # ... and no feasible point of a crude independent search does better
    best = nu @ Wd @ nu
    for _ in range(200):
        a = alpha + 0.1 * rng.standard_normal(R) * max(1.0, alpha.max())
        a = np.maximum(a, 0)
        Va = V @ a
        if np.any(Va > theta):
            a *= np.min(theta[Va > theta] / Va[Va > theta])
        r = theta - V @ a
        assert r @ Wd @ r >= best - 1e-12 * (theta @ Wd @ theta)


def test_mcpg_split_exact_when_theta_in_cone():
    rng = np.random.default_rng(1)
    V = rng.random((20, 4))
    theta = V @ np.array([0.5, 0.0, 2.0, 1.0])
    _, tt, nu, status = cones.mcpg_split(theta, V, np.ones(20))
    assert status["ok"] and np.abs(nu).max() <= 1e-12 * theta.max()
    assert np.allclose(tt, theta, atol=1e-12 * theta.max())


# --------------------------------------------------------------- deterministic cases
def test_cpg_hand_computed():
    # W = diag(1, 2, 1); ||t1|| = 1, ||t2|| = sqrt(2), ||t3|| = 2.
    W = np.array([1.0, 2.0, 1.0])
    T = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0], [0.0, 0.0, 1.0]])
    b = cones.cpg(T, W, tol=0.0)
    # r=1: t3 (largest norm). Residuals on Span+{t3}: t1 -> (3,-1,-1)/4, norm sqrt(3)/2;
    # t2 -> (-1,1,-1)/2, norm 1: r=2 picks t2. Then t1 on Span+{t3,t2}: min over b>=0 of
    # (1-b)^2 + 2 b^2 + b^2 (a = 0 on t2) -> b = 1/4, error^2 = 3/4.
    assert b.selected == [2, 1, 0]
    assert np.allclose(b.e_proj, [1 / 2, np.sqrt(3) / 4, 0.0], atol=1e-14)
    assert np.allclose(b.e_orth, [1.0, 1 / np.sqrt(2), np.sqrt(3) / 2], atol=1e-14)
    assert np.allclose(b.generators[:, 0], T[:, 2] / 2)
    assert cones.cpg(T, W, tol=1e-12).info["stop"] == "tol"
    assert cones.cpg(T, W, tol=0.6).R == 1
    assert cones.cpg(T, W, tol=0.0, r_max=2).info["stop"] == "r_max"


def test_mcpg_hand_computed_wider_aperture_than_cpg():
    # W = I, t1 = (0,3,0) is picked first; t2 = (1,1,1). mCPG: max feasible peel of t2 along
    # t1 is theta_tilde = (0,1,0) (also the unconstrained optimum), so nu_2 = (1,0,1)/sqrt2,
    # W-orthogonal to t1 (e_orth = 1); CPG adds t2 itself (e_orth = sqrt(2/3)).
    T = np.array([[0.0, 1.0], [3.0, 1.0], [0.0, 1.0]])
    W = np.ones(3)
    bm = cones.mcpg(T, W, tol=0.0)
    bc = cones.cpg(T, W, tol=0.0)
    assert bm.selected == bc.selected == [0, 1]
    assert np.allclose(bm.generators[:, 1], np.array([1, 0, 1]) / np.sqrt(2), atol=1e-12)
    assert np.allclose(bm.e_orth, [1.0, 1.0], atol=1e-12)
    assert np.allclose(bc.e_orth, [1.0, np.sqrt(2 / 3)], atol=1e-12)
    assert bm.e_proj[-1] <= 1e-12 and bc.e_proj[-1] <= 1e-12
    assert bm.info["cond_G"][-1] < bc.info["cond_G"][-1]


def test_negative_snapshots_rejected_and_noise_clipped():
    T = np.array([[1.0, 0.5], [0.0, -0.2]])
    with pytest.raises(ValueError, match="negative"):
        cones.cpg(T, np.ones(2))
    T[1, 1] = -1e-17
    b = cones.cpg(T, np.ones(2), tol=0.0)
    assert b.info["clipped_negative"] == 1 and b.generators.min() >= 0


# ----------------------------------------------------------------- greedy invariants
def _check_greedy(b, T, W, nested: bool = True):
    M = cones.as_metric(W)
    assert b.is_cone and b.R == len(b.e_proj) == len(b.e_orth) == len(b.selected)
    assert np.all(b.generators >= 0)
    assert np.allclose(M.norm(b.generators), 1.0, atol=1e-12)
    e = np.asarray(b.e_proj)
    assert np.all(e <= 1 + 1e-12) and np.all(e >= 0)
    if nested:
        assert np.all(np.diff(e) <= 1e-12)  # nested cones: theorem
    o = np.asarray(b.e_orth)
    assert np.all((o >= 0) & (o <= 1))
    if b.R:
        assert o[0] == pytest.approx(1.0)
    assert len(set(b.selected)) == len(b.selected)
    # every selected snapshot is reproduced by the final cone
    scale = M.norm(T).max()
    _, _, err = cones.cone_projection(T[:, b.selected], gram=cones.cone_gram(b.generators, M))
    assert np.all(err <= 1e-9 * scale)


@FAST
@given(fam=families())
def test_cpg_invariants(fam):
    T, W = fam
    Q = T.shape[1]
    b = cones.cpg(T, W, tol=0.0, r_max=Q)
    _check_greedy(b, T, W)
    assert b.e_proj[-1] <= 1e-10  # all snapshots available: exact
    assert b.info["stop"] in {"exhausted", "r_max", "tol"}
    # each selected snapshot is exact right after it is added (nested: stays so)
    M = cones.as_metric(W)
    for r in range(1, b.R + 1):
        g = cones.cone_gram(b.generators[:, :r], M)
        assert cones.cone_projection(T[:, b.selected[r - 1]], gram=g)[2] <= 1e-10 * M.norm(T).max()
        # first pick: the largest snapshot
    assert b.selected[0] == int(np.argmax(M.norm(T)))


@FAST
@given(fam=families())
def test_mcpg_invariants(fam):
    T, W = fam
    b = cones.mcpg(T, W, tol=0.0, r_max=T.shape[1])
    _check_greedy(b, T, W)
    assert b.info["qp_fallbacks"] == 0 and b.info["qp_min_shrink"] >= 1 - 1e-6
    assert b.e_proj[-1] <= 1e-8


@pytest.mark.parametrize("case", [(0, 4, 7), (11, 4, 10)])
def test_mcpg_more_generators_than_n(case):
    # R > n: singular QP Hessian and degenerate rows (theta_i = 0); regression cases in
    # which daqp alone reported infeasibility at tight tolerance (fixed by the presolve).
    T, W = _random_nonneg(*case)
    for f in (cones.mcpg, cones.eng):
        b = f(T, W, tol=0.0, r_max=T.shape[1])
        assert b.info["qp_fallbacks"] == 0
        _check_greedy(b, T, W)


@settings(max_examples=30, deadline=None, derandomize=True)
@given(fam=families(max_q=8))
def test_eng_invariants(fam):
    T, W = fam
    b = cones.eng(T, W, tol=0.0, r_max=T.shape[1])
    _check_greedy(b, T, W)
    assert b.e_proj[-1] <= 1e-8


@settings(max_examples=20, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), n=st.integers(3, 15), R=st.integers(2, 6))
def test_eng_peeling_only_enlarges_the_cone(seed, n, R):
    rng = np.random.default_rng(seed)
    V = rng.random((n, R)) * (rng.random((n, R)) < 0.8) + 0.05 * rng.random((n, 1))
    M = cones.as_metric(rng.uniform(0.5, 2.0, n))
    V = V / M.norm(V)
    info: dict = {}
    Vp = cones._peel_all(V, M, info, sweeps=2, min_gain=1e-10)
    assert np.all(Vp >= 0) and np.allclose(M.norm(Vp), 1.0)
    _, _, err = cones.cone_projection(V, gram=cones.cone_gram(Vp, M))
    assert np.all(err <= 1e-9)  # the old generators are inside the new cone


def test_eng_differs_from_cpg_on_nested_supports():
    # a narrow bump inside a wide one: peeling strips the narrow part off the wide generator
    x = np.linspace(0, 1, 41)
    wide = np.maximum(0, 1 - ((x - 0.5) / 0.4) ** 2)
    narrow = 2 * np.maximum(0, 1 - ((x - 0.5) / 0.1) ** 2)
    side = np.maximum(0, 1 - ((x - 0.3) / 0.1) ** 2)
    T = np.column_stack([wide, narrow, side])
    be = cones.eng(T, np.ones(41), tol=0.0)
    bc = cones.cpg(T, np.ones(41), tol=0.0)
    assert be.info["peel_replacements"] >= 1
    assert be.info["cond_G"][-1] <= bc.info["cond_G"][-1] + 1e-9
    assert np.all(be.generators >= 0) and be.e_proj[-1] <= 1e-10


# ------------------------------------------------------------------------ baselines
@FAST
@given(fam=families())
def test_pod_dual_baseline(fam):
    T, W = fam
    b = cones.pod_dual(T, W, tol=1e-6)
    M = cones.as_metric(W)
    assert not b.is_cone and b.selected == []
    assert np.allclose(M.inner(b.generators, b.generators), np.eye(b.R), atol=1e-10)
    e = np.asarray(b.e_proj)
    assert np.all(np.diff(e) <= 1e-12) and e[-1] <= 1e-6
    _, _, err = b.project(T, W)
    assert np.isclose(err.max() / M.norm(T).max(), e[-1], atol=1e-12)


@settings(max_examples=15, deadline=None, derandomize=True)
@given(fam=families(max_q=6), r=st.integers(1, 4))
def test_nnmf_baseline(fam, r):
    T, W = fam
    b = cones.nnmf(T, W, r, max_iter=200)
    assert b.is_cone and b.R == r and np.all(b.generators >= 0)
    e = np.asarray(b.e_proj)
    assert e.shape == (r,) and np.all(e[np.isfinite(e)] <= 1 + 1e-12)
    assert np.isfinite(e[-1])
    o = np.asarray(b.e_orth)
    assert np.all((o >= 0) & (o <= 1))
    b2 = cones.nnmf(T, W, r, max_iter=200)
    assert np.array_equal(b.generators, b2.generators)  # deterministic


def test_nnmf_history_modes_and_general_metric():
    T, _ = _bumps(0, 40, 6)
    Wt = _metric("tridiag", 40, np.random.default_rng(0))
    b = cones.nnmf(T, Wt, 3, history=False, max_iter=100)
    assert np.isnan(b.e_proj[0]) and np.isfinite(b.e_proj[-1])
    assert b.info["e_proj_history"] == "final rank only" and "lumped" in b.info["metric"]
    b = cones.nnmf(T, Wt, 3, history=True, max_iter=100)
    assert np.all(np.isfinite(b.e_proj))


def test_registry_common_signature():
    T, W = _bumps(5, 60, 8)
    assert set(cones.DUAL_COMPRESSORS) == {"pod", "cpg", "mcpg", "eng", "nnmf"}
    for name, f in cones.DUAL_COMPRESSORS.items():
        b = f(T, W, 1e-2, 5)
        assert isinstance(b, cones.DualBasis) and b.name == name
        assert 1 <= b.R <= 5 and b.info["stop"] in {"tol", "r_max", "rank", "exhausted"}
        assert b.e_proj[-1] <= 1e-2 or b.R == 5
        assert b.is_cone == (name != "pod")
    with pytest.raises(TypeError):
        cones.cpg(T, W, 1e-2, 5, bogus=1)


def test_cones_on_a_general_metric():
    T, _ = _bumps(2, 50, 7)
    W = _metric("tridiag", 50, np.random.default_rng(0))
    for f in (cones.cpg, cones.mcpg, cones.eng):
        _check_greedy(f(T, W, tol=0.0), T, W)

"""Span / cone inf-sup constants, the exact beta = 0 LP, and the supremizer property."""

import numpy as np
import pytest
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from hypothesis import given, settings
from hypothesis import strategies as st

from rbbench.rb.algorithms.infsup import (
    beta_zero_certificate,
    beta_zero_test,
    boundedness_constant,
    cone_coupling,
    infsup_cone,
    infsup_span,
    make_solver,
    quotient_matrices,
    supremizer_operator,
)
from rbbench.rb.algorithms.pga import supremizers

PROPS = settings(derandomize=True, max_examples=40, deadline=None)


def _spd(rng, R, cond=1.0):
    Q, _ = np.linalg.qr(rng.standard_normal((R, R)))
    return (Q * np.geomspace(1.0, 1.0 / cond, R)) @ Q.T


def _pencil(seed, R, k, cond):
    """S = C^T C with C (k x R) (singular when k < R), M SPD with condition number cond."""
    rng = np.random.default_rng(seed)
    C = rng.standard_normal((k, R))
    return C, C.T @ C, _spd(rng, R, cond)


def _quotient(Y, S, M):
    return np.einsum("ci,ij,cj->c", Y, S, Y) / np.einsum("ci,ij,cj->c", Y, M, Y)


def _problem(seed, n=40, m=6):
    """Random sparse SPD X, B with full row rank, diagonal W."""
    rng = np.random.default_rng(seed)
    L = sp.diags([2 * np.ones(n), -np.ones(n - 1), -np.ones(n - 1)], [0, 1, -1])
    Rn = sp.random(n, n, density=0.05, random_state=seed)
    X = (L + 0.3 * (Rn @ Rn.T) + sp.diags(rng.uniform(0.05, 1.0, n))).tocsr()
    B = (sp.random(m, n, density=0.2, random_state=seed + 1) + sp.eye(m, n, k=3)).tocsr()
    assert np.linalg.matrix_rank(B.toarray()) == m
    W = rng.uniform(0.5, 2.0, m)
    return rng, X, B, W


# ----------------------------------------------------------------------------- span vs cone


@PROPS
@given(seed=st.integers(0, 10**6), R=st.integers(1, 6), dk=st.integers(-3, 2),
       cond=st.sampled_from([1.0, 1e2, 1e6]))
def test_span_is_lower_bound_of_cone(seed, R, dk, cond):
    C, S, M = _pencil(seed, R, max(1, R + dk), cond)
    res = infsup_cone(S, M, C=C)
    assert res.kind == "cone-exact"
    assert res.span == pytest.approx(infsup_span(S, M))
    scale = boundedness_constant(S, M)
    assert res.span <= res.value + 1e-9 * scale
    assert res.value <= scale * (1 + 1e-12)
    # value is attained at the returned feasible point
    y = res.argmin
    assert np.all(y >= 0) and y.sum() == pytest.approx(1.0)
    assert np.sqrt(max(_quotient(y[None], S, M)[0], 0)) == pytest.approx(res.value, abs=1e-12)


@PROPS
@given(seed=st.integers(0, 10**6), R=st.integers(1, 7), cond=st.sampled_from([1.0, 1e3]))
def test_exact_below_every_local_minimum(seed, R, cond):
    """Face enumeration (exact) <= multistart SLSQP (upper), and they agree."""
    C, S, M = _pencil(seed, R, R + 1, cond)
    exact = infsup_cone(S, M, C=C)
    upper = infsup_cone(S, M, C=C, exact_max_r=0, n_starts=64, seed=seed)
    assert upper.kind == "cone-upper"
    assert exact.value <= upper.value + 1e-10
    assert exact.value == pytest.approx(upper.value, rel=1e-6, abs=1e-9)


def test_face_enumeration_vs_dense_simplex_sampling():
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 1.0, 20001)
    g = np.linspace(0.0, 1.0, 401)
    a, b = np.meshgrid(g, g)
    keep = a + b <= 1.0
    grids = {2: np.column_stack([t, 1 - t]),
             3: np.column_stack([a[keep], b[keep], 1 - a[keep] - b[keep]])}
    for trial in range(10):
        for R, Y in grids.items():
            A = rng.standard_normal((R + 1, R))
            S, M = A.T @ A, _spd(rng, R, 10.0 ** rng.integers(0, 3))
            q_exact = infsup_cone(S, M).value ** 2
            q_grid = _quotient(Y, S, M)
            assert q_exact <= q_grid.min() + 1e-12, (trial, R)
            tol = 1e-6 if R == 2 else 1e-4  # O(h^2) grid error, relative to the range of q
            assert q_grid.min() - q_exact <= tol * q_grid.max(), (trial, R)
            upper = infsup_cone(S, M, exact_max_r=0, n_starts=64).value ** 2
            assert abs(upper - q_exact) <= 1e-6 * max(q_exact, 1e-12) + 1e-14


def test_cone_strictly_above_span():
    """Columns (1,0), (0,1), (1,1): a sign-changing null vector (span beta = 0) but all
    columns in the half-plane x + y > 0 (cone beta > 0)."""
    C = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0]])
    S, M = C.T @ C, np.eye(3)
    res = infsup_cone(S, M, C=C)
    assert res.span == pytest.approx(0.0, abs=1e-7)
    # min over the simplex of ||C y||^2 / ||y||^2: attained at y = e_1 or e_2 -> 1
    assert res.value == pytest.approx(1.0, abs=1e-12)
    assert not res.is_zero and not beta_zero_test(C)


def test_dependent_generators():
    rng = np.random.default_rng(0)
    Vg = np.abs(rng.standard_normal((6, 3)))
    Vg = np.column_stack([Vg, Vg[:, 0] + Vg[:, 1]])  # dependent, still non-negative
    H = rng.standard_normal((6, 4))
    C = cone_coupling(H, Vg)
    S, M = C.T @ C, Vg.T @ Vg
    assert infsup_span(S, M) == pytest.approx(infsup_span(S[:3, :3], M[:3, :3]), rel=1e-9)
    # same cone as the 3 independent generators (v1 + v2 is in it): same constant
    assert infsup_cone(S, M).value == pytest.approx(
        infsup_cone(S[:3, :3], M[:3, :3]).value, rel=1e-8)


# ----------------------------------------------------------------------------- beta = 0 LP


def _with_nonneg_null(rng, k, R):
    alpha = rng.uniform(0.1, 1.0, R)
    C = rng.standard_normal((k, R))
    return C - np.outer(C @ alpha, alpha) / (alpha @ alpha), alpha / alpha.sum()


@pytest.mark.parametrize("k,R", [(2, 3), (4, 4), (10, 5), (3, 8)])
def test_beta_zero_true(k, R):
    rng = np.random.default_rng(k * 10 + R)
    C, _ = _with_nonneg_null(rng, k, R)
    C *= 1e3  # scale-free
    dist, alpha = beta_zero_certificate(C)
    assert beta_zero_test(C)
    assert dist <= 1e-10 and np.all(alpha >= 0) and alpha.sum() == pytest.approx(1.0)
    assert np.linalg.norm(C @ alpha) <= 1e-9 * np.linalg.norm(C)
    res = infsup_cone(C.T @ C, _spd(rng, R, 10.0), C=C)
    assert res.is_zero and res.value <= 1e-6 * np.linalg.norm(C)
    # also through the S-only route (C recovered from S)
    assert infsup_cone(C.T @ C, _spd(rng, R, 10.0)).is_zero


@pytest.mark.parametrize("k,R", [(2, 3), (4, 4), (10, 5), (3, 8)])
def test_beta_zero_false_open_half_space(k, R):
    rng = np.random.default_rng(k * 10 + R + 1)
    h = rng.standard_normal(k)
    h /= np.linalg.norm(h)
    C = rng.standard_normal((k, R))
    C += np.outer(h, 0.05 - h @ C + np.abs(rng.standard_normal(R)))  # h . c_j > 0.05
    assert np.all(h @ C > 0.05 - 1e-12)
    dist, _ = beta_zero_certificate(C)
    assert not beta_zero_test(C)
    assert dist >= 0.05 / np.linalg.norm(C, axis=0).max() / 2
    res = infsup_cone(C.T @ C, np.eye(R), C=C)
    assert not res.is_zero and res.value > 1e-3


def test_beta_zero_zero_column_and_empty():
    C = np.array([[1.0, 0.0], [2.0, 0.0]])
    assert beta_zero_test(C)
    assert not beta_zero_test(np.zeros((3, 0)))


@PROPS
@given(seed=st.integers(0, 10**6), k=st.integers(1, 3), R=st.integers(2, 6))
def test_is_zero_consistent_with_cone_value(seed, k, R):
    """k < R random columns: both outcomes occur. is_zero <=> exact cone value ~ 0."""
    C, S, M = _pencil(seed, R, k, 10.0)
    res = infsup_cone(S, M, C=C)
    c = boundedness_constant(S, M)
    if res.is_zero:
        assert res.value <= 1e-6 * c
    if res.value > 1e-5 * c:
        assert not res.is_zero
    assert res.is_zero == infsup_cone(S, M).is_zero  # S-only route agrees


# ----------------------------------------------------------------------------- operators


def test_solver_inputs_agree():
    _, X, B, _ = _problem(1)
    H_sparse = supremizer_operator(B, X)
    G = B @ spla.spsolve(X.tocsc(), B.T.toarray())
    for Xin in (X.toarray(), spla.splu(X.tocsc()), make_solver(X)):
        H = supremizer_operator(B, Xin)
        assert np.allclose(H @ H.T, H_sparse @ H_sparse.T, rtol=1e-10, atol=1e-12)
    assert np.allclose(H_sparse @ H_sparse.T, G, rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("use_pardiso", [True, False])
def test_make_solver_of_a_sparse_matrix_solves_it(use_pardiso, monkeypatch):
    """Both factorisations of a sparse X (PARDISO when installed, else SuperLU) against a
    dense solve, for one and for several right-hand sides."""
    from rbbench.hf.condensation import pardiso

    if use_pardiso and not pardiso.available():
        pytest.skip("pypardiso / MKL not installed")
    monkeypatch.setattr(pardiso, "available", lambda: use_pardiso)
    _, X, _, _ = _problem(1)
    rhs = np.random.default_rng(3).standard_normal((X.shape[0], 4))
    want = np.linalg.solve(X.toarray(), rhs)
    solve = make_solver(X)
    assert np.allclose(solve(rhs), want, rtol=1e-10, atol=1e-12 * np.abs(want).max())
    assert np.allclose(solve(rhs[:, 0]), want[:, 0], rtol=1e-10,
                       atol=1e-12 * np.abs(want).max())


def test_hf_constants_against_dense_svd():
    """Independent dense computation: beta_HF(span, Vg = I) and c_HF are the extreme
    singular values of W^{-1/2} B L^{-T}, X = L L^T."""
    _, X, B, W = _problem(2)
    m = B.shape[0]
    S, M = quotient_matrices(B, X, np.eye(m), W)
    L = np.linalg.cholesky(X.toarray())
    s = np.linalg.svd((B.toarray() / np.sqrt(W)[:, None]) @ np.linalg.inv(L).T, compute_uv=False)
    assert infsup_span(S, M) == pytest.approx(s[-1], rel=1e-9)
    assert boundedness_constant(S, M) == pytest.approx(s[0], rel=1e-9)
    # W given as a diagonal sparse matrix: same
    S2, M2 = quotient_matrices(B, X, np.eye(m), sp.diags(W))
    assert np.allclose(M, M2) and np.allclose(S, S2)


def test_whole_space_basis_equals_hf_formula():
    """Z spanning the whole HF space: Z (Z^T X Z)^{-1} Z^T = X^{-1}."""
    rng, X, B, W = _problem(4, n=30)
    Vg = np.abs(rng.standard_normal((B.shape[0], 4)))
    Z = rng.standard_normal((30, 30))
    S_hf, M_hf = quotient_matrices(B, X, Vg, W)  # sparse LU, m solves
    S_z, M_z = quotient_matrices(B, X, Vg, W, Z=Z)  # eigendecomposition of Z^T X Z
    assert np.allclose(S_z, S_hf, rtol=1e-8, atol=1e-10 * np.abs(S_hf).max())
    assert np.array_equal(M_z, M_hf)
    assert infsup_span(S_z, M_z) == pytest.approx(infsup_span(S_hf, M_hf), rel=1e-7)
    assert infsup_cone(S_z, M_z).value == pytest.approx(infsup_cone(S_hf, M_hf).value, rel=1e-7)


@pytest.mark.parametrize("seed", [5, 6, 7])
def test_supremizer_enrichment_recovers_hf(seed):
    """Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
    variational inequalities" (talk), slide "Parameter-dependent context": beta_on >= beta_HF.
    With the online
    supremizers the sup over V_N + S_R(mu) equals the sup over V (the supremizer T y of
    eta = Vg y lies in S_R(mu)), so beta_on equals the HF value over the same cone and is
    >= the HF value over all multipliers; without them (beta_dec) it is smaller."""
    rng, X, B, W = _problem(seed, n=50, m=8)
    R, N = 4, 3
    Vg = np.abs(rng.standard_normal((8, R)))
    Z = rng.standard_normal((50, N))
    T = supremizers(B, make_solver(X), Vg)
    Vg_dense = np.linalg.solve(X.toarray(), B.T.toarray() @ Vg)
    assert np.allclose(T, Vg_dense, rtol=1e-10, atol=1e-12)
    S_on, M = quotient_matrices(B, X, Vg, W, Z=np.hstack([Z, T]))
    S_hf, _ = quotient_matrices(B, X, Vg, W)
    S_all, M_all = quotient_matrices(B, X, np.eye(8), W)
    S_dec, _ = quotient_matrices(B, X, Vg, W, Z=Z)
    beta_hf_all = infsup_span(S_all, M_all)
    on_span, on_cone = infsup_span(S_on, M), infsup_cone(S_on, M)
    assert on_span >= beta_hf_all * (1 - 1e-10)
    assert on_cone.value >= beta_hf_all * (1 - 1e-10)
    assert on_span == pytest.approx(infsup_span(S_hf, M), rel=1e-8)
    assert on_cone.value == pytest.approx(infsup_cone(S_hf, M).value, rel=1e-8)
    assert infsup_cone(S_dec, M).value <= on_cone.value * (1 + 1e-10)
    assert infsup_span(S_dec, M) <= on_span * (1 + 1e-10)


def test_large_r_is_upper_estimate():
    C, S, M = _pencil(11, 14, 16, 10.0)
    up = infsup_cone(S, M, C=C, n_starts=16)
    ex = infsup_cone(S, M, C=C, exact_max_r=14)
    assert up.kind == "cone-upper" and ex.kind == "cone-exact"
    assert ex.value <= up.value + 1e-12 and up.span <= ex.value + 1e-12


def test_span_generalised_eigenvalue():
    C, S, M = _pencil(12, 5, 7, 1e3)
    w = sla.eigh(S, M, eigvals_only=True)
    assert infsup_span(S, M) == pytest.approx(np.sqrt(w[0]), rel=1e-9)
    assert boundedness_constant(S, M) == pytest.approx(np.sqrt(w[-1]), rel=1e-12)


def test_cone_value_with_dependent_generators():
    """Span+{v1, v2, v3, v1 + v2} = Span+{v1, v2, v3}: same cone, same constant, although
    M is singular for the first family (cones often need dependent generators)."""
    from rbbench.rb.algorithms.infsup import infsup_cone, quotient_matrices

    rng = np.random.default_rng(7)
    m, n = 12, 30
    B = rng.standard_normal((m, n))
    X = np.eye(n)
    W = np.diag(rng.uniform(0.5, 2.0, m))
    V3 = rng.uniform(0.0, 1.0, (m, 3))
    V4 = np.column_stack([V3, V3[:, 0] + V3[:, 1]])
    Z = rng.standard_normal((n, 4))
    S3, M3 = quotient_matrices(B, X, V3, W, Z=Z)
    S4, M4 = quotient_matrices(B, X, V4, W, Z=Z)
    assert np.linalg.eigvalsh(M4)[0] < 1e-10 * np.linalg.eigvalsh(M4)[-1]
    r3, r4 = infsup_cone(S3, M3), infsup_cone(S4, M4)
    assert r4.kind == "cone-exact"
    assert np.isclose(r3.value, r4.value, rtol=1e-8)
    r4u = infsup_cone(S4, M4, exact_max_r=2)  # multistart path with singular M
    assert r4u.value >= r3.value * (1 - 1e-8)


def test_span_value_below_round_off_is_zero():
    """A pencil whose smallest eigenvalue is round-off of the largest (ratio 3e-16, the
    membrane's beta_dec) gives 0, not a positive 'lower bound'; a small but
    resolved one (ratio 1e-8) keeps its value."""
    from rbbench.rb.algorithms.infsup import infsup_span

    M = np.eye(3)
    assert infsup_span(np.diag([3e-16, 0.5, 1.0]), M) == 0.0
    assert infsup_span(np.diag([1e-8, 0.5, 1.0]), M) == pytest.approx(1e-4, rel=1e-6)

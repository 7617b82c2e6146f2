"""Reduced model: exactness when the bases contain the snapshot, affine decomposition."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

from rbbench.hf.components import make_components
from rbbench.hf.model import solve_hf
from rbbench.rb.algorithms.affine import NotAffineError, affine_decomposition
from rbbench.rb.mixed.model import build_affine_model, projector
from rbbench.rb.online import ReducedBasis
from rbbench.scene.loading import load_scene


def _x_orthonormal(U, X):
    """X-orthonormal basis of span(U) (dense, small): independent of rbbench.rb.algorithms.pod."""
    G = U.T @ (X @ U)
    w, V = np.linalg.eigh(G)
    keep = w > 1e-12 * w.max()
    return U @ (V[:, keep] / np.sqrt(w[keep]))


@pytest.fixture(scope="module")
def membrane():
    sc = load_scene("membrane_obstacle", ["discretization.n_cells=8"])
    comps = make_components(sc)
    mus = np.array([[h, c] for h in (0.1, 0.25, 0.4) for c in (2.0, 4.0, 6.0)])
    sols = [solve_hf(sc, mu, components=comps) for mu in mus]
    U = np.stack([s.result.u[s.problem.free] for s in sols], axis=1)
    LAM = np.stack([s.result.lam for s in sols], axis=1)
    Z = _x_orthonormal(U, sols[0].problem.X[sols[0].problem.free][:, sols[0].problem.free])
    Vg = LAM / np.linalg.norm(LAM, axis=0)
    b, f, _ = comps
    model = build_affine_model(projector(lambda mu: f.build(b.discretize(mu)), Z, Vg),
                               sc.bounds)
    return sc, comps, mus, sols, Z, Vg, model


def test_reduced_equals_hf_when_bases_contain_the_snapshot(membrane):
    """u_N = u exactly; lam_R is *a* multiplier (Z^T B^T (lam_R - lam) = 0), not
    necessarily lam: without stabilisation the reduced multiplier need not be unique."""
    sc, comps, mus, sols, Z, Vg, model = membrane
    model.basis = ReducedBasis(Z, Vg)
    for mu, sol in zip(mus, sols, strict=True):
        res = model.solve(mu)
        assert res.stop_reason == "converged"
        hf = model.reconstruct(res)
        u_n, lam_r = hf.u, hf.lam
        u = sol.result.u[sol.problem.free]
        assert np.linalg.norm(u_n - u) <= 1e-9 * np.linalg.norm(u)
        B = sol.problem.B
        r = Z.T @ (B.T @ (lam_r - sol.result.lam))
        assert np.linalg.norm(r) <= 1e-9 * np.linalg.norm(Z.T @ (B.T @ sol.result.lam))


def test_supremizers_make_the_multiplier_exact(membrane):
    """With Z enriched by the supremizers X^{-1} B^T Vg (Benaceur, Drouet, Ehrlacher,
    Ern & Niakh, "Model order reduction methods: parametric variational inequalities"
    (talk), "Enhancement by supremizers") the reduced problem is inf-sup stable, so
    lam_R = lam exactly."""
    import scipy.sparse.linalg as spla

    sc, comps, mus, sols, Z, Vg, _ = membrane
    p = sols[0].problem
    X = p.X[p.free][:, p.free]
    T = spla.splu(X.tocsc()).solve(np.asarray(p.B.T @ Vg))
    Zs = _x_orthonormal(np.hstack([Z, T]), X)
    b, f, _ = comps
    model = build_affine_model(projector(lambda mu: f.build(b.discretize(mu)), Zs, Vg),
                               sc.bounds)
    model.basis = ReducedBasis(Zs, Vg)
    for mu, sol in zip(mus, sols, strict=True):
        lam_r = model.reconstruct(model.solve(mu)).lam
        assert np.linalg.norm(lam_r - sol.result.lam) <= 1e-8 * np.linalg.norm(sol.result.lam)


def test_reduced_model_pickles_and_is_small(membrane):
    *_, model = membrane
    blob = pickle.dumps(model)
    assert len(blob) < 200_000
    again = pickle.loads(blob)
    mu = np.array([0.3, 3.0])
    assert np.allclose(again.solve(mu).c, model.solve(mu).c)


def test_reduced_solution_is_feasible_off_training(membrane):
    sc, comps, *_, Z, Vg, model = membrane
    mu = np.array([0.33, 4.7])
    res = model.solve(mu)
    A, F, B, G = model.arrays(mu)
    assert res.alpha_raw_min >= -1e-10  # daqp's multipliers before the clip at 0
    assert res.alpha.min() >= 0
    assert (G - B @ res.c).min() >= -1e-10 * np.abs(G).max()
    hf = solve_hf(sc, mu, components=comps)
    u = hf.result.u[hf.problem.free]
    err = np.linalg.norm(Z @ res.c - u) / np.linalg.norm(u)
    assert err < 0.05  # 9 snapshots, 2 parameters: a coarse but real approximation


def test_affine_decomposition_detects_non_affine():
    bounds = np.array([[0.0, 1.0], [1.0, 2.0]])
    terms = affine_decomposition(lambda mu: np.array([1 + 2 * mu[0], 3 * mu[1] - mu[0]]), bounds)
    assert np.allclose(terms, [[1, 0], [2, -1], [0, 3]])
    with pytest.raises(NotAffineError, match="deviation"):
        affine_decomposition(lambda mu: np.array([mu[0] ** 2, mu[1]]), bounds)


def test_hertz_contact_operators_are_not_affine():
    """B(mu) of the half-disks depends non-affinely on mu: exact-affine must refuse."""
    sc = load_scene("hertz_halfdisks", ["discretization.h_contact=0.04",
                                        "discretization.h_max=0.3"])
    b, f, _ = make_components(sc)
    p0 = f.build(b.discretize(1.0))
    Z = np.asarray(p0.B[:3].T.todense())  # primal directions that touch the contact zone
    Vg = np.eye(p0.B.shape[0])[:, :4]
    with pytest.raises(NotAffineError, match="reduced B"):
        build_affine_model(projector(lambda mu: f.build(b.discretize(mu)), Z, Vg), sc.bounds)


# ---------------------------------------------------------------------------
# online solvers: daqp (compiled QP) against the PDAS LCP, badly scaled data
# ---------------------------------------------------------------------------
from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from rbbench.rb.mixed.model import solve_reduced  # noqa: E402


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), n=st.integers(2, 40), m=st.integers(1, 30),
       row_scale=st.sampled_from([1e-8, 1e-6, 1.0, 1e3]),
       load_scale=st.sampled_from([1e-3, 1.0, 1e5]))
def test_online_methods_match_pdas(seed, n, m, row_scale, load_scale):
    """daqp, nnls and pdas solve the same KKT system: A c + B^T a = F, a >= 0, B c <= G,
    a.(G - Bc) = 0.

    Scales mimic Hertz (rows 1e-6, loads 1e5) where daqp's absolute tolerances
    would otherwise accept infeasible points."""
    m = min(m, n)  # m > n: alpha not unique, PDAS's reference may stagnate
    rng = np.random.default_rng(seed)
    Q = rng.standard_normal((n, n))
    A = Q @ Q.T + n * np.eye(n)
    F = load_scale * rng.standard_normal(n)
    B = row_scale * rng.standard_normal((m, n))
    c_free = np.linalg.solve(A, F)
    G = B @ c_free - row_scale * load_scale * rng.random(m) * 0.1  # some rows violated
    G[: m // 2] += row_scale * load_scale  # others slack
    ref = solve_reduced(A, F, B, G, method="pdas")
    assert ref.stop_reason == "converged"
    for method in ("daqp", "nnls"):
        got = solve_reduced(A, F, B, G, method=method)
        assert got.stop_reason.startswith("converged")
        assert np.linalg.norm(got.c - ref.c) <= 1e-8 * np.linalg.norm(ref.c)
        scale = np.linalg.norm(ref.alpha) + 1e-300
        assert (np.linalg.norm(got.alpha - ref.alpha)
                <= 1e-6 * scale + 1e-14 * load_scale / row_scale)
        assert np.all(got.alpha >= 0)
        assert (B @ got.c - G).max() <= 1e-9 * row_scale * load_scale


def test_unknown_online_method_is_refused():
    with pytest.raises(ValueError, match="valid: auto, nnls, daqp, pdas"):
        solve_reduced(np.eye(2), np.ones(2), np.ones((1, 2)), np.ones(1), method="qp")

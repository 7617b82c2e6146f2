"""The online bound with a moving contact (two half-disks, B(mu) not affine): its terms
against the HF evaluation of the same theorem, above the true error at random mu, zero where
the reduced spaces hold the HF solution, and a coercivity constant that is not a lower bound
caught."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.optimize as so
from hypothesis import given, settings
from hypothesis import strategies as st

from rbbench.hf.components import make_components
from rbbench.hf.model import solve_hf
from rbbench.rb.algorithms.bounds import hf_bound_terms, natural_dual, vi_bound
from rbbench.rb.algorithms.infsup import make_solver
from rbbench.rb.mixed.bounds import BoundUnsupported
from rbbench.rb.mixed.contact_bound import build_contact_bound, contact_rows
from rbbench.rb.mixed.greedy import x_orthonormal
from rbbench.scene.loading import load_scene

COARSE = ["discretization.h_contact=0.04", "discretization.h_max=0.3"]
#: a cap on the master-half modes above the rank of the fixture's training vectors
SPANNING = 250


@pytest.fixture(scope="module")
def hertz():
    sc = load_scene("hertz_halfdisks", COARSE)
    comps = make_components(sc)
    b, f, _ = comps
    at = lambda mu: f.build(b.discretize(mu))  # noqa: E731
    mus = np.array([[0.7], [1.0], [1.3]])
    sols = [solve_hf(sc, mu, components=comps) for mu in mus]
    p0 = sols[0].problem
    X = p0.X[p0.free][:, p0.free].tocsr()
    xs = make_solver(X)
    U = np.stack([s.result.u[p0.free] for s in sols], axis=1)
    LAM = np.stack([s.result.lam for s in sols], axis=1)
    Z = x_orthonormal(U, X)
    Vg = LAM / np.linalg.norm(LAM, axis=0)
    # enough modes to span the training vectors B_M(mu)^T Vg (25 x 3): no compression
    # remainder where the reduced spaces hold the solution (the default cap is smaller)
    bound = build_contact_bound(b.contact_layout(), at, Z, Vg, X, xs, sc.bounds, _sample(sc),
                                pod_max=SPANNING)
    return sc, comps, mus, sols, Z, Vg, X, xs, bound, at


def _sample(sc):
    return np.linspace(sc.bounds[0, 0], sc.bounds[0, 1], 25)[:, None]


def _reduced_pair(Z, Vg, X, u, lam):
    """Some ``u_N = Z c``, ``lam_N = Vg a`` (a >= 0) near the HF pair (the bound holds for
    any such pair): the X-projection of u and a non-negative least-squares fit of lam."""
    c = Z.T @ (X @ u)
    a = so.nnls(Vg, lam)[0]
    return c, a


def test_online_rows_are_the_hf_rows(hertz):
    sc, _, _, _, _, _, _, _, bound, at = hertz
    for mu in (np.array([0.83]), np.array([1.21])):
        p = at(mu)
        B, G = contact_rows(bound.ev, bound.Msp, mu)
        loc = np.flatnonzero(np.abs(p.B).sum(axis=0).A1 > 0)
        assert B.shape[0] == p.B.shape[0]
        assert np.abs(G - p.G).max() <= 1e-12 * np.abs(p.G).max()
        # the same non-zero columns of B(mu), the same values
        dense = p.B.toarray()
        assert np.allclose(np.sort(np.abs(B.toarray()).sum(axis=0))[-loc.size:],
                           np.sort(np.abs(dense[:, loc]).sum(axis=0)), rtol=1e-12)


@settings(max_examples=5, deadline=None, derandomize=True)
@given(x=st.floats(0, 1))
def test_bound_holds_and_is_above_the_hf_terms(hertz, x):
    sc, comps, _, _, Z, Vg, X, xs, bound, at = hertz
    mu = sc.bounds[:, 0] + x * (sc.bounds[:, 1] - sc.bounds[:, 0])
    hf = solve_hf(sc, mu, components=comps)
    p = hf.problem
    u, lam = hf.result.u[p.free], hf.result.lam
    c, a = _reduced_pair(Z, Vg, X, u, lam)
    u_N, lam_N = Z @ c, Vg @ a
    online = bound(mu, c, a)
    ref = hf_bound_terms(p.A, p.F, p.B, p.G, xs, natural_dual(p.B, xs), u_N, lam_N)
    t = online.terms
    # each online term bounds the HF one from above, up to round-off: the residual is a
    # cancellation of terms of size l_N, the constraint residual one of lam_N |B| |u_N|
    tiny_r = 1e-9 * t.lam_norm
    tiny_d = 1e-9 * float(lam_N @ (abs(p.B) @ np.abs(u_N)))
    assert t.rho >= ref.rho - tiny_r
    assert t.rho - bound.last_remainder <= ref.rho + bound.last_remainder + tiny_r
    assert t.sigma >= ref.sigma * (1 - 1e-9)
    assert t.kappa == pytest.approx(ref.kappa, abs=tiny_d)
    err = float(np.sqrt((u - u_N) @ (X @ (u - u_N))))
    assert online.delta_u >= err
    floor = 1e-6 * np.sqrt(u @ (X @ u))  # sqrt(round-off), where the spaces hold u(mu)
    assert online.delta_u <= 50 * err + floor  # informative, not only valid


def test_bound_vanishes_where_the_spaces_hold_the_solution(hertz):
    _, _, mus, sols, Z, Vg, X, _, bound, _ = hertz
    for k, (mu, s) in enumerate(zip(mus, sols, strict=True)):
        u = s.result.u[s.problem.free]
        c = Z.T @ (X @ u)
        a = np.zeros(Vg.shape[1])
        a[k] = np.linalg.norm(s.result.lam)
        b = bound(mu, c, a)
        # zero in exact arithmetic; sqrt(round-off) through kappa (module docstring)
        assert b.delta_u <= 1e-6 * np.sqrt(u @ (X @ u))


def test_a_coercivity_constant_that_is_no_lower_bound_fails(hertz):
    """The check above is sharp enough to catch a wrong alpha: with alpha 100x too large
    (no lower bound of a(.,.) in X) the 'bound' falls below the true error."""
    sc, comps, _, _, Z, Vg, X, _, bound, _ = hertz
    mu = np.array([0.91])
    hf = solve_hf(sc, mu, components=comps)
    u = hf.result.u[hf.problem.free]
    c, a = _reduced_pair(Z, Vg, X, u, hf.result.lam)
    err = float(np.sqrt((u - Z @ c) @ (X @ (u - Z @ c))))
    t = bound.terms(mu, c, a)
    assert vi_bound(t, bound.alpha, bound.gamma).delta_u >= err
    assert vi_bound(t, 100 * bound.alpha, bound.gamma).delta_u < err


def test_refuses_a_mu_dependent_stiffness(hertz):
    sc, _, _, _, Z, Vg, X, xs, _, at = hertz
    b, _, _ = hertz[1]

    def stiffer(mu):
        p = at(mu)
        p.A = p.A * float(mu[0])
        return p

    with pytest.raises(BoundUnsupported, match="depends on mu"):
        build_contact_bound(b.contact_layout(), stiffer, Z, Vg, X, xs, sc.bounds,
                            np.array([[1.0]]))


def test_compiled_pairing_matches_the_python_one_and_pickles(hertz):
    import pickle

    sc, _, mus, sols, Z, Vg, X, _, bound, _ = hertz
    assert bound.plan is not None
    rng = np.random.default_rng(0)
    for mu in (np.array([0.74]), np.array([1.27])):
        c, a = rng.standard_normal(Z.shape[1]), rng.random(Vg.shape[1])
        dc, bc, _ = bound.residuals(mu, c, a, compiled=True)
        dp, bp, _ = bound.residuals(mu, c, a, compiled=False)
        assert np.allclose(dc, dp, rtol=0, atol=1e-12 * np.abs(dp).max())
        assert np.allclose(bc, bp, rtol=0, atol=1e-12 * np.abs(bp).max())
    again = pickle.loads(pickle.dumps(bound))
    res = bound(mus[1], c, a)
    assert again(mus[1], c, a).delta_u == pytest.approx(res.delta_u, rel=1e-12)
    # outside D the kernels decline and the Python pairing decides (here: it still pairs)
    assert np.isfinite(bound(np.array([1.31]), c, a).delta_u)


@settings(max_examples=8, deadline=None, derandomize=True)
@given(x=st.floats(0, 1), seed=st.integers(0, 2**16))
def test_fast_terms_equal_the_reference(hertz, x, seed):
    """The kernel (pairing, slave rows from their affine form, master rows at the paired
    facets only, g over the support of b_M, T used as upper trapezoidal) against the numpy
    reference from the Python pairing: the same terms to round-off at random mu, c, a."""
    sc, _, _, _, Z, Vg, _, _, bound, _ = hertz
    mu = sc.bounds[:, 0] + x * (sc.bounds[:, 1] - sc.bounds[:, 0])
    rng = np.random.default_rng(seed)
    c, a = rng.standard_normal(Z.shape[1]), rng.random(Vg.shape[1])
    a[rng.random(a.size) < 0.3] = 0.0  # a sparser multiplier: rows with lam = 0
    assert bound._fast_terms(mu, c, a) is not None  # the kernel ran (did not decline)
    fast = bound.terms(mu, c, a, compiled=True)
    rem_f = bound.last_remainder
    ref = bound.terms(mu, c, a, compiled=False)
    rem_r = bound.last_remainder
    tiny = 1e-12 * ref.lam_norm
    for f, r in ((fast.rho - rem_f, ref.rho - rem_r), (fast.lam_norm - rem_f,
                                                       ref.lam_norm - rem_r)):
        assert f == pytest.approx(r, rel=1e-10, abs=tiny)
    # the remainder sqrt(lambda_c (|b_M|^2 - |g|^2)) is resolved to sqrt(round-off) of b_M
    assert rem_f == pytest.approx(rem_r, rel=1e-6, abs=1e-7 * ref.lam_norm)
    assert fast.sigma == pytest.approx(ref.sigma, rel=1e-10, abs=1e-14 * ref.lam_norm)
    # kappa: a sum of lam_N [-d]_+ where d cancels terms of size lam |B| |u_N|
    assert fast.kappa == pytest.approx(ref.kappa, rel=1e-9, abs=tiny)


def test_fewer_modes_are_a_build_with_that_cap(hertz):
    """``with_modes(k)`` cuts the bound without rebuilding it: the same bound as a second
    build with ``pod_max = k``, to round-off, at random mu, c, a."""
    sc, comps, _, _, Z, Vg, X, xs, bound, at = hertz
    K = bound.U.shape[1]
    assert K > 6  # the fixture's POD keeps enough modes to cut
    assert bound.with_modes(K, xs) is bound and bound.with_modes(10 * K, xs) is bound
    k = K // 3
    rebuilt = build_contact_bound(comps[0].contact_layout(), at, Z, Vg, X, xs, sc.bounds,
                                  _sample(sc), pod_max=k)
    cut = bound.with_modes(k, xs)
    assert rebuilt.U.shape == cut.U.shape == (bound.U.shape[0], k)
    assert rebuilt.T.shape == cut.T.shape
    assert np.array_equal(rebuilt.kj, cut.kj)
    assert cut.lam_c == pytest.approx(rebuilt.lam_c, rel=1e-8)
    assert cut.lam_c >= bound.lam_c  # fewer modes deflate less of P_M^T X^-1 P_M
    rng = np.random.default_rng(3)
    for mu in (np.array([0.77]), np.array([1.18])):
        c, a = rng.standard_normal(Z.shape[1]), rng.random(Vg.shape[1])
        for compiled in (True, False):
            r, t = rebuilt(mu, c, a, compiled), cut(mu, c, a, compiled)
            assert t.delta_u == pytest.approx(r.delta_u, rel=1e-9)
            assert t.terms.rho == pytest.approx(r.terms.rho, rel=1e-9)
            assert cut.last_remainder > 0
    with pytest.raises(ValueError, match="bound_pod_max 0: give an integer >= 1"):
        bound.with_modes(0, xs)


@settings(max_examples=5, deadline=None, derandomize=True)
@given(x=st.floats(0, 1))
def test_a_small_cap_still_bounds_the_error_and_its_remainder_grows(hertz, x):
    """With 1 to K modes the bound stays above the true error (raw values, the HF solution
    at random mu), the remainder lambda_c^(1/2) ||b_M - U_k g_k|| stays above the exact X'
    norm of what it stands for, and it does not fall as the cap k falls (nested modes, and
    lambda_c on the complement of fewer modes)."""
    sc, comps, _, _, Z, Vg, X, xs, bound, _ = hertz
    mu = sc.bounds[:, 0] + x * (sc.bounds[:, 1] - sc.bounds[:, 0])
    hf = solve_hf(sc, mu, components=comps)
    u = hf.result.u[hf.problem.free]
    c, a = _reduced_pair(Z, Vg, X, u, hf.result.lam)
    err = float(np.sqrt((u - Z @ c) @ (X @ (u - Z @ c))))
    K = bound.U.shape[1]
    rems = []
    full = bound(mu, c, a).terms.lam_norm  # the size of b = B^T lam_N: the round-off scale
    for k in (K, K // 2, 4, 1):
        cut = bound.with_modes(k, xs)
        b = cut(mu, c, a)
        assert b.delta_u >= err
        rems.append(cut.last_remainder)
        # the remainder bounds the exact X' norm of the left-out part P_M (b_M - U U^T b_M)
        bm = cut.residuals(mu, c, a, compiled=False)[1][cut.mloc]
        Um = cut.U[cut.mloc]
        v = np.zeros(X.shape[0])
        v[cut.mfree] = bm - Um @ (Um.T @ bm)
        assert np.sqrt(v @ np.ravel(xs(v))) <= cut.last_remainder * (1 + 1e-8) + 1e-9 * full
    assert np.all(np.diff(rems) >= -1e-7 * full)
    assert rems[-1] > rems[0]  # one mode leaves more out than all of them

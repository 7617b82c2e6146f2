"""2D collocated friction on the condensed problem: solvers against independent references.

Conventions (rbbench.hf.algebra.friction): x = [lam_n; lam_t], w = q + D x, gap = w_n,
slip v = -w_t, slip law lam_t = +s sign(v) (the traction on the body, -lam_t, opposes v).
"""

from __future__ import annotations

import itertools

import daqp
import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

from rbbench.hf.algebra.friction import (
    MODEL_B,
    SLIP_RTOL,
    CoefficientLaw,
    condense_friction,
    law_residuals,
    node_array,
    slip,
    uzawa_friction,
)
from rbbench.hf.solvers import lcp
from rbbench.hf.solvers.friction import (
    coulomb_direct,
    coulomb_fixed_point,
    coulomb_model_b,
    pdas_tresca,
)
from rbbench.interfaces import STOP_REASONS


def _problem(seed: int, m: int, shift: float = 0.1):
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((2 * m, 2 * m))
    D = M @ M.T + shift * 2 * m * np.eye(2 * m)
    q = rng.standard_normal(2 * m)
    return D, q


def _check_solution(D, q, lam_n, lam_t, s, tol=1e-9):
    """Every condition, from D and q, on the raw multipliers (no clipping)."""
    m = lam_n.size
    x = np.concatenate([lam_n, lam_t])
    w = q + D @ x
    gap, v = w[:m], -w[m:]
    dtol = tol * np.abs(q).max()
    ftol = tol * max(np.abs(x).max(), np.abs(q).max() / np.mean(np.diag(D)))
    assert lam_n.min() >= -ftol, "lam_n >= 0"
    assert gap.min() >= -dtol, "non-penetration"
    assert np.all((np.abs(lam_n) <= ftol) | (np.abs(gap) <= dtol)), "complementarity"
    assert np.all(np.abs(lam_t) <= s + ftol), "cone / box"
    inside = np.abs(lam_t) < s - ftol
    assert np.all(np.abs(v[inside]) <= dtol), "stick: |lam_t| < s => v = 0"
    moving = np.abs(v) > dtol
    assert np.allclose(lam_t[moving], s[moving] * np.sign(v[moving]), atol=ftol, rtol=0), \
        "slip: lam_t = s sign(v)"


def _qp_reference(D, q, s):
    """The Tresca box QP by daqp (compiled dual active set; independent of the solvers)."""
    m = s.size
    lb = np.concatenate([np.zeros(m), -s])
    ub = np.concatenate([np.full(m, 1e30), s])
    x, _, flag, _ = daqp.solve(D, q, np.zeros((0, 2 * m)), ub, lb,
                               np.zeros(2 * m, dtype=np.int32), primal_tol=1e-12)
    assert flag == 1
    return np.asarray(x)


def _coulomb_enumeration(D, q, F, tol=1e-9):
    """All solutions of the 2D Coulomb LCP by trying the 4^m node patterns."""
    m = F.size
    sols = []
    for pat in itertools.product(range(4), repeat=m):
        M, r = np.zeros((2 * m, 2 * m)), np.zeros(2 * m)
        for i, p in enumerate(pat):
            if p == 0:
                M[i, i] = M[m + i, m + i] = 1.0
                continue
            M[i], r[i] = D[i], -q[i]
            if p == 1:
                M[m + i], r[m + i] = D[m + i], -q[m + i]
            else:
                M[m + i, m + i], M[m + i, i] = 1.0, -(1.0 if p == 2 else -1.0) * F[i]
        try:
            x = np.linalg.solve(M, r)
        except np.linalg.LinAlgError:
            continue
        w = q + D @ x
        ln, lt, gap, v = x[:m], x[m:], w[:m], -w[m:]
        ft, dt = tol * max(1.0, np.abs(x).max()), tol * max(1.0, np.abs(q).max())
        ok = all([
            (pat[i] == 0 and gap[i] >= -dt) or (pat[i] != 0 and ln[i] >= -ft and (
                (pat[i] == 1 and abs(lt[i]) <= F[i] * ln[i] + ft)
                or (pat[i] == 2 and v[i] >= -dt) or (pat[i] == 3 and v[i] <= dt)))
            for i in range(m)])
        if ok and not any(np.allclose(x, y, atol=1e-8 * max(1.0, np.abs(y).max()))
                          for y in sols):
            sols.append(x)
    return sols


# ----------------------------------------------------------------- frictionless limit

@settings(max_examples=25, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), m=st.integers(1, 15))
def test_zero_friction_reproduces_the_frictionless_lcp(seed, m):
    D, q = _problem(seed, m)
    lam_ref, _, reason, _, _ = lcp.pdas(D[:m, :m], q[:m])
    assert reason == "converged"
    zero = CoefficientLaw("zero", lambda t: 0.0 * np.asarray(t))
    for r in (pdas_tresca(D, q, 0.0), coulomb_fixed_point(D, q, 0.0),
              coulomb_direct(D, q, 0.0), coulomb_model_b(D, q, law=zero)):
        assert r.stop_reason == "converged"
        assert np.abs(r.lam_n - lam_ref).max() <= 1e-10 * max(1.0, np.abs(lam_ref).max())
        assert np.abs(r.lam_t).max() == 0.0
    u = uzawa_friction(D, q, F=0.0, tol=1e-12)
    assert u.stop_reason == "converged"
    assert np.abs(u.lam_n - lam_ref).max() <= 1e-9 * max(1.0, np.abs(lam_ref).max())


@pytest.mark.parametrize("seed", range(6))
def test_huge_friction_sticks_on_the_contact_set(seed):
    """Tresca with a huge threshold: no slip anywhere. Coulomb with F = 1e3: no slip where
    lam_n is not O(1/F) (random D may leave grazing nodes slipping with lam_n ~ 1/F)."""
    D, q = _problem(seed, 8)
    tr = pdas_tresca(D, q, 1e12)
    assert tr.stop_reason == "converged"
    assert np.abs(slip(D, q, tr.lam_n, tr.lam_t)).max() <= 1e-10 * np.abs(q).max()
    assert set(tr.states) <= {"open", "stick"}
    r = coulomb_direct(D, q, 1e3)
    assert r.stop_reason == "converged"
    v = slip(D, q, r.lam_n, r.lam_t)
    contact = r.lam_n > 0.1 * r.lam_n.max()  # grazing slip: lam_n = |lam_t| / F, tiny
    assert contact.any()
    assert np.abs(v[contact]).max() <= 1e-10 * np.abs(q).max()
    assert set(r.states[contact]) == {"stick"}


# ----------------------------------------------------------------------------- Tresca

@settings(max_examples=60, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), m=st.integers(1, 12),
       s_scale=st.sampled_from([0.0, 1e-3, 0.3, 1.0, 10.0]))
def test_tresca_pdas_is_the_box_qp_minimiser(seed, m, s_scale):
    D, q = _problem(seed, m)
    s = s_scale * np.random.default_rng(seed + 1).uniform(0.2, 1.0, m)
    r = pdas_tresca(D, q, s, fallback=False)
    assert r.stop_reason == "converged"
    ref = _qp_reference(D, q, s)
    assert np.abs(r.x - ref).max() <= 1e-8 * max(1.0, np.abs(ref).max())
    _check_solution(D, q, r.lam_n, r.lam_t, s)
    u = uzawa_friction(D, q, s=s, tol=1e-12)
    assert u.stop_reason == "converged"
    assert np.abs(u.x - ref).max() <= 1e-8 * max(1.0, np.abs(ref).max())


def test_tresca_fallback_and_iteration_cap_stop_with_a_reason():
    D, q = _problem(5, 20)
    r = pdas_tresca(D, q, 0.2, max_iter=1)
    assert r.stop_reason in ("max_iterations", "converged")
    assert r.iterations == 1
    full = pdas_tresca(D, q, 0.2)
    assert full.stop_reason == "converged" and full.iterations <= 10
    assert full.residuals["max"] <= 1e-10


# ---------------------------------------------------------------------------- Coulomb

@settings(max_examples=40, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), m=st.integers(1, 4), F=st.floats(0.0, 2.0))
def test_coulomb_solvers_find_an_enumerated_solution(seed, m, F):
    D, q = _problem(seed, m)
    Fs = np.full(m, F)
    sols = _coulomb_enumeration(D, q, Fs)
    assert sols, "the 2D Coulomb LCP has a solution"
    direct = coulomb_direct(D, q, F)
    fixed = coulomb_fixed_point(D, q, F)
    for r in (direct, fixed):
        assert r.stop_reason in STOP_REASONS
        if r.stop_reason == "converged":
            _check_solution(D, q, r.lam_n, r.lam_t, Fs * r.lam_n)
            assert any(np.abs(r.x - y).max() <= 1e-7 * max(1.0, np.abs(y).max()) for y in sols)
    if len(sols) == 1:
        assert direct.stop_reason == "converged"
    if fixed.stop_reason == "converged" and direct.stop_reason == "converged":
        assert fixed.info["contraction"] < 1.0
        assert np.abs(fixed.x - direct.x).max() <= 1e-8 * max(1.0, np.abs(direct.x).max())


@pytest.mark.parametrize("seed", range(8))
def test_coulomb_fixed_point_and_direct_agree_when_contracting(seed):
    D, q = _problem(seed, 10)
    fixed = coulomb_fixed_point(D, q, 0.3)
    direct = coulomb_direct(D, q, 0.3)
    assert fixed.stop_reason == direct.stop_reason == "converged"
    assert max(fixed.info["ratios"][1:]) < 1.0
    assert np.abs(fixed.x - direct.x).max() <= 1e-9 * np.abs(direct.x).max()
    uz = uzawa_friction(D, q, F=0.3, tol=1e-12)
    assert uz.stop_reason == "converged"
    assert np.abs(uz.x - direct.x).max() <= 1e-8 * np.abs(direct.x).max()


# --------------------------------------------------------------------------- extremes

@pytest.mark.timeout(120)
@pytest.mark.parametrize("F", [0.0, 1e-3, 0.2, 1.0, 10.0])
def test_extreme_coefficients_converge_or_stop_with_a_reason(F):
    for seed in range(4):
        D, q = _problem(seed, 12)
        for r in (coulomb_direct(D, q, F), coulomb_fixed_point(D, q, F),
                  uzawa_friction(D, q, F=F, max_iter=20_000)):
            assert r.stop_reason in STOP_REASONS
            if r.stop_reason == "converged":
                _check_solution(D, q, r.lam_n, r.lam_t, F * r.lam_n, tol=1e-8)
                assert max(v for k, v in r.residuals.items()) <= 1e-9
            else:
                assert r.stop_reason != "nan"


@pytest.mark.timeout(120)
@pytest.mark.parametrize("s", [0.0, 1e-14, 1e-6, 1e6, 1e14])
def test_extreme_thresholds_converge_or_stop_with_a_reason(s):
    for seed in range(4):
        D, q = _problem(seed, 12)
        sv = np.full(12, s)
        r = pdas_tresca(D, q, s)
        assert r.stop_reason == "converged"
        _check_solution(D, q, r.lam_n, r.lam_t, sv)
        u = uzawa_friction(D, q, s=s, max_iter=20_000)
        assert u.stop_reason in STOP_REASONS
        if u.stop_reason == "converged":
            _check_solution(D, q, u.lam_n, u.lam_t, sv, tol=1e-8)


def test_ill_conditioned_and_singular_delassus_stop_with_a_reason():
    D, q = _problem(2, 6, shift=0.0)  # rank 12 of 12, badly conditioned
    D[:, -1] = D[-1, :] = 0.0  # a redundant (zero) tangential row: PSD
    q[-1] = 0.0
    for r in (pdas_tresca(D, q, 0.5), coulomb_direct(D, q, 0.5),
              coulomb_fixed_point(D, q, 0.5), uzawa_friction(D, q, s=0.5, max_iter=5000)):
        assert r.stop_reason in STOP_REASONS


def test_non_finite_data_stops_with_nan():
    D, q = _problem(1, 3)
    q[0] = np.nan
    assert pdas_tresca(D, q, 0.1).stop_reason == "nan"
    assert coulomb_direct(D, q, 0.1).stop_reason == "nan"


# ---------------------------------------------------------------------------- model B

def test_model_b_converges_with_its_contraction_and_a_consistent_coefficient():
    D, q = _problem(3, 10)
    ut_prev = np.random.default_rng(0).uniform(-0.5, 0.5, 10)
    r = coulomb_model_b(D, q, MODEL_B, ut_prev=ut_prev)
    assert r.stop_reason == "converged"
    assert 0.0 <= r.info["contraction"] < 1.0
    ut = ut_prev + slip(D, q, r.lam_n, r.lam_t)
    F = 0.25 / (ut**2 + 1.0)
    assert np.abs(r.info["coefficient"] - F).max() <= 1e-9
    _check_solution(D, q, r.lam_n, r.lam_t, F * r.lam_n, tol=1e-8)
    assert r.info["max_abs_dcoef"] <= 0.25


def test_model_b_reports_why_it_fails():
    D, q = _problem(0, 3)
    wild = CoefficientLaw("wild", lambda t: 10.0 + 9.0 * np.cos(50.0 * np.asarray(t)))
    r = coulomb_model_b(D, q, wild, max_iter=30)
    assert r.stop_reason in STOP_REASONS
    if r.stop_reason != "converged":
        assert "why" in r.info or r.stop_reason == "max_iterations"


# -------------------------------------------------------------- condensation, bad input

def test_condense_friction_measures_slip_from_the_previous_step():
    rng = np.random.default_rng(4)
    n, m = 30, 4
    K = rng.standard_normal((n, n))
    A = sp.csr_matrix(K @ K.T + n * np.eye(n))
    Fv = rng.standard_normal(n)
    Bn = sp.csr_matrix(rng.standard_normal((m, n)))
    Bt = sp.csr_matrix(rng.standard_normal((m, n)))
    G = rng.uniform(0.0, 1.0, m)
    ut_prev = rng.standard_normal(m)
    cond = condense_friction(A, Fv, Bn, Bt, G, ut_prev=ut_prev)
    r = pdas_tresca(cond.D, cond.q, 0.4)
    assert r.stop_reason == "converged"
    u = cond.displacement(r.x)
    assert np.allclose(A @ u + Bn.T @ r.lam_n + Bt.T @ r.lam_t, Fv, atol=1e-9)
    assert np.allclose(slip(cond.D, cond.q, r.lam_n, r.lam_t), Bt @ u - ut_prev, atol=1e-10)
    assert np.allclose(G - Bn @ u, cond.q[:m] + cond.D[:m] @ r.x, atol=1e-10)


def test_bad_input_raises_naming_the_quantity():
    D, q = _problem(0, 3)
    with pytest.raises(ValueError, match="F"):
        coulomb_direct(D, q, -0.1)
    with pytest.raises(ValueError, match="s"):
        pdas_tresca(D, q, np.inf)
    with pytest.raises(ValueError, match="exactly one"):
        uzawa_friction(D, q, s=0.1, F=0.1)
    with pytest.raises(ValueError, match="2m"):
        pdas_tresca(D, q[:-1], 0.1)
    with pytest.raises(ValueError, match="entries"):
        node_array(np.ones(2), 3, "F")


@pytest.mark.parametrize("F", [0.2, 1.0])
def test_law_residuals_vanish_at_a_coulomb_solution_and_measure_a_wrong_slip_force(F):
    """At a converged Coulomb solution (raw multipliers) every node satisfies the law; moving
    the tangential force of one slipping node by delta gives exactly delta (relative)."""
    found = 0
    for seed in range(40):
        D, q = _problem(seed, 6)
        r = coulomb_direct(D, q, F)
        assert r.stop_reason == "converged"
        ln, lt = r.lam_n, r.lam_t
        v = slip(D, q, ln, lt)
        vs, fs = np.abs(v).max(), max(ln.max(), 1e-300)
        law, slipping = law_residuals(v, ln, lt, F * ln, vs, fs)
        assert law.max() <= 1e-8 and slipping.max() <= 1e-8
        moving = np.flatnonzero(np.abs(v) > 10 * SLIP_RTOL * vs)
        if moving.size == 0:
            continue
        found += 1
        i = moving[0]
        delta = 0.5 * F * ln[i]
        lt2 = lt.copy()
        lt2[i] -= delta * np.sign(v[i])  # inside the cone, but no longer opposing the slip
        law2, slipping2 = law_residuals(v, ln, lt2, F * ln, vs, fs)
        assert slipping2[i] == pytest.approx(delta / fs, rel=1e-7)
        assert law2[i] == pytest.approx(min(abs(v[i]) / vs, delta / fs), rel=1e-7)
        assert np.delete(law2, i).max() <= 1e-8
    assert found >= 5


@given(st.integers(1, 12), st.integers(0, 2**32 - 1))
@settings(max_examples=40, deadline=None)
def test_law_residuals_zero_exactly_on_law_states_and_positive_off(m, seed):
    """Constructed states: stick (v = 0, |lam_t| <= s) and slip (lam_t = s sign v) give 0;
    a stick node made to move and a node pushed outside the cone give > 0."""
    rng = np.random.default_rng(seed)
    ln = rng.uniform(0.1, 2.0, m)
    s = 0.4 * ln
    stick = rng.random(m) < 0.5
    v = np.where(stick, 0.0, rng.uniform(0.1, 1.0, m) * rng.choice([-1.0, 1.0], m))
    lt = np.where(stick, rng.uniform(-1.0, 1.0, m) * s, s * np.sign(v))
    law, slipping = law_residuals(v, ln, lt, s, 1.0, 1.0)
    assert law.max() == 0.0 and slipping.max() == 0.0
    i = int(rng.integers(m))
    lt_out = lt.copy()
    lt_out[i] = 1.5 * s[i] * (np.sign(lt[i]) or 1.0)
    assert law_residuals(v, ln, lt_out, s, 1.0, 1.0)[0][i] >= 0.5 * s[i] - 1e-12
    if stick[i] and abs(lt[i]) < s[i]:
        v_mv = v.copy()
        v_mv[i] = 0.3
        expected = min(0.3, abs(lt[i] - s[i]))
        assert law_residuals(v_mv, ln, lt, s, 1.0, 1.0)[0][i] == pytest.approx(expected)

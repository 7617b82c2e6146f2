"""The beta = 0 test never fails the reduction. An SVD bound decides full-rank
couplings without an LP; an LP that returns no point ("HiGHS Status 0: Not Set") is retried
with other HiGHS methods, and when none decides the row says undecided (None) and why."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import OptimizeResult

import rbbench.rb.algorithms.infsup_zero as iz
from rbbench.hf.components import make_components
from rbbench.hf.model import ProblemCache
from rbbench.rb.algorithms import infsup as inf
from rbbench.rb.mixed.offline import _labelled
from rbbench.rb.validation import beta_summary
from rbbench.scene.loading import load_scene

NOT_SET = "The HiGHS solver ran into a problem. (HiGHS Status 0: Not Set)"


def _with_nonneg_null(rng, k, R):
    """``C`` (k x R) with ``C alpha = 0`` for a positive ``alpha`` (beta = 0 exactly)."""
    alpha = rng.uniform(0.1, 1.0, R)
    C = rng.standard_normal((k, R))
    return C - np.outer(C @ alpha, alpha) / (alpha @ alpha)


@pytest.mark.parametrize("k,R", [(5, 5), (12, 4), (40, 40)])
def test_svd_bound_agrees_with_the_lp(k, R):
    """Full column rank: the SVD bound decides 'not zero', and it is a true lower bound of
    the distance the LP finds (run without the bound)."""
    C = np.random.default_rng(k + R).standard_normal((k, R))
    fast = iz.zero_test(C)
    lp = iz.zero_test(C, svd_bound=False)
    assert fast.method == "svd-bound" and fast.is_zero is False
    assert lp.method == "lp:highs" and lp.is_zero is False
    assert fast.dist <= lp.dist * (1 + 1e-12)


def test_rank_deficient_goes_to_the_lp_and_scale_free():
    """A square C with a positive null vector: the bound cannot decide (s_min ~ 0), the LP
    finds the witness; scaling C by 1e300 (overflow of a plain norm) changes nothing."""
    C = _with_nonneg_null(np.random.default_rng(3), 6, 6)
    for scale in (1.0, 1e300, 1e-300):
        r = iz.zero_test(scale * C)
        assert r.is_zero is True and r.method == "lp:highs", scale
        assert np.all(r.alpha >= 0) and np.linalg.norm(C @ r.alpha) <= 1e-9 * np.abs(C).max()


def _fake_linprog(fail: set[str], calls: list[str]):
    real = iz.linprog

    def fake(*args, method, **kw):
        calls.append(method)
        if method in fail:
            return OptimizeResult(x=None, status=4, message=NOT_SET)
        return real(*args, method=method, **kw)

    return fake


def test_lp_without_a_point_is_retried(monkeypatch):
    """HiGHS' default returns no point: the dual simplex decides, the same as unpatched."""
    C = _with_nonneg_null(np.random.default_rng(4), 3, 6)
    calls: list[str] = []
    monkeypatch.setattr(iz, "linprog", _fake_linprog({"highs"}, calls))
    r = iz.zero_test(C)
    assert calls == ["highs", "highs-ds"] and r.method == "lp:highs-ds" and r.is_zero is True


def test_undecided_is_none_with_the_reason(monkeypatch):
    """No method returns a point: is_zero None (not an exception), the note names every
    method and HiGHS' message; infsup_cone and the result row carry it, and the summary
    counts it as undecided, not as zero."""
    C = _with_nonneg_null(np.random.default_rng(5), 3, 5)
    calls: list[str] = []
    monkeypatch.setattr(iz, "linprog", _fake_linprog(set(iz.LP_METHODS), calls))
    r = iz.zero_test(C)
    assert r.is_zero is None and calls == list(iz.LP_METHODS)
    assert all(m in r.note for m in iz.LP_METHODS) and "Not Set" in r.note
    assert inf.beta_zero_test(C) is None
    res = inf.infsup_cone(C.T @ C, np.eye(5), C=C)
    assert res.is_zero is None and "Not Set" in res.zero_note
    row = _labelled(res, c_hf=2.0)
    assert row["is_zero"] is None and "Not Set" in row["zero_note"]
    s = beta_summary({"dec": [row, {**row, "is_zero": False, "zero_note": ""}]})
    assert s["beta_dec_zero_undecided"] == 1 and s["beta_dec_zero_any"] is False


def test_membrane_hf_row_decided_without_lp():
    """The membrane's HF coupling H^T (nodal multipliers: full rank) is decided by the SVD
    bound; the LP, run anyway, agrees (n_cells = 8: 49 multipliers)."""
    scene = load_scene("membrane_obstacle", ["discretization.n_cells=8"])
    b, f, _ = make_components(scene)
    problems = ProblemCache(b, f, scene)
    p = problems(scene.default_mu)
    H = inf.supremizer_operator(p.B, inf.make_solver(problems.X_free(scene.default_mu)))
    fast, lp = iz.zero_test(H.T), iz.zero_test(H.T, svd_bound=False)
    assert fast.method == "svd-bound" and fast.is_zero is False and lp.is_zero is False
    assert fast.dist <= lp.dist

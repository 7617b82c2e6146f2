"""The reduced Nitsche model (rbbench.rb.nitsche): exact on a basis holding the snapshot, DEIM
at its magic points, errors decreasing with N, small and picklable."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from rbbench_plugins.formulations.nitsche import NitscheFormulation
from rbbench_plugins.solvers.newton import NewtonSolver

from rbbench.hf.model import solve_hf
from rbbench.rb.algorithms.eim import deim
from rbbench.rb.config import make_config
from rbbench.rb.nitsche.model import (
    _plain_system,
    full_points,
    reduced_newton,
    sparse_nnls,
)
from rbbench.rb.offline import reduce
from rbbench.registry import default_registry
from rbbench.scene.loading import load_scene
from rbbench.testing import HERTZ_COARSE

COARSE = list(HERTZ_COARSE)


def _scene(*extra):
    return load_scene("hertz_halfdisks", [*COARSE, *extra])


def _nitsche(sc, mu, theta=1.0, gamma0=10.0, backend=None):
    reg = default_registry()
    b = backend or reg.create("backend", "skfem", scene=sc)
    return solve_hf(sc, mu, formulation="nitsche", solver="newton",
                    components=(b, NitscheFormulation(theta, gamma0), NewtonSolver()))


def test_plain_reduced_model_is_exact_when_the_basis_contains_the_snapshot():
    sc = _scene()
    reg = default_registry()
    b = reg.create("backend", "skfem", scene=sc)
    mu = np.array([0.9])
    sol = _nitsche(sc, mu, backend=b)
    prob = sol.problem
    u = sol.result.u[prob.free]
    other = _nitsche(sc, 1.2, backend=b).result.u[prob.free]
    X = prob.X[prob.free][:, prob.free]
    Z = np.linalg.qr(np.stack([other, u], axis=1))[0]
    L = np.linalg.cholesky(Z.T @ (X @ Z))
    Z = np.linalg.solve(L, Z.T).T  # X-orthonormal, spans u
    Zfull = np.zeros((prob.u_lift.size, 2))
    Zfull[prob.free] = Z
    rp = full_points(b.contact_layout(), mu, Zfull, prob.u_lift, prob.gamma0)
    A, F = Z.T @ (prob.A @ Z), Z.T @ prob.F
    res = reduced_newton(_plain_system(A, F, rp, prob.theta), np.zeros(2))
    assert res.stop_reason == "converged"
    err = np.sqrt((u - Z @ res.c) @ (X @ (u - Z @ res.c)) / (u @ (X @ u)))
    assert err < 1e-8


def test_deim_is_exact_at_its_magic_points_and_nnls_meets_its_tolerance():
    rng = np.random.default_rng(3)
    S = rng.standard_normal((60, 6)) @ rng.standard_normal((6, 40))
    eim = deim(S, tol=1e-12)
    new = rng.standard_normal(60)
    approx = eim.interpolate(new[eim.magic])
    assert np.allclose(approx[eim.magic], new[eim.magic], atol=1e-12)
    assert np.allclose(eim.approximate(S), S, atol=1e-9 * np.abs(S).max())
    # empirical cubature of smooth integrands: a few positive weights reproduce the sums
    x = np.linspace(0.0, 1.0, 200)
    G = np.stack([np.cos(k * x) for k in range(8)])  # (8 "snapshots", 200 points)
    bvec = G @ np.full(200, 1.0 / 200)
    w, errors = sparse_nnls(G.T @ G, G.T @ bvec, float(bvec @ bvec), tol=1e-8)
    assert np.all(w >= 0) and errors[-1] <= 1e-8 and np.count_nonzero(w) <= 10
    assert np.linalg.norm(G @ w - bvec) <= 1.01e-8 * np.linalg.norm(bvec)


@pytest.fixture(scope="module")
def nitsche_reductions(tmp_path_factory):
    cache = str(tmp_path_factory.mktemp("nitsche_cache"))
    sc = _scene()
    out = {}
    for N in (2, 4, 8):
        out[N] = reduce(sc, make_config(formulation="nitsche", N=N, n_train=9, n_valid=5,
                                         online_repeats=2, cache_dir=cache, n_jobs=1))
    out["deim"] = reduce(sc, make_config(formulation="nitsche", N=4, hyper="eim", n_train=9,
                                          n_valid=5, online_repeats=1, cache_dir=cache,
                                          n_jobs=1))
    return sc, out


def test_reduced_errors_decrease_with_N_and_meet_the_target(nitsche_reductions):
    _, out = nitsche_reductions
    errs = [out[N].summary()["err_u_max"] for N in (2, 4, 8)]
    assert errs[0] > errs[1] > errs[2], errs
    s = out[8].summary()
    assert s["err_u_max"] <= 1e-3
    assert s["hyper"] == "ecsw" and s["online_stops"] == {"converged": 5}
    assert s["speedup"] > 10
    eim = s["histories"]["eim"]
    assert eim["rows"] < out[8].n_contact  # fewer points than the HF contact quadrature
    assert eim["e_eim_cv_valid"] < 1e-2 and eim["e_eim_valid"] < 1e-2
    # the cubature is at most as good as the plain model: same V_N
    assert s["err_u_max"] <= 2 * max(s["histories"]["err_u_plain"]) + 1e-6
    for k in ("beta_hf_min", "beta_off_min"):
        assert s.get(k) is None


def test_reduced_model_is_small_and_evaluates_its_points_exactly(nitsche_reductions):
    sc, out = nitsche_reductions
    res = out[4]
    model = pickle.loads(pickle.dumps(res.model))
    assert len(pickle.dumps(model)) < 2e6
    b = default_registry().create("backend", "skfem", scene=sc)
    mu = res.valid_mus[0]
    p = model.points(mu)
    layout = b.contact_layout()
    Zfull = np.zeros((layout.n_dofs, model.N))
    Zfull[model.evaluator.local_dofs] = model.Z_loc
    lift = np.zeros(layout.n_dofs)
    lift[model.evaluator.local_dofs] = model.lift_loc
    full = full_points(layout, mu, Zfull, lift, model.gamma0).take(model.evaluator.points)
    for f in ("UZ", "SZ", "u0", "s0", "gap", "w", "gamma"):
        a, c = getattr(p, f), getattr(full, f)
        assert np.allclose(a, c, rtol=1e-12, atol=1e-12 * max(np.abs(c).max(), 1e-300)), f
    r = model.solve(mu)
    assert r.stop_reason == "converged" and r.c.shape == (model.N,)


def test_deim_variant_runs_and_reports_the_published_errors(nitsche_reductions):
    _, out = nitsche_reductions
    s = out["deim"].summary()
    assert s["hyper"] == "deim"
    eim = s["histories"]["eim"]
    assert eim["method"] == "deim" and len(eim["e_eim_valid_by_iteration"]) >= 1
    assert all(np.isfinite(v) for v in (eim["e_eim_valid"], eim["e_eim_cv_valid"]))


def test_residual_indicator_rows(nitsche_reductions):
    """The indicator over the true error per mu is the reported effectivity (both divided by
    the same ||u||_X), its summary the statistics of those rows, and the indicator follows the
    error as N grows (not claimed rigorous: no test that it is above the error)."""
    _, out = nitsche_reductions
    medians = []
    for N in (2, 4, 8):
        s = out[N].summary()
        ind, err = np.array(s["per_mu"]["err_indicator_u"]), np.array(s["per_mu"]["err_u"])
        eff = np.array(s["per_mu"]["indicator_effectivity"])
        assert np.allclose(eff, ind / err, rtol=1e-10)
        assert s["indicator_effectivity_min"] == pytest.approx(eff.min())
        assert s["indicator_effectivity_median"] == pytest.approx(np.median(eff))
        medians.append(float(np.median(ind)))
    assert medians[2] < medians[0]

"""Nitsche formulation (seed 000, "Nitsche's method"): normal stress operator, Newton
solver, agreement with the mixed formulation, Alart-Curnier residual, stability over
gamma0, and the reduced Nitsche model (coarse meshes, fixed seeds)."""

from __future__ import annotations

import contextlib
import io
import json
import pickle

import numpy as np
import pytest
from rbbench_plugins.formulations.nitsche import NitscheFormulation
from rbbench_plugins.solvers.newton import NewtonSolver
from support.fields import affine_field

from rbbench.cli import main
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
#: The e_AC study's former setting (GPTS): the seed's load, P1, one point per facet.
TABLE = ["load.displacement=0.09", "discretization.quadrature=1", "discretization.h_max=0.2"]
#: The e_AC table's setting (README "The e_AC^n table"): P2, smooth slave normals,
#: segment-to-segment contact quadrature.
SEED_TABLE = ["load.displacement=0.09", "discretization.degree=2", "discretization.h_max=0.2",
              "discretization.normals=smooth", "discretization.contact_integration=segmented"]


def _scene(*extra):
    return load_scene("hertz_halfdisks", [*COARSE, *extra])


def _nitsche(sc, mu, theta=1.0, gamma0=10.0, backend=None):
    reg = default_registry()
    b = backend or reg.create("backend", "skfem", scene=sc)
    return solve_hf(sc, mu, formulation="nitsche", solver="newton",
                    components=(b, NitscheFormulation(theta, gamma0), NewtonSolver()))


def _independent_residual(prob, u):
    """The Nitsche equations written out from the seed's slide (not rbbench.hf.algebra.nitsche)."""
    s = prob.Snn @ u + prob.snn_lift
    P = s - prob.gamma * (prob.Un @ u - prob.gap)
    neg = np.minimum(P, 0.0)
    d = prob.weights / prob.gamma
    bnd = prob.Snn.T @ (prob.theta * d * (neg - s)) - prob.Un.T @ (prob.weights * neg)
    R = prob.A @ u - prob.F + bnd
    return np.linalg.norm(R) / max(np.linalg.norm(prob.F), np.linalg.norm(prob.A @ u))


@pytest.mark.parametrize("degree", [1, 2])
def test_snn_is_exact_for_affine_fields_and_only_on_request(degree):
    sc = _scene(f"discretization.degree={degree}")
    b = default_registry().create("backend", "skfem", scene=sc)
    assert b.discretize(0.8).contact.Snn is None
    mu = 0.8
    d = b.discretize(mu, needs=frozenset({"stress"}))
    G = np.array([[1e-3, 2e-3], [-5e-4, 3e-3]])
    E, nu = sc.material("upper")
    lam, mu_l = E * nu / ((1 + nu) * (1 - 2 * nu)), E / (2 * (1 + nu))
    eps = 0.5 * (G + G.T)
    sig = lam * np.trace(eps) * np.eye(2) + 2 * mu_l * eps
    n = d.contact.normals
    want = np.einsum("qi,ij,qj->q", n, sig, n)
    got = d.contact.Snn @ affine_field(b, d, mu, G)
    assert np.abs(got - want).max() <= 1e-10 * np.abs(want).max()
    # rigid motions of the slave body are stress free
    rot = affine_field(b, d, mu, np.array([[0.0, -1e-3], [1e-3, 0.0]]))
    assert np.abs(d.contact.Snn @ rot).max() <= 1e-10 * np.abs(want).max()
    # facet lengths: the mapped slave facets
    assert np.allclose(np.add.reduceat(d.contact.weights, np.arange(0, n.shape[0], degree + 1)),
                       d.contact.facet_length[:: degree + 1], rtol=1e-12)


@pytest.mark.parametrize("degree", [1, 2])
def test_snn_is_the_same_on_ngsolve_and_skfem_on_one_mesh(degree):
    pytest.importorskip("ngsolve")
    from rbbench_plugins.backends.ngsolve.backend import NGSolveBackend

    sc = _scene(f"discretization.degree={degree}")
    bs = default_registry().create("backend", "skfem", scene=sc)
    bn = NGSolveBackend(sc, mesh="skfem")
    ds = bs.discretize(1.3, needs=frozenset({"stress"}))
    dn = bn.discretize(1.3, needs=frozenset({"stress"}))
    # the same affine field on both dof numberings: u = G x on the upper body
    G = np.array([[2e-3, -1e-3], [4e-4, 1e-3]])
    us = affine_field(bs, ds, 1.3, G)
    t = bn.dof_table()
    scale, shift = bn._body_maps()["upper"].at(np.array([1.3]))
    x = scale * t["x_hat"] + shift
    un = np.where(t["body"] == 0, np.einsum("ij,nj->ni", G, x)[np.arange(x.shape[0]),
                                                                  t["component"]], 0.0)
    a, c = ds.contact.Snn @ us, dn.contact.Snn @ un
    assert np.abs(a - c).max() <= 1e-10 * np.abs(a).max()
    assert np.allclose(ds.contact.facet_length, dn.contact.facet_length, rtol=1e-12)


# ---------------------------------------------------------------------------
# HF Nitsche solve
# ---------------------------------------------------------------------------
def test_newton_converges_cold_and_agrees_with_mixed_within_the_discretisation_error():
    """|F_nitsche - F_mixed| / F_mixed <= |F_mixed(h) - F_mixed(2h)| / F_mixed: within the
    discretisation error of the force, estimated by its change under refinement; checked
    at two mesh sizes, so the tolerance shrinks with h."""
    reg = default_registry()
    forces = {}
    for hc in (0.04, 0.02, 0.01):
        sc = load_scene("hertz_halfdisks", [f"discretization.h_contact={hc}",
                                            "discretization.h_max=0.2"])
        b = reg.create("backend", "skfem", scene=sc)
        for mu in (0.7, 1.3):
            n = _nitsche(sc, mu, backend=b)
            assert n.result.converged, n.result.info["reason"]
            assert n.result.info["start"].startswith("cold")
            assert _independent_residual(n.problem, n.result.u[n.problem.free]) < 1e-9
            m = solve_hf(sc, mu, components=(b, reg.create("formulation", "mixed"),
                                             reg.create("solver", "ssn")))
            forces[hc, mu] = (n.metrics["contact_force"], m.metrics["contact_force"])
            assert 0.0 < n.metrics["e_ac"] < 1.0
            assert n.result.lam.shape == (m.result.lam.size,) and n.result.lam.min() >= 0
    for coarse, fine in ((0.04, 0.02), (0.02, 0.01)):
        for mu in (0.7, 1.3):
            fn, fm = forces[fine, mu]
            tol = abs(fm - forces[coarse, mu][1]) / fm
            assert abs(fn - fm) / fm <= tol, (fine, mu, abs(fn - fm) / fm, tol)
    assert abs(forces[0.01, 0.7][1] - forces[0.02, 0.7][1]) < \
        abs(forces[0.02, 0.7][1] - forces[0.04, 0.7][1])


def test_ac_residual_decreases_under_refinement():
    reg = default_registry()
    e = []
    for hc in (0.04, 0.02, 0.01):
        sc = load_scene("hertz_halfdisks", [*TABLE, f"discretization.h_contact={hc}"])
        sol = _nitsche(sc, 1.0, backend=reg.create("backend", "skfem", scene=sc))
        assert sol.result.converged
        e.append(sol.metrics["e_ac"])
    assert e[0] > e[1] > e[2], e
    assert np.log(e[0] / e[2]) / np.log(4.0) > 0.5  # observed order (seed: 1)


def _e_ac_order(setting, mu, hcs=(0.02, 0.01)):
    reg = default_registry()
    e, h = [], []
    for hc in hcs:
        sc = load_scene("hertz_halfdisks", [*setting, f"discretization.h_contact={hc}"])
        sol = _nitsche(sc, mu, backend=reg.create("backend", "skfem", scene=sc))
        assert sol.result.converged
        e.append(sol.metrics["e_ac"])
        h.append(float(np.mean(sol.problem.h)))
    return np.log(e[0] / e[1]) / np.log(h[0] / h[1]), e


@pytest.mark.parametrize("mu", [0.7, 1.3])
def test_ac_residual_converges_at_order_one_on_non_matching_meshes(mu):
    """The seed's order 1 (README "The e_AC^n table"): two bodies, non-matching contact
    meshes, P2, smooth normals and segment-to-segment quadrature; GPTS with facet
    normals (the former setting) stagnates on the same meshes."""
    order, e = _e_ac_order(SEED_TABLE, mu)
    assert 0.7 < order < 1.6, (order, e)
    assert e[1] < 0.015
    if mu == 1.3:
        order_gpts, e_gpts = _e_ac_order(TABLE, mu)
        assert order_gpts < 0.3 and e_gpts[1] > 3 * e[1], (order_gpts, e_gpts)


def test_nodal_ac_residual_is_zero_for_an_exact_alart_curnier_field():
    from rbbench.hf.algebra.nitsche import ac_residual_nodal

    gamma = np.full(4, 1e12)
    s = np.array([-3.0, -1.0, 0.0, 0.0])  # active: no penetration; inactive: a gap
    pen = np.array([0.0, 0.0, -1e-6, -2e-3])
    assert ac_residual_nodal(s, pen, gamma) == 0.0
    assert ac_residual_nodal(s, pen + 1e-12, gamma) > 0.0  # penetration
    assert ac_residual_nodal(s + 0.5, pen, gamma) > 0.0  # tension


def test_ac_residual_variants_on_a_rigid_obstacle():
    """The three e_AC readings: ``quad`` is the solve's ``e_ac``; on a rigid flat
    obstacle (no non-matching master mesh) the nodal one decreases under refinement."""
    from rbbench.hf.algebra.nitsche import ac_residual_variants

    reg = default_registry()
    e = []
    for hc in (0.04, 0.02, 0.01):
        sc = load_scene("hertz_halfdisks", [*TABLE, f"discretization.h_contact={hc}",
                                            "geometry.lower=rigid_flat"])
        b = reg.create("backend", "skfem", scene=sc)
        sol = _nitsche(sc, 1.0, backend=b)
        assert sol.result.converged
        v = ac_residual_variants(b.contact_layout(), sol.problem, sol.result.u, sol.mu)
        assert v["quad"] == pytest.approx(sol.metrics["e_ac"], rel=1e-12)
        assert all(0.0 < x < 1.0 for x in v.values()), v
        e.append(v["nodal"])
    assert e[0] > e[1] > e[2], e


@pytest.mark.parametrize("theta", [1.0, -1.0])
def test_gamma_sweep_converges_or_reports_why(theta):
    sc = _scene()
    b = default_registry().create("backend", "skfem", scene=sc)
    outcomes = {}
    for mu in (0.7, 1.3):
        for g0 in (1e-3, 1.0, 10.0, 1e3, 1e7):
            sol = _nitsche(sc, mu, theta, g0, backend=b)
            r = sol.result
            outcomes[mu, g0] = r.stop_reason
            if r.converged:
                assert _independent_residual(sol.problem, r.u[sol.problem.free]) < 1e-6
                assert np.isfinite(sol.metrics["contact_force"])
            else:
                assert r.stop_reason in ("diverged", "stagnation", "max_iterations", "nan")
                assert r.info["reason"]
    assert all(outcomes[mu, g] == "converged" for mu in (0.7, 1.3) for g in (10.0, 1e3))
    if theta == 1.0:  # the Nitsche energy is not convex for a tiny gamma0: said so
        assert outcomes[0.7, 1e-3] == "diverged"
        sol = _nitsche(sc, 0.7, 1.0, 1e-3, backend=b)
        assert "gamma0" in sol.result.info["reason"]
    else:  # theta = -1: stable for small gamma0
        assert outcomes[0.7, 1e-3] == "converged"


def test_nan_input_and_warm_start():
    sc = _scene()
    sol = _nitsche(sc, 1.0)
    prob = sol.problem
    again = NewtonSolver().solve(prob, warm_start=sol.result.u)
    assert again.converged and again.iterations == 0
    prob.gap = prob.gap.copy()
    prob.gap[0] = np.nan
    assert NewtonSolver().solve(prob).stop_reason == "nan"


def test_formulation_declares_its_needs_and_checks_them():
    sc = _scene()
    b = default_registry().create("backend", "skfem", scene=sc)
    assert NitscheFormulation.needs == frozenset({"stress"})
    with pytest.raises(ValueError, match="needs"):
        NitscheFormulation().build(b.discretize(1.0))
    with pytest.raises(ValueError, match="gamma0"):
        NitscheFormulation(gamma0=0.0)
    with pytest.raises(ValueError, match="unknown needs"):
        b.discretize(1.0, needs=frozenset({"curvature"}))


# ---------------------------------------------------------------------------
# reduced Nitsche model
# ---------------------------------------------------------------------------
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


def test_deim_variant_runs_and_reports_the_seed_errors(nitsche_reductions):
    _, out = nitsche_reductions
    s = out["deim"].summary()
    assert s["hyper"] == "deim"
    eim = s["histories"]["eim"]
    assert eim["method"] == "deim" and len(eim["e_eim_valid_by_iteration"]) >= 1
    assert all(np.isfinite(v) for v in (eim["e_eim_valid"], eim["e_eim_cv_valid"]))


# ---------------------------------------------------------------------------
# CLI
# ---------------------------------------------------------------------------
def _run(argv):
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = main(argv)
    return code, out.getvalue()


def test_cli_solve_nitsche_picks_newton_and_writes_e_ac(tmp_path):
    args = ["solve", "hertz_halfdisks", "--formulation", "nitsche", "--mu", "0.7", "--no-plot",
            "--quiet", "--out", str(tmp_path)]
    for s in COARSE:
        args += ["--set", s]
    code, text = _run(args)
    assert code == 0, text
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["solver"] == "newton" and summary["formulation"] == "nitsche"
    assert 0.0 < summary["e_ac"] < 1.0 and summary["converged"]
    assert "e_ac" in text


def test_renamed_study_names_still_import_with_a_deprecation_warning():
    import rbbench.studies as studies
    from rbbench.studies.nitsche_eac import PUBLISHED_H, published_h_overrides

    with pytest.warns(DeprecationWarning, match="SEED_H is now PUBLISHED_H"):
        assert studies.SEED_H == PUBLISHED_H
    with pytest.warns(DeprecationWarning, match="seed_h_overrides is now published_h_overrides"):
        assert studies.seed_h_overrides is published_h_overrides


def test_cli_nitsche_table(tmp_path):
    code, text = _run(["nitsche-table", "--h", "10", "5", "--mu", "1.0", "--quiet",
                       "--degree", "1", "--set", "discretization.h_max=0.2"])
    assert code == 0, text
    assert "| 1 | 10 |" in text and "published e_AC" in text and "| 1 | 5 |" in text
    assert "e_AC nodal" in text and "e_AC L2" in text and "e_AC quad:" in text

"""Reduced friction model: the small Coulomb solve against the HF friction
solver, GCNS and its stopping rule, the plain reduced model on hertz_friction (coarse P1)
against the HF snapshots, friction snapshots with lam_t, ``rbbench reduce`` on a friction
scene, pickling."""

from __future__ import annotations

import dataclasses
import json
import pickle

import numpy as np
import pytest

from rbbench.hf.snapshots.cache import cache_path
from rbbench.hf.snapshots.compute import compute_snapshots
from rbbench.hf.snapshots.key import snapshot_key
from rbbench.hf.solvers import friction as fs
from rbbench.rb.algorithms.gcns import gcns, tangential_violation
from rbbench.rb.config import make_config
from rbbench.rb.friction.collocation.model import (
    FrictionArrays,
    condense_reduced,
    project_friction,
    solve_coulomb,
)
from rbbench.rb.friction.wedge.model import project_wedge
from rbbench.rb.offline import offline
from rbbench.rb.validation import validate
from rbbench.scene.loading import load_scene

COARSE = ["discretization.degree=1", "discretization.h_contact=0.02",
          "discretization.h_max=0.25"]
SOLVER = "friction-ssn"


def _random_problem(seed: int, n: int = 14, m: int = 5) -> FrictionArrays:
    """A small SPD friction problem pushed into contact (``F = Bn^T c``, c > 0)."""
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((n, n))
    Bn, Bt = rng.standard_normal((m, n)), rng.standard_normal((m, n))
    F = Bn.T @ rng.uniform(0.5, 1.5, m) + 0.3 * rng.standard_normal(n)
    return FrictionArrays(M @ M.T + n * np.eye(n), F, Bn, rng.uniform(0.0, 0.3, m), Bt,
                          0.05 * rng.standard_normal(m), np.full(m, 0.3))


# ---------------------------------------------------------------------------
# the small solve, against the HF friction algebra (a different algorithm)
# ---------------------------------------------------------------------------
def test_identity_bases_equal_hf_coulomb_and_tresca():
    """With identity bases and every node collocated, the reduced problem IS the HF one:
    the fixed point of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods:
    parametric variational inequalities" (talk), on daqp Tresca QPs, equals the semismooth
    Newton on the wedge (coulomb_direct) and the Tresca PDAS, on problems with open, stick and
    slip nodes."""
    states = set()
    for seed in range(6):
        arr = _random_problem(seed)
        cond = condense_reduced(arr)
        m = arr.Gn.size
        eye = np.eye(m)
        hf = fs.coulomb_direct(cond.D, cond.q, 0.3)
        assert hf.stop_reason == "converged"
        states.update(hf.states)
        red = solve_coulomb(cond, eye, eye, np.full(m, 0.3), "coulomb")
        assert red.stop_reason == "converged"
        assert np.abs(red.x - hf.x).max() <= 1e-8 * np.abs(hf.x).max()
        tr_hf = fs.pdas_tresca(cond.D, cond.q, 0.2)
        tr = solve_coulomb(cond, eye, eye, np.full(m, 0.2), "tresca")
        assert tr.iterations == 1 and tr.stop_reason == "converged"
        assert np.abs(tr.x - tr_hf.x).max() <= 1e-8 * np.abs(tr_hf.x).max()
    assert {"stick", "slip"} <= states


def test_raw_multipliers_respect_the_collocated_constraints():
    """Raw reduced multipliers (no clipping): c_n >= 0, |Qt theta| <= nu_F Qn c_n at the
    collocation nodes, normal complementarity of the reduced problem."""
    arr = _random_problem(1)
    cond = condense_reduced(arr)
    rng = np.random.default_rng(7)
    Qn, Qt = np.abs(rng.standard_normal((3, 5))), rng.standard_normal((3, 5))
    res = solve_coulomb(cond, Qn, Qt, np.full(3, 0.3), "coulomb")
    assert res.stop_reason == "converged"
    scale = np.abs(res.x).max()
    assert res.c_n.min() >= -1e-10 * scale
    assert np.all(np.abs(Qt @ res.theta) <= 0.3 * (Qn @ res.c_n) + 1e-9 * scale)
    gap = cond.q[:5] + cond.D[:5] @ res.x  # reduced normal gap Gn_N - Bn_N a
    assert gap.min() >= -1e-9 * np.abs(cond.q).max()
    assert abs(res.c_n @ gap) <= 1e-9 * scale * np.abs(cond.q).max()


# ---------------------------------------------------------------------------
# GCNS on a synthetic solve_all
# ---------------------------------------------------------------------------
def _fake_solve(errors: list[float], m: int = 12):
    """``solve_all`` whose e_GCNS after k additions is ``errors[k]`` and whose violation is
    positive off the selected nodes and exactly 0 at them."""
    lam_t = np.linspace(1.0, 2.0, m)[:, None]

    def solve_all(nodes):
        k = min(nodes.size // 2, len(errors) - 1)
        lt = lam_t * (1.0 + errors[k])
        bound = lam_t.copy()  # violated by lam_t * errors[k] everywhere ...
        bound[nodes] = np.abs(lt[nodes])  # ... except at the selected nodes
        return lt, bound

    return solve_all, lam_t


def test_gcns_stops_by_the_published_rule_and_keeps_the_previous_set():
    solve_all, lam_t = _fake_solve([0.5, 0.3, 0.2, 0.25, 0.1, 0.05, 0.07])
    W = [np.eye(lam_t.shape[0])]
    res = gcns(solve_all, lam_t, W, per_iteration=2)
    e = [h["e_gcns"] for h in res.history]
    assert np.allclose(e, [0.5, 0.3, 0.2, 0.25])  # stopped at the first increase
    assert res.stop == "e_gcns increased" and res.iterations == 2 and res.S_q == 4
    assert [h["S_q"] for h in res.history] == [0, 2, 4, 6]
    # the largest violation is picked: lam_t grows with the node index
    assert sorted(res.nodes.tolist()) == [8, 9, 10, 11]
    # patience 3 runs past the bump, keeps the best set
    res3 = gcns(solve_all, lam_t, W, per_iteration=2, patience=3)
    assert res3.iterations == 5 and res3.S_q == 10 and res3.stop == "no violation"
    assert len(res3.history) == 7  # S_q = 12 (all nodes, e = 0.07) computed, not kept
    assert gcns(solve_all, lam_t, W, max_iterations=1).stop == "max_iterations"


def test_gcns_violation_is_zero_at_the_selected_nodes():
    """On the real reduced model (raw values): after selection, the reduced lam_t of every
    training mu satisfies the constraint at the selected nodes (to solver tolerance)."""
    stage = _offline().stage
    res = stage.gcns
    assert res.S_q > 0 and len(res.history) >= 2
    lt, bound = stage._solve_training(res.nodes)
    viol = tangential_violation(lt, bound)
    scale = np.abs(stage.ctx.train.LAM_T).max()
    assert viol[res.nodes].max() <= 1e-9 * scale
    # and the recorded history is the algorithm's: e_nt of the kept set is this violation
    kept = res.history[res.iterations]
    assert kept["S_q"] == res.S_q
    assert np.isclose(kept["e_nt"], viol.max(), rtol=1e-6, atol=1e-9 * scale)


# ---------------------------------------------------------------------------
# the plain reduced model on hertz_friction (coarse P1)
# ---------------------------------------------------------------------------
_CACHE: dict = {}


def _offline(patience: int = 1, dual: str = "collocation", **kw):
    key = (patience, dual, tuple(sorted(kw.items())))
    if key not in _CACHE:
        scene = load_scene("hertz_friction", overrides=COARSE)
        cfg = make_config(solver=SOLVER, n_train=7, n_valid=3, n_jobs=2, online_repeats=1,
                           R=7, tol_dual=1e-12, cache_dir=str(_workdir() / ".rbbench_cache"),
                          gcns_patience=patience, friction_dual=dual, **kw)
        _CACHE[key] = offline(scene, cfg)
    return _CACHE[key]


def _workdir():
    """One temporary directory for the module (its ``.rbbench_cache`` is the CLI's too)."""
    import tempfile
    from pathlib import Path

    if "dir" not in _CACHE:
        _CACHE["dir"] = Path(tempfile.mkdtemp(prefix="rbbench_friction_rb_"))
    return _CACHE["dir"]


def test_friction_snapshots_store_lam_t():
    off = _offline()
    train = off.context.train
    assert train.LAM_T is not None and train.LAM_T.shape == train.LAM.shape
    assert np.abs(train.LAM_T).max() > 0.05 * train.LAM.max()  # friction is active
    assert np.all(np.abs(train.LAM_T) <= 0.2 * train.LAM + 1e-8 * train.LAM.max())


def test_friction_cache_without_lam_t_is_recomputed(tmp_path):
    """A friction snapshot file of the previous format (no lam_t) is solved again; the key
    is the frictionless formula (friction scenes only gain a stored array)."""
    scene = load_scene("hertz_friction", overrides=COARSE)
    mu = np.array([1.0])
    first = compute_snapshots(scene, [mu], solver=SOLVER, cache_dir=tmp_path, n_jobs=1,
                              progress=False)
    key = snapshot_key(scene, solver=SOLVER)
    assert first.key == key and first.LAM_T is not None
    path = cache_path(tmp_path, key, mu)
    with np.load(path) as z:
        old = {k: z[k] for k in z.files if k != "lam_t"}
    np.savez(path, **old)
    again = compute_snapshots(scene, [mu], solver=SOLVER, cache_dir=tmp_path, n_jobs=1,
                              progress=False)
    assert again.n_computed == 1 and np.allclose(again.LAM_T, first.LAM_T)
    cached = compute_snapshots(scene, [mu], solver=SOLVER, cache_dir=tmp_path, n_jobs=1,
                               progress=False)
    assert cached.n_computed == 0


def test_full_bases_and_all_nodes_reproduce_the_training_snapshots():
    """Brute force: full-rank bases (N = R = S = n_train, PGA on b^n + b^tau) and every HF
    node collocated give the HF solution at each training mu to solver tolerance."""
    off = _offline()
    st, ctx = off.stage, off.context
    assert st.R == st.S == len(ctx.mus_train)
    allnodes = np.arange(ctx.train.LAM.shape[0])
    X = ctx.X
    for j, mu in enumerate(ctx.mus_train):
        p = ctx.problem_at(mu)
        res = solve_coulomb(st.train_cond[j], st.Vn, st.Vt, p.coefficient, "coulomb")
        assert res.stop_reason == "converged"
        du = st.Z_off @ res.a - ctx.train.U[:, j]
        assert np.sqrt(du @ (X @ du) / (ctx.train.U[:, j] @ (X @ ctx.train.U[:, j]))) < 1e-9
        for V, c, lam in ((st.Vn, res.c_n, ctx.train.LAM), (st.Vt, res.theta, ctx.train.LAM_T)):
            d = V @ c - lam[:, j]
            assert np.sqrt(d @ (p.W @ d) / (lam[:, j] @ (p.W @ lam[:, j]))) < 1e-8
        assert allnodes.size == p.n_nodes


def test_errors_decrease_as_the_bases_grow():
    """At a training mu (all nodes collocated): the u and lam_t errors of nested sub-bases
    (first n POD / cone / tangential modes, the PGA space kept) decrease to ~0."""
    off = _offline()
    st, ctx = off.stage, off.context
    j = 3
    p = ctx.problem_at(ctx.mus_train[j])
    u, lt = ctx.train.U[:, j], ctx.train.LAM_T[:, j]
    errs = []
    for k in (2, 4, 7):
        Z = np.hstack([st.Z[:, :k], st.Z_off[:, st.N:]])
        Vn, Vt = st.Vn[:, :k], st.Vt[:, :k]
        cond = condense_reduced(project_friction(p, Z, Vn, Vt))
        res = solve_coulomb(cond, Vn, Vt, p.coefficient, "coulomb")
        du, dt = Z @ res.a - u, Vt @ res.theta - lt
        errs.append((np.sqrt(du @ (ctx.X @ du) / (u @ (ctx.X @ u))),
                     np.sqrt(dt @ (p.W @ dt) / (lt @ (p.W @ lt)))))
    e_u, e_t = np.array(errs).T
    assert e_u[0] > e_u[1] > e_u[2] and e_t[0] > e_t[2]
    assert e_u[2] < 1e-9 and e_t[2] < 1e-8 and e_u[0] > 1e-4


def test_reduced_model_pickles_and_solves_the_same():
    off = _offline()
    st, ctx = off.stage, off.context
    model = pickle.loads(pickle.dumps(st.reduced))
    mu = ctx.mus_valid[0]
    arrays = project_friction(ctx.problem_at(mu), st.Z_off, st.Vn, st.Vt)
    a, b = st.reduced.solve_arrays(mu, arrays), model.solve_arrays(mu, arrays)
    assert a.stop_reason == b.stop_reason == "converged"
    assert np.array_equal(a.x, b.x)
    # the online arrays are small; the HF size is in the reconstruction basis and in the
    # recipe of the plain model's online assembly (PlainArrays: scene and component names)
    light = dataclasses.replace(model, basis=None, arrays_at=None)
    assert len(pickle.dumps(light)) < 200_000
    with pytest.raises(ValueError, match="arrays_at"):
        light.solve(mu)
    # the unpickled plain model rebuilds its components and solves as the original
    c, d = st.reduced.solve(mu), model.solve(mu)
    assert np.array_equal(c.x, d.x) and np.array_equal(c.x, a.x)
    np.testing.assert_array_equal(model.reconstruct(d).u, st.Z_off @ d.a)


def test_rbbench_reduce_on_the_friction_scene(monkeypatch):
    """``rbbench reduce hertz_friction`` picks the friction solver, writes the friction keys;
    the reduced constraint holds at the GCNS nodes of every validation mu (raw values)."""
    from rbbench.cli import main

    tmp_path = _workdir()  # its .rbbench_cache holds the snapshots of _offline()
    _offline()
    monkeypatch.chdir(tmp_path)
    argv = ["reduce", "hertz_friction", "--n-train", "7", "--n-valid", "3", "--jobs", "2",
            "-R", "7", "--stabilizer", "pga", "--friction-dual", "collocation",
            "--out", str(tmp_path / "out"), "--quiet"]
    for o in COARSE:
        argv += ["--set", o]
    assert main(argv) == 0
    s = json.loads((tmp_path / "out" / "result.json").read_text())
    for k in ("err_lam_t_max", "err_lam_t_mean", "lam_t_best_max", "S", "S_q",
              "gcns_iterations", "gcns_nodes", "gcns_history", "friction_residual_max"):
        assert k in s, k
    assert s["config"]["solver"] == SOLVER and s["S"] == s["R"]
    assert s["S_q"] == len(s["gcns_nodes"]) and s["online_stops"] == {"converged": 3}
    assert s["collocation_violation_max"] <= 1e-9
    assert s["lam_t_best_max"] <= s["err_lam_t_max"] + 1e-12
    assert s["err_u_max"] < 0.05
    # combined inf-sup rows (2m = 258 <= HF_ROWS_MAX: the hf row too): a smaller dual set
    # (dec) or primal space (off) moves the raw values the way inf over subsets must
    kinds = s["beta_kind"]
    assert kinds["hf"] == "span-lower-bound" and kinds["dec"] == kinds["off"] == "cone-exact"
    assert 0 < s["beta_hf_span_min"] <= s["beta_dec_span_min"] * (1 + 1e-9)
    assert 0 < s["beta_off_min"] <= s["beta_dec_min"] * (1 + 1e-9)
    assert not (s["beta_dec_zero_any"] or s["beta_off_zero_any"])
    prof = s["lam_t_profiles"]
    assert prof["mu"] == [[0.7], [1.0], [1.3]]  # 7 training mu on [0.7, 1.3]
    assert all(np.all(np.diff(x) >= 0) for x in prof["x"])
    assert {len(v) for k, v in prof.items()} == {3}


# ---------------------------------------------------------------------------
# the wedge dual model (cones of F lam_n +- lam_t, De Saxce's fixed point)
# ---------------------------------------------------------------------------
def test_wedge_full_bases_reproduce_the_training_snapshots():
    """Full-rank wedge cones (R+ = R- = n_train) and the PGA space: the HF solution of each
    training mu is a solution of the reduced problem (its (w+, w-) is a generator pair and
    the modified gap is in the dual cone node by node); the fixed point finds it."""
    off = _offline(dual="wedge")
    st, ctx = off.stage, off.context
    assert st.R == st.S == len(ctx.mus_train) and st.summary()["S_q"] == 0
    X = ctx.X
    for j, mu in enumerate(ctx.mus_train):
        p = ctx.problem_at(mu)
        res = st.reduced.solve_arrays(mu, project_wedge(p, st.Z_off, st.wedge),
                                      x0=np.zeros(st.wedge.R))
        assert res.stop_reason == "converged"
        du = st.Z_off @ res.a - ctx.train.U[:, j]
        assert np.sqrt(du @ (X @ du) / (ctx.train.U[:, j] @ (X @ ctx.train.U[:, j]))) < 1e-8
        for L, lam in ((st.wedge.Ln, ctx.train.LAM), (st.wedge.Lt, ctx.train.LAM_T)):
            d = L @ res.c - lam[:, j]
            assert np.sqrt(d @ (p.W @ d) / (lam[:, j] @ (p.W @ lam[:, j]))) < 1e-7
        law = st.metrics(mu, p, ctx.train.U[:, j], ctx.train.LAM[:, j], res,
                         st.reduced.reconstruct(res))
        assert law["friction_law_residual"] < 1e-6 and law["slip_law_residual"] < 1e-6


def test_friction_rows_report_the_law_residual_of_the_reconstruction():
    """Validation rows carry the friction law residual at every HF node (the wedge cone holds
    by construction, the law need not): finite, non-negative, and the slipping-node part never
    above the whole (both are maxima over HF nodes of the same off-bound distance)."""
    for d in ("collocation", "wedge"):
        s = validate(_offline(dual=d).context, _offline(dual=d).stage).summary()
        for key in ("friction_law_residual", "slip_law_residual"):
            assert len(s["per_mu"][key]) == s["n_valid"]
            assert 0.0 <= s[f"{key}_max"] < np.inf
        assert s["slip_law_residual_max"] <= max(s["friction_law_residual_max"], 1.0)


def test_wedge_model_against_the_collocation_model_on_validation():
    """Same (N, R + S) on the coarse mesh: the wedge model's raw reduced multipliers are in
    the Coulomb cone at EVERY HF node (the collocation model's are not off its collocation
    nodes), and its lam_t error is far below the collocation model's (measured 0.19 against
    3.6), above its floor."""
    res = {d: validate(_offline(dual=d).context, _offline(dual=d).stage).summary()
           for d in ("collocation", "wedge")}
    w, s = res["wedge"], res["collocation"]
    assert w["online_stops"] == {"converged": 3} and w["S_q"] == 0
    assert w["friction_residual_max"] <= 1e-12 < s["friction_residual_max"]
    assert w["lam_t_best_max"] <= w["err_lam_t_max"] + 1e-12
    assert w["lam_t_best_max"] <= w["lam_t_best_cone_max"] + 1e-12
    assert w["err_lam_t_max"] < 0.1 * s["err_lam_t_max"]
    assert w["err_u_max"] < s["err_u_max"]

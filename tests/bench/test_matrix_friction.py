"""Run matrices of the reduced friction models: the ``friction_dual`` axis (both models with
and without hyper-reduction), the combinations refused as skip rows, the friction columns of
a row and the case details, and (slow) ``problems/matrices/friction_rb.toml`` on a coarse P1 mesh
through the runner and the report."""

from __future__ import annotations

import json
import math
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from rbbench.bench import schema
from rbbench.bench.execution import decided_row, execute_case
from rbbench.bench.matrix import MatrixError, load_matrix, reduced_model_check
from rbbench.registry import default_registry
from rbbench.scene.loading import PROBLEMS_DIR, load_scene, tomllib

#: the friction columns of a reduce row (schema names; S_tau is result.json's S)
FRICTION_COLUMNS = ("err_lam_t_max", "err_lam_t_mean", "lam_t_best_max",
                    "friction_residual_max", "S_tau", "S_q", "gcns_iterations",
                    "online_iterations_max", "dim_v_off", "delta_pga")
COARSE = ["discretization.degree=1", "discretization.h_contact=0.02",
          "discretization.h_max=0.25"]


def _smoke_matrix(tmp_path: Path, n_train: int = 5, n_valid: int = 2) -> Path:
    """friction_rb.toml (the coarse P1 mesh) with small sizes (its own tables otherwise)."""
    text = (PROBLEMS_DIR / "matrices" / "friction_rb.toml").read_text()
    data = tomllib.loads(text)
    assert data["sizes"]["pairs"] == [[30, 20]] and data["reduce"]["S"] == 20
    assert data["scene_overrides"]["hertz_friction"] == COARSE
    text = (text.replace('name = "friction_rb"', 'name = "friction_rb_smoke"')
            .replace("pairs = [[30, 20]]", "pairs = [[10, 5]]")
            .replace("S = 20", "S = 5").replace("n_train = 41", f"n_train = {n_train}")
            .replace("n_valid = 20", f"n_valid = {n_valid}")
            .replace("k_pga_max = 40", "k_pga_max = 10\nonline_repeats = 1"))
    p = tmp_path / "friction_smoke.toml"
    p.write_text(text)
    return p


def _key(case) -> tuple:
    return (case.params.get("friction_dual"), case.components["hyper"],
            case.params.get("gcns_patience"))


# --------------------------------------------------------------------------- the matrix
def test_friction_rb_matrix_expands_both_models_with_and_without_eim():
    """friction_rb.toml: collocation (patience 1, 10) and wedge, hyper none and eim, every
    case runs (both models are hyper-reduced by the friction EIM)."""
    m = load_matrix("friction_rb", registry=default_registry())
    by = {_key(c): c for c in m.cases}
    assert set(by) == {("collocation", "none", 1), ("collocation", "none", 10),
                       ("wedge", "none", None), ("collocation", "eim", 1),
                       ("collocation", "eim", 10), ("wedge", "eim", None)}
    for k, c in by.items():
        assert c.status == "run", (k, c.reason)
        assert c.components["solver"] == "friction-ssn" and (c.N, c.R) == (30, 20)
        assert c.params["S"] == 20 and c.params["k_pga_max"] == 40
    assert len({c.case_id for c in m.cases}) == 6
    assert by[("wedge", "eim", None)].reduce_config("/tmp").options["friction_dual"] == "wedge"
    # the P2 variant: the same cases on the scene's own (P2) mesh, no scene override
    p2 = load_matrix("friction_rb_p2", registry=default_registry())
    assert {_key(c) for c in p2.cases} == set(by)
    assert all(c.status == "run" and not c.overrides for c in p2.cases)
    assert all(tuple(c.overrides) == tuple(COARSE) for c in m.cases)


def test_friction_dual_axis_is_the_reduce_field(tmp_path):
    """[components] friction_dual = ["wedge"] is the same case as [reduce] friction_dual =
    "wedge" (same case id); both at once, a bad value, a grid of a value not swept: errors
    naming the field; the selector keeps one value."""
    head = '[matrix]\nscenes = ["hertz_friction"]\n[components]\nsolver = ["friction-ssn"]\n'
    axis, field = tmp_path / "axis.toml", tmp_path / "field.toml"
    axis.write_text(head + 'friction_dual = ["wedge"]\n')
    field.write_text(head + '[reduce]\nfriction_dual = "wedge"\n')
    reg = default_registry()
    a, f = load_matrix(axis, registry=reg).cases, load_matrix(field, registry=reg).cases
    assert [c.case_id for c in a] == [c.case_id for c in f]
    both = tmp_path / "both.toml"
    both.write_text(head + 'friction_dual = ["wedge"]\n[reduce]\nfriction_dual = "collocation"\n')
    with pytest.raises(MatrixError, match="friction_dual is swept in \\[components\\]"):
        load_matrix(both, registry=reg)
    with pytest.raises(MatrixError, match="friction_dual is swept"):
        load_matrix(axis, sets=["friction_dual=collocation"], registry=reg)
    bad = tmp_path / "bad.toml"
    bad.write_text(head + 'friction_dual = ["box"]\n')
    with pytest.raises(MatrixError,
                       match="friction_dual = 'box'; valid: auto, collocation, wedge, seed"):
        load_matrix(bad, registry=reg)
    grid = tmp_path / "grid.toml"
    grid.write_text(head + "[params.friction_dual.collocation]\ngcns_patience = [1, 2]\n")
    with pytest.raises(MatrixError,
                       match="'collocation' is not in \\[components\\] friction_dual"):
        load_matrix(grid, registry=reg)
    m = load_matrix("friction_rb", selectors=["friction_dual=wedge"], registry=reg)
    assert {c.params["friction_dual"] for c in m.cases} == {"wedge"} and len(m.cases) == 2


def test_reduced_model_check_only_on_friction_scenes():
    """A frictionless scene is not checked here (its cases record their own failures); the
    friction scene's refusals come from the model (stabilizer, hyper); both dual models take
    hyper 'eim'."""
    reg = default_registry()
    comp = {"backend": "skfem", "formulation": "mixed", "solver": "friction-ssn",
            "primal": "pod", "dual": "mcpg", "stabilizer": "pga", "hyper": "eim"}
    assert reduced_model_check(load_scene("hertz_halfdisks"), comp, {}, reg) == ("run", "")
    fr = load_scene("hertz_friction")
    assert reduced_model_check(fr, comp, {"friction_dual": "wedge"}, reg) == ("run", "")
    assert reduced_model_check(fr, comp, {}, reg) == ("run", "")  # default: auto, wedge
    assert reduced_model_check(fr, comp, {"friction_dual": "collocation"}, reg) == ("run", "")
    status, reason = reduced_model_check(fr, {**comp, "hyper": "deim"},
                                         {"friction_dual": "collocation"}, reg)
    assert status == "skip" and "'deim'" in reason
    status, reason = reduced_model_check(fr, {**comp, "stabilizer": "supremizer",
                                              "hyper": "none"}, {}, reg)
    assert status == "skip" and "supremizer" in reason
    assert reduced_model_check(fr, comp, {}, None) == ("run", "")


# ------------------------------------------------------------------------------ the rows
def _summary(dual: str) -> dict:
    """A reduction summary in the layout of a friction ``result.json`` (values arbitrary
    but distinct, so that a column copied from the wrong key is seen)."""
    hist = [{"q": 0, "S_q": 0, "e_nt": 5.0, "e_nt_rel": 2.0, "e_gcns": 3.0, "mu_index": 1},
            {"q": 1, "S_q": 2, "e_nt": 1.0, "e_nt_rel": 0.4, "e_gcns": 0.9, "mu_index": 0}]
    prof = {"mu": [[0.7]], "x": [[-0.1, 0.0, 0.1]], "lam_t_hf": [[1.0, 0.0, -1.0]],
            "lam_t_rb": [[0.9, 0.0, -1.1]], "bound_hf": [[2.0, 3.0, 2.0]],
            "lam_n_hf": [[10.0, 15.0, 10.0]], "lam_n_rb": [[9.0, 15.0, 11.0]]}
    return {"n_hf_dofs": 100, "n_contact": 20, "n_train": 5, "n_valid": 2, "N": 10, "R": 5,
            "K_pga": 7, "M_eim": None, "hyper": "none", "err_u_max": 1.5e-3,
            "err_u_mean": 1e-3, "err_lam_max": 0.07, "err_lam_mean": 0.05,
            "lam_best_max": 0.03, "penetration_max": 0.0, "complementarity_max": 1e-9,
            "energy_err_max": 1e-6, "t_offline_s": 3.0, "t_online_median_s": 0.01,
            "t_online_iqr_s": 0.001, "t_hf_median_s": 2.0, "speedup": 200.0,
            "timings": {"snapshots_s": 1.0}, "online_stops": {"converged": 2},
            "config": {"stabilizer": "pga", "friction_dual": dual},
            "err_lam_t_max": 0.19, "err_lam_t_mean": 0.08, "lam_t_best_max": 0.09,
            "friction_residual_max": 6e-17, "online_iterations_max": 6.0, "S": 4,
            "S_q": 2 if dual == "collocation" else 0,
            "gcns_iterations": 1 if dual == "collocation" else 0,
            "gcns_history": hist if dual == "collocation" else [], "dim_v_off": 17,
            "delta_pga": 0.072, "lam_t_profiles": prof, "histories": {},
            "per_mu": {"err_u": [1e-3, 1.5e-3], "beta": {
                "dec": [{"value": 2e-6, "value_rel": 0.03}, {"value": 1e-6, "value_rel": 0.05}],
                "off": [{"value": 1e-6, "value_rel": float("nan")},
                        {"value": 2e-6, "value_rel": 0.02}]}}}


def _fake_reduce(summary: dict):
    def reduce(scene, config, progress=None, registry=None):
        return SimpleNamespace(summary=lambda: summary, valid_mus=np.array([[0.8], [1.1]]))
    return reduce


@pytest.mark.parametrize("dual", ["collocation", "wedge"])
def test_friction_row_columns_and_details(monkeypatch, tmp_path, dual):
    """A friction reduction's summary goes into its row column by column (S_tau = S; the
    row's S stays the stabiliser size K), and its details keep gcns_history and
    lam_t_profiles."""
    import rbbench.rb.offline as offline

    s = _summary(dual)
    monkeypatch.setattr(offline, "reduce", _fake_reduce(s))
    m = load_matrix("friction_rb", selectors=[f"friction_dual={dual}", "hyper=none"],
                    registry=default_registry())
    rec = execute_case(m.cases[0], "r", str(tmp_path))
    row, det = rec["row"], rec["details"]
    assert row["status"] == "ok", row["reason"]
    for col in FRICTION_COLUMNS:
        assert row[col] == s["S" if col == "S_tau" else col], col
    assert row["S"] == 7 and row["friction_dual"] == dual
    # beta / c_HF: min over the finite per-mu values (not at the raw minimum's mu)
    assert (row["beta_dec_rel_min"], row["beta_off_rel_min"], row["beta_hf_rel_min"]) == \
        (0.03, 0.02, None)
    assert det["gcns_history"] == s["gcns_history"]
    assert det["lam_t_profiles"] == s["lam_t_profiles"]
    assert set(row) == set(schema.names())


def test_frictionless_row_leaves_friction_columns_empty(monkeypatch, tmp_path):
    import rbbench.rb.offline as offline

    s = {k: v for k, v in _summary("collocation").items()
         if k not in (*FRICTION_COLUMNS, "S", "gcns_history", "lam_t_profiles")}
    monkeypatch.setattr(offline, "reduce", _fake_reduce(s))
    case = load_matrix("hertz_rb", registry=default_registry()).cases[0]
    rec = execute_case(case, "r", str(tmp_path))
    assert rec["row"]["status"] == "ok"
    for col in (*FRICTION_COLUMNS, "friction_dual", "beta_dec_rel_min", "beta_off_rel_min"):
        assert rec["row"][col] is None, col
    assert "gcns_history" not in rec["details"] and "lam_t_profiles" not in rec["details"]


def test_skip_row_names_the_pair(tmp_path):
    """A refused friction case (an online stabiliser with hyper 'eim') is a skip row that
    keeps its friction_dual and hyper, with the reason and no friction numbers."""
    text = (PROBLEMS_DIR / "matrices" / "friction_rb.toml").read_text()
    p = tmp_path / "online_stab.toml"
    p.write_text(text.replace('stabilizer = ["pga"]', 'stabilizer = ["supremizer"]'))
    m = load_matrix(p, selectors=["friction_dual=collocation", "hyper=eim"],
                    registry=default_registry())
    row = decided_row(m.cases[0], "r", "serial")["row"]
    assert row["status"] == "skip" and row["friction_dual"] == "collocation"
    assert row["hyper"] == "eim" and "eim" in row["reason"]
    assert all(row[c] is None for c in FRICTION_COLUMNS)


# ------------------------------------------------------------- the runner, coarse P1 (slow)
@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_friction_rb_smoke_run_and_report(tmp_path):
    """friction_rb.toml on the coarse P1 mesh (5 training / 2 validation mu, N = 10,
    R = S = 5, K <= 10) through the runner (serial) and the report: every friction column
    finite on every row (all six run), the raw properties of each model, the figures.
    About 5 minutes on a loaded 2-core machine (the HF snapshots dominate)."""
    from rbbench.bench.report import report
    from rbbench.bench.runner import load_rows, run_matrix

    reg = default_registry()
    m = load_matrix(_smoke_matrix(tmp_path), registry=reg)
    run_matrix(m, tmp_path / "out", executor="serial", jobs=1, registry=reg,
               cache_dir=tmp_path / "cache", progress=False)
    recs = load_rows(tmp_path / "out")
    rows = {(r["row"]["friction_dual"], r["row"]["hyper"],
             json.loads(r["row"]["params"]).get("gcns_patience")): r for r in recs.values()}
    ok = {k: r for k, r in rows.items() if r["row"]["status"] == "ok"}
    assert set(ok) == {(d, h, p) for d, p in (("collocation", 1), ("collocation", 10),
                                              ("wedge", None)) for h in ("none", "eim")}, \
        {k: r["row"]["reason"] for k, r in rows.items()}
    for k, r in ok.items():
        row = r["row"]
        assert all(row[c] is not None and math.isfinite(row[c]) for c in FRICTION_COLUMNS), k
        assert row["S_tau"] == 5 and row["dim_v_off"] == row["N"] + row["S"]
        assert all(math.isfinite(row[f"beta_{b}_rel_min"]) for b in ("dec", "off")), k
        # the reduced lam_t lies in the tangential space: its error is at least the floor
        assert row["err_lam_t_max"] >= row["lam_t_best_max"] * (1 - 1e-12)
        assert len(r["details"]["lam_t_profiles"]["mu"]) == 3
        if k[0] == "wedge":  # the Coulomb cone at every HF node by construction (raw values)
            assert row["friction_residual_max"] <= 1e-10 and row["S_q"] == 0
        else:
            kept = [e for e in r["details"]["gcns_history"] if e["q"] == row["gcns_iterations"]]
            assert len(kept) == 1 and row["S_q"] == kept[0]["S_q"] > 0
    for k in (("wedge", "eim", None), ("collocation", "eim", 1), ("collocation", "eim", 10)):
        assert ok[k]["row"]["hyper_used"] == "eim", k
    out = report(tmp_path / "out", formats=("png",))
    assert "gcns" in out.figures and len([n for n in out.figures if n.startswith("lam_t_")]) == 6
    md = out.summary_md.read_text()
    assert "## Reduced friction models" in md and "collocation+eim" in md

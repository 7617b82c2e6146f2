"""The linear scenes in run matrices, rows and the report, and the side-by-side
study with pyMOR (optional: its column is ``not_installed`` without it)."""

from __future__ import annotations

import importlib.util
import sys

import numpy as np
import pandas as pd
import pytest

from rbbench.bench.matrix import load_matrix
from rbbench.bench.runner import run_matrix
from rbbench.registry import default_registry

pytestmark = pytest.mark.timeout(300)
HAS_PYMOR = importlib.util.find_spec("pymor") is not None

_MATRIX = """
[matrix]
name = "lin"
scenes = ["thermal_block", "heat_robin", "membrane_obstacle"]
timeout_s = 120
[components]
formulation = ["mixed", "linear"]
dual = ["cpg", "mcpg"]
stabilizer = ["none"]
[sizes]
N = [3]
R = [3]
[reduce]
n_train = 5
n_valid = 3
online_repeats = 2
[scene_overrides]
thermal_block = ["discretization.n_cells=8"]
heat_robin = ["discretization.n_cells=8", "time.steps=5"]
membrane_obstacle = ["discretization.n_cells=8"]
"""


@pytest.fixture(scope="module")
def matrix_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("m") / "lin.toml"
    path.write_text(_MATRIX)
    return path


def test_shipped_linear_matrix_expands_without_contact_roles():
    m = load_matrix("linear", registry=default_registry())
    assert {c.scene for c in m.cases} == {"thermal_block", "heat_robin"}
    ngsolve = importlib.util.find_spec("ngsolve") is not None
    for c in m.cases:  # without the ngsolve extra its cases are not_installed rows
        assert c.status == ("run" if ngsolve or c.components["backend"] != "ngsolve"
                            else "not_installed")
        assert (c.components["solver"], c.components["dual"],
                c.components["stabilizer"]) == ("", "", "")


def test_mixed_matrix_prunes_across_physics(matrix_file):
    m = load_matrix(matrix_file, registry=default_registry())
    by = {}
    for c in m.cases:
        by.setdefault((c.scene, c.components["formulation"]), []).append(c)
    # the linear formulation ignores the dual axis: one case per scene, not two
    assert len(by[("thermal_block", "linear")]) == 1
    assert len(by[("membrane_obstacle", "mixed")]) == 2
    assert all(c.status == "skip" and "does not support" in c.reason
               for c in by[("thermal_block", "mixed")] + by[("membrane_obstacle", "linear")])


def test_runner_rows_and_report_of_linear_scenes(matrix_file, tmp_path):
    import rbbench
    from rbbench.bench.report import report

    m = load_matrix(matrix_file, selectors=["formulation=linear", "scene=thermal_block,heat*"],
                    registry=default_registry())
    out = tmp_path / "run"
    s = run_matrix(m, out, executor="serial", cache_dir=tmp_path / "cache", progress=False)
    assert s.counts.get("ok") == 2
    df = rbbench.load_results(out)
    for _, row in df.iterrows():
        assert row["status"] == "ok" and "no contact" in row["reason"]
        for col in ("n_contact", "R", "S", "err_lam_max", "penetration_max", "beta_dec_min",
                    "contact_force"):
            assert pd.isna(row[col]), col  # missing (NaN / <NA>), never 0
        assert row["err_u_max"] < 1 and row["effectivity_min"] >= 1
        assert row["hyper_used"] == "affine" and row["N"] == 3
    written = report(out, formats=("png",))
    assert written.out_dir == out / "report"
    text = (out / "report" / "summary.md").read_text()
    assert "Not applicable to heat_robin, thermal_block: no ok row has a value of err_lam_max" \
        in text


def test_hf_mode_row_of_a_linear_scene(tmp_path):
    from rbbench.bench.execution import execute_case
    from rbbench.bench.matrix import Case

    comp = {"backend": "skfem", "formulation": "linear", "solver": "", "primal": "",
            "dual": "", "stabilizer": "", "hyper": ""}
    case = Case("heat_robin", ("discretization.n_cells=8", "time.steps=4"), comp, None, None,
                {"hf_repeats": 2}, 0, 0, 60.0, mode="hf")
    row = execute_case(case, "r", str(tmp_path))["row"]
    assert row["status"] == "ok" and row["n_hf_dofs"] == 81
    assert row["contact_force"] is None and "no contact" in row["reason"]


def test_pymor_study_reports_not_installed(monkeypatch):
    from rbbench.studies import pymor_thermal_block as st

    monkeypatch.setitem(sys.modules, "pymor", None)  # import pymor raises ImportError
    col = st.pymor_column(8, 2, 3, np.full((2, 4), 0.5), np.full((1, 4), 0.5), 1)
    assert col == {"status": "not_installed", "reason": st.INSTALL_HINT}
    res = {"setup": {"n_cells": 8, "blocks": 2, "N": 3, "n_train": 2, "n_valid": 1,
                     "repeats": 1, "backend": "skfem"},
           "rbbench": {"status": "ok", "n_hf_dofs": 81, "N": 3, "t_offline_s": 1.0,
                       "t_online_median_s": 1e-5, "err_u_max": 0.1, "effectivity_min": 1.5,
                       "effectivity_max": 2.0, "t_hf_median_s": 0.01},
           "pymor": col, "ratio_rbbench_over_pymor": {}}
    text = st.side_by_side_markdown(res)
    assert "not_installed" in text and "pip install pymor" in text


@pytest.mark.skipif(not HAS_PYMOR, reason="pyMOR not installed (pip install pymor)")
def test_pymor_study_small_run_agrees():
    """Coarse mesh, both tools on the same sets: the same POD space up to the mesh, so the
    errors are close and both bounds are rigorous."""
    from rbbench.studies.pymor_thermal_block import side_by_side

    res = side_by_side(n_cells=16, N=5, n_train=20, n_valid=5, repeats=3,
                       progress=lambda m: None)
    ours, theirs = res["rbbench"], res["pymor"]
    assert theirs["status"] == "ok" and theirs["N"] == ours["N"] == 5
    assert 0.5 < res["ratio_rbbench_over_pymor"]["err_u_max"] < 2.0
    assert ours["effectivity_min"] >= 1 and theirs["effectivity_min"] >= 1


@pytest.mark.slow
@pytest.mark.skipif(not HAS_PYMOR, reason="pyMOR not installed (pip install pymor)")
def test_done_when_thermal_block_n10_side_by_side():
    """At N = 10 (64 x 64, 100 training, 20 validation) rbbench's max error is
    within 2x of pyMOR's and its online median not slower."""
    from rbbench.studies.pymor_thermal_block import side_by_side

    r = side_by_side(progress=lambda m: None)["ratio_rbbench_over_pymor"]
    assert r["err_u_max"] <= 2.0 and r["t_online_median_s"] <= 1.0


@pytest.mark.slow
def test_done_when_heat_n25_below_one_percent(tmp_path):
    from rbbench.rb.config import make_config
    from rbbench.rb.linear.offline import reduce_linear
    from rbbench.scene.loading import load_scene

    cfg = make_config(formulation="linear", primal="pod", dual="", stabilizer="", N=25,
                       cache_dir=str(tmp_path), online_repeats=5)
    s = reduce_linear(load_scene("heat_robin"), cfg).summary()
    assert s["N"] == 25 and s["err_u_max"] < 1e-2 and s["effectivity_min"] >= 1


def test_study_subcommands_parse_and_print(capsys, monkeypatch):
    import argparse

    from rbbench.cli import studies

    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="study")
    studies._add_pymor_thermal_block_parser(sub)
    studies._add_heat_robin_parser(sub)
    monkeypatch.setitem(sys.modules, "pymor", None)  # the not_installed row, quickly
    args = ap.parse_args(["pymor-thermal-block", "--n-cells", "8", "-N", "3", "--n-train",
                          "8", "--n-valid", "2", "--repeats", "1"])
    assert studies.cmd_pymor_thermal_block(args) == 0
    out = capsys.readouterr().out
    assert "| max relative error, H1_0 seminorm |" in out and "pip install pymor" in out
    args = ap.parse_args(["heat-robin", "--n-cells", "8", "-N", "3", "--repeats", "1"])
    assert studies.cmd_heat_robin(args) == 0
    out = capsys.readouterr().out
    assert "| N | 25 | 3 |" in out and "| HF nodes | 51,500 | 81 |" in out

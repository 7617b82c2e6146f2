"""Run matrices: parsing errors, pruning, failing plugins as rows, resume, executors."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import rbbench.testing.faulty as faulty
from rbbench.bench import schema
from rbbench.bench.matrix import MatrixError, load_matrix
from rbbench.bench.runner import load_rows, run_matrix
from rbbench.registry import default_registry, discover

pytestmark = pytest.mark.timeout(300)

TINY = """
[matrix]
name = "tiny"
scenes = ["membrane_obstacle"]
timeout_s = {timeout}

[components]
dual = {duals}
stabilizer = {stabs}
hyper = {hyper}

[sizes]
pairs = [[3, 3], [4, 4]]

[reduce]
n_train = 5
n_valid = 3
online_repeats = 2
exact_max_r = 4

[scene_overrides]
membrane_obstacle = ["discretization.n_cells=6"]
"""


def _matrix(tmp_path: Path, duals=("cpg",), stabs=("none",), hyper=("auto",), timeout=120,
            name="m.toml") -> Path:
    p = tmp_path / name
    p.write_text(TINY.format(duals=json.dumps(list(duals)), stabs=json.dumps(list(stabs)),
                             hyper=json.dumps(list(hyper)), timeout=timeout))
    return p


# ------------------------------------------------------------------------ matrix files
@pytest.mark.parametrize("text, match", [
    ("[matrix]\nscenes=['membrane_obstacle']\n[sizes]\nN=[0]\n", r"\[sizes\] N = 0"),
    ("[matrix]\nscenes=['membrane_obstacle']\n[components]\ndual=['nope']\n",
     r"\[components\] dual: unknown dual 'nope'; valid: .*mcpg"),
    ("[matrix]\nscenes=['membrane_obstacle']\n[reduce]\nn_trian=3\n",
     r"unknown field 'n_trian'; valid: .*n_train"),
    ("[matrix]\nscenes=['membrane_obstacle']\n[compnents]\n", r"unknown key\(s\) \['compnents'\]"),
    ("[matrix]\nscenes=['membrane_obstacle']\n[params.dual.eng]\ntol_dual=[1e-3]\n",
     r"\[params.dual.eng\]: 'eng' is not in \[components\] dual"),
    ("[matrix]\nscenes=['no_scene']\n", r"\[matrix\] scenes: 'no_scene'"),
    ("[matrix\n", r"not valid TOML"),
])
def test_bad_matrix_names_file_and_field(tmp_path, text, match):
    p = tmp_path / "bad.toml"
    p.write_text(text)
    with pytest.raises(MatrixError, match=match) as exc:
        load_matrix(p, registry=default_registry())
    assert str(p) in str(exc.value)


def test_selectors_globs_and_sets(tmp_path):
    p = _matrix(tmp_path, duals=("cpg", "mcpg", "eng"), stabs=("none", "pga"))
    m = load_matrix(p, registry=default_registry())
    assert len(m.cases) == 3 * 2 * 2
    m = load_matrix(p, selectors=["dual=*cpg", "N=3"], sets=["n_valid=2"],
                    registry=default_registry())
    assert {c.components["dual"] for c in m.cases} == {"cpg", "mcpg"}
    assert {c.N for c in m.cases} == {3} and len(m.cases) == 4
    assert all(c.params["n_valid"] == 2 for c in m.cases)
    # the case id depends on what determines the numbers, not on the selection
    ids = {c.key for c in load_matrix(p, registry=default_registry()).cases}
    assert {c.key for c in m.cases} & ids == set()  # n_valid changed: different cases
    with pytest.raises(MatrixError, match="unknown role 'duel'"):
        load_matrix(p, selectors=["duel=cpg"], registry=default_registry())


def test_incompatible_combinations_are_pruned_without_import(tmp_path):
    p = _matrix(tmp_path, stabs=("supremizer",), hyper=("eim", "auto"))
    m = load_matrix(p, registry=default_registry())
    skipped = [c for c in m.cases if c.status == "skip"]
    assert len(skipped) == 2 and all(c.components["hyper"] == "eim" for c in skipped)
    assert "needs the HF B(mu) online" in skipped[0].reason


# ----------------------------------------------------------------- failing plugins as rows
@pytest.fixture(scope="module")
def faulty_registry():
    return discover(extra_plugins=(faulty,))


def test_failing_plugins_yield_rows_and_the_run_goes_on(tmp_path, faulty_registry):
    p = _matrix(tmp_path, duals=("cpg", "faulty-raise", "faulty-nan", "faulty-sleep",
                                 "faulty-missing"), timeout=20)
    m = load_matrix(p, selectors=["N=3"], registry=faulty_registry)
    assert [c.status for c in m.cases if c.components["dual"] == "faulty-missing"] == [
        "not_installed"]
    s = run_matrix(m, tmp_path / "run", jobs=2, registry=faulty_registry,
                   cache_dir=tmp_path / "cache", progress=False)
    df = pd.read_parquet(tmp_path / "run" / "results.parquet")
    assert len(df) == 5 and list(df.columns) == schema.names()
    status = dict(zip(df["dual"], df["status"], strict=True))
    assert status == {"cpg": "ok", "faulty-raise": "error", "faulty-nan": "diverged",
                      "faulty-sleep": "timeout", "faulty-missing": "not_installed"}
    row = df.set_index("dual")
    assert "injected failure" in row.loc["faulty-raise", "reason"]
    assert "RuntimeError" in row.loc["faulty-raise", "traceback"]
    assert "pip install" in row.loc["faulty-missing", "reason"]
    assert "20 s" in row.loc["faulty-sleep", "reason"]
    assert row.loc["cpg", "err_u_max"] < 1.0
    assert s.counts == {"ok": 1, "error": 1, "diverged": 1, "timeout": 1, "not_installed": 1}
    man = json.loads((tmp_path / "run" / "manifest.json").read_text())
    assert man["state"] == "finished" and man["columns"]["err_u_max"]["unit"] == "1"


def test_serial_executor_times_out_in_process(tmp_path, faulty_registry):
    p = _matrix(tmp_path, duals=("faulty-sleep",), timeout=3)
    m = load_matrix(p, selectors=["N=3"], registry=faulty_registry)
    t0 = time.perf_counter()
    run_matrix(m, tmp_path / "run", executor="serial", registry=faulty_registry,
               cache_dir=tmp_path / "cache", progress=False)
    assert time.perf_counter() - t0 < 60
    rows = load_rows(tmp_path / "run")
    assert [r["row"]["status"] for r in rows.values()] == ["timeout"]


# ------------------------------------------------------------------------------ resume
def test_killed_run_resumes_without_recomputing(tmp_path):
    p = _matrix(tmp_path, duals=("cpg", "mcpg"), stabs=("none", "pga"))
    out = tmp_path / "run"
    cmd = [sys.executable, "-m", "rbbench.cli", "run", str(p), "--out", str(out), "--jobs", "1",
           "--cache-dir", str(tmp_path / "cache"), "--quiet"]
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            start_new_session=True)
    deadline = time.time() + 200
    while time.time() < deadline and len(list((out / "cases").glob("*.json"))) < 2:
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)  # the whole session: no clean-up at all
    proc.wait()
    before = {f.name: f.read_text() for f in (out / "cases").glob("*.json")}
    assert 2 <= len(before) < 8, "kill the run half-way"
    res = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=250)
    assert res.returncode == 0, res.stderr
    after = {f.name: f.read_text() for f in (out / "cases").glob("*.json")}
    assert len(after) == 8
    assert all(after[k] == v for k, v in before.items())  # finished cases untouched
    assert f"{8 - len(before)} computed, {len(before)} kept" in res.stdout
    df = pd.read_parquet(out / "results.parquet")
    assert len(df) == 8 and set(df["status"]) == {"ok"}


# ---------------------------------------------------------------------------- executors
def test_dask_executor_gives_the_same_rows(tmp_path):
    pytest.importorskip("distributed", reason='dask not installed: pip install "rbbench[dask]"')
    p = _matrix(tmp_path, duals=("cpg", "mcpg"), stabs=("none", "pga"))
    m = load_matrix(p, selectors=["N=3"], registry=default_registry())
    cache = tmp_path / "cache"
    run_matrix(m, tmp_path / "proc", jobs=2, cache_dir=cache, progress=False)
    run_matrix(m, tmp_path / "dask", executor="dask", jobs=2, cache_dir=cache, progress=False)
    a = pd.read_parquet(tmp_path / "proc" / "results.parquet").set_index("case_id")
    b = pd.read_parquet(tmp_path / "dask" / "results.parquet").set_index("case_id")
    assert set(a.index) == set(b.index) and len(a) == 4
    assert (b["executor"] == "dask").all() and (a["status"] == b.loc[a.index, "status"]).all()
    for col in ("N", "R", "S", "err_u_max", "err_lam_max", "beta_dec_min", "penetration_max"):
        np.testing.assert_allclose(a[col].astype(float), b.loc[a.index, col].astype(float),
                                   rtol=1e-10, err_msg=col)


def test_hf_mode_matrix_times_backends_and_solvers(tmp_path):
    p = tmp_path / "hf.toml"
    p.write_text("""
[matrix]
name = "hf"
mode = "hf"
scenes = ["membrane_obstacle@a", "membrane_obstacle@b"]
[components]
solver = ["ssn", "uzawa"]
[hf]
repeats = 2
[scene_overrides]
"membrane_obstacle@a" = ["discretization.n_cells=6"]
"membrane_obstacle@b" = ["discretization.n_cells=12"]
""")
    m = load_matrix(p, registry=default_registry())
    assert len(m.cases) == 4 and {c.mode for c in m.cases} == {"hf"}
    run_matrix(m, tmp_path / "run", jobs=2, cache_dir=tmp_path / "cache", progress=False)
    df = pd.read_parquet(tmp_path / "run" / "results.parquet")
    assert set(df["status"]) == {"ok"} and df["dual"].isna().all()
    # a 2D row: the half-width, no 3D radius, no Hertz check on this scene
    assert (df["dim"] == 2).all() and (df["contact_half_width"] > 0).all()
    assert df["contact_radius"].isna().all() and df["hertz_a_rel_error"].isna().all()
    dofs = df.groupby("scene")["n_hf_dofs"].first()
    assert dofs["membrane_obstacle@b"] > dofs["membrane_obstacle@a"]
    # both solvers solve the same problem: same force on each mesh (Uzawa to its tolerance)
    for _, g in df.groupby("scene"):
        f = g.set_index("solver")["contact_force"]
        assert f["uzawa"] == pytest.approx(f["ssn"], rel=1e-6)
    # the floor (one factorisation + one solve of A) is timed once per case, beside the solve
    assert (df["floor_s"] > 0).all() and np.isfinite(df["solve_over_floor"]).all()
    with pytest.raises(MatrixError, match=r"\[sizes\] does not apply to mode 'hf'"):
        p.write_text(p.read_text() + "\n[sizes]\nN = [3]\n")
        load_matrix(p, registry=default_registry())


def test_component_options_are_matrix_parameters(tmp_path):
    """Backend / formulation constructor options: a parameter grid, part of the case id and
    of the HF snapshot cache key (empty options keep the old keys)."""
    from rbbench.hf.snapshots.key import snapshot_key
    from rbbench.scene.loading import load_scene

    p = tmp_path / "opt.toml"
    p.write_text(TINY.format(duals='["cpg"]', stabs='["none"]', hyper='["auto"]', timeout=120)
                 + '\n[params.backend.skfem]\nbackend_options = [{}, {bogus = 1}]\n')
    m = load_matrix(p, selectors=["N=3"], registry=default_registry())
    assert len(m.cases) == 2 and len({c.key for c in m.cases}) == 2
    run_matrix(m, tmp_path / "run", jobs=2, cache_dir=tmp_path / "cache", progress=False)
    df = pd.read_parquet(tmp_path / "run" / "results.parquet").set_index("params")
    ok = df.loc[[i for i in df.index if "bogus" not in i]]
    bad = df.loc[[i for i in df.index if "bogus" in i]]
    assert list(ok["status"]) == ["ok"]
    # refused before any HF work (the backend declares its options): a skip row naming it
    assert list(bad["status"]) == ["skip"] and "bogus" in bad["reason"].iloc[0]
    sc = load_scene("membrane_obstacle")
    k0 = snapshot_key(sc, "skfem", "mixed", "ssn")
    assert snapshot_key(sc, "skfem", "mixed", "ssn", None, {"backend": {}}) == k0
    assert snapshot_key(sc, "skfem", "mixed", "ssn", None, {"backend": {"a": 1}}) != k0


def test_a_hung_hf_solver_cannot_stall_the_run(tmp_path, faulty_registry):
    """The shared snapshot preparation is killed at the time limit; the case then gets its
    own timeout row, and the other solver's case runs."""
    p = tmp_path / "hang.toml"
    p.write_text(TINY.format(duals='["cpg"]', stabs='["none"]', hyper='["auto"]', timeout=6))
    p.write_text(p.read_text().replace(
        "[components]\n", '[components]\nsolver = ["ssn", "faulty-hang"]\n'))
    m = load_matrix(p, selectors=["N=3"], registry=faulty_registry)
    t0 = time.perf_counter()
    run_matrix(m, tmp_path / "run", jobs=2, registry=faulty_registry,
               cache_dir=tmp_path / "cache", progress=False)
    assert time.perf_counter() - t0 < 60
    df = pd.read_parquet(tmp_path / "run" / "results.parquet").set_index("solver")
    assert df.loc["faulty-hang", "status"] == "timeout"
    assert df.loc["ssn", "status"] == "ok"


def test_frictionless_rows_carry_beta_over_c_hf(tmp_path):
    """Every stability column of a frictionless reduction row is filled: beta / c_HF(mu) of
    the HF, decoupled, online and offline pairs, equal to what ``reduce`` reports for the
    same case (they were empty outside friction scenes)."""
    import math

    import rbbench

    run = rbbench.run("quick", out=str(tmp_path / "r"), executor="serial",
                      sets=["n_train=7", "n_valid=2"],
                      select=["scene=membrane_obstacle", "dual=cpg", "stabilizer=pga", "N=6"])
    row = rbbench.load_results(run.out_dir).iloc[0]
    assert row["status"] == "ok", row["reason"]
    s = rbbench.reduce(rbbench.load_scene("membrane_obstacle"), N=6, R=int(row["R"]),
                       n_train=7, n_valid=2, dual="cpg", stabilizer="pga",
                       cache_dir=str(tmp_path / "cache")).summary()
    for b in ("hf", "dec", "on", "off"):
        value = row[f"beta_{b}_rel_min"]
        assert math.isfinite(value) and value > 0, b
        assert value == pytest.approx(s[f"beta_{b}_rel_min"], rel=1e-9), b


def test_processes_fork_from_the_main_thread_only():
    """A child forked from a thread other than the main one may hang at its exit (with a live
    SciPy SuperLU in the parent): both process launchers (the run matrix's executor and the
    snapshot groups, through one context) switch to forkserver there."""
    import threading

    from rbbench_plugins.executors import ProcessExecutor

    from rbbench.runtime.workers import process_context

    assert ProcessExecutor(1).ctx.get_start_method() == process_context().get_start_method() \
        == "fork"
    seen = []
    th = threading.Thread(target=lambda: seen.extend(
        [ProcessExecutor(1).ctx.get_start_method(), process_context().get_start_method(),
         ProcessExecutor(1, "spawn").ctx.get_start_method()]))
    th.start()
    th.join()
    assert seen == ["forkserver", "forkserver", "spawn"]

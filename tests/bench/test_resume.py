"""Resume that survives damaged case files; one writer per run directory; no orphans.

* a case file of the wrong shape (nested 200,000 levels deep included), or copied under
  another name, is recomputed with a warning naming it, and no row is lost;
* the table is rebuilt from every valid case file (also other selections');
* a second writer on the same run directory gets a clear error;
* SIGKILL of a run during its snapshot preparation leaves no process of the run, and
  the manifest says ``interrupted``.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
import uuid
from pathlib import Path

import pandas as pd
import pytest

from rbbench.bench.guard import RunLock, RunLockedError
from rbbench.bench.matrix import load_matrix
from rbbench.bench.runner import load_rows, run_matrix
from rbbench.registry import default_registry

pytestmark = pytest.mark.timeout(300)

MATRIX = """
[matrix]
name = "rl"
scenes = ["membrane_obstacle"]
timeout_s = 120

[components]
dual = ["cpg", "mcpg"]
stabilizer = ["none"]

[sizes]
pairs = [[3, 3]]

[reduce]
n_train = 5
n_valid = 3
online_repeats = 2
exact_max_r = 4

[scene_overrides]
membrane_obstacle = ["discretization.n_cells=6"]
"""


@pytest.fixture(scope="module")
def finished(tmp_path_factory):
    """A finished run of two cases (computed once for the module)."""
    tmp = tmp_path_factory.mktemp("rl")
    p = tmp / "m.toml"
    p.write_text(MATRIX)
    m = load_matrix(p, registry=default_registry())
    run_matrix(m, tmp / "run", jobs=1, cache_dir=tmp / "cache", progress=False)
    return p, tmp


def _copy_run(src: Path, dst: Path) -> Path:
    dst.mkdir()
    (dst / "cases").mkdir()
    for f in (src / "cases").glob("*.json"):
        (dst / "cases" / f.name).write_text(f.read_text())
    return dst


@pytest.mark.parametrize("content", ["{}", "[]", '{"row": null}', '{"row": {"status": "ok"}}',
                                     '{"row": {"case_id": "x", "repetition": 0, '
                                     '"status": "bogus"}}', "not json", "\xff",
                                     "[" * 200_000 + "]" * 200_000,
                                     '{"row": ' * 500 + "0" + "}" * 500])
def test_damaged_case_files_are_recomputed_with_a_warning(finished, tmp_path, content):
    p, tmp = finished
    out = _copy_run(tmp / "run", tmp_path / "run")
    files = sorted((out / "cases").glob("*.json"))
    good = {f.name: f.read_text() for f in files}
    files[0].write_text(content)
    m = load_matrix(p, registry=default_registry())
    with pytest.warns(RuntimeWarning, match=files[0].name):
        s = run_matrix(m, out, jobs=1, cache_dir=tmp / "cache", progress=False)
    assert s.computed == [files[0].stem] and s.kept == [files[1].stem]
    df = pd.read_parquet(out / "results.parquet")
    assert len(df) == 2 and set(df["status"]) == {"ok"}
    assert json.loads(files[0].read_text())["row"]["case_id"] == files[0].stem.split("-r")[0]
    assert files[1].read_text() == good[files[1].name]


def test_a_copy_under_another_name_is_ignored(finished, tmp_path):
    p, tmp = finished
    out = _copy_run(tmp / "run", tmp_path / "run")
    files = sorted((out / "cases").glob("*.json"))
    (out / "cases" / "0123456789abcdef-r0.json").write_text(files[0].read_text())
    with pytest.warns(RuntimeWarning, match="0123456789abcdef-r0.json.*copied or renamed"):
        rows = load_rows(out)
    assert sorted(rows) == sorted(f.stem for f in files)
    m = load_matrix(p, registry=default_registry())
    with pytest.warns(RuntimeWarning):
        s = run_matrix(m, out, jobs=1, cache_dir=tmp / "cache", progress=False)
    assert s.computed == [] and len(s.kept) == 2
    df = pd.read_parquet(out / "results.parquet")
    assert len(df) == 2 and df["case_id"].is_unique


def test_the_table_keeps_every_selection(finished, tmp_path):
    p, tmp = finished
    out = _copy_run(tmp / "run", tmp_path / "run")
    m_all = load_matrix(p, registry=default_registry())
    m_one = load_matrix(p, selectors=["dual=cpg"], registry=default_registry())
    s = run_matrix(m_one, out, jobs=1, cache_dir=tmp / "cache", progress=False)
    assert s.computed == [] and len(s.kept) == 1 and s.counts == {"ok": 1}
    df = pd.read_parquet(out / "results.parquet")
    assert sorted(df["dual"]) == ["cpg", "mcpg"]  # the mcpg row of the earlier run stays
    man = json.loads((out / "manifest.json").read_text())
    assert man["state"] == "finished" and man["rows_in_table"] == 2
    assert len(m_all.cases) == 2


def test_a_second_writer_gets_a_clear_error(finished, tmp_path):
    p, tmp = finished
    out = tmp_path / "run"
    out.mkdir()
    m = load_matrix(p, registry=default_registry())
    with RunLock(out):  # another writer (this process) holds the directory
        with pytest.raises(RunLockedError, match=rf"another rbbench run .*pid {os.getpid()}"):
            run_matrix(m, out, jobs=1, cache_dir=tmp / "cache", progress=False)
        from rbbench.cli import main

        assert main(["run", str(p), "--out", str(out), "--quiet"]) == 2
    assert list((out / "cases").glob("*.json")) == []  # nothing ran


def test_the_lock_of_a_dead_run_is_taken_over(tmp_path):
    """The lock is an flock: a killed holder leaves a file with its pid, not a lock."""
    out = tmp_path / "run"
    out.mkdir()
    code = ("import sys, time; from rbbench.bench.guard import RunLock; "
            f"RunLock({str(out)!r}).acquire(); print('locked', flush=True); time.sleep(60)")
    proc = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "locked"
    with pytest.raises(RunLockedError, match=f"pid {proc.pid}"):
        RunLock(out).acquire()
    proc.kill()
    proc.wait()
    lock = RunLock(out).acquire()
    assert lock.previous["pid"] == proc.pid
    lock.release()


def _run_processes(tag: str) -> list[int]:
    """The pids whose environment carries ``tag`` (every process of the run)."""
    pids = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            env = (d / "environ").read_bytes()
            stat = (d / "stat").read_text()
        except OSError:
            continue
        if tag.encode() in env and stat.rsplit(")", 1)[1].split()[0] != "Z":
            pids.append(int(d.name))
    return pids


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc and prctl: Linux")
@pytest.mark.parametrize("kill", ["process", "group"])
def test_sigkill_during_snapshot_preparation_leaves_no_process(tmp_path, kill):
    """The preparation runs in its own session with pool workers (jobs = 2) on a solver
    that hangs; SIGKILL of the run (its process, or its process group) must take them
    all down, and the manifest must say ``interrupted``."""
    m = tmp_path / "m.toml"
    m.write_text(MATRIX.replace('stabilizer = ["none"]',
                                'stabilizer = ["none"]\nsolver = ["faulty-hang"]'))
    script = textwrap.dedent(f"""
        import rbbench.testing.faulty as faulty
        from rbbench.bench.matrix import load_matrix
        from rbbench.bench.runner import run_matrix
        from rbbench.registry import discover
        reg = discover(extra_plugins=(faulty,))
        mx = load_matrix({str(m)!r}, registry=reg)
        run_matrix(mx, {str(tmp_path / 'run')!r}, jobs=2, registry=reg,
                   cache_dir={str(tmp_path / 'cache')!r}, progress=False)
    """)
    tag = f"RBBENCH_TEST_TAG={uuid.uuid4().hex}"
    env = {**os.environ, tag.split("=")[0]: tag.split("=")[1], "OPENBLAS_NUM_THREADS": "1"}
    proc = subprocess.Popen([sys.executable, "-c", script], env=env, start_new_session=True,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.time() + 120
        while time.time() < deadline and len(_run_processes(tag)) < 5:  # run, watchdog,
            time.sleep(0.2)  # preparation and its two pool workers
        assert len(_run_processes(tag)) >= 5, "the preparation did not start"
        time.sleep(1.0)
        (os.killpg if kill == "group" else os.kill)(proc.pid, signal.SIGKILL)
        proc.wait()
        deadline = time.time() + 20
        while time.time() < deadline and _run_processes(tag):
            time.sleep(0.2)
        assert _run_processes(tag) == []
        man = json.loads((tmp_path / "run" / "manifest.json").read_text())
        assert man["state"] == "interrupted"
    finally:
        for pid in _run_processes(tag):
            os.kill(pid, signal.SIGKILL)

"""Generated hostile run directories for ``rbbench report`` and ``rbbench compare`` (and the
readers under them): files that are symbolic links to outside files or to ``/dev/zero``,
case files and manifests nested 200,000 levels deep, binary, empty or of the wrong shape,
results tables with hostile cells (deep JSON, +-1e308, NaN, case ids with ``../``).

Readers leave what they cannot read out with a note naming the file; writers never write
through a link (an outside file keeps its content); a table nobody can read is exit 2 naming
the file; nothing ends in a traceback or a hang.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest
from support.fuzz import assert_rejected, hard_limit, run_cli
from support.run_records import write_run_dir

from rbbench.bench import schema
from rbbench.bench.report import load_run
from rbbench.bench.runner import load_rows

pytestmark = pytest.mark.timeout(120)

#: the files ``rbbench report`` writes for a run of two ok rows, ``--format svg``
REPORT_FILES = ("pareto.svg", "error_vs_size.svg", "status.svg", "summary.md", "summary.html")


def _record(i: int, **row) -> dict:
    base = {"run_id": "r", "case_id": f"c{i:03d}", "repetition": 0,
            "scene": "membrane_obstacle", "backend": "skfem", "formulation": "mixed",
            "solver": "ssn", "primal": "pod", "dual": "cpg" if i == 0 else "mcpg",
            "stabilizer": "none", "hyper": "auto", "params": "{}", "status": "ok",
            "N_req": 3, "R_req": 3, "N": 3, "R": 3, "err_u_max": 1e-3 * (i + 1),
            "t_online_median_s": 1e-4, "t_hf_median_s": 0.1}
    return {"row": schema.normalise_row({**base, **row}), "details": {}}


def _run(base: Path, name: str = "run", **row) -> Path:
    return write_run_dir(base / "inputs" / name, [_record(0, **row), _record(1)])


def _outside(base: Path, name: str) -> Path:
    victim = base / "outside" / name
    victim.parent.mkdir(parents=True, exist_ok=True)
    victim.write_text("keep me\n")
    return victim


def test_report_never_writes_through_links():
    """Every file the report writes, and the run's lock file, is a link to an outside file:
    each keeps its content (one report for all of them: a report takes seconds); a case file
    nested 200,000 levels deep is left out."""
    def prepare(base):
        run = _run(base)
        (run / "cases" / "c001-r0.json").write_text("[" * 200_000 + "]" * 200_000)
        (run / "report").mkdir()
        for name in REPORT_FILES:
            (run / "report" / name).symlink_to(_outside(base, name))
        (run / ".rbbench.lock").symlink_to(_outside(base, "lock"))

    code, err, outside = run_cli(lambda d, out: ["report", str(d / "run"), "--format", "svg"],
                                 prepare=prepare, limit=60)
    assert code == 0 and "Traceback" not in err, err
    assert [f for f in outside if f.startswith("outside")] == []


def test_a_report_folder_that_is_a_link_is_refused():
    def prepare(base):
        run = _run(base)
        (base / "outside").mkdir()
        (run / "report").symlink_to(base / "outside", target_is_directory=True)

    code, err, outside = run_cli(lambda d, out: ["report", str(d / "run"), "--format", "svg"],
                                 prepare=prepare)
    assert_rejected(code, err, outside, "report", "symbolic link", "--out")


# ------------------------------------------------------------------ readers, in process
def _hostile_case_files() -> dict[str, object]:
    return {"deep-array": "[" * 200_000 + "]" * 200_000,
            "deep-object": '{"row": ' * 200_000 + "0" + "}" * 200_000,
            "deep-details": json.dumps({"row": _record(0)["row"], "details": {}})[:-3]
            + ": " + "[" * 150 + "]" * 150 + "}",
            "binary": b"\xff\xfe\x00" * 100, "empty": "", "list": "[1, 2]",
            "null-row": '{"row": null}', "string-details": json.dumps(
                {"row": _record(0)["row"], "details": "x"}),
            "dev-zero": Path("/dev/zero"), "outside-link": "LINK", "directory": "DIR",
            "renamed": json.dumps(_record(1))}


CASES = _hostile_case_files()


@pytest.mark.parametrize("label", list(CASES))
@pytest.mark.parametrize("reader", ["load_run", "load_rows"])
def test_a_hostile_case_file_is_left_out_with_a_note(tmp_path, label, reader):
    run = write_run_dir(tmp_path / "run", [_record(0), _record(1)])
    target = run / "cases" / "c000-r0.json"
    content = CASES[label]
    target.unlink()
    if isinstance(content, Path):
        target.symlink_to(content)
    elif content == "LINK":
        target.symlink_to(_outside(tmp_path, "victim.json"))
    elif content == "DIR":
        target.mkdir()
    else:
        target.write_bytes(content if isinstance(content, bytes) else content.encode())
    with hard_limit():
        if reader == "load_run":
            data = load_run(run)
            assert len(data.rows) == 2  # the table is there; the case's details are not
            if label not in ("deep-details", "string-details"):
                assert any("c000-r0.json" in n for n in data.notes), data.notes
        else:
            with pytest.warns(RuntimeWarning, match="c000-r0.json"):
                rows = load_rows(run)
            assert sorted(rows) == ["c001-r0"]


MANIFESTS = {"deep": "[" * 200_000 + "]" * 200_000, "list": "[1]", "binary": b"\xff\x00",
             "dev-zero": Path("/dev/zero"), "directory": "DIR"}


@pytest.mark.parametrize("label", list(MANIFESTS))
def test_a_hostile_manifest_is_noted(tmp_path, label):
    run = write_run_dir(tmp_path / "run", [_record(0), _record(1)])
    m = run / "manifest.json"
    m.unlink()
    content = MANIFESTS[label]
    if isinstance(content, Path):
        m.symlink_to(content)
    elif content == "DIR":
        m.mkdir()
    else:
        m.write_bytes(content if isinstance(content, bytes) else content.encode())
    with hard_limit():
        data = load_run(run)
    assert data.manifest == {} and len(data.rows) == 2


# ------------------------------------------------------- results tables through compare
CELLS = {"params-deep": {"params": "[" * 100_000 + "]" * 100_000},
         "params-list": {"params": "[1, 2]"}, "params-junk": {"params": "{x"},
         "err-1e308": {"err_u_max": 1e308}, "err--1e308": {"err_u_max": -1e308},
         "err-nan": {"err_u_max": float("nan")}, "time-inf": {"t_online_median_s": 1e308},
         "time-neg": {"t_online_median_s": -1e308},
         "case-id-dots": {"case_id": "../../outside/x"},
         "case-id-slash": {"case_id": "/tmp/x"}, "scene-nul": {"scene": "a\x00b"}}


@pytest.mark.parametrize("label", list(CELLS))
def test_compare_hostile_cells(label):
    def prepare(base):
        _run(base, "a")
        b = base / "inputs" / "b"
        b.mkdir(parents=True)
        df = pd.read_parquet(base / "inputs" / "a" / "results.parquet")
        for k, v in CELLS[label].items():
            df[k] = df[k].astype(object)
            df.loc[0, k] = v
        df.to_csv(b / "results.csv", index=False)

    code, err, outside = run_cli(lambda d, out: ["compare", str(d / "a"), str(d / "b")],
                                 prepare=prepare)
    assert "Traceback" not in err, err
    assert code in (0, 1, 2), (code, err)
    assert outside == []


TABLES = {"binary": b"\x00\xff" * 1000, "empty": b"", "header-only": b"x,y\n",
          "dev-zero": Path("/dev/zero"), "directory": "DIR", "garbage-parquet": "PARQUET",
          "deep-json": ("[" * 100_000 + "]" * 100_000).encode()}


@pytest.mark.parametrize("label", list(TABLES))
def test_compare_unreadable_tables(label):
    def prepare(base):
        _run(base, "a")
        b = base / "inputs" / "b"
        b.mkdir(parents=True)
        content = TABLES[label]
        if isinstance(content, Path):
            (b / "results.csv").symlink_to(content)
        elif content == "DIR":
            (b / "results.csv").mkdir()
        elif content == "PARQUET":
            (b / "results.parquet").write_bytes(b"PAR1" + b"\x00" * 100)
        else:
            (b / "results.csv").write_bytes(content)

    code, err, outside = run_cli(lambda d, out: ["compare", str(d / "a"), str(d / "b")],
                                 prepare=prepare)
    assert_rejected(code, err, outside, "b")

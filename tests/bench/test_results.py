"""``rbbench.bench.results.load_results``: the results table read back with its column
types (Parquet, CSV and ``cases/*.json`` alike), and clear errors for what is not one."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pytest

from rbbench.bench import schema
from rbbench.bench.results import (
    DTYPES,
    ResultsError,
    ResultsNotFoundError,
    load_results,
    results_frame,
)
from rbbench.bench.runner import write_table

WANT = {c.name: DTYPES[c.dtype] for c in schema.COLUMNS}


def _rows() -> list[dict]:
    """Two ok rows and a failed one (numbers, empty cells, a bool, text)."""
    base = {"run_id": "r", "scene": "hertz", "dual": "cpg", "stabilizer": "none",
            "hyper": "auto", "params": "{}", "N_req": 4, "R_req": 3}
    return [
        {**base, "case_id": "a", "repetition": 0, "status": "ok", "N": 4, "R": 3,
         "err_u_max": 1.2345678901234567e-05, "err_lam_max": 0.1, "beta_dec_min": 3e-7,
         "beta_dec_zero_any": False, "t_online_median_s": 2.5e-4},
        {**base, "case_id": "a", "repetition": 1, "status": "ok", "N": 4, "R": 3,
         "err_u_max": 2e-5, "beta_dec_zero_any": True, "t_online_median_s": 3e-4},
        {**base, "case_id": "b", "repetition": 0, "status": "error",
         "reason": "ValueError: boom, with a comma"},
    ]


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("run")
    (d / "cases").mkdir()
    recs = [{"row": schema.normalise_row(r)} for r in _rows()]
    for r in recs:
        row = r["row"]
        (d / "cases" / f"{row['case_id']}-r{row['repetition']}.json").write_text(
            json.dumps({"row": row, "details": {}}))
    write_table(d, recs, csv=True)
    return d


def _check_typed(df: pd.DataFrame) -> None:
    assert list(df.columns) == schema.names()
    assert {c: str(t) for c, t in df.dtypes.items()} == WANT
    assert df["err_u_max"].dtype == "float64" and df["N"].dtype == "Int64"
    assert df["beta_dec_zero_any"].dtype == "boolean" and df["scene"].dtype == "string"
    assert df["err_u_max"].iloc[0] == 1.2345678901234567e-05
    assert df["N"].tolist()[:2] == [4, 4] and df["N"].isna().tolist() == [False, False, True]
    assert df["err_lam_max"].isna().tolist() == [False, True, True]
    assert df["beta_dec_zero_any"].tolist()[:2] == [False, True]
    assert pd.isna(df["beta_dec_zero_any"].iloc[2])
    assert df["reason"].iloc[2] == "ValueError: boom, with a comma"
    assert df["err_u_max"].max() == 2e-5  # numbers, not objects


def test_parquet_keeps_its_dtypes(run_dir):
    _check_typed(load_results(run_dir))
    _check_typed(load_results(run_dir / "results.parquet"))


def test_csv_gets_the_parquet_dtypes(run_dir):
    from_csv = load_results(run_dir / "results.csv")
    _check_typed(from_csv)
    pd.testing.assert_frame_equal(from_csv, load_results(run_dir / "results.parquet"))


def test_case_files_get_the_same_dtypes(run_dir, tmp_path):
    (tmp_path / "cases").mkdir()
    for f in (run_dir / "cases").glob("*.json"):
        (tmp_path / "cases" / f.name).write_bytes(f.read_bytes())
    notes: list[str] = []
    df = load_results(tmp_path, notes)
    _check_typed(df.sort_values(["case_id", "repetition"]).reset_index(drop=True))
    assert any("cases/*.json" in n for n in notes)


def test_the_report_reexports_the_loader():
    from rbbench.bench import report

    assert report.load_results is load_results


def test_rows_are_typed_and_undeclared_columns_noted():
    notes: list[str] = []
    df = results_frame([{**_rows()[0], "extra": 1}], notes)
    assert df["err_u_max"].dtype == "float64" and df["repetition"].dtype == "Int64"
    assert notes == ["column 'extra' is not declared in rbbench/schema.py: ignored"]
    with pytest.raises(ResultsError, match="status 'fine'"):
        results_frame([{**_rows()[0], "status": "fine"}])


def test_missing_paths_raise_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError, match="nothing-here: no such run directory"):
        load_results(tmp_path / "nothing-here")
    (tmp_path / "empty").mkdir()
    with pytest.raises(ResultsNotFoundError, match="empty: no results.parquet"):
        load_results(tmp_path / "empty")


def test_garbage_raises_a_results_error(tmp_path):
    (tmp_path / "notes.txt").write_text("hello")
    with pytest.raises(ResultsError, match=r"notes.txt: expected a run directory"):
        load_results(tmp_path / "notes.txt")
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "results.parquet").write_bytes(b"not a parquet file at all")
    with pytest.raises(ValueError, match="results.parquet: not a readable Parquet"):
        load_results(tmp_path / "bad")
    (tmp_path / "other.csv").write_text("a,b\n1,2\n")
    with pytest.raises(ResultsError, match="other.csv: no results column"):
        load_results(tmp_path / "other.csv")
    (tmp_path / "typo.csv").write_text("scene,N\nhertz,four\n")
    with pytest.raises(ResultsError, match="typo.csv: column 'N' does not hold int"):
        load_results(tmp_path / "typo.csv")

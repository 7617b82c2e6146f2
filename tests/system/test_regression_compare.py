"""``tools/regression/compare.py``, the check of a "no numerical change" step: identical
recordings pass, a number moved beyond the tolerance, a changed status or a lost key fail,
times are left out."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))
from tools.regression.compare import compare_recordings  # noqa: E402


def _record(d: Path, err: float = 0.125, status: str = "ok", time_s: float = 1.0,
            extra: bool = False) -> Path:
    (d / "quick").mkdir(parents=True)
    pd.DataFrame({"case_id": ["a", "b"], "status": [status, "ok"], "err_u_max": [err, 0.5],
                  "online_time_s": [time_s, 2.0]}).to_parquet(d / "quick" / "results.parquet")
    (d / "friction").mkdir()
    (d / "friction" / "result.json").write_text(json.dumps({"beta": [1.0, 2.0], "time_s": time_s}))
    (d / "optimize").mkdir()
    summary = {"J": 3.0, **({"published": 1.0} if extra else {})}
    (d / "optimize" / "summary.json").write_text(json.dumps(summary))
    pd.DataFrame({"J": [3.0, 2.0], "time_s": [time_s, 1.0]}).to_csv(d / "optimize" / "history.csv",
                                                                   index=False)
    res = d / "asv_results" / "vm"
    res.mkdir(parents=True)
    (res / "abc.json").write_text(json.dumps({"results": {"bench.A.track_err": [[err]]}}))
    return d


def test_identical_recordings_with_other_times_pass(tmp_path):
    c = compare_recordings(_record(tmp_path / "b"), _record(tmp_path / "a", time_s=9.0))
    assert c.differences == [] and c.n == 8 and c.max_rel == 0.0


@pytest.mark.parametrize("change, where", [
    ({"err": 0.125 * (1 + 1e-9)}, "quick[a].err_u_max"),
    ({"status": "error"}, "quick[a].status"),
    ({"extra": True}, "optimize/summary.json.published: only in after"),
])
def test_a_changed_number_status_or_key_is_named(tmp_path, change, where):
    c = compare_recordings(_record(tmp_path / "b"), _record(tmp_path / "a", **change))
    assert c.differences and all(where.split(":")[0] in d or "asv" in d for d in c.differences)
    assert any(where in d for d in c.differences)


def test_differences_within_the_tolerance_pass(tmp_path):
    close = 0.125 * (1 + 1e-14)
    c = compare_recordings(_record(tmp_path / "b"), _record(tmp_path / "a", err=close))
    assert c.differences == [] and 0 < c.max_rel < 1e-12

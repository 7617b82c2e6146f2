"""Test helper: a run directory written from synthetic case records (shared by the report
tests)."""

from __future__ import annotations

import json
from pathlib import Path

from rbbench.bench import schema
from rbbench.bench.runner import write_table


def write_run_dir(d: Path, recs: list[dict]) -> Path:
    """``cases/<case_id>-r0.json`` per record, the results table and a manifest."""
    (d / "cases").mkdir(parents=True)
    for r in recs:
        (d / "cases" / f"{r['row']['case_id']}-r0.json").write_text(json.dumps(r))
    write_table(d, recs)
    (d / "manifest.json").write_text(json.dumps({"run_id": d.name,
                                                 "columns": schema.column_definitions()}))
    return d

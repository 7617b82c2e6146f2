"""A run directory read for the report: the typed results table, the manifest and the
per-case details."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from rbbench.bench import json_text, schema
from rbbench.bench.results import ResultsNotFoundError, load_results, records


@dataclass
class RunData:
    """One run directory, read.

    Attributes
    ----------
    run_dir : Path
        The directory.
    rows : pandas.DataFrame
        Every schema column, typed (:func:`rbbench.bench.results.load_results`), one row
        per case x repetition, in file order.
    manifest : dict
        ``manifest.json`` (empty if absent).
    details : dict
        ``(case_id, repetition) -> details`` from ``cases/*.json`` (``per_mu``,
        ``histories``, ``valid_mus``); absent cases have no entry.
    notes : list of str
        What was odd while reading (unknown columns, unreadable case files).
    """

    run_dir: Path
    rows: pd.DataFrame
    manifest: dict = field(default_factory=dict)
    details: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)

    def records(self) -> list[dict[str, Any]]:
        """The rows as a list of dicts (``None`` for empty cells)."""
        return records(self.rows)


def _manifest(d: Path, notes: list[str]) -> dict:
    if not (d / "manifest.json").is_file():
        return {}
    try:
        man = json_text.loads(json_text.read_text(d / "manifest.json"))
    except (OSError, ValueError) as exc:
        notes.append(f"manifest.json unreadable ({exc})")
        return {}
    if not isinstance(man, dict):
        notes.append("manifest.json is not a JSON object; ignored")
        return {}
    return man


def _details(d: Path, notes: list[str]) -> dict[tuple[str, int], dict]:
    """``(case_id, repetition) -> details`` of the readable ``cases/*.json``."""
    details: dict[tuple[str, int], dict] = {}
    if not (d / "cases").is_dir():
        return details
    for f in sorted((d / "cases").glob("*.json")):
        try:
            doc = json_text.loads(json_text.read_text(f))
        except (OSError, ValueError) as exc:
            notes.append(f"cases/{f.name}: unreadable ({exc}); ignored")
            continue
        problem = schema.case_record_problem(f.name, doc)
        if problem is not None:
            notes.append(f"cases/{f.name}: {problem}; ignored")
            continue
        row, det = doc["row"], doc.get("details")
        if isinstance(det, dict) and det:
            details[(str(row["case_id"]), int(row["repetition"]))] = det
    return details


def load_run(run_dir: str | Path) -> RunData:
    """Read a run directory: results, manifest and per-case details.

    Parameters
    ----------
    run_dir : str or Path
        The directory written by ``rbbench run``.

    Returns
    -------
    RunData

    Raises
    ------
    rbbench.bench.results.ResultsNotFoundError
        (a :class:`FileNotFoundError`) If ``run_dir`` is not a directory or holds no
        results.
    """
    d = Path(run_dir)
    if not d.is_dir():
        raise ResultsNotFoundError(f"{d}: not a run directory")
    notes: list[str] = []
    rows = load_results(d, notes)
    manifest = _manifest(d, notes)
    return RunData(d, rows, manifest, _details(d, notes), notes)

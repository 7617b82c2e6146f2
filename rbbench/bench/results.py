"""The results table of a run, read back with the column types of :mod:`rbbench.bench.schema`.

``rbbench run`` writes ``results.parquet`` (and optionally ``results.csv``) with one row
per case x repetition, plus ``cases/<case_id>-r<rep>.json`` whose ``"row"`` is the same
row. :func:`load_results` reads any of them into a :class:`pandas.DataFrame` holding
every declared column, in schema order, with the dtypes the runner writes: ``float64``
(NaN where empty), ``Int64``, ``boolean`` and ``string`` (``<NA>`` where empty). A CSV
file gets the same dtypes as the Parquet file it was written beside.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rbbench.bench import json_text, schema
from rbbench.bench.errors import ResultsError, ResultsNotFoundError

__all__ = ["DTYPES", "ResultsError", "ResultsNotFoundError", "load_results", "records",
           "results_frame"]

#: pandas dtype of each schema column type (those of ``results.parquet``, written by
#: :func:`rbbench.bench.runner.write_table` through :func:`results_frame`)
DTYPES: dict[str, str] = {"float": "float64", "int": "Int64", "bool": "boolean",
                          "str": "string"}
_COL = {c.name: c for c in schema.COLUMNS}
_NA_TEXT = ("", "nan", "none", "null")
_TRUE_TEXT = ("true", "1", "yes")
_CAST = {"str": str, "int": int, "float": float, "bool": bool}


def plain(v: Any) -> Any:
    """A cell as plain Python: NaN / NA -> ``None``, numpy scalars -> Python scalars."""
    if v is None:
        return None
    if isinstance(v, np.generic):
        v = v.item()
    try:
        if pd.isna(v):
            return None
    except (TypeError, ValueError):
        pass
    return v


def records(df: pd.DataFrame) -> list[dict[str, Any]]:
    """The rows of a table as a list of dicts of plain Python values (``None`` if empty)."""
    return [{k: plain(v) for k, v in r.items()} for r in df.to_dict("records")]


def _value(v: Any, kind: str) -> Any:
    """One cell cast to the schema type ``kind`` (text such as ``"nan"`` or ``""`` is
    empty; ``"true"``, ``"1"``, ``"yes"`` are true); ``None`` where empty."""
    v = plain(v)
    if v is None:
        return None
    if isinstance(v, str) and kind != "str":
        s = v.strip()
        if s.lower() in _NA_TEXT:
            return None
        if kind == "bool":
            return s.lower() in _TRUE_TEXT
        if kind == "int":
            return int(float(s))
    elif kind == "int" and isinstance(v, float):
        v = int(v)
    v = _CAST[kind](v)
    return None if kind == "float" and v != v else v


def _column(values: pd.Series, kind: str, source: str) -> pd.Series:
    """A column cast to the dtype of its schema type (unchanged if it has it already)."""
    dtype = pd.api.types.pandas_dtype(DTYPES[kind])
    if values.dtype == dtype:
        return values.reset_index(drop=True)
    try:
        cells = [_value(v, kind) for v in values]
    except (TypeError, ValueError, OverflowError) as exc:
        raise ResultsError(f"{source}: column {values.name!r} does not hold {kind} values "
                           f"({exc})") from None
    return pd.Series(cells, dtype=dtype, name=values.name)


def _note_undeclared(columns: Iterable[str], notes: list[str] | None) -> None:
    for k in columns:
        msg = f"column {k!r} is not declared in rbbench/schema.py: ignored"
        if k not in _COL and notes is not None and msg not in notes:
            notes.append(msg)


def results_frame(rows: pd.DataFrame | Iterable[dict[str, Any]],
                  notes: list[str] | None = None, source: str = "results") -> pd.DataFrame:
    """Rows as a results table: every schema column, in schema order, with its dtype.

    Parameters
    ----------
    rows : pandas.DataFrame or iterable of dict
        Results rows (e.g. from a file, or :func:`rbbench.bench.schema.normalise_row`).
    notes : list of str, optional
        Receives a note per undeclared column (dropped).
    source : str
        Where the rows came from (for the error messages).

    Returns
    -------
    pandas.DataFrame
        Columns of :data:`rbbench.bench.schema.COLUMNS` typed as :data:`DTYPES`.

    Raises
    ------
    ResultsError
        For a cell that does not fit its column's type, or a status outside
        :data:`rbbench.bench.schema.STATUSES`.
    """
    df = rows if isinstance(rows, pd.DataFrame) else pd.DataFrame(list(rows), dtype=object)
    _note_undeclared(df.columns, notes)
    n = len(df)
    out = {c.name: (_column(df[c.name], c.dtype, source) if c.name in df.columns
                    else pd.Series([None] * n, dtype=DTYPES[c.dtype], name=c.name))
           for c in schema.COLUMNS}
    frame = pd.DataFrame(out, columns=schema.names())
    bad = frame["status"].dropna()
    bad = bad[~bad.isin(schema.STATUSES)]
    if len(bad):
        raise ResultsError(f"{source}: results row: status {bad.iloc[0]!r}; valid: "
                           f"{', '.join(schema.STATUSES)}")
    return frame


def _read_csv(path: Path) -> pd.DataFrame:
    header = pd.read_csv(path, nrows=0).columns
    dtype = {c: str for c in header if c in _COL and _COL[c].dtype in ("str", "bool")}
    return pd.read_csv(path, dtype=dtype, keep_default_na=False,
                       na_values={c: [""] for c in header})


def _read_file(p: Path) -> pd.DataFrame:
    """A ``.parquet`` or ``.csv`` results file, as stored (before the schema types)."""
    kind = "Parquet" if p.suffix == ".parquet" else "CSV"
    try:
        df = pd.read_parquet(p) if p.suffix == ".parquet" else _read_csv(p)
    except (OSError, ValueError, UnicodeDecodeError) as exc:
        raise ResultsError(f"{p}: not a readable {kind} results table ({exc})") from None
    if not any(c in _COL for c in df.columns):
        raise ResultsError(f"{p}: no results column (expected the columns of "
                           "rbbench.bench.schema, e.g. case_id, scene, status)")
    return df


def _case_rows(d: Path, notes: list[str] | None) -> list[dict[str, Any]]:
    """The ``"row"`` of every readable ``cases/*.json`` of a run directory."""
    files = sorted((d / "cases").glob("*.json")) if (d / "cases").is_dir() else []
    raw = []
    for f in files:
        try:
            rec = json_text.loads(json_text.read_text(f))
        except (OSError, ValueError) as exc:
            problem = f"unreadable ({exc})"
        else:
            problem = schema.case_record_problem(f.name, rec)
        if problem is None:
            raw.append(rec["row"])
        elif notes is not None:
            notes.append(f"{f.name}: {problem}; ignored")
    if not raw:
        raise ResultsNotFoundError(f"{d}: no results.parquet, results.csv or cases/*.json")
    if notes is not None:
        notes.append("no results.parquet / results.csv: rows read from cases/*.json")
    return raw


def load_results(path: str | Path, notes: list[str] | None = None) -> pd.DataFrame:
    """The results table of a run directory or of one results file.

    Parameters
    ----------
    path : str or Path
        A run directory (``results.parquet``, else ``results.csv``, else the rows of
        ``cases/*.json``), or a ``.parquet`` / ``.csv`` file.
    notes : list of str, optional
        Receives what was odd (e.g. undeclared columns, ignored).

    Returns
    -------
    pandas.DataFrame
        Every column of :data:`rbbench.bench.schema.COLUMNS` in schema order, typed
        (``float64``, ``Int64``, ``boolean``, ``string``: :data:`DTYPES`), one row per case
        x repetition in file order.

    Raises
    ------
    ResultsNotFoundError
        (a :class:`FileNotFoundError`) If nothing is at ``path`` or a directory holds no
        results.
    ResultsError
        (a :class:`ValueError`) If ``path`` is a file of another kind, or a results file
        that cannot be read as a results table.
    """
    p = Path(path)
    if p.is_dir():
        for name in ("results.parquet", "results.csv"):
            if (p / name).is_file():
                return load_results(p / name, notes)
        return results_frame(_case_rows(p, notes), notes, source=str(p / "cases"))
    if p.is_file() and p.suffix in (".parquet", ".csv"):
        return results_frame(_read_file(p), notes, source=str(p))
    if p.is_file():
        raise ResultsError(f"{p}: expected a run directory, a .parquet or a .csv file")
    raise ResultsNotFoundError(f"{p}: no such run directory or results file")

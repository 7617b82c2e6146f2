"""Formatting shared by the studies' Markdown tables."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np


def markdown_table(head: Sequence[str], rows: Iterable[Sequence[Any]]) -> str:
    """A Markdown table: the header cells, the separator, one line per row of cells (each
    written with ``str``)."""

    def line(cells: Sequence[Any]) -> str:
        return "| " + " | ".join(str(c) for c in cells) + " |"

    return "\n".join([line(head), "|" + "---|" * len(head), *(line(r) for r in rows)])


def percent(x: float | None) -> str:
    """A fraction in percent with three decimals; empty for ``None``."""
    return "" if x is None else f"{100 * x:.3f}"


def observed_order(e_prev: float | None, e: float | None, h_prev: float, h: float) -> str:
    """The observed order ``log(e_prev / e) / log(h_prev / h)`` (two decimals); empty when an
    error is missing or not positive."""
    if not e_prev or not e or e_prev <= 0 or e <= 0:
        return ""
    return f"{np.log(e_prev / e) / np.log(h_prev / h):.2f}"


def print_and_dump(text: str, figures: dict[str, Any], path: str | None) -> int:
    """Print a study's table and, with ``path``, write its figures as JSON (exit 0)."""
    import json

    print(text)
    if path:
        with open(path, "w") as fh:
            json.dump(figures, fh, indent=1, default=float)
    return 0


def significant(table: Any, digits: int = 3) -> Any:
    """A copy of the pandas DataFrame ``table`` for display: every float with ``digits``
    significant digits (``1.23e-04``, ``0.0123``, ``1.23e+06``), a missing value (None, NaN)
    as an empty cell, other cells as they are. The figures are unchanged in ``table``."""

    def cell(v: Any) -> Any:
        if v is None or (isinstance(v, float) and np.isnan(v)):
            return ""
        if isinstance(v, (float, np.floating)) and not float(v).is_integer():
            return f"{float(v):.{digits}g}"
        return v

    return table.astype(object).apply(lambda col: col.map(cell))

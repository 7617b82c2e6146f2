"""The errors of reading a results table (raised by :mod:`rbbench.bench.results`), in a
module without pandas: the CLI catches them without loading it."""

from __future__ import annotations

__all__ = ["ResultsError", "ResultsNotFoundError"]


class ResultsError(ValueError):
    """A path that does not hold a readable results table (the message names the path
    and what was expected)."""


class ResultsNotFoundError(ResultsError, FileNotFoundError):
    """No results at a path: no such file or directory, or a directory without
    ``results.parquet``, ``results.csv`` or ``cases/*.json``."""

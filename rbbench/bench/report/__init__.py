"""Plots and tables from a run directory (``rbbench report``) and the comparison of two
runs (``rbbench compare``).

A run directory (written by ``rbbench run``) holds::

    manifest.json                 run id, matrix, column definitions, provenance
    results.parquet               one row per case x repetition (rbbench.bench.schema.COLUMNS)
    results.csv                   optional, the same rows
    cases/<case_id>-r<rep>.json   {"row": {...}, "details": {"per_mu", "histories",
                                  "valid_mus"}}

:func:`report` reads it and writes figures (Pareto fronts, offline cost against online
time, error against size, inf-sup constants per validation parameter, compressor / PGA /
EIM histories, speed-ups, status counts; for reduced friction models the GCNS curves and
lam_t HF against RB) and ``summary.md`` / ``summary.html``. :func:`compare` matches the
rows of two runs on the identity of the case and lists regressions and improvements.

Only the columns declared in :mod:`rbbench.bench.schema` are read, by name; labels and
footnotes come from their docs. Rows whose status is not ``ok`` are never plotted or
tabulated as numbers. Matplotlib is used through :class:`matplotlib.figure.Figure` only
(no pyplot): no backend is selected and no global figure state is touched.

Modules: :mod:`~rbbench.bench.report.loading` (a run directory read),
:mod:`~rbbench.bench.report.analysis` (tables computed from the rows),
:mod:`~rbbench.bench.report.figures`, :mod:`~rbbench.bench.report.cost_figures`,
:mod:`~rbbench.bench.report.detail_figures` and
:mod:`~rbbench.bench.report.friction_figures` (the figures; the friction table),
:mod:`~rbbench.bench.report.document` (:func:`report` and its summaries),
:mod:`~rbbench.bench.report.comparison` (:func:`compare`). The results table itself is
read by :func:`rbbench.bench.results.load_results`.
"""

from rbbench.bench.report.analysis import best_per_level, pareto_front, status_counts
from rbbench.bench.report.common import ERROR_LEVELS, IDENTITY
from rbbench.bench.report.comparison import CompareResult, compare, format_compare
from rbbench.bench.report.document import ReportOutput, report
from rbbench.bench.report.loading import RunData, load_run
from rbbench.bench.results import load_results

__all__ = [
    "ERROR_LEVELS",
    "IDENTITY",
    "CompareResult",
    "ReportOutput",
    "RunData",
    "best_per_level",
    "compare",
    "format_compare",
    "load_results",
    "load_run",
    "pareto_front",
    "report",
    "status_counts",
]

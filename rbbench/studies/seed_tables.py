"""Transitional: the seed-table studies now live one module per study.

:mod:`rbbench.studies.hertz` (``hertz_table``), :mod:`rbbench.studies.nitsche_eac`
(``nitsche_table``), :mod:`rbbench.studies.scaling` (``online_scaling``) and
:mod:`rbbench.studies.nitsche_compare` (``formulation_comparison``); import from there or
from :mod:`rbbench.studies`. This module only re-exports their names.
"""

from __future__ import annotations

from rbbench.studies.hertz import hertz_markdown, hertz_table
from rbbench.studies.nitsche_compare import comparison_markdown, formulation_comparison
from rbbench.studies.nitsche_eac import (
    NITSCHE_COLUMNS,
    SEED_EAC,
    SEED_H,
    nitsche_markdown,
    nitsche_table,
    seed_h_overrides,
)
from rbbench.studies.scaling import online_scaling, scaling_markdown

markdown = hertz_markdown  #: the former name of :func:`hertz_markdown`

__all__ = ["NITSCHE_COLUMNS", "SEED_EAC", "SEED_H", "comparison_markdown",
           "formulation_comparison", "hertz_markdown", "hertz_table", "markdown",
           "nitsche_markdown", "nitsche_table", "online_scaling", "scaling_markdown",
           "seed_h_overrides"]

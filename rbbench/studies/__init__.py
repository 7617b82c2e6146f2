"""Reproductions of published figures, built on the core and never imported by it.

The figures are those of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction
methods: parametric variational inequalities" (talk), and of the talk "On coupling of
complementarity with friction in contact shape optimization". One module per study:
:mod:`~rbbench.studies.hertz` (the 2D Hertz table),
:mod:`~rbbench.studies.nitsche_eac` (Benaceur et al.'s e_AC^n table of the Nitsche solve),
:mod:`~rbbench.studies.nitsche_compare` (Nitsche against mixed),
:mod:`~rbbench.studies.scaling` (online time against the HF size) and
:mod:`~rbbench.studies.beta_dec` (the beta_dec stability study),
:mod:`~rbbench.studies.heat_robin` (the heat equation beside the published valve figures),
:mod:`~rbbench.studies.snapshot_workers` (HF snapshots, 1 against n worker processes);
Markdown helpers in :mod:`~rbbench.studies.formatting`. The studies' public names are
importable from here too (loaded on first use).
"""

from __future__ import annotations

import importlib
import warnings
from typing import Any

#: public name -> the module defining it
_NAMES = {
    "hertz_table": "hertz", "hertz_markdown": "hertz",
    "nitsche_table": "nitsche_eac", "nitsche_markdown": "nitsche_eac",
    "published_h_overrides": "nitsche_eac", "NITSCHE_COLUMNS": "nitsche_eac",
    "PUBLISHED_EAC": "nitsche_eac", "PUBLISHED_H": "nitsche_eac",
    "online_scaling": "scaling", "scaling_markdown": "scaling",
    "formulation_comparison": "nitsche_compare", "comparison_markdown": "nitsche_compare",
    "beta_dec_study": "beta_dec", "BetaDecStudy": "beta_dec",
    "heat_robin_study": "heat_robin", "heat_robin_markdown": "heat_robin",
}
#: former names (the flat ``rbbench/studies.py``) -> (module, name)
_ALIASES = {"markdown": ("hertz", "hertz_markdown")}
#: renamed public names, still importable with a DeprecationWarning until rbbench 0.3
_DEPRECATED = {"seed_h_overrides": "published_h_overrides", "SEED_EAC": "PUBLISHED_EAC",
               "SEED_H": "PUBLISHED_H"}

__all__ = sorted([*_NAMES, *_ALIASES])


def __getattr__(name: str) -> Any:
    if name in _DEPRECATED:
        warnings.warn(f"rbbench.studies.{name} is now {_DEPRECATED[name]} (the old name goes "
                      "in rbbench 0.3)", DeprecationWarning, stacklevel=2)
        name = _DEPRECATED[name]
    module, attr = _ALIASES.get(name, (_NAMES.get(name), name))
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{module}"), attr)


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])

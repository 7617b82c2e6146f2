"""rbbench: benchmark reduced-basis methods for parametric variational inequalities.

The Python face (:mod:`rbbench.api`): ``load_scene``, ``solve``, ``reduce``, ``run``,
``load_results``, loaded on first use, so ``import rbbench`` stays cheap.

The core never imports a finite-element backend at import time; backends,
formulations and solvers are plugins discovered through the ``rbbench``
entry-point group (see :mod:`rbbench.registry`).
"""

from __future__ import annotations

import importlib
from typing import Any

from rbbench import _compat
from rbbench._version import __version__

_compat.install()

#: public name -> the module that defines it (imported on first access)
_LAZY = {
    "load_scene": "rbbench.scene.loading",
    "solve": "rbbench.api",
    "reduce": "rbbench.api",
    "run": "rbbench.api",
    "load_results": "rbbench.api",
}

__all__ = ["__version__", "load_results", "load_scene", "reduce", "run", "solve"]


def __getattr__(name: str) -> Any:
    """The names of :data:`_LAZY`, imported from their module on first access."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'rbbench' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})

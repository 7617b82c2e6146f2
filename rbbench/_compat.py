"""Deprecated module paths of rbbench <= 0.1 (the flat layout), kept importable.

``import rbbench.lcp`` still works until 0.3 and warns with the new path
(:class:`DeprecationWarning`); the module object is the new one, so
``isinstance`` checks and monkeypatching agree. Only the public plugin API kept its
path: :mod:`rbbench.hookspecs`, :mod:`rbbench.registry`, :mod:`rbbench.interfaces`,
:mod:`rbbench.testing`.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import warnings

#: old flat module -> its module in the layered package
MOVED = {
    "rbbench.sampling": "rbbench.scene.sampling",
    "rbbench.contact_geometry": "rbbench.hf.geometry.operators",
    "rbbench.lcp": "rbbench.hf.solvers.lcp",
    "rbbench.nitsche": "rbbench.hf.algebra.nitsche",
    "rbbench.hertz": "rbbench.hf.references.hertz",
    "rbbench.output": "rbbench.hf.output",
    "rbbench.snapshots": "rbbench.hf.snapshots.compute",
    "rbbench.pod": "rbbench.rb.algorithms.pod",
    "rbbench.cones": "rbbench.rb.algorithms.cones",
    "rbbench.pga": "rbbench.rb.algorithms.pga",
    "rbbench.infsup": "rbbench.rb.algorithms.infsup",
    "rbbench.eim": "rbbench.rb.algorithms.eim",
    "rbbench.hyper": "rbbench.rb.hyper.contact_eim",
    "rbbench.compressors": "rbbench.rb.compressors",
    "rbbench.reduced": "rbbench.rb.mixed.model",
    "rbbench.nitsche_reduced": "rbbench.rb.nitsche.model",
    "rbbench.rb_pipeline": "rbbench.rb.offline",
    "rbbench.matrix": "rbbench.bench.matrix",
    "rbbench.runner": "rbbench.bench.runner",
    "rbbench.schema": "rbbench.bench.schema",
    "rbbench.report": "rbbench.bench.report",
    "rbbench.stability_study": "rbbench.studies.beta_dec",
}


class _Alias(importlib.abc.Loader):
    def __init__(self, new: str) -> None:
        self.new = new

    def create_module(self, spec):  # the new module itself, not a copy
        return importlib.import_module(self.new)

    def exec_module(self, module) -> None:
        return None


class _MovedFinder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):
        new = MOVED.get(fullname)
        if new is None:
            return None
        warnings.warn(f"{fullname} moved to {new}; the old path goes in rbbench 0.3",
                      DeprecationWarning, stacklevel=3)
        return importlib.util.spec_from_loader(fullname, _Alias(new))


def install() -> None:
    """Put the finder on ``sys.meta_path`` once."""
    if not any(isinstance(f, _MovedFinder) for f in sys.meta_path):
        sys.meta_path.append(_MovedFinder())

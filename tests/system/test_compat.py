"""The import paths of rbbench 0.1 (the flat layout and the first layered one) still work
until 0.3: every module path and every public name it had resolves, with a
DeprecationWarning naming the new place (``tests/data/api_0_1.json``: the public names of
each module at the last commit of each layout, read from their source)."""

from __future__ import annotations

import importlib
import json
import warnings
from pathlib import Path

import pytest

import rbbench  # noqa: F401 - installs the finder of the old paths

API = json.loads((Path(__file__).resolve().parents[1] / "data" / "api_0_1.json").read_text())
MOVED_SINCE = "the old path goes in rbbench 0.3"
#: the optional dependencies of the extras (an old path of their plugins cannot import without)
OPTIONAL = {"ngsolve", "netgen", "petsc4py", "dask", "distributed", "pymor", "pypardiso"}


@pytest.mark.parametrize("module", sorted(API))
def test_every_0_1_path_and_name_resolves(module):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        try:
            mod = importlib.import_module(module)
            missing = [n for n in API[module] if not hasattr(mod, n)]
        except ModuleNotFoundError as exc:
            if (exc.name or "").split(".")[0] not in OPTIONAL:
                raise
            pytest.skip(f"{module} needs {exc.name} (an extra), not installed")
    assert not missing, f"{module}: {missing}"


@pytest.mark.parametrize("old, new", [
    ("rbbench.rb.pod", "rbbench.rb.algorithms.pod"),
    ("rbbench.hf.lcp", "rbbench.hf.solvers.lcp"),
    ("rbbench_plugins.backends.skfem_backend", "rbbench_plugins.backends.skfem.backend"),
])
def test_a_moved_module_warns_with_its_new_path(old, new):
    import sys

    sys.modules.pop(old, None)
    with pytest.warns(DeprecationWarning, match=f"{old} moved to {new}.*{MOVED_SINCE}"):
        importlib.import_module(old)


def test_names_that_left_a_module_warn_and_are_the_new_objects():
    from rbbench.hf.metrics import DEFINITIONS
    from rbbench.hf.model import ProblemCache, solve_hf

    with pytest.warns(DeprecationWarning, match="rbbench.hf.solve_hf moved to "
                      "rbbench.hf.model.solve_hf"):
        from rbbench.hf import solve_hf as old
    assert old is solve_hf
    with pytest.warns(DeprecationWarning, match="rbbench.hf.model.DEFINITIONS moved to "
                      "rbbench.hf.metrics.DEFINITIONS"):
        from rbbench.hf.model import DEFINITIONS as old_defs
    assert old_defs is DEFINITIONS
    with pytest.warns(DeprecationWarning, match="rbbench.rb.offline.SceneProblems moved"):
        from rbbench.rb.offline import SceneProblems
    assert SceneProblems is ProblemCache
    with pytest.raises(ImportError, match="cannot import name .nonexistent."):
        from rbbench.hf import nonexistent  # noqa: F401


def test_a_module_moved_whole_is_the_new_module_object():
    import rbbench.rb.algorithms.pod as new

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        old = importlib.import_module("rbbench.rb.pod")
    assert old is new

"""``rbbench.plugin``: the names a plugin package imports, cheap to import, each the very
object its defining module holds (the built-in components use the same)."""

from __future__ import annotations

import importlib
import subprocess
import sys
import textwrap

import pytest

import rbbench.plugin as plugin

#: where each public name is defined (written out here, independently of the module's table)
DEFINED_IN = {
    "hookimpl": "rbbench.hookspecs", "ComponentSpec": "rbbench.registry",
    "Registry": "rbbench.registry", "ROLES": "rbbench.registry",
    "Backend": "rbbench.interfaces.roles", "Formulation": "rbbench.interfaces.roles",
    "Solver": "rbbench.interfaces.roles", "Executor": "rbbench.interfaces.roles",
    "Discretization": "rbbench.interfaces.operators",
    "ContactOperators": "rbbench.interfaces.operators",
    "BodyMesh": "rbbench.interfaces.operators",
    "ContactProblem": "rbbench.interfaces.problems",
    "NitscheProblem": "rbbench.interfaces.problems",
    "FrictionProblem": "rbbench.interfaces.problems",
    "SolveResult": "rbbench.interfaces.problems", "STOP_REASONS": "rbbench.interfaces.problems",
    "Scene": "rbbench.scene.loading", "SceneError": "rbbench.scene.loading",
    "PrimalCompressor": "rbbench.rb.compressors", "PrimalBasis": "rbbench.rb.compressors",
    "DualCompressor": "rbbench.rb.compressors", "Stabilizer": "rbbench.rb.compressors",
    "NoStabilizer": "rbbench.rb.compressors",
    "DualBasis": "rbbench.rb.algorithms.cones.greedy",
    "WMetric": "rbbench.rb.algorithms.cones.metric",
    "as_metric": "rbbench.rb.algorithms.cones.metric",
    "cone_projection": "rbbench.rb.algorithms.cones.metric",
    "span_projection": "rbbench.rb.algorithms.cones.metric",
    "supremizers": "rbbench.rb.algorithms.pga", "x_orthonormalize": "rbbench.rb.algorithms.pga",
    "HyperReducer": "rbbench.rb.hyper.reducers", "Case": "rbbench.bench.matrix",
    "execute_case": "rbbench.bench.execution", "failed_row": "rbbench.bench.execution",
}


def test_every_public_name_is_the_defining_modules_object():
    assert sorted(plugin.__all__) == sorted(DEFINED_IN)
    for name, module in DEFINED_IN.items():
        assert getattr(plugin, name) is getattr(importlib.import_module(module), name), name
    assert set(plugin.__all__) <= set(dir(plugin))


def test_the_built_in_components_derive_from_the_public_bases():
    from rbbench.registry import default_registry

    reg = default_registry()
    for name in reg.names("dual"):
        assert issubclass(reg.load("dual", name), plugin.DualCompressor)
    for name in reg.names("hyper"):
        assert issubclass(reg.load("hyper", name), plugin.HyperReducer)
    for name in reg.names("stabilizer"):
        assert isinstance(reg.create("stabilizer", name), plugin.Stabilizer)
    for name in reg.names("primal"):
        assert isinstance(reg.create("primal", name), plugin.PrimalCompressor)
    assert issubclass(reg.load("backend", "skfem"), plugin.Backend)
    assert issubclass(reg.load("formulation", "mixed"), plugin.Formulation)
    assert issubclass(reg.load("solver", "ssn"), plugin.Solver)
    assert isinstance(reg.create("executor", "serial"), plugin.Executor)


def test_an_unknown_name_lists_the_public_ones():
    with pytest.raises(AttributeError, match="no attribute 'DualBasys'; its names: .*DualBasis"):
        plugin.DualBasys  # noqa: B018


def test_importing_it_is_cheap():
    code = textwrap.dedent("""
        import sys
        from rbbench.plugin import ComponentSpec, hookimpl, ROLES
        heavy = sorted(m for m in ("numpy", "scipy", "pandas", "skfem")
                       if m in sys.modules)
        print(heavy)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, check=True)
    assert out.stdout.strip() == "[]"

"""The plugin template (``examples/plugin_template``) imported from its path, nothing
installed: its components pass their contracts, its entry point names its hook, and its
run matrix loads with it (the default suite catches a broken template)."""

from __future__ import annotations

import importlib
import sys
from pathlib import Path

import pytest

from rbbench.registry import Registry, default_registry
from rbbench.scene.loading import tomllib
from rbbench.testing import run_contract

TEMPLATE = Path(__file__).resolve().parents[2] / "examples" / "plugin_template"


@pytest.fixture
def template(monkeypatch):
    """The template's package, imported from its src folder."""
    monkeypatch.syspath_prepend(str(TEMPLATE / "src"))
    for name in [m for m in sys.modules if m.startswith("rbbench_plugin_template")]:
        monkeypatch.delitem(sys.modules, name)
    module = importlib.import_module("rbbench_plugin_template")
    assert Path(module.__file__).is_relative_to(TEMPLATE)
    return module


def _registry(template, with_builtins: bool) -> Registry:
    """The template's declarations (its hook called as discovery calls it), with or without
    the installed components."""
    reg = Registry()
    if with_builtins:  # the installed components (the template's own too, when installed)
        for spec in default_registry().specs():
            if spec.package != "rbbench-plugin-template":
                reg.add(spec)
    reg._current_package = ("rbbench-plugin-template", "0.1.0")
    template.rbbench_register(reg)
    reg._current_package = ("", "")
    return reg


def test_its_components_pass_their_contracts(template):
    reg = _registry(template, with_builtins=False)
    assert [(s.role, s.name) for s in reg.specs()] == [("dual", "random-cone")]
    for spec in reg.specs():
        run_contract(spec, reg)  # a ContractViolation names the broken property


def test_its_entry_point_and_version(template):
    meta = tomllib.loads((TEMPLATE / "pyproject.toml").read_text())
    assert meta["project"]["entry-points"]["rbbench"] == {"template": template.__name__}
    assert meta["project"]["version"] == template.__version__
    assert callable(template.rbbench_register)


def test_its_matrix_compares_it_with_the_greedy_cones(template):
    from rbbench.bench.matrix import load_matrix

    m = load_matrix(TEMPLATE / "matrix.toml", registry=_registry(template, with_builtins=True))
    duals = {c.components["dual"] for c in m.cases}
    assert duals == {"random-cone", "cpg", "mcpg"}
    assert {c.status for c in m.cases} == {"run"} and len(m.cases) == 6

"""The contract suite without pytest (:mod:`rbbench.testing.contract_runner`): one result per
component of the selected package, a broken component named with the property it breaks."""

from __future__ import annotations

import sys
import types

import numpy as np
import pytest

from rbbench.hookspecs import hookimpl
from rbbench.rb.compressors import CPG
from rbbench.registry import ComponentSpec, discover
from rbbench.testing import ContractResult, run_contracts
from rbbench.testing.contract_runner import format_result, select_specs, summary_line

CONE = {"cone": True, "nested": True}


class _Rescaled(CPG):
    """CPG whose last e_proj is halved: the contract recomputes it and must disagree."""

    name = "rescaled"

    def compress(self, LAM, W, **kw):
        basis = super().compress(LAM, W, **kw)
        basis.e_proj[-1] *= 0.5
        return basis


@pytest.fixture
def registry(monkeypatch):
    mod = types.ModuleType("rbbench_runner_demo")
    mod.Good, mod.Rescaled = CPG, _Rescaled

    @hookimpl
    def rbbench_register(registry):
        add = registry.add
        add(ComponentSpec(name="good", role="dual", target="rbbench_runner_demo:Good",
                          capabilities=CONE, description="CPG under another name"))
        add(ComponentSpec(name="rescaled", role="dual", target="rbbench_runner_demo:Rescaled",
                          capabilities=CONE, description="reports a wrong e_proj"))
        add(ComponentSpec(name="absent", role="dual", target="rbbench_runner_demo:Good",
                          modules=("surely_missing_mod_xyz",), extras=("absent",),
                          capabilities=CONE, description="needs a module not installed"))

    mod.rbbench_register = rbbench_register
    monkeypatch.setitem(sys.modules, "rbbench_runner_demo", mod)
    return discover(extra_plugins=(mod,))


def test_one_result_per_component_of_the_package(registry):
    seen: list[ContractResult] = []
    results = run_contracts(registry, package="rbbench_runner_demo", on_result=seen.append)
    assert seen == results
    by_name = {r.name: r for r in results}
    assert sorted(by_name) == ["absent", "good", "rescaled"]  # no built-in component
    assert by_name["good"].status == "passed" and by_name["good"].message == ""
    assert by_name["rescaled"].status == "failed"
    assert "e_proj[-1]" in by_name["rescaled"].message
    assert "does not match the recomputed projection error" in by_name["rescaled"].message
    assert by_name["absent"].status == "skipped"
    assert "surely_missing_mod_xyz" in by_name["absent"].message
    assert summary_line(results) == "contracts: 1 passed, 1 failed, 1 skipped"
    line = format_result(by_name["rescaled"])
    assert line.startswith("FAILED  dual") and "\n        dual compressor" in line


def test_package_names_compare_as_pip_does(registry):
    names = {s.name for s in select_specs(registry, "RBBENCH-runner.demo")}
    assert names == {"absent", "good", "rescaled"}
    with pytest.raises(ValueError, match="no registered component with role 'hyper' comes "
                       "from it; packages with components: rbbench$"):
        select_specs(registry, "rbbench_runner_demo", "hyper")


def test_bad_selections_name_the_option_and_the_valid_values(registry):
    with pytest.raises(ValueError, match="--package 'nope'.*packages with components: .*"
                       "rbbench_runner_demo"):
        select_specs(registry, "nope")
    with pytest.raises(ValueError, match="--role 'duel': valid roles: backend, .*dual"):
        select_specs(registry, None, "duel")


def test_an_exception_is_a_failure_saying_where(registry, monkeypatch):
    def boom(self, LAM, W, **kw):
        raise np.linalg.LinAlgError("singular Gram matrix")

    monkeypatch.setattr(_Rescaled, "compress", boom)
    (res,) = [r for r in run_contracts(registry, package="rbbench_runner_demo", role="dual")
              if r.name == "rescaled"]
    assert res.status == "failed"
    assert res.message.startswith("raised LinAlgError: singular Gram matrix (at ")
    assert "in boom)" in res.message


def test_a_plugin_that_fails_to_load_is_a_failed_line(registry):
    registry.broken.append(("demo", "rbbench_runner_demo", "entry point failed: ImportError"))
    results = run_contracts(registry, package="rbbench_runner_demo")
    assert (results[0].role, results[0].name, results[0].status) == ("?", "demo", "failed")
    assert "ImportError" in results[0].message

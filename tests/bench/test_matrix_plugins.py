"""A run matrix takes the components of another package by their registered names: a
hyper-reducer of a plugin is a valid ``[components] hyper`` value, pruned by what the
formulations declare and carry out (no built-in table decides)."""

from __future__ import annotations

import sys
import types

import pytest

from rbbench.bench.matrix import load_matrix
from rbbench.bench.matrix_checks import MatrixError
from rbbench.hookspecs import hookimpl
from rbbench.registry import ComponentSpec, discover


class _OutsideHyper:
    name, formulations = "outside-hyper", ("mixed",)

    def check(self, formulation):
        if formulation not in self.formulations:
            raise ValueError(f"hyper {self.name!r} does not apply to {formulation!r}")


@pytest.fixture
def registry(monkeypatch):
    mod = types.ModuleType("rbbench_outside_hyper")
    mod._OutsideHyper = _OutsideHyper

    @hookimpl
    def rbbench_register(registry):
        registry.add(ComponentSpec(name="outside-hyper", role="hyper",
                                   target="rbbench_outside_hyper:_OutsideHyper",
                                   capabilities={"formulations": ("mixed",)},
                                   description="a hyper-reducer no formulation carries out"))

    mod.rbbench_register = rbbench_register
    monkeypatch.setitem(sys.modules, "rbbench_outside_hyper", mod)
    return discover(extra_plugins=(mod,))


def _matrix(tmp_path, hyper: str):
    path = tmp_path / "mx.toml"
    path.write_text('[matrix]\nname = "mx"\nscenes = ["membrane_obstacle"]\n[components]\n'
                    f'dual = ["cpg"]\nstabilizer = ["none"]\nhyper = ["{hyper}", "none"]\n'
                    '[sizes]\nN = [3]\nR = [3]\n')
    return path


def test_a_plugin_hyper_is_a_valid_matrix_value(tmp_path, registry):
    m = load_matrix(_matrix(tmp_path, "outside-hyper"), registry=registry)
    by_hyper = {c.components["hyper"]: c for c in m.cases}
    assert by_hyper["none"].status == "run"
    # declared for mixed, but the mixed steps do not carry it out: a skip row saying so
    plugin = by_hyper["outside-hyper"]
    assert plugin.status == "skip"
    assert "carries out 'affine', 'eim', 'none' or 'auto'" in plugin.reason


def test_an_unknown_hyper_lists_the_registered_ones(tmp_path, registry):
    with pytest.raises(MatrixError, match=r"\[components\] hyper: 'nope'; valid: auto, "
                       r"affine, .*outside-hyper"):
        load_matrix(_matrix(tmp_path, "nope"), registry=registry)


@pytest.mark.parametrize("value, ok", [(0.0, True), (1e-6, True), (-1e-3, False),
                                       (float("nan"), False), (True, False)])
def test_matrix_tolerances_as_the_reduction_takes_them(value, ok):
    """A run matrix takes a tolerance of 0 (as many terms as the data allow), as
    ``ReduceConfig`` does, and refuses a negative or non-finite one, naming the field."""
    from rbbench.bench.matrix_checks import MatrixError, check_reduce_value

    if ok:
        check_reduce_value("tol_pod", value, "m.toml [reduce]")
    else:
        with pytest.raises(MatrixError, match=r"m\.toml \[reduce\]: tol_pod = .*>= 0"):
            check_reduce_value("tol_pod", value, "m.toml [reduce]")

"""The shared validation and the runner reach a reduced model only through the model interface
(``parameters``, ``solve``, ``reconstruct``): a spy around every model built offline records
who touches which attribute."""

from __future__ import annotations

import sys

import pytest

import rbbench
import rbbench.rb.offline as skeleton

PROTOCOL = {"parameters", "solve", "reconstruct"}
#: the modules that may use the model interface only (the formulation's own stage may do more)
SHARED = ("rbbench.rb.validation", "rbbench.bench", "rbbench.api")

MATRIX = """
[matrix]
name = "spy"
scenes = ["membrane_obstacle", "thermal_block"]

[components]
formulation = ["mixed", "linear"]
dual = ["cpg"]
stabilizer = ["none"]
hyper = ["auto", "none"]

[sizes]
pairs = [[3, 3]]

[reduce]
n_train = 5
n_valid = 2
online_repeats = 2

[scene_overrides]
membrane_obstacle = ["discretization.n_cells=6"]
thermal_block = ["discretization.n_cells=6"]
"""


class Spy:
    """Forwards every attribute to ``model`` and logs ``(name, calling module)``."""

    def __init__(self, model):
        self.__dict__["_model"] = model
        self.__dict__["log"] = []

    def __getattr__(self, name):
        self.log.append((name, sys._getframe(1).f_globals.get("__name__", "?")))
        return getattr(self._model, name)


@pytest.fixture
def spies(monkeypatch):
    found = []
    real = skeleton._build  # the shared skeleton behind reduce() and offline()

    def spied(*args, **kwargs):
        off = real(*args, **kwargs)
        off.stage.model = Spy(off.stage.model)
        found.append(off.stage.model)
        return off

    monkeypatch.setattr(skeleton, "_build", spied)
    import rbbench.rb.linear.offline as linear

    real_linear = linear.LinearStage.__init__

    def linear_init(self, ctx):
        real_linear(self, ctx)
        self.model = Spy(self.model)
        found.append(self.model)

    monkeypatch.setattr(linear.LinearStage, "__init__", linear_init)
    return found


def _shared_calls(spy):
    return {name for name, mod in spy.log if mod.startswith(SHARED)}


def test_the_runner_and_validation_call_only_the_model_interface(spies, tmp_path):
    (tmp_path / "m.toml").write_text(MATRIX)
    run = rbbench.run(tmp_path / "m.toml", out=tmp_path / "out", executor="serial",
                      cache_dir=tmp_path / "cache", progress=False)
    df = rbbench.load_results(run.out_dir)
    ok = df[df["status"] == "ok"]
    # membrane: affine and plain; thermal block (linear, hyper auto); the other combinations
    # are skip rows (a formulation or hyper-reducer that does not apply)
    assert set(df["status"]) == {"ok", "skip"} and len(ok) == len(spies) == 3, df
    assert set(ok["formulation"]) == {"mixed", "linear"}
    for spy in spies:
        used = _shared_calls(spy)
        assert {"solve", "reconstruct"} <= used, spy.log
        assert used <= PROTOCOL, sorted(used - PROTOCOL)


def test_the_python_api_reduce_calls_only_the_model_interface(spies, tmp_path):
    rbbench.reduce("membrane_obstacle", N=3, R=3, n_train=5, n_valid=2, dual="cpg",
                   stabilizer="supremizer", hyper="none", online_repeats=1,
                   cache_dir=str(tmp_path))
    (spy,) = spies
    assert {"solve", "reconstruct"} <= _shared_calls(spy) <= PROTOCOL

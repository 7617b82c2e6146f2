"""The shared validation and the runner reach a reduced model only through the model interface
(``parameters``, ``solve``, ``reconstruct``): a spy around every model built offline records
who touches which attribute."""

from __future__ import annotations

import sys
from types import SimpleNamespace

import numpy as np
import pytest

import rbbench
import rbbench.rb.offline as skeleton

PROTOCOL = {"parameters", "solve", "reconstruct"}
#: the modules that may use the model interface only (the formulation's own stage may do more)
SHARED = ("rbbench.rb.validation", "rbbench.rb.online", "rbbench.bench", "rbbench.api")

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


def test_every_reduction_row_has_the_hf_floor_beside_the_timed_hf(tmp_path, monkeypatch):
    """The floor is timed at every validation mu on that mu's own HF problem; the summary
    holds its median and both speed-ups, each defined."""
    import rbbench.hf.model as hf_model

    seen = []
    real = hf_model.solve_floor

    def spy(problem, linear_solver=None):
        seen.append((problem, linear_solver))
        return real(problem, linear_solver)

    monkeypatch.setattr(hf_model, "solve_floor", spy)
    scene = rbbench.load_scene("membrane_obstacle", ["discretization.n_cells=6"])
    res = rbbench.reduce(scene, N=3, R=3, n_train=5, n_valid=3, dual="cpg",
                         stabilizer="none", hyper="affine", online_repeats=2,
                         cache_dir=str(tmp_path))
    s = res.summary()
    assert len(seen) == len(res.t_floor) == 3
    # each floor solved that mu's stiffness (the problems differ: mu moves the obstacle)
    from rbbench.hf.condensation.pardiso import available

    expected = "pardiso" if available() else None  # the membrane backend gives no solver
    assert len({id(p) for p, _ in seen}) == 3 and all(ls == expected for _, ls in seen)
    assert all(t > 0 for t in res.t_floor)
    assert s["floor_s"] == float(np.median(res.t_floor))
    assert s["speedup_floor"] == pytest.approx(s["floor_s"] / s["t_online_median_s"])
    assert s["speedup"] / s["speedup_floor"] == pytest.approx(s["t_hf_median_s"]
                                                              / s["floor_s"])
    assert s["floor_solver"].startswith("PARDISO" if expected else "SuperLU")
    for key in ("floor_s", "floor_solver", "speedup_floor", "speedup"):
        assert key in s["definitions"]
    assert "timed HF solve" in s["definitions"]["speedup"]


def test_the_floor_uses_the_default_solves_direct_solver(monkeypatch):
    """The backend's solver when the problem gives one, PARDISO only when it is installed
    and the backend gives none (the ``auto`` rule of the condensation), else SuperLU."""
    import rbbench.hf.condensation.pardiso as pardiso
    import rbbench.hf.model as hf_model

    calls = []
    monkeypatch.setattr(hf_model, "solve_floor", lambda p, ls=None: calls.append(ls) or {})
    own = SimpleNamespace(factorize=lambda A: None)
    none = SimpleNamespace(factorize=None)
    for installed in (False, True):
        monkeypatch.setattr(pardiso, "available", lambda v=installed: v)
        hf_model.default_floor(own)
        hf_model.default_floor(none)
    assert calls == [None, None, None, "pardiso"]


def test_no_floor_for_a_problem_that_is_not_one_stiffness_solve():
    """A parabolic scene's space-time view (no stiffness of one HF solve) has no floor."""
    from rbbench.rb.validation import _floor_summary, hf_floor

    assert hf_floor(SimpleNamespace(A=None, F=None)) is None
    assert _floor_summary([], None, 1e-5) == {"floor_s": None, "floor_solver": None,
                                              "speedup_floor": None}

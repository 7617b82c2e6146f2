"""The RB pipeline end to end on the cheap membrane scene (seconds)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rbbench.cli import main
from rbbench.rb.config import make_config
from rbbench.rb.offline import reduce
from rbbench.scene.loading import load_scene

FAST = ["discretization.n_cells=8"]


@pytest.fixture(scope="module")
def scene():
    return load_scene("membrane_obstacle", FAST)


@pytest.mark.parametrize("dual,stab", [("mcpg", "pga"), ("cpg", "none"), ("eng", "supremizer")])
def test_pipeline_runs_and_is_accurate(scene, tmp_path_factory, dual, stab):
    cache = tmp_path_factory.getbasetemp() / "cache"
    r = reduce(scene, make_config(dual=dual, stabilizer=stab, n_jobs=1, n_valid=6,
                                   cache_dir=str(cache), online_repeats=3))
    s = r.summary()
    assert s["n_valid"] == 6 and len(r.err_u) == 6
    assert s["err_u_max"] < 0.1  # 25 snapshots, 2 parameters, 49 dofs of contact
    # cone methods keep the multiplier non-negative, so penetration stays small
    assert s["penetration_max"] < 0.05
    # the online supremizer space contains V_N: beta_on >= beta_dec (a property)
    for on, dec in zip(r.beta["on"], r.beta["dec"], strict=True):
        assert on["value"] >= dec["value"] * (1 - 1e-9)
        assert on["span"] <= on["value"] * (1 + 1e-9)
    # the reduced multiplier lies in the cone: it cannot beat the cone's best approximation
    best = s["histories"]["lam_best_valid"]
    assert all(e >= b * (1 - 1e-9) for e, b in zip(r.err_lam, best, strict=True))
    if stab == "pga":
        sig = s["histories"]["sigma_max"]
        assert all(a >= b - 1e-12 for a, b in zip(sig, sig[1:], strict=False))
        assert s["beta_off_min"] > 0


def test_cones_beat_pod_of_multipliers(scene, tmp_path_factory):
    """Plain POD of lam (not a cone) loses positivity: larger errors than mCPG."""
    cache = tmp_path_factory.getbasetemp() / "cache"
    kw = dict(stabilizer="none", n_jobs=1, n_valid=6, cache_dir=str(cache), online_repeats=1)
    e_pod = reduce(scene, make_config(dual="pod", **kw)).summary()["err_u_max"]
    e_cone = reduce(scene, make_config(dual="mcpg", **kw)).summary()["err_u_max"]
    assert e_cone < e_pod


def test_reduce_cli_writes_result_json(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the snapshot cache goes to ./.rbbench_cache
    out = tmp_path / "red"
    code = main(["reduce", "membrane_obstacle", "--set", FAST[0], "--n-valid", "4",
                 "--jobs", "1", "--out", str(out), "--quiet"])
    assert code == 0
    res = json.loads((out / "result.json").read_text())
    for key in ["N", "R", "err_u_max", "err_u_mean", "err_lam_max", "err_lam_mean",
                "penetration_max", "beta_hf_min", "beta_dec_min", "beta_on_min",
                "beta_off_min", "beta_kind", "t_offline_s", "t_online_median_s",
                "t_hf_median_s", "speedup", "histories", "definitions"]:
        assert key in res, key
    assert np.isfinite(res["err_u_max"])
    assert "e_proj" in res["histories"] and "sigma_max" in res["histories"]


def test_reduce_cli_rejects_unknown_compressor(capsys):
    with pytest.raises(SystemExit) as exc:  # argparse choices: the registered names
        main(["reduce", "membrane_obstacle", "--dual", "nope", "--quiet"])
    err = capsys.readouterr().err
    assert exc.value.code == 2 and "argument --dual: invalid choice:" in err
    assert "nope" in err and "cpg" in err and "mcpg" in err


# ---------------------------------------------------------------------------
# components of another package: taken by their declarations, no internal table
# ---------------------------------------------------------------------------
class _PluginHyper:
    """A hyper-reducer declared for the mixed formulation, whose steps do not carry it out."""

    name, formulations = "outside-hyper", ("mixed",)

    def check(self, formulation):
        if formulation not in self.formulations:
            raise ValueError(f"hyper {self.name!r} does not apply to {formulation!r}")


class _PluginPGA:
    """PGA under another name: an offline stabiliser declaring the 'training set' guarantee."""

    name, online = "outside-pga", False

    def __init__(self):
        from rbbench.rb.compressors import PGAStabilizer

        self._pga = PGAStabilizer()

    def offline(self, Z, Vg, X, x_solve, B_train, delta=None):
        self.delta_seen = delta
        return self._pga.offline(Z, Vg, X, x_solve, B_train, delta)

    def online_basis(self, Z_off, Vg, X, x_solve, B):
        return Z_off


@pytest.fixture
def outside_registry(monkeypatch):
    """The installed components plus a hyper-reducer and two stabilisers of a module that is
    not rbbench's (an online one, under the supremizer's target)."""
    import sys
    import types

    from rbbench.hookspecs import hookimpl
    from rbbench.registry import ComponentSpec, discover

    mod = types.ModuleType("rbbench_outside_roles")
    mod._PluginHyper, mod._PluginPGA = _PluginHyper, _PluginPGA

    @hookimpl
    def rbbench_register(registry):
        registry.add(ComponentSpec(name="outside-hyper", role="hyper",
                                   target="rbbench_outside_roles:_PluginHyper",
                                   capabilities={"formulations": ("mixed",)}, description="d"))
        registry.add(ComponentSpec(name="outside-pga", role="stabilizer",
                                   target="rbbench_outside_roles:_PluginPGA",
                                   capabilities={"online_hf": False, "inf_sup": "training set"},
                                   description="d"))
        registry.add(ComponentSpec(name="outside-online", role="stabilizer",
                                   target="rbbench.rb.compressors:SupremizerStabilizer",
                                   capabilities={"online_hf": True, "inf_sup": "every mu"},
                                   description="d"))

    mod.rbbench_register = rbbench_register
    monkeypatch.setitem(sys.modules, "rbbench_outside_roles", mod)
    return discover(extra_plugins=(mod,))


def test_a_plugin_hyper_name_is_valid_and_the_formulation_says_what_it_carries_out(
        scene, outside_registry):
    from rbbench.rb.offline import prepare_config
    from rbbench.registry import UnknownComponentError
    from rbbench.scene.loading import SceneError

    cfg = make_config(hyper="outside-hyper", dual="cpg", stabilizer="none")  # no table refuses
    with pytest.raises(SceneError, match="hyper 'outside-hyper': the mixed formulation .* "
                       "carries out 'affine', 'eim', 'none' or 'auto'"):
        prepare_config(scene, cfg, outside_registry)
    with pytest.raises(UnknownComponentError, match="valid hypers: auto, .*outside-hyper"):
        prepare_config(scene, make_config(hyper="nope"), outside_registry)


def test_a_plugin_stabilizer_is_taken_by_its_capabilities(scene, tmp_path_factory,
                                                           outside_registry):
    from rbbench.rb.offline import prepare_config
    from rbbench.scene.loading import SceneError

    with pytest.raises(SceneError, match="'outside-online' builds its space online"):
        prepare_config(scene, make_config(stabilizer="outside-online", hyper="affine"),
                       outside_registry)
    cache = tmp_path_factory.getbasetemp() / "cache"
    kw = dict(dual="mcpg", n_jobs=1, n_valid=3, cache_dir=str(cache), online_repeats=1)
    ref = reduce(scene, make_config(stabilizer="pga", **kw)).summary()
    got = reduce(scene, make_config(stabilizer="outside-pga", **kw),
                 registry=outside_registry).summary()
    # given the same delta as PGA (the 'training set' guarantee is stated in delta), it
    # builds the same enrichment, counted in the online primal size
    assert got["histories"]["pga_delta"] == ref["histories"]["pga_delta"]
    assert got["K_pga"] == ref["K_pga"] > 0
    assert got["dim_primal_online"] == got["N"] + got["K_pga"]

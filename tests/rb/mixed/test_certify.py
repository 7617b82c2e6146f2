"""The bound's rows in a reduction: online where the model is affine, HF-evaluated otherwise,
above the true error at every validation parameter."""

from __future__ import annotations

import numpy as np
import pytest

import rbbench


@pytest.mark.parametrize("stabilizer, certified", [("pga", "rigorous"),
                                                   ("supremizer", "rigorous (HF-evaluated)")])
def test_rows_of_the_bound(tmp_path, stabilizer, certified):
    scene = rbbench.load_scene("membrane_obstacle", ["discretization.n_cells=8"])
    res = rbbench.reduce(scene, N=4, R=4, n_train=9, n_valid=4, online_repeats=2,
                         stabilizer=stabilizer, cache_dir=str(tmp_path))
    s = res.summary()
    assert s["certified"] == certified
    bound, err = np.array(s["per_mu"]["err_bound_u"]), np.array(s["per_mu"]["err_u"])
    assert bound.shape == err.shape == (4,)
    assert np.all(bound >= err)  # the same norm and normalisation
    eff = np.array(s["per_mu"]["effectivity"])
    assert s["effectivity_min"] == pytest.approx(eff.min()) and s["effectivity_min"] >= 1
    assert s["effectivity_median"] == pytest.approx(np.median(eff))
    assert s["err_bound_u_max"] == pytest.approx(bound.max())
    assert np.all(np.array(s["per_mu"]["err_bound_lam"]) >=
                  np.array(s["per_mu"]["err_lam_nat"]))
    assert "err_bound_u" in s["definitions"] and "certified" in s["definitions"]
    if certified == "rigorous":
        # side by side: both medians from one interleaved loop, the ratio their quotient
        assert s["t_bound_median_s"] > 0 and s["t_bound_solve_median_s"] > 0
        assert s["t_bound_ratio"] == pytest.approx(s["t_bound_median_s"]
                                                   / s["t_bound_solve_median_s"])
        assert "side by side" in s["definitions"]["t_bound"]
        b = res.model.error_bound(res.model.solve(res.valid_mus[0]))
        assert b.delta_u > 0
    else:
        assert s["t_bound_median_s"] is None and s["t_bound_solve_median_s"] is None
        assert s["t_bound_ratio"] is None


def test_a_parameter_without_natural_norm_gets_nan_rows(tmp_path, monkeypatch):
    from rbbench.rb.mixed import certify

    def not_injective(*args, **kwargs):
        raise ValueError("B X^-1 B^T is not positive definite: B^T is not injective")

    monkeypatch.setattr(certify, "hf_bound", not_injective)
    scene = rbbench.load_scene("membrane_obstacle", ["discretization.n_cells=8"])
    res = rbbench.reduce(scene, N=4, R=4, n_train=9, n_valid=3, online_repeats=1,
                         stabilizer="supremizer", cache_dir=str(tmp_path))
    s = res.summary()
    assert s["certified"] == "rigorous (HF-evaluated)"
    assert len(s["per_mu"]["err_bound_u"]) == len(s["per_mu"]["err_u"]) == 3
    assert all(np.isnan(v) for v in s["per_mu"]["err_bound_u"])
    assert len(s["histories"]["bound"]["no_bound_at"]) == 3
    assert s["effectivity_min"] is None


def test_bound_hf_skips_the_online_bound(tmp_path):
    scene = rbbench.load_scene("membrane_obstacle", ["discretization.n_cells=8"])
    res = rbbench.reduce(scene, N=4, R=4, n_train=9, n_valid=3, online_repeats=1,
                         bound="hf", cache_dir=str(tmp_path))
    s = res.summary()
    assert s["certified"] == "rigorous (HF-evaluated)"
    assert s["effectivity_min"] >= 1 and s["t_bound_median_s"] is None
    with pytest.raises(ValueError, match="bound.*valid: auto, online, hf"):
        rbbench.reduce(scene, N=4, R=4, n_train=9, n_valid=3, bound="certified",
                       cache_dir=str(tmp_path))


@pytest.mark.parametrize("value, rule", [(0, r"\[1, "), (-3, r"\[1, "), (2.5, r"\[1, "),
                                         ("60", r"\[1, "), (True, r"\[1, ")])
def test_bound_pod_max_is_checked_before_any_work(tmp_path, value, rule):
    """The cap on the bound's POD modes: refused, naming the option and the valid values,
    before any HF solve (the cache folder stays empty)."""
    scene = rbbench.load_scene("membrane_obstacle", ["discretization.n_cells=8"])
    with pytest.raises(ValueError, match="bound_pod_max.*" + rule):
        rbbench.reduce(scene, N=4, R=4, n_train=9, n_valid=3, bound="online",
                       bound_pod_max=value, cache_dir=str(tmp_path))
    assert not any(tmp_path.iterdir())


def test_bound_pod_max_flag(capsys):
    from rbbench.cli import main

    assert main(["reduce", "hertz_halfdisks", "--bound", "online", "--bound-pod-max", "0"]) == 2
    assert "--bound-pod-max 0: must be an integer >= 1" in capsys.readouterr().err

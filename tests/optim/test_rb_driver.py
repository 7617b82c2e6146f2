"""Trust-region reduced-basis optimisation of shape_coulomb on a coarse
scene: HF-verified monotone decrease on accepted steps, feasibility of the raw design,
the reported HF objective against an independent HF evaluation, option validation."""
import numpy as np
import pytest

from rbbench.optim import rb_driver
from rbbench.optim.bundle import BundleOptions
from rbbench.optim.rb_driver import RBOptions, optimize_rb
from rbbench.optim.shape_adjoint import evaluate
from rbbench.optim.shape_reduced import hf_snapshots
from rbbench.optim.shape_scene import load_shape_scene

COARSE = {"geometry.contact_nodes": 21, "geometry.ny": 8}


@pytest.fixture(scope="module")
def run():
    sc = load_shape_scene(overrides=COARSE)
    rows = []
    opts = RBOptions(max_outer=4, inner=BundleOptions(max_iter=40, max_evals=80))
    res = optimize_rb(sc, sc.initial_design(), opts, callback=rows.append)
    return sc, res, rows


def test_accepted_steps_decrease_the_hf_objective(run):
    sc, res, rows = run
    J0 = evaluate(sc, sc.initial_design()).J
    accepted = [r["J"] for r in rows if r["kind"] == "accepted"]
    assert accepted, rows
    assert np.all(np.diff([J0, *accepted]) < 0)
    assert rows == res.history
    assert res.J_hf < 0.5 * J0


def test_optimum_feasible_and_hf_verified(run):
    sc, res, _ = run
    assert max(sc.residuals(res.x).values()) <= 1e-8
    hf = evaluate(sc, res.x)
    assert abs(hf.J - res.J_hf) <= 1e-10 * hf.J
    assert abs(res.f - res.J_hf) <= 1e-6 * res.J_hf   # the model is exact at its centre
    assert res.hf_solves == 1 + sum(r["kind"] in ("accepted", "rejected") for r in res.history)
    assert res.rb_solves > res.hf_solves and res.basis_size > 0 and res.wall_s > 0


def test_options_and_infeasible_start():
    with pytest.raises(ValueError, match="delta0"):
        RBOptions(delta0=0.0)
    with pytest.raises(ValueError, match="eta_accept"):
        RBOptions(eta_accept=0.9, eta_expand=0.5)
    with pytest.raises(ValueError, match="centre_update.*'fast'.*incremental, rebuild"):
        RBOptions(centre_update="fast")
    sc = load_shape_scene(overrides=COARSE)
    bad = sc.initial_design() + 1.0
    with pytest.raises(ValueError, match="alpha0 is infeasible"):
        optimize_rb(sc, bad)


def test_history_file_and_method_check(tmp_path, run):
    from rbbench.optim.rb_driver import RBHistory, optimize_rb_run
    from rbbench.optim.run import OptimizeConfig

    sc, res, rows = run
    assert rows[0]["kind"] == "start" and rows[0]["J"] == evaluate(sc, sc.initial_design()).J
    hist = RBHistory(tmp_path / "history.csv", quiet=True)
    for row in rows:
        hist(row)
    lines = (tmp_path / "history.csv").read_text().splitlines()
    assert lines[0].split(",") == list(RBHistory.FIELDS) and len(lines) == len(rows) + 1
    assert [r["serious"] for r in hist.rows] == [r["kind"] in ("start", "accepted") for r in rows]
    with pytest.raises(ValueError, match="bundle method only"):
        optimize_rb_run(sc, OptimizeConfig(driver="rb", method="slsqp"), tmp_path)


def test_poor_model_is_rejected_and_the_region_shrinks(monkeypatch):
    """With only the HF state and adjoint as the interior basis, replaced at each centre
    (a poor model away from the centre) candidates get rejected: Delta shrinks, J never
    increases."""
    monkeypatch.setattr(rb_driver, "interior_space", hf_snapshots)
    sc = load_shape_scene(overrides=COARSE)
    opts = RBOptions(max_outer=6, inner=BundleOptions(max_iter=20, max_evals=40),
                     centre_update="rebuild")
    res = optimize_rb(sc, sc.initial_design(), opts)
    rows = res.history
    rejected = [i for i, r in enumerate(rows) if r["kind"] == "rejected"]
    assert rejected, [r["kind"] for r in rows]
    for i in rejected:
        assert rows[i]["delta"] < rows[i - 1]["delta"]
        assert rows[i]["J"] == rows[i - 1]["J"] and rows[i]["J_trial"] > rows[i]["J"] * (
            1 - 0.1 * rows[i]["pred"] / rows[i]["J"])
    assert np.all(np.diff([r["J"] for r in rows]) <= 0)
    assert max(sc.residuals(res.x).values()) <= 1e-8

"""`rbbench optimize`: files, summary fields, feasibility at the optimum, bad input (exit 2),
a state solve failing mid-run (history kept, exit 1)."""
import csv
import json

import numpy as np
import pytest

from rbbench.cli import main
from rbbench.optim import run as run_mod
from rbbench.optim.shape_state import StateSolveError

TINY = ["--set", "geometry.contact_nodes=11", "--set", "geometry.ny=4"]


def test_hf_bundle_run_writes_everything(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["optimize", *TINY, "--max-iter", "4", "--out", str(out)]) == 0
    s = json.loads((out / "summary.json").read_text())
    for key in ("J0", "J_opt", "ratio", "iterations", "hf_solves", "wall_s",
                "constraint_residuals_opt", "stop_reason", "published"):
        assert key in s
    assert s["J_opt"] <= s["J0"]
    assert s["constraint_residual_max_opt"] <= 1e-8
    assert s["J_opt"] >= s["J_uniform_bound"]
    assert s["strategy"] == "equalise" and s["J_over_bound"] == s["J_opt"] / s["J_uniform_bound"]
    assert s["constraints_satisfied_opt"] and s["constraint_worst_opt"] in s[
        "constraint_residuals_opt"]
    cost = s["strategy_cost"]
    assert cost["hf_solves_total"] == cost["phase_state_solves"] + cost["local_hf_solves"]
    assert cost["hf_solves_total"] == s["hf_solves"] and cost["outer_stages"] >= 1
    rows = list(csv.DictReader(open(out / "history.csv")))
    assert len(rows) == s["evaluations"] and rows[0]["kind"] == "start"
    assert int(rows[-1]["hf_solves"]) == s["hf_solves"]
    assert sum(r["kind"].startswith("equalise") for r in rows) + cost["outer_stages"] == cost[
        "phase_state_solves"]                       # one row per phase solve
    its = [int(r["iteration"]) for r in rows]
    assert its == sorted(its)                       # continued across the stages
    for png in ("designs.png", "pressure.png", "history.png"):
        assert (out / png).stat().st_size > 1000
    assert "it " in capsys.readouterr().out                     # progress lines


@pytest.mark.parametrize("args, key", [
    (["--set", "design.C2=2.5"], "design.C2"),
    (["--set", "geometry.contact_nodes=1"], "geometry.contact_nodes"),
    (["--set", "design.initial_height=0.9"], "design.initial"),
    (["--max-iter", "0"], "--max-iter"),
    (["--set", "nodot=1"], "SECTION.KEY"),
])
def test_bad_input_exits_2_naming_the_key(tmp_path, capsys, args, key):
    assert main(["optimize", *TINY, *args, "--out", str(tmp_path / "x")]) == 2
    assert key in capsys.readouterr().err


def test_failing_state_solve_keeps_the_history(tmp_path, monkeypatch):
    real = run_mod.evaluate
    calls = {"n": 0}

    def flaky(sc, alpha, y0=None):
        calls["n"] += 1
        if calls["n"] == 4:
            raise StateSolveError("semismooth Newton: no convergence (injected)")
        return real(sc, alpha, y0=y0)

    monkeypatch.setattr(run_mod, "evaluate", flaky)
    out = tmp_path / "f"
    assert main(["optimize", *TINY, "--max-iter", "20", "--out", str(out), "--quiet",
                 "--strategy", "none"]) == 1
    s = json.loads((out / "summary.json").read_text())
    assert s["stop_reason"].startswith("oracle failed") and "injected" in s["stop_reason"]
    rows = list(csv.DictReader(open(out / "history.csv")))
    assert len(rows) == 3
    assert np.isfinite(s["J_opt"])


def test_failing_first_state_solve_of_the_strategy(tmp_path, monkeypatch):
    """The state at the initial design fails: exit 1, the reason in summary.json."""
    def failing(sc, alpha, y0=None):
        raise StateSolveError("semismooth Newton: no convergence (injected)")

    monkeypatch.setattr(run_mod, "solve_state", failing)
    out = tmp_path / "f"
    assert main(["optimize", *TINY, "--out", str(out), "--quiet"]) == 1
    s = json.loads((out / "summary.json").read_text())
    assert s["stop_reason"].startswith("oracle failed") and "injected" in s["stop_reason"]
    assert s["strategy_cost"]["outer_stages"] == 0


def test_strategy_none_is_the_plain_bundle_method(tmp_path):
    """``--strategy none`` runs the bundle method from the initial design: the same J
    sequence as bundle_trust called directly; its summary says so."""
    from rbbench.optim.bundle import BundleOptions, Polyhedron, bundle_trust
    from rbbench.optim.run import HFOracle
    from rbbench.optim.shape_scene import load_shape_scene

    out = tmp_path / "n"
    assert main(["optimize", *TINY, "--strategy", "none", "--max-iter", "6", "--out",
                 str(out), "--quiet"]) == 0
    s = json.loads((out / "summary.json").read_text())
    assert s["strategy"] == "none" and s["config"]["strategy"] == "none"
    assert s["strategy_cost"]["phase_state_solves"] == 0
    sc = load_shape_scene(overrides={"geometry.contact_nodes": 11, "geometry.ny": 4})
    ref = bundle_trust(HFOracle(sc), sc.initial_design(), Polyhedron(**sc.admissible()),
                       BundleOptions(max_iter=6, max_evals=300))
    rows = list(csv.DictReader(open(out / "history.csv")))
    assert [float(r["f"]) for r in rows] == pytest.approx([h["f"] for h in ref.history],
                                                          rel=1e-9)
    assert s["J_opt"] == pytest.approx(ref.f, rel=1e-9)


def test_rb_driver_runs_with_the_strategy(tmp_path):
    """``--driver rb`` as the local solver of the strategy: HF-verified J, feasible, far
    below the plain RB run's J with the same budget, HF counts consistent."""
    from rbbench.optim.shape_adjoint import evaluate
    from rbbench.optim.shape_scene import load_shape_scene

    coarse = ["--set", "geometry.contact_nodes=21", "--set", "geometry.ny=8"]
    got = {}
    for strategy in ("equalise", "none"):
        out = tmp_path / strategy
        assert main(["optimize", *coarse, "--driver", "rb", "--strategy", strategy,
                     "--max-iter", "4", "--out", str(out), "--quiet"]) == 0
        got[strategy] = json.loads((out / "summary.json").read_text())
    s, plain = got["equalise"], got["none"]
    assert s["strategy"] == "equalise" and s["driver"] == "rb"
    sc = load_shape_scene(overrides={"geometry.contact_nodes": 21, "geometry.ny": 8})
    J = evaluate(sc, np.array(s["alpha_opt"])).J               # an independent HF solve
    assert J == pytest.approx(s["J_opt_hf"], rel=1e-8)
    assert J / sc.uniform_pressure_bound() <= 2 < plain["J_over_bound"]
    assert max(sc.residuals(np.array(s["alpha_opt"])).values()) <= 1e-8
    rows = list(csv.DictReader(open(tmp_path / "equalise" / "history.csv")))
    assert int(rows[-1]["hf_solves"]) == s["hf_solves"] == s["strategy_cost"]["hf_solves_total"]
    assert s["rb_solves"] >= 1


def test_cli_refuses_an_unknown_strategy(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["optimize", "--strategy", "gaps"])
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert "--strategy" in err and "'equalise', 'none'" in err     # argparse's choices


def test_shape_side_by_side_study(tmp_path, capsys):
    """``rbbench studies shape-side-by-side`` on two coarse body meshes: both drivers from the
    same J0 on each, the RB driver's J is its HF-verified value, both designs feasible on
    raw residuals, the dof count of each mesh, the printed tables and the JSON agree."""
    out = tmp_path / "s.json"
    assert main(["studies", "shape-side-by-side", "--set", "geometry.ny=8", "--set",
                 "geometry.contact_nodes=21", "--max-evals", "10", "--max-iter", "10",
                 "--ny", "4", "8", "--json", str(out)]) == 0
    res = json.loads(out.read_text())
    assert [r["ny"] for r in res["runs"]] == [4, 8]
    assert [r["dofs"] for r in res["runs"]] == [2 * 21 * 5, 2 * 21 * 9]
    text = capsys.readouterr().out
    for r in res["runs"]:
        assert r["hf_evaluations"] <= 10 and r["rb_hf_solves"] >= 1
        assert r["hf_J"] <= r["J0"] and r["rb_J_hf"] <= r["J0"]
        assert max(r["hf_residuals"].values()) <= 1e-8
        assert max(r["rb_residuals"].values()) <= 1e-8
        assert r["J_uniform_bound"] <= min(r["hf_J"], r["rb_J_hf"])  # sum lam = load
        assert f"{r['hf_J']:.6e}" in text and f"{r['wall_ratio']:.2f}" in text
    assert "uniform-pressure bound" in text
    assert res["runs"][0]["J0"] != res["runs"][1]["J0"]      # two different meshes ran


@pytest.mark.parametrize("eps", ["nan", "-1", "0", "inf"])
def test_optimize_refuses_a_bad_eps(eps, capsys, tmp_path):
    from rbbench.cli import main

    assert main(["optimize", "--eps", eps, "--out", str(tmp_path / "o")]) == 2
    assert "--eps" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_optimize_config_refuses_what_the_cli_refuses():
    from rbbench.optim.run import OptimizeConfig
    from rbbench.scene.parameters import SceneError

    for bad in ({"eps": float("nan")}, {"max_iter": 0}, {"driver": "fast"},
                {"metric": "newton"}, {"max_evals": 2.5}, {"strategy": "gaps"}):
        with pytest.raises(SceneError, match=next(iter(bad))):
            OptimizeConfig(**bad)


def test_an_optimize_rerun_never_mixes_files_and_holds_the_lock(tmp_path):
    """A rerun into a folder removes the previous run's files before its first row (a
    killed rerun leaves no older summary beside its history); a folder whose lock is held
    is refused; a link among the outputs is removed, not written through."""
    from rbbench.bench.guard import RunLock, RunLockedError
    from rbbench.optim.run import OUTPUTS, run_optimization
    from rbbench.optim.shape_scene import load_shape_scene

    out = tmp_path / "o"
    out.mkdir()
    outside = tmp_path / "outside.txt"
    outside.write_text("precious")
    (out / "summary.json").write_text("{\"old\": true}")
    (out / "designs.png").symlink_to(outside)
    sc = load_shape_scene("shape_coulomb", {"geometry.contact_nodes": 9, "geometry.ny": 4})
    cfg_stop = _tiny_config()
    with RunLock(out), pytest.raises(RunLockedError):
        run_optimization(sc, cfg_stop, out)
    seen = {}

    def spy(*a, **k):  # the first row: the old files are gone already
        seen["files"] = sorted(p.name for p in out.iterdir() if p.name in OUTPUTS)
        raise KeyboardInterrupt

    import rbbench.optim.run as run_mod

    orig = run_mod._run
    run_mod._run = spy
    try:
        with pytest.raises(KeyboardInterrupt):
            run_optimization(sc, cfg_stop, out)
    finally:
        run_mod._run = orig
    assert seen["files"] == []
    assert outside.read_text() == "precious"


def _tiny_config():
    from rbbench.optim.run import OptimizeConfig

    return OptimizeConfig(max_iter=1, max_evals=2, quiet=True)


def test_shape_strategy_study(tmp_path, capsys):
    """``rbbench studies shape-strategy`` on a coarse scene: both strategies from the same
    J0, the strategy's J far below the plain method's, feasible designs, repeats agree,
    the printed table and the JSON agree."""
    out = tmp_path / "s.json"
    assert main(["studies", "shape-strategy", "--set", "geometry.ny=8", "--set",
                 "geometry.contact_nodes=21", "--max-iter", "6", "--repeats", "2",
                 "--out-dir", str(tmp_path / "runs"), "--json", str(out)]) == 0
    r = json.loads(out.read_text())
    plain, eq = r["runs"]["hf/none"], r["runs"]["hf/equalise"]
    assert plain["J0"] == eq["J0"] and eq["J"] < plain["J"]
    assert eq["J_over_bound"] <= 2 and eq["phase_state_solves"] >= 2
    assert plain["phase_state_solves"] == 0
    for fig in (plain, eq):
        assert fig["constraint_residual_max_opt"] <= 1e-8 and fig["wall_s_median"] > 0
        assert fig["J"] == pytest.approx(fig["J_over_bound"] * r["J_uniform_bound"], rel=1e-12)
    s = json.loads((tmp_path / "runs" / "hf_equalise_1" / "summary.json").read_text())
    assert s["J_opt"] == eq["J"]                        # the second repeat, same figures
    text = capsys.readouterr().out
    assert f"{eq['J']:.6e}" in text and "strategy equalise" in text


def test_shape_strategy_study_refuses_bad_repeats(capsys):
    assert main(["studies", "shape-strategy", "--repeats", "0"]) == 2
    assert "--repeats" in capsys.readouterr().err


def test_failing_first_state_solve_of_the_strategy_rb_driver(tmp_path, monkeypatch):
    def failing(sc, alpha, y0=None):
        raise StateSolveError("semismooth Newton: no convergence (injected)")

    monkeypatch.setattr(run_mod, "solve_state", failing)
    out = tmp_path / "f"
    assert main(["optimize", *TINY, "--driver", "rb", "--out", str(out), "--quiet"]) == 1
    s = json.loads((out / "summary.json").read_text())
    assert s["stop_reason"].startswith("oracle failed") and s["rb_solves"] == 0

"""The asv suites in ``benchmarks/`` import, are well formed, and run on tiny settings.

The full suites run under asv (``asv check``, ``asv run --quick``: see the README); here
only what is cheap: every module imports, every ``time_`` / ``peakmem_`` / ``track_``
benchmark is callable with a docstring, parameters are consistent, and the tracked
accuracy of one tiny membrane reduction is a finite float.
"""

from __future__ import annotations

import importlib
import inspect
import math
import pkgutil
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PREFIXES = ("time_", "timeraw_", "peakmem_", "mem_", "track_")

#: benchmarks the suites promise (module, name)
EXPECTED = {
    ("bench_hf", "HFSolve.time_hf_solve"),
    ("bench_hf", "HFSolve.peakmem_hf_solve"),
    ("bench_hf", "HertzAccuracy.track_a_rel_error"),
    ("bench_hf", "NitscheAlartCurnier.track_e_ac"),
    ("bench_hf", "ContactPairing.time_pair"),
    ("bench_offline", "Snapshots.time_snapshots"),
    ("bench_offline", "PrimalPOD.time_primal_pod"),
    ("bench_offline", "DualCompressor.time_dual_compressor"),
    ("bench_offline", "PGA.time_pga"),
    ("bench_offline", "EIM.time_eim_build"),
    ("bench_offline", "EIM.time_eim_operators"),
    ("bench_online", "OnlineSolve.track_online_median_s"),
    ("bench_online", "OnlineSolve.peakmem_online_solve"),
    ("bench_bound", "OnlineBound.track_bound_median_s"),
    ("bench_bound", "OnlineBound.track_bound_over_solve"),
    ("bench_online3d", "OnlineSolve3D.track_online_median_s"),
    ("bench_online", "Accuracy.track_err_u_max"),
    ("bench_online", "Accuracy.track_err_lam_max"),
    ("bench_online", "Accuracy.track_neg_log10_beta_off"),
    ("bench_friction_online", "FrictionOnlineSolve.time_online_solve"),
    ("bench_shape_optimisation", "ShapeRBDriver.time_rb_driven_optimisation"),
    ("bench_shape_optimisation", "ShapeRBDriver.track_hf_solves"),
    ("bench_shape_optimisation", "ShapeRBDriver.track_J_over_bound"),
    ("bench_shape_optimisation", "ShapeReducedEvaluation.time_reduced_evaluation"),
}


@pytest.fixture(scope="module")
def bench_pkg():
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    try:
        yield importlib.import_module("benchmarks")
    finally:
        if sys.path and sys.path[0] == str(ROOT):
            sys.path.pop(0)


@pytest.fixture(scope="module")
def modules(bench_pkg):
    names = sorted(m.name for m in pkgutil.iter_modules(bench_pkg.__path__))
    assert names, "no module in benchmarks/"
    return {n: importlib.import_module(f"benchmarks.{n}") for n in names}


def _benchmarks(module):
    """(qualified name, function, owning class or None), as asv finds them."""
    out = []
    for name, obj in vars(module).items():
        if name.startswith("_"):
            continue
        if inspect.isclass(obj) and obj.__module__ == module.__name__:
            for attr, fn in inspect.getmembers(obj):
                if attr.startswith(PREFIXES):
                    out.append((f"{name}.{attr}", fn, obj))
        elif inspect.isfunction(obj) and name.startswith(PREFIXES):
            out.append((name, obj, None))
    return out


def test_every_module_imports_and_benchmarks_are_callable(modules):
    found = set()
    for mname, module in modules.items():
        assert module.__doc__, f"benchmarks/{mname}.py: no module docstring"
        for qual, fn, cls in _benchmarks(module):
            found.add((mname, qual))
            assert callable(fn), f"{mname}.{qual} is not callable"
            assert fn.__doc__ or (cls is not None and cls.__doc__), \
                f"{mname}.{qual}: no docstring saying what it measures"
            if qual.split(".")[-1].startswith("track_"):
                assert isinstance(getattr(fn, "unit", None), str), f"{mname}.{qual}: no unit"
            if cls is not None and hasattr(cls, "params"):
                params, names = cls.params, cls.param_names
                params = params if isinstance(params, (list, tuple)) and params and \
                    isinstance(params[0], (list, tuple)) else [params]
                assert len(params) == len(names), f"{mname}.{qual}: params / param_names"
                n_args = len(inspect.signature(fn).parameters) - 1  # self
                has_cache = getattr(cls, "setup_cache", None) or \
                    getattr(module, "setup_cache", None)
                assert n_args == len(names) + (1 if has_cache else 0), \
                    f"{mname}.{qual}: takes {n_args} arguments"
    missing = EXPECTED - found
    assert not missing, f"benchmarks missing: {sorted(missing)}"


def test_benchmarks_holds_asv_benchmarks_only(modules):
    """Every module of ``benchmarks/`` but its shared settings defines asv benchmarks; the
    diagnostics of the machine live in ``tools/diagnostics/`` (and import)."""
    empty = [m for m, mod in modules.items() if m != "_common" and not _benchmarks(mod)]
    assert not empty, f"benchmarks/ modules without an asv benchmark: {empty}"
    if str(ROOT) not in sys.path:
        sys.path.insert(0, str(ROOT))
    for m in pkgutil.iter_modules([str(ROOT / "tools" / "diagnostics")]):
        importlib.import_module(f"tools.diagnostics.{m.name}")


def test_module_level_benchmarks_take_no_arguments(modules):
    """asv runs every module-level function with a benchmark prefix without arguments:
    a helper named ``time_...`` (taking the problem) fails ``asv check``; name helpers
    otherwise."""
    for mname, module in modules.items():
        for qual, fn, cls in _benchmarks(module):
            if cls is None:
                required = [p for p in inspect.signature(fn).parameters.values()
                            if p.default is p.empty and p.kind in (p.POSITIONAL_ONLY,
                                                                    p.POSITIONAL_OR_KEYWORD)]
                assert not required, f"benchmarks/{mname}.py: {qual} needs {required}"


def test_asv_discovers_the_same_benchmarks(bench_pkg, modules):
    discovery = pytest.importorskip("asv_runner.discovery")
    names = {b.name for b in discovery.disc_benchmarks(str(ROOT / "benchmarks"))}
    ours = {f"{m}.{q}" for m, mod in modules.items() for q, _, _ in _benchmarks(mod)}
    assert names == ours


def test_hf_benchmark_takes_every_case_with_every_solver(modules):
    """Every (case, solver) pair of the HF suite passes the component checks that
    ``setup`` runs (no meshing: the names are checked against the scene first)."""
    import importlib.util

    from rbbench.hf.components import check_names
    from rbbench.registry import default_registry
    from rbbench.scene.loading import SceneError

    mod = modules["bench_hf"]
    cases, solvers = mod.HFSolve.params
    no_netgen = importlib.util.find_spec("netgen") is None
    for case in cases:
        sc = mod.scene(case)
        for solver in solvers:
            if no_netgen and sc.data["geometry"]["kind"] == "hemispheres":
                with pytest.raises(SceneError, match="Netgen"):  # the 3D mesher: an extra
                    check_names(sc, default_registry(), "skfem", "mixed", solver)
                continue
            check_names(sc, default_registry(), "skfem", "mixed", solver)


def test_hf_benchmark_runs_on_the_membrane(modules):
    bench = modules["bench_hf"].HFSolve()
    bench.setup("membrane_obstacle", "ssn")
    bench.time_hf_solve("membrane_obstacle", "ssn")


def test_online_and_tracked_accuracy_on_a_tiny_reduction(modules, tmp_path):
    from benchmarks._common import reduced_case

    online = modules["bench_online"]
    case = "membrane_obstacle"
    cache = {case: reduced_case(case, str(tmp_path), n_train=4, n_valid=2)}
    acc = online.Accuracy()
    for name in ("track_err_u_max", "track_err_lam_max", "track_neg_log10_beta_off"):
        value = getattr(acc, name)(cache, case)
        assert isinstance(value, float) and math.isfinite(value), (name, value)
        assert value >= 0.0, (name, value)
    bench = online.OnlineSolve()
    for method in online.OnlineSolve.params[1]:
        bench.setup(cache, case, method)
        t = bench.track_online_median_s(cache, case, method)
        assert isinstance(t, float) and 0 < t < 1, (method, t)


def test_friction_online_suite_on_a_tiny_reduction(modules, tmp_path):
    """The friction online suite's setup and benchmark, both paths, on its coarser mesh
    with 3 training and 1 validation mu."""
    from benchmarks._common import reduced_case

    bench_mod = modules["bench_friction_online"]
    case = bench_mod.FRICTION_CASES[0]
    cache = {case: reduced_case(case, str(tmp_path), n_train=3, n_valid=1)}
    assert cache[case]["summary"]["hyper"] == "eim"
    bench = bench_mod.FrictionOnlineSolve()
    for path in bench_mod.FrictionOnlineSolve.params[1]:
        bench.setup(cache, case, path)
        bench.time_online_solve(cache, case, path)


def test_tracked_values_fail_instead_of_recording_nan(modules):
    acc = modules["bench_online"].Accuracy()
    for bad in (None, float("nan"), float("inf")):
        cache = {"c": {"summary": {"err_u_max": bad}}}
        with pytest.raises(ValueError, match="not a finite number"):
            acc.track_err_u_max(cache, "c")
    cache = {"c": {"summary": {"beta_off_min": 0.0}}}
    assert acc.track_neg_log10_beta_off(cache, "c") == modules["bench_online"].NEG_LOG10_CAP


def test_stage_suites_get_the_names_reduce_would_resolve(modules):
    """The stage suites call the stage functions directly: their configuration carries the
    formulation and solver ``reduce()`` resolves for the scene (never None)."""
    from benchmarks._common import RB_CASES, reduce_config
    from rbbench.registry import default_registry

    reg = default_registry()
    for case in RB_CASES:
        cfg = reduce_config(case)
        reg.get("formulation", cfg.formulation)
        reg.get("solver", cfg.solver)


def test_offline_stages_run_on_the_membrane(modules, tmp_path):
    """Every stage suite of ``bench_offline`` on the membrane, with the inputs its
    ``setup_cache`` computes, on 4 training parameters (EIM is coarse Hertz only)."""
    from dataclasses import replace

    off = modules["bench_offline"]
    case = "membrane_obstacle"
    bench = off.Snapshots()
    bench.setup(case)
    bench.mus = bench.mus[:2]
    bench.time_snapshots(case)
    sc, cfg, mus = off._training(case, str(tmp_path))
    snaps = off._snapshots(sc, replace(cfg, n_jobs=1), mus[:4])
    data = {case: {"mus": snaps.mus, "U": snaps.U, "LAM": snaps.LAM}}
    pod = off.PrimalPOD()
    pod.setup(data, case)
    pod.time_primal_pod(data, case)
    for dual in off.DUALS:
        stage = off.DualCompressor()
        stage.setup(data, case, dual)
        stage.time_dual_compressor(data, case, dual)
    pga = off.PGA()
    pga.setup(data, case)
    pga.time_pga(data, case)


def test_shape_optimisation_suite_on_its_small_mesh(modules):
    """The shape suite's setup and benchmarks on its smaller body mesh: the RB-driven run
    needs HF solves and ends at or above the uniform-pressure bound."""
    mod = modules["bench_shape_optimisation"]
    case = mod.SHAPE_CASES[0]
    ev = mod.ShapeReducedEvaluation()
    ev.setup(case)
    ev.time_reduced_evaluation(case)
    run = mod.ShapeRBDriver()
    run.setup(case)
    assert run.track_hf_solves(case) >= 1.0
    assert run.track_J_over_bound(case) >= 1.0

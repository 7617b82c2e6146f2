"""One shape-optimisation run: oracle, optimiser, progress, ``history.csv``, summary, figures.

``rbbench optimize shape_coulomb [--driver hf|rb] [--method bundle|slsqp]`` lands here.
Every history row is appended to ``history.csv`` (flushed) as it comes, and the summary is
written even when a state solve fails mid-run (its reason is the stop reason): nothing
computed is lost.
"""
from __future__ import annotations

import csv
import json
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from rbbench.optim.shape_adjoint import evaluate
from rbbench.optim.shape_scene import ShapeScene
from rbbench.optim.shape_state import solve_state
from rbbench.runtime.threads import one_blas_thread
from rbbench.scene.parameters import SceneError

#: the values published in the talk "On coupling of complementarity with friction in contact
#: shape optimization" (model B, Example 1, its own data): J(alpha_0), J(alpha_opt)
PUBLISHED_J0, PUBLISHED_J_OPT = 2.1159e11, 2.6513e8


@dataclass
class OptimizeConfig:
    """What to run: the state solver (``hf`` or ``rb``), the optimiser, its budget."""

    driver: str = "hf"
    method: str = "bundle"
    max_iter: int = 100
    max_evals: int = 300
    eps: float = 1e-6
    quiet: bool = False
    metric: str = "identity"

    def __post_init__(self) -> None:
        choices = {"driver": ("hf", "rb"), "method": ("bundle", "slsqp"),
                   "metric": ("identity", "bfgs")}
        for name, valid in choices.items():
            if getattr(self, name) not in valid:
                raise SceneError(f"optimize: {name} = {getattr(self, name)!r}: valid are "
                                 f"{', '.join(valid)}")
        for name in ("max_iter", "max_evals"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise SceneError(f"optimize: {name} = {v!r}: give an integer >= 1")
        if (isinstance(self.eps, bool) or not isinstance(self.eps, (int, float))
                or not math.isfinite(self.eps) or not 0 < self.eps <= 1):
            raise SceneError(f"optimize: eps = {self.eps!r}: give a finite number in (0, 1] "
                             "(the stopping tolerance on the predicted decrease, relative to "
                             "J0)")


class HFOracle:
    """``alpha -> (Theta(alpha), xi)`` by the HF state and adjoint; counts and times solves.

    The last state warm-starts the next semismooth Newton solve.
    """

    def __init__(self, sc: ShapeScene) -> None:
        self.sc, self.solves, self.time_s, self.last = sc, 0, 0.0, None

    def __call__(self, alpha: np.ndarray) -> tuple[float, np.ndarray]:
        t0 = time.perf_counter()
        y0 = None
        if self.last is not None:
            s = self.last.state
            y0 = np.concatenate([s.u_t, s.u_n, s.lam, s.tau])
        self.solves += 1
        try:
            ev = evaluate(self.sc, alpha, y0=y0)
        finally:
            self.time_s += time.perf_counter() - t0
        self.last = ev
        return ev.J, ev.xi


class _History:
    """Append-only ``history.csv`` plus the progress line."""

    FIELDS = ("iteration", "kind", "serious", "f", "f_trial", "step_norm", "t", "agg_norm",
              "pred", "evaluations", "hf_solves", "wall_s")

    def __init__(self, path: Path, oracle, quiet: bool) -> None:
        self.path, self.oracle, self.quiet, self.rows = path, oracle, quiet, []
        self.t0 = time.perf_counter()
        with open(path, "w", newline="") as fh:
            csv.writer(fh).writerow(self.FIELDS)

    def __call__(self, row: dict) -> None:
        row = {**row, "hf_solves": getattr(self.oracle, "solves", math.nan),
               "wall_s": time.perf_counter() - self.t0}
        self.rows.append(row)
        with open(self.path, "a", newline="") as fh:
            csv.writer(fh).writerow([row.get(k, "") for k in self.FIELDS])
        if not self.quiet:
            print(f"  it {row['iteration']:>4} {row.get('kind', ''):<8} J {row['f']:.6e}  "
                  f"trial {row.get('f_trial', math.nan):.4e}  step {row.get('step_norm', 0):.2e}"
                  f"  t {row.get('t', math.nan):.2e}  |p| {row.get('agg_norm', math.nan):.2e}"
                  f"  HF solves {row['hf_solves']}  {row['wall_s']:.1f} s", flush=True)


def _optimise(sc: ShapeScene, cfg: OptimizeConfig, oracle, callback):
    from rbbench.optim.bundle import BundleOptions, Polyhedron, bundle_trust

    poly = Polyhedron(**sc.admissible())
    alpha0 = sc.initial_design()
    if cfg.method == "bundle":
        opts = BundleOptions(max_iter=cfg.max_iter, max_evals=cfg.max_evals, eps=cfg.eps,
                             metric=cfg.metric)
        return bundle_trust(oracle, alpha0, poly, opts, callback)
    if cfg.method == "slsqp":
        from rbbench.optim.baselines import slsqp

        return slsqp(oracle, alpha0, poly, max_iter=cfg.max_iter, callback=callback)
    raise ValueError(f"--method {cfg.method!r}: valid are 'bundle', 'slsqp'")


def summary_of(sc: ShapeScene, cfg: OptimizeConfig, res, J0: float, wall_s: float,
               counts: dict) -> dict:
    """``summary.json``: J0, J_opt, their ratio, counts, residuals at the optimum, reasons."""
    res_opt = sc.residuals(res.x)
    return {
        "scene": sc.name, "driver": cfg.driver, "method": cfg.method,
        "J_definition": "J = sum_i lam_i^6, lam_i the nodal normal contact force (kN per m "
                        "of depth) at the I design nodes (the shape-optimisation talk)",
        "J0": J0, "J_opt": res.f, "ratio": res.f / J0 if J0 else math.nan,
        "J_uniform_bound": sc.uniform_pressure_bound(),
        "published": {"J0": PUBLISHED_J0, "J_opt": PUBLISHED_J_OPT,
                      "ratio": PUBLISHED_J_OPT / PUBLISHED_J0,
                      "note": "the shape-optimisation talk's own (unstated) material and load; "
                              "compare the ratios"},
        "iterations": res.iterations, "evaluations": res.evaluations, **counts,
        "wall_s": wall_s, "stop_reason": res.stop_reason,
        "constraint_residuals_opt": res_opt,
        "constraint_residual_max_opt": max(res_opt.values()),
        "residual_definition": "largest violation per group, > 0 violated, raw (no clipping)",
        "alpha_opt": [float(v) for v in res.x], "alpha0": [float(v) for v in
                                                           sc.initial_design()],
        "config": asdict(cfg),
        "scene_data": {k: v for k, v in asdict(sc).items() if k != "extra"},
    }


#: the files of a run; a rerun into the same folder removes the previous run's first
OUTPUTS = ("history.csv", "summary.json", "designs.png", "pressure.png", "history.png")


def run_optimization(sc: ShapeScene, cfg: OptimizeConfig, out: Path) -> dict:
    """Run, write ``history.csv``, ``summary.json`` and the PNGs into ``out``.

    One writer per folder (its run lock, as ``rbbench run``: a second run into ``out``
    raises :class:`~rbbench.bench.guard.RunLockedError`); the previous run's files
    (:data:`OUTPUTS`) are removed before the first new row, so a killed rerun never leaves
    its history beside an older summary, and a file of that name that is a symbolic link is
    removed, never written through."""
    from rbbench.bench.guard import RunLock

    out.mkdir(parents=True, exist_ok=True)
    with RunLock(out):
        for name in OUTPUTS:
            (out / name).unlink(missing_ok=True)
        return _run(sc, cfg, out)


def _run(sc: ShapeScene, cfg: OptimizeConfig, out: Path) -> dict:
    t0 = time.perf_counter()
    with one_blas_thread():
        if cfg.driver == "hf":
            oracle = HFOracle(sc)
            hist = _History(out / "history.csv", oracle, cfg.quiet)
            res = _optimise(sc, cfg, oracle, hist)
            counts = {"hf_solves": oracle.solves, "hf_time_s": oracle.time_s}
        elif cfg.driver == "rb":
            from rbbench.optim.rb_driver import optimize_rb_run

            res, counts, hist = optimize_rb_run(sc, cfg, out)
        else:
            raise ValueError(f"--driver {cfg.driver!r}: valid are 'hf', 'rb'")
        wall = time.perf_counter() - t0
        J0 = next((r["f"] for r in hist.rows if r.get("kind") == "start"), math.nan)
        summary = summary_of(sc, cfg, res, J0, wall, counts)
        (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float))
        _pictures(sc, res, hist.rows, summary, out)
    return summary


def _pictures(sc: ShapeScene, res, rows: list[dict], summary: dict, out: Path) -> None:
    from rbbench.optim.figures import plot_bodies, plot_history, plot_pressure

    try:
        states = {"initial design": solve_state(sc, sc.initial_design()),
                  "optimal design": solve_state(sc, res.x)}
    except Exception as exc:  # noqa: BLE001 - the run's files are written already
        summary["figures_error"] = f"{type(exc).__name__}: {exc}"
        (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float))
        return
    plot_bodies(sc, states, out / "designs.png")
    plot_pressure(sc, states, out / "pressure.png")
    plot_history([r for r in rows if r.get("serious")], out / "history.png",
                 summary["J_uniform_bound"])


from rbbench._compat import deprecated_names  # noqa: E402 - after the module's own names

__getattr__ = deprecated_names(__name__)  # renamed names (rbbench._compat)

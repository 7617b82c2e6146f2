"""One shape-optimisation run: oracle, optimiser, progress, ``history.csv``, summary, figures.

``rbbench optimize shape_coulomb [--driver hf|rb] [--method bundle|slsqp]
[--strategy equalise|none]`` lands here. ``equalise`` (the default) runs stages of the
load-equalising phase and the local solver (:mod:`rbbench.optim.strategy`); ``none`` the
local solver alone from the initial design (the seed's method).
Every history row is appended to ``history.csv`` (flushed) as it comes, and the summary is
written even when a state solve fails mid-run (its reason is the stop reason): nothing
computed is lost.
"""
from __future__ import annotations

import csv
import json
import math
import time
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from rbbench.optim.bundle import BundleResult
from rbbench.optim.shape_adjoint import evaluate
from rbbench.optim.shape_scene import ShapeScene
from rbbench.optim.shape_state import ShapeState, solve_state
from rbbench.optim.strategy import STRATEGIES, EqualiseOptions, StagedResult, staged
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
    strategy: str = "equalise"

    def __post_init__(self) -> None:
        choices = {"driver": ("hf", "rb"), "method": ("bundle", "slsqp"),
                   "metric": ("identity", "bfgs"), "strategy": STRATEGIES}
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

    The last state warm-starts the next semismooth Newton solve. :meth:`state` solves the
    state alone (the load-equalising phase); ``solves`` counts both kinds.
    """

    def __init__(self, sc: ShapeScene) -> None:
        self.sc, self.solves, self.time_s, self.last = sc, 0, 0.0, None

    def _timed(self, solve: Any, alpha: np.ndarray) -> Any:
        """``solve(sc, alpha, y0=)`` warm-started from the last state, counted and timed."""
        t0 = time.perf_counter()
        y0 = None
        if self.last is not None:
            s = self.last.state
            y0 = np.concatenate([s.u_t, s.u_n, s.lam, s.tau])
        self.solves += 1
        try:
            return solve(self.sc, alpha, y0=y0)
        finally:
            self.time_s += time.perf_counter() - t0

    def __call__(self, alpha: np.ndarray) -> tuple[float, np.ndarray]:
        ev = self._timed(evaluate, alpha)
        self.last = ev
        return ev.J, ev.xi

    def state(self, alpha: np.ndarray) -> ShapeState:
        """The HF state at ``alpha`` (no adjoint), warm-started; counted and timed."""
        st = self._timed(solve_state, alpha)
        self.last = _StateOnly(st)
        return st


@dataclass
class _StateOnly:
    """The last state of :meth:`HFOracle.state` (the warm start of the next solve)."""

    state: ShapeState


class _History:
    """Append-only ``history.csv`` plus the progress line."""

    FIELDS = ("iteration", "kind", "serious", "f", "f_trial", "step_norm", "t", "agg_norm",
              "pred", "evaluations", "hf_solves", "wall_s", "stage", "relax",
              "force_mismatch", "contact_nodes")

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


def _optimise(sc: ShapeScene, cfg: OptimizeConfig, oracle, callback,
              alpha0: np.ndarray | None = None, f_lower: float = -math.inf):
    """The local solver from ``alpha0`` (default: the initial design); ``f_lower`` a lower
    bound on ``J`` for the bundle's lower-bound cut."""
    from rbbench.optim.bundle import BundleOptions, Polyhedron, bundle_trust

    poly = Polyhedron(**sc.admissible())
    alpha0 = sc.initial_design() if alpha0 is None else alpha0
    if cfg.method == "bundle":
        opts = BundleOptions(max_iter=cfg.max_iter, max_evals=cfg.max_evals, eps=cfg.eps,
                             metric=cfg.metric, f_lower=f_lower)
        return bundle_trust(oracle, alpha0, poly, opts, callback)
    if cfg.method == "slsqp":
        from rbbench.optim.baselines import slsqp

        return slsqp(oracle, alpha0, poly, max_iter=cfg.max_iter, callback=callback)
    raise ValueError(f"--method {cfg.method!r}: valid are 'bundle', 'slsqp'")


#: the tolerance ``summary.json`` judges the raw constraint residuals by
FEASIBILITY_TOL = 1e-8

BOUND_DEFINITION = ("I (P / I)^p, P = pressure (b - a) the whole vertical load, which passes "
                    "through the I contact nodes (sum lam = P); by Jensen's inequality "
                    "J = sum lam_i^p is least when the nodal forces are equal. J is not "
                    "normalised: J / bound = 1 is the best any design can do")


def summary_of(sc: ShapeScene, cfg: OptimizeConfig, res, J0: float, wall_s: float,
               counts: dict) -> dict:
    """``summary.json``: J0, J_opt, their ratio, J / the uniform-pressure bound, counts,
    the strategy and its cost, residuals at the optimum, reasons."""
    res_opt = sc.residuals(res.x)
    worst = max(res_opt, key=res_opt.get)
    bound = sc.uniform_pressure_bound()
    J_hf = counts.get("J_opt_hf", res.f)
    return {
        "scene": sc.name, "driver": cfg.driver, "method": cfg.method,
        "strategy": cfg.strategy,
        "J_definition": "J = sum_i lam_i^6, lam_i the nodal normal contact force (kN per m "
                        "of depth) at the I design nodes (the shape-optimisation talk)",
        "J0": J0, "J_opt": res.f, "ratio": res.f / J0 if J0 else math.nan,
        "J_uniform_bound": bound, "J_uniform_bound_definition": BOUND_DEFINITION,
        "J_over_bound": J_hf / bound, "J0_over_bound": J0 / bound,
        "published": {"J0": PUBLISHED_J0, "J_opt": PUBLISHED_J_OPT,
                      "ratio": PUBLISHED_J_OPT / PUBLISHED_J0,
                      "note": "the shape-optimisation talk's own (unstated) material and load; "
                              "compare the ratios"},
        "iterations": res.iterations, "evaluations": res.evaluations, **counts,
        "wall_s": wall_s, "stop_reason": res.stop_reason,
        "constraint_residuals_opt": res_opt,
        "constraint_residual_max_opt": res_opt[worst],
        "constraint_worst_opt": worst,
        "constraints_satisfied_opt": bool(res_opt[worst] <= FEASIBILITY_TOL),
        "residual_definition": "largest violation per group, > 0 violated, raw (no clipping); "
                               f"satisfied: every group <= {FEASIBILITY_TOL:g}",
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
        if cfg.driver not in ("hf", "rb"):
            raise ValueError(f"--driver {cfg.driver!r}: valid are 'hf', 'rb'")
        if cfg.strategy == "equalise":
            res, counts, hist = _run_staged(sc, cfg, out, t0)
        elif cfg.driver == "hf":
            oracle = HFOracle(sc)
            hist = _History(out / "history.csv", oracle, cfg.quiet)
            res = _optimise(sc, cfg, oracle, hist)
            counts = {"hf_solves": oracle.solves, "hf_time_s": oracle.time_s,
                      "strategy_cost": _plain_cost(oracle.solves, time.perf_counter() - t0)}
        else:
            from rbbench.optim.rb_driver import optimize_rb_run

            res, counts, hist = optimize_rb_run(sc, cfg, out)
            counts["strategy_cost"] = _plain_cost(res.hf_solves, time.perf_counter() - t0)
        wall = time.perf_counter() - t0
        J0 = next((r["f"] for r in hist.rows if r.get("kind") == "start"), math.nan)
        summary = summary_of(sc, cfg, res, J0, wall, counts)
        (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float))
        _pictures(sc, res, hist.rows, summary, out)
    return summary


def _plain_cost(hf_solves: int, wall_s: float) -> dict:
    return {"outer_stages": 1, "phase_state_solves": 0, "local_hf_solves": hf_solves,
            "hf_solves_total": hf_solves, "wall_s": wall_s, "stages": []}


class _StageRows:
    """Rows of a staged run for the history: iteration numbers continued across the
    phases and local runs, the stage number, and (RB driver) the HF and reduced solve
    counts summed over all of them; ``wall_s`` from the start of the run."""

    def __init__(self, sink, t0: float, phase_oracle: HFOracle | None) -> None:
        self.sink, self.t0, self.phase = sink, t0, phase_oracle
        self.stage, self.offset, self.last = 0, 0, 0
        self.hf_done = self.rb_done = 0       # RB: solves of the finished local runs
        self.local = False

    def begin(self, local: bool) -> None:
        self.offset, self.local = self.last, local

    def __call__(self, row: dict) -> None:
        row = dict(row)
        if not self.local and row["kind"] in ("start", "stage"):
            self.stage += 1
            self.offset = self.last
        row["iteration"] = self.last = self.offset + row["iteration"]
        row["stage"] = self.stage
        if self.phase is not None:              # the RB history's columns
            local_hf = row.get("hf_solves", 0) if self.local else 0
            row.update(hf_solves=self.phase.solves + self.hf_done + local_hf,
                       rb_solves=self.rb_done + (row.get("rb_solves", 0) if self.local else 0),
                       wall_s=time.perf_counter() - self.t0)
            for key in ("delta", "grad_norm", "pred", "rho", "err_J_trial", "err_xi_trial"):
                row.setdefault(key, math.nan)
            row.setdefault("basis_size", 0)
        self.sink(row)


def _run_staged(sc: ShapeScene, cfg: OptimizeConfig, out: Path, t0: float):
    """``--strategy equalise``: :func:`~rbbench.optim.strategy.staged` with the HF-driven
    bundle (or SLSQP) or the RB driver as the local solver. The bundle gets the
    uniform-pressure bound as its lower-bound cut ``v >= J_bound - J(x_k)``: a valid bound
    (Jensen), it caps the model's predicted decrease near the optimum, where ``J ~ lam^6``
    is steep and the cutting-plane model alone proposes steps far too long (measured on the
    21-node scene from the phase's design: 0 serious steps in 100 iterations without it,
    13 and convergence after 77 evaluations with it)."""
    oracle, local_hf = HFOracle(sc), []      # HF solves of each local run
    bound = sc.uniform_pressure_bound()      # the local bundle's lower-bound cut
    if cfg.driver == "hf":
        hist = _History(out / "history.csv", oracle, cfg.quiet)
        rows = _StageRows(hist, t0, None)

        def local(x0):
            rows.begin(local=True)
            n0 = oracle.solves
            res = _optimise(sc, cfg, oracle, rows, x0, f_lower=bound)
            rows.begin(local=False)
            local_hf.append(oracle.solves - n0)
            return res, res.f
    else:
        from rbbench.optim.rb_driver import RBHistory, optimize_rb, rb_options

        opts = rb_options(cfg)
        opts.inner.f_lower = bound
        hist = RBHistory(out / "history.csv", cfg.quiet)
        rows = _StageRows(hist, t0, oracle)

        def local(x0):
            rows.begin(local=True)
            res = optimize_rb(sc, x0, opts, rows)
            rows.begin(local=False)
            rows.hf_done += res.hf_solves
            rows.rb_done += res.rb_solves
            local_hf.append(res.hf_solves)
            return res, res.J_hf

    result = staged(sc, sc.initial_design(), oracle.state, local, EqualiseOptions(), rows)
    cost = _staged_cost(result, local_hf, time.perf_counter() - t0)
    final = result.final
    if final is None:                         # the state at the initial design failed
        n = sc.n_contact
        final = BundleResult(x=sc.initial_design(), f=math.nan, g=np.full(n, math.nan),
                             iterations=0, evaluations=0, stop_reason="")
    local_stop = final.stop_reason
    stop = (f"{local_stop} ({result.reason})" if local_stop.startswith("oracle failed")
            else f"{result.reason}; last local run: {local_stop}" if local_stop
            else result.reason)
    res = replace(final, iterations=sum(s.local.iterations for s in result.stages if s.local),
                  evaluations=cost["hf_solves_total"] + rows.rb_done, stop_reason=stop)
    counts = {"hf_solves": cost["hf_solves_total"], "hf_time_s": oracle.time_s,
              "strategy_cost": cost}
    if cfg.driver == "rb":
        counts.update(rb_solves=rows.rb_done, basis_size=getattr(final, "basis_size", 0),
                      J_opt_hf=getattr(final, "J_hf", math.nan), J_opt_reduced=final.f)
    return res, counts, hist


def _staged_cost(result: StagedResult, local_hf: list[int], wall_s: float) -> dict:
    """The strategy's cost for ``summary.json``: per stage and in total (``local_hf``: the
    HF solves of each local run, in order)."""
    hf = iter(local_hf)
    stages = [{"stage": k, "phase_state_solves": s.phase.solves,
               "phase_accepted_steps": s.phase.accepted, "phase_J": s.phase.J,
               "phase_force_mismatch": s.phase.mismatch, "phase_stop": s.phase.reason,
               "phase_wall_s": s.phase.wall_s,
               "local_hf_solves": next(hf) if s.local else 0,
               "local_J": s.J_local, "local_wall_s": s.local_wall_s,
               "local_stop": s.local.stop_reason if s.local else "not run"}
              for k, s in enumerate(result.stages, 1)]
    phase = sum(s["phase_state_solves"] for s in stages)
    local = sum(s["local_hf_solves"] for s in stages)
    return {"outer_stages": len(stages), "phase_state_solves": phase,
            "local_hf_solves": local, "hf_solves_total": phase + local, "wall_s": wall_s,
            "stop": result.reason, "stages": stages,
            "definition": "phase_state_solves: HF state solves of the load-equalising phases "
                          "(no adjoint); local_hf_solves: HF solves of the local solver "
                          "(state + adjoint; RB driver: its HF solves); wall_s: the whole "
                          "run without the figures"}


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

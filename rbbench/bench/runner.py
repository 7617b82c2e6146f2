"""Run a matrix: one results row per case x repetition, incremental, resumable.

Layout of a run directory (the contract with :mod:`rbbench.bench.report`)::

    DIR/manifest.json            matrix, column definitions, provenance, progress
    DIR/results.parquet          the table (rbbench.bench.schema columns), rewritten atomically
    DIR/results.csv              the same, with --csv
    DIR/cases/<case_id>-r<k>.json  {"row": ..., "details": {per_mu, histories, valid_mus}}

A case's file is written (atomically) the moment the case ends, whatever its
status, and is the truth: on a rerun (after Ctrl-C, a kill or a crash) every
case with a file is kept and not recomputed (``retry`` names statuses to
recompute, e.g. ``error``, ``timeout``). HF snapshots are cached on disk
(:mod:`rbbench.hf.snapshots`) and computed once per scene / HF components /
parameter set before the cases that share them start.
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import platform
import resource
import signal
import time
import traceback
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from typing import Any

import numpy as np

from rbbench.bench import schema
from rbbench.bench.matrix import Case, Matrix
from rbbench.hf.snapshots import atomic_write
from rbbench.provenance import _jsonable
from rbbench.registry import NotInstalledError, Registry, default_registry

__all__ = ["CaseTimeout", "RunSummary", "execute_case", "load_rows", "run_matrix"]

#: Summary keys of :meth:`rbbench.rb.offline.ReduceResult.summary` copied as they are.
_COPIED = ("n_hf_dofs", "n_contact", "n_train", "n_valid", "N", "R", "M_eim", "err_u_max",
           "err_u_mean", "err_lam_max", "err_lam_mean", "lam_best_max", "penetration_max",
           "complementarity_max", "energy_err_max", "t_offline_s", "t_online_median_s",
           "t_online_iqr_s", "t_hf_median_s", "speedup")
_TIMINGS = {"t_snapshots_s": "snapshots_s", "t_primal_s": "primal_s", "t_dual_s": "dual_s",
            "t_stabilizer_s": "stabilizer_s", "t_hyper_s": "hyper_s"}


class CaseTimeout(Exception):
    """Raised inside a case when its time limit is reached (serial executor)."""


@dataclass
class RunSummary:
    """What :func:`run_matrix` did: counts per status, cases computed and kept."""

    out_dir: Path
    counts: dict[str, int]
    computed: list[str] = field(default_factory=list)
    kept: list[str] = field(default_factory=list)
    interrupted: bool = False
    wall_s: float = 0.0


# ----------------------------------------------------------------------------- one case
def _threads() -> str:
    keys = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
    return json.dumps({k: os.environ.get(k) for k in keys})


@functools.lru_cache(maxsize=1)
def _provenance() -> dict[str, Any]:
    """Versions, git sha, machine and threads: the same for every row of a process (computed
    once; callers copy it into rows, never mutate it)."""
    import importlib.metadata as md

    from rbbench.provenance import provenance

    p = provenance()
    versions = {k: p[k] for k in ("numpy", "scipy", "python")}
    for mod in ("skfem", "daqp", "ngsolve", "petsc4py"):
        with contextlib.suppress(Exception):
            versions[mod] = md.version({"skfem": "scikit-fem"}.get(mod, mod))
    return {"rbbench_version": p["rbbench"], "git_sha": p["git_sha"] or "",
            "versions": json.dumps(versions, sort_keys=True),
            "machine": f"{p['machine']} ({platform.processor() or platform.machine()}, "
                       f"{p['cpus']} cpus)",
            "threads": _threads()}


def base_row(case: Case, run_id: str, executor: str) -> dict[str, Any]:
    """The identity, component and provenance columns of a case's row."""
    c = case.components
    return {"run_id": run_id, "case_id": case.case_id, "repetition": case.repetition,
            "seed": case.seed, "mode": case.mode, "scene": case.scene,
            "scene_overrides": json.dumps(list(case.overrides)),
            **{k: c[k] or None for k in ("backend", "formulation", "solver", "primal", "dual",
                                         "stabilizer", "hyper")},
            "executor": executor, "params": json.dumps(case.params, sort_keys=True),
            "N_req": case.N, "R_req": case.R,
            "started_at": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            **_provenance()}


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # KiB on Linux


def _fill(row: dict, s: dict) -> None:
    for k in _COPIED:
        row[k] = s.get(k)
    for col, key in _TIMINGS.items():
        row[col] = s["timings"].get(key)
    row["t_online_hf_assembly_s"] = s["timings"].get("t_online_hf_assembly_s")
    row["hyper_used"] = s["hyper"]
    row["S"] = s["K_pga"] if s["config"]["stabilizer"] != "supremizer" else s["R"]
    for b in ("hf", "dec", "on", "off"):
        row[f"beta_{b}_min"] = s.get(f"beta_{b}_min")
        row[f"beta_{b}_kind"] = (s.get("beta_kind") or {}).get(b)
    row["beta_dec_zero_any"] = s.get("beta_dec_zero_any")


def _finite(s: dict) -> bool:
    keys = ("err_u_max", "err_lam_max", "t_online_median_s")
    return all(s.get(k) is not None and np.isfinite(s[k]) for k in keys)


def execute_case(case: Case, run_id: str, cache_dir: str, executor: str = "serial",
                 registry: Registry | None = None,
                 progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Run one case in this process; never raises for a failing case.

    Returns ``{"row": <schema row>, "details": {...}}`` with the status set:
    ``ok``; ``diverged`` (an HF snapshot or an online solve did not converge, or
    the errors are not finite); ``not_installed`` (a component's extra is
    missing); ``timeout`` (:class:`CaseTimeout`); ``error`` (any other exception,
    with its traceback).
    """
    from rbbench.hf.snapshots import SnapshotError
    from rbbench.rb.offline import DivergedError
    from rbbench.scene.loading import load_scene

    t0 = time.perf_counter()
    row = base_row(case, run_id, executor)
    details: dict[str, Any] = {}
    try:
        scene = load_scene(case.base_scene, case.overrides)
        if case.mode == "hf":
            _execute_hf(case, scene, row, registry)
        else:
            details = _execute_rb(case, scene, row, cache_dir, registry, progress)
    except CaseTimeout:
        row.update(status="timeout", reason=f"exceeded the case limit of {case.timeout_s:g} s")
    except NotInstalledError as exc:
        row.update(status="not_installed", reason=str(exc))
    except SnapshotError as exc:
        row.update(status="diverged", reason=f"HF snapshots: {exc}")
    except DivergedError as exc:
        row.update(status="diverged", reason=str(exc))
    except Exception as exc:  # noqa: BLE001 - a failing case is a row, never a lost run
        row.update(status="error", reason=f"{type(exc).__name__}: {exc}",
                   traceback=traceback.format_exc())
    row["t_case_s"] = time.perf_counter() - t0
    row["peak_rss_mb"] = _peak_rss_mb()
    return {"row": schema.normalise_row(row), "details": _jsonable(details)}


def _quiet(msg: str) -> None:
    return None


def _execute_rb(case: Case, scene: Any, row: dict, cache_dir: str, registry: Registry | None,
                progress: Callable[[str], None] | None) -> dict[str, Any]:
    """Mode rb: the reduction and its online validation; fills the row's columns and
    status and returns the case's details (per-mu values, histories, validation mus)."""
    from rbbench.rb.offline import reduce

    res = reduce(scene, case.reduce_config(cache_dir), progress=progress or _quiet,
                 registry=registry)
    s = res.summary()
    _fill(row, s)
    stops = s.get("online_stops", {})
    bad_stops = {k: v for k, v in stops.items() if not k.startswith("converged")}
    if not _finite(s):
        row.update(status="diverged", reason="non-finite reduced errors or online time")
    elif bad_stops:
        row.update(status="diverged", reason=f"online solves did not converge: {bad_stops}")
    else:
        row.update(status="ok", reason="")
    return {"per_mu": s.get("per_mu", {}), "histories": s.get("histories", {}),
            "valid_mus": np.asarray(res.valid_mus).tolist(), "timings": s.get("timings", {})}


def _execute_hf(case: Case, scene: Any, row: dict, registry: Registry | None) -> None:
    """Mode hf: ``hf_repeats`` HF solves at the scene's default mu (components built once,
    meshing not timed); fills the sizes, force, iterations and HF time columns."""
    from rbbench.hf.model import make_components, solve_hf

    c = case.components
    comps = make_components(scene, c["backend"], c["formulation"], c["solver"], registry)
    times, sol = [], None
    for _ in range(int(case.params.get("hf_repeats", 3))):
        sol = solve_hf(scene, None, c["backend"], c["formulation"], c["solver"],
                       registry=registry, components=comps)
        times.append(sol.times["total_s"])
    m = sol.metrics
    row.update(n_hf_dofs=m["n_dofs"], n_contact=m["n_contact"],
               contact_force=m["contact_force"], hf_iterations=m["iterations"],
               t_hf_median_s=float(np.median(times)))
    if not sol.result.converged:
        row.update(status="diverged", reason=f"HF solver stopped: {sol.result.stop_reason}")
    elif not np.isfinite(m["contact_force"]):
        row.update(status="diverged", reason="non-finite contact force")
    else:
        row.update(status="ok", reason="")


def decided_row(case: Case, run_id: str, executor: str) -> dict[str, Any]:
    """The row of a case decided without running it (skip / not_installed)."""
    row = base_row(case, run_id, executor)
    row.update(status=case.status, reason=case.reason, t_case_s=0.0)
    return {"row": schema.normalise_row(row), "details": {}}


def failed_row(case: Case, run_id: str, executor: str, status: str, reason: str,
               tb: str = "") -> dict[str, Any]:
    """The row of a case that the executor itself lost (killed, crashed)."""
    row = base_row(case, run_id, executor)
    row.update(status=status, reason=reason, traceback=tb or None)
    return {"row": schema.normalise_row(row), "details": {}}


# ------------------------------------------------------------------------- persistence
def _atomic_write_text(path: Path, text: str) -> None:
    atomic_write(path, lambda fh: fh.write(text.encode()))


def load_rows(out_dir: Path) -> dict[str, dict]:
    """``{case key: {"row", "details"}}`` of every finished case in ``out_dir/cases``."""
    out = {}
    for p in sorted((Path(out_dir) / "cases").glob("*.json")):
        try:
            out[p.stem] = json.loads(p.read_text())
        except (OSError, json.JSONDecodeError):
            continue  # a torn file cannot exist (atomic writes); ignore foreign files
    return out


def write_table(out_dir: Path, records: Iterable[dict], csv: bool = False) -> Path:
    """Rewrite ``results.parquet`` (and ``results.csv``) atomically from case records."""
    import pandas as pd

    rows = [schema.normalise_row(r["row"]) for r in records]
    df = pd.DataFrame(rows, columns=schema.names())
    for c in schema.COLUMNS:  # stable dtypes even for all-empty columns
        if c.dtype == "float":
            df[c.name] = pd.to_numeric(df[c.name], errors="coerce").astype("float64")
        elif c.dtype == "int":
            df[c.name] = df[c.name].astype("Int64")
        elif c.dtype == "bool":
            df[c.name] = df[c.name].astype("boolean")
        else:
            df[c.name] = df[c.name].astype("string")
    df = df.sort_values(["scene", "case_id", "repetition"], kind="stable").reset_index(drop=True)
    path = Path(out_dir) / "results.parquet"
    atomic_write(path, lambda fh: df.to_parquet(fh, index=False))
    if csv:
        atomic_write(path.with_name("results.csv"), lambda fh: df.to_csv(fh, index=False))
    return path


def _write_manifest(out_dir: Path, matrix: Matrix, extra: dict) -> None:
    man = {"run_id": out_dir.name, "matrix": matrix.data, "matrix_file": matrix.path,
           "n_cases": len(matrix.cases), "columns": schema.column_definitions(),
           "provenance": _provenance(), **extra}
    _atomic_write_text(out_dir / "manifest.json", json.dumps(_jsonable(man), indent=2) + "\n")


# ------------------------------------------------------------------------------ the run
def _snapshot_group(c: Case) -> tuple:
    """What determines a case's HF snapshot sets (cases with equal keys share them)."""
    comp = c.components
    return (c.scene, c.overrides, comp["backend"], comp["formulation"], comp["solver"],
            c.params.get("n_train"), c.params.get("n_valid"),
            json.dumps([c.params.get("backend_options"), c.params.get("formulation_options")],
                       sort_keys=True))


def _prepare_group(c: Case, cache_dir: str, jobs: int | None, registry: Any = None) -> None:
    """The HF snapshots (training + validation) of one case's group, into the cache."""
    from rbbench.hf.snapshots import compute_snapshots
    from rbbench.scene.loading import load_scene
    from rbbench.scene.sampling import parameter_set

    comp = c.components
    scene = load_scene(c.base_scene, c.overrides)
    mus = np.vstack([parameter_set(scene, "train", c.params.get("n_train")),
                     parameter_set(scene, "valid", c.params.get("n_valid"))])
    compute_snapshots(scene, mus, backend=comp["backend"], formulation=comp["formulation"],
                      solver=comp["solver"], cache_dir=Path(cache_dir), n_jobs=jobs,
                      progress=True, strict=False, registry=registry, component_options={
                          "backend": c.params.get("backend_options") or {},
                          "formulation": c.params.get("formulation_options") or {}})


def _prepare_child(c: Case, cache_dir: str, jobs: int | None, registry: Any) -> None:
    os.setsid()  # its own process group: a time-out kills its snapshot workers too
    try:
        _prepare_group(c, cache_dir, jobs, registry)
    except Exception:  # noqa: BLE001 - the cases meet (and record) the same failure
        os._exit(1)
    os._exit(0)


def prepare_snapshots(cases: list[Case], cache_dir: str, jobs: int | None,
                      progress: Callable[[str], None],
                      registry: Registry | None = None) -> dict[tuple, str]:
    """Compute the HF snapshots the cases share, once per group, before the cases start.

    Each group runs in a child process limited to the longest time limit of its cases
    (a hung HF solver cannot stall the run: the group is killed and its cases compute
    what they need under their own limits). Failures are not raised: each affected case
    meets the same failure itself and records it in its row. Returns ``{group: why}``.
    """
    import multiprocessing as mp

    ctx = mp.get_context("fork" if hasattr(os, "fork") else "spawn")
    groups: dict[tuple, Case] = {}
    limits: dict[tuple, float] = {}
    for c in cases:
        k = _snapshot_group(c)
        groups.setdefault(k, c)
        limits[k] = max(limits.get(k, 0.0), c.timeout_s)
    failures = {}
    for key, c in groups.items():
        comp = c.components
        progress(f"HF snapshots for {c.scene} ({comp['backend']}/{comp['solver']})")
        p = ctx.Process(target=_prepare_child, args=(c, cache_dir, jobs, registry))
        p.start()
        try:
            p.join(limits[key])
        except BaseException:  # Ctrl-C: do not leave the group running
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, signal.SIGKILL)
            raise
        if p.is_alive():
            with contextlib.suppress(ProcessLookupError):
                os.killpg(p.pid, signal.SIGKILL)
            p.join(5)
            failures[key] = f"snapshot preparation killed after {limits[key]:g} s"
        elif p.exitcode != 0:
            failures[key] = f"snapshot preparation failed (exit code {p.exitcode})"
    return failures


def run_matrix(matrix: Matrix, out_dir: str | Path, executor: str = "processes",
               jobs: int | None = None, registry: Registry | None = None,
               retry: Iterable[str] = (), csv: bool = False,
               cache_dir: str | Path | None = None, progress: bool = True,
               executor_options: dict | None = None) -> RunSummary:
    """Run every case of ``matrix`` not already finished in ``out_dir``.

    Parameters
    ----------
    executor : str
        A registered executor (``serial``, ``processes``, ``dask``).
    jobs : int, optional
        Concurrent cases (default: the CPUs available).
    retry : statuses
        Recompute finished cases whose status is one of these.
    cache_dir : path, optional
        HF snapshot cache (default ``.rbbench_cache``), shared by all runs.
    """
    from tqdm.auto import tqdm

    reg = registry or default_registry()
    out_dir = Path(out_dir)
    (out_dir / "cases").mkdir(parents=True, exist_ok=True)
    cache_dir = str(cache_dir or ".rbbench_cache")
    retry = set(retry)
    bad = retry - set(schema.STATUSES)
    if bad:
        raise ValueError(f"retry: unknown status(es) {sorted(bad)}; valid: "
                         f"{', '.join(schema.STATUSES)}")
    t0 = time.perf_counter()
    done = load_rows(out_dir)
    records: dict[str, dict] = {}
    kept, todo = [], []
    for c in matrix.cases:
        prev = done.get(c.key)
        if prev is not None and prev["row"].get("status") not in retry:
            records[c.key] = prev
            kept.append(c.key)
        else:
            todo.append(c)
    _write_manifest(out_dir, matrix, {"state": "running", "executor": executor})
    summary = RunSummary(out_dir, {}, kept=kept)
    bar = tqdm(total=len(matrix.cases), initial=len(kept), desc=f"{matrix.name}",
               unit="case", disable=not progress, dynamic_ncols=True)

    def finish(case: Case, record: dict) -> None:
        _atomic_write_text(out_dir / "cases" / f"{case.key}.json",
                           json.dumps(record, indent=1) + "\n")
        records[case.key] = record
        summary.computed.append(case.key)
        write_table(out_dir, records.values(), csv)
        bar.update(1)
        bar.set_postfix_str(f"{record['row']['status']}: {case.label}"[:60])

    def stage(msg: str) -> None:
        bar.set_postfix_str(msg[:60])

    runnable = [c for c in todo if c.status == "run"]
    rb_cases = [c for c in runnable if c.mode == "rb"]
    for c in todo:
        if c.status != "run":
            finish(c, decided_row(c, out_dir.name, executor))
    ex = reg.create("executor", executor, jobs=jobs, **(executor_options or {}))
    try:
        if runnable:
            prepare_snapshots(rb_cases, cache_dir, jobs, stage, reg)
            ex.run(runnable, run_id=out_dir.name, cache_dir=cache_dir, registry=reg,
                   on_result=finish, on_stage=stage)
    except KeyboardInterrupt:
        summary.interrupted = True
    finally:
        bar.close()
        write_table(out_dir, records.values(), csv)
        summary.counts = {}
        for r in records.values():
            st = r["row"]["status"]
            summary.counts[st] = summary.counts.get(st, 0) + 1
        summary.wall_s = time.perf_counter() - t0
        _write_manifest(out_dir, matrix, {
            "state": "interrupted" if summary.interrupted else "finished",
            "executor": executor, "counts": summary.counts,
            "computed_this_run": len(summary.computed), "kept_from_before": len(kept),
            "wall_s": summary.wall_s})
    if summary.interrupted:
        raise KeyboardInterrupt
    return summary


# -------------------------------------------------------------------- timeouts in-process
@contextlib.contextmanager
def alarm(seconds: float):
    """Raise :class:`CaseTimeout` in the main thread after ``seconds`` (SIGALRM).

    Python checks signals between bytecodes: a long compiled call (one sparse
    factorisation) finishes first. The process executors kill instead.
    """
    if seconds is None or seconds <= 0 or not hasattr(signal, "setitimer"):
        yield
        return

    def handler(signum, frame):
        raise CaseTimeout()

    old = signal.signal(signal.SIGALRM, handler)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)

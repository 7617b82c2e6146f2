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
(:mod:`rbbench.hf.snapshots.compute`) and computed once per scene / HF components /
parameter set before the cases that share them start. One case becomes its row in
:mod:`rbbench.bench.execution`, shared with the executors.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import time
import warnings
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rbbench.bench import json_text, schema
from rbbench.bench.execution import (
    CaseTimeout,
    decided_row,
    execute_case,
    run_provenance,
)
from rbbench.bench.guard import RunLock, Watchdog
from rbbench.bench.matrix import Case, Matrix
from rbbench.hf.snapshots.cache import atomic_write
from rbbench.provenance import _jsonable
from rbbench.registry import Registry, default_registry
from rbbench.runtime.workers import die_with_parent

__all__ = ["CaseTimeout", "RunSummary", "execute_case", "load_rows", "run_matrix"]


@dataclass
class RunSummary:
    """What :func:`run_matrix` did: counts per status, cases computed and kept."""

    out_dir: Path
    counts: dict[str, int]
    computed: list[str] = field(default_factory=list)
    kept: list[str] = field(default_factory=list)
    interrupted: bool = False
    wall_s: float = 0.0


# ------------------------------------------------------------------------- persistence
def _atomic_write_text(path: Path, text: str) -> None:
    atomic_write(path, lambda fh: fh.write(text.encode()))


def load_rows(out_dir: Path) -> dict[str, dict]:
    """``{case key: {"row", "details"}}`` of every valid case file in ``out_dir/cases``.

    A file that is not a case record of its own name (unreadable, not JSON, JSON of
    another shape, a row without identity or status, a copy under another case's name)
    is left out with a warning naming it: its case, if selected, is computed again.
    """
    out = {}
    for p in sorted((Path(out_dir) / "cases").glob("*.json")):
        try:
            rec = json_text.loads(json_text.read_text(p))
        except (OSError, ValueError) as exc:
            problem = f"unreadable ({type(exc).__name__}: {exc})"
        else:
            problem = schema.case_record_problem(p.name, rec)
        if problem is not None:
            warnings.warn(f"{p}: {problem}; ignored (its case is computed again when "
                          "selected)", RuntimeWarning, stacklevel=2)
            continue
        rec.setdefault("details", {})
        out[p.stem] = rec
    return out


def write_table(out_dir: Path, records: Iterable[dict], csv: bool = False) -> Path:
    """Rewrite ``results.parquet`` (and ``results.csv``) atomically from case records."""
    from rbbench.bench.results import results_frame

    # every column with its schema dtype (rbbench.bench.results.DTYPES), even all-empty ones
    df = results_frame(schema.normalise_row(r["row"]) for r in records)
    df = df.sort_values(["scene", "case_id", "repetition"], kind="stable").reset_index(drop=True)
    path = Path(out_dir) / "results.parquet"
    atomic_write(path, lambda fh: df.to_parquet(fh, index=False))
    if csv:
        atomic_write(path.with_name("results.csv"), lambda fh: df.to_csv(fh, index=False))
    return path


def _write_manifest(out_dir: Path, matrix: Matrix, extra: dict) -> None:
    man = {"run_id": out_dir.name, "matrix": matrix.data, "matrix_file": matrix.path,
           "n_cases": len(matrix.cases), "columns": schema.column_definitions(),
           "provenance": run_provenance(), **extra}
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
    from rbbench.hf.snapshots.compute import compute_snapshots
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
    die_with_parent()  # and the run's watchdog kills the group if the run is killed
    try:
        _prepare_group(c, cache_dir, jobs, registry)
    except Exception:  # noqa: BLE001 - the cases meet (and record) the same failure
        os._exit(1)
    os._exit(0)


def prepare_snapshots(cases: list[Case], cache_dir: str, jobs: int | None,
                      progress: Callable[[str], None],
                      registry: Registry | None = None,
                      watchdog: Watchdog | None = None) -> dict[tuple, str]:
    """Compute the HF snapshots the cases share, once per group, before the cases start.

    Each group runs in a child process limited to the longest time limit of its cases
    (a hung HF solver cannot stall the run: the group is killed and its cases compute
    what they need under their own limits). Failures are not raised: each affected case
    meets the same failure itself and records it in its row. Returns ``{group: why}``.
    ``watchdog`` kills a group's processes if the run is killed meanwhile.
    """
    from rbbench.runtime.workers import process_context

    ctx = process_context()  # fork from the main thread only
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
        if watchdog is not None:
            watchdog.protect(p.pid)
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
        with contextlib.suppress(ProcessLookupError):  # its pool workers, if any are left
            os.killpg(p.pid, signal.SIGKILL)
        if watchdog is not None:
            watchdog.forget(p.pid)
    return failures


def _check_retry(retry: Iterable[str]) -> set[str]:
    """The statuses to recompute, checked against :data:`rbbench.bench.schema.STATUSES`."""
    retry = set(retry)
    bad = retry - set(schema.STATUSES)
    if bad:
        raise ValueError(f"retry: unknown status(es) {sorted(bad)}; valid: "
                         f"{', '.join(schema.STATUSES)}")
    return retry


def _split_finished(cases: list[Case], done: dict[str, dict],
                    retry: set[str]) -> tuple[dict[str, dict], list[str], list[Case]]:
    """The records kept from before (by case key), their keys, and the cases to compute
    (not finished, or finished with a status in ``retry``)."""
    records: dict[str, dict] = {}
    kept, todo = [], []
    for c in cases:
        prev = done.get(c.key)
        if prev is not None and prev["row"].get("status") not in retry:
            records[c.key] = prev
            kept.append(c.key)
        else:
            todo.append(c)
    return records, kept, todo


@dataclass
class _Run:
    """A run in progress: its records by case key, its summary (with the run directory) and
    its progress bar. ``others``: the valid case files of the run directory outside this
    run's matrix (other selections): they stay in the table."""

    records: dict[str, dict]
    summary: RunSummary
    csv: bool
    bar: Any
    others: dict[str, dict] = field(default_factory=dict)

    @property
    def out_dir(self) -> Path:
        return self.summary.out_dir

    def table(self) -> None:
        """Rewrite the table from every valid case file of the run directory."""
        write_table(self.out_dir, [*self.others.values(), *self.records.values()], self.csv)

    def finish(self, case: Case, record: dict) -> None:
        """A case ended: write its file, then the table (``on_result`` of the executors)."""
        _atomic_write_text(self.out_dir / "cases" / f"{case.key}.json",
                           json.dumps(record, indent=1) + "\n")
        self.records[case.key] = record
        self.summary.computed.append(case.key)
        self.table()
        self.bar.update(1)
        self.bar.set_postfix_str(f"{record['row']['status']}: {case.label}"[:60])

    def stage(self, msg: str) -> None:
        """What a running case does now (``on_stage`` of the executors)."""
        self.bar.set_postfix_str(msg[:60])

    def close(self, matrix: Matrix, executor: str, t0: float) -> None:
        """The final table, counts per status, wall time and manifest (also on Ctrl-C)."""
        summary = self.summary
        self.bar.close()
        self.table()
        summary.counts = {}
        for r in self.records.values():
            st = r["row"]["status"]
            summary.counts[st] = summary.counts.get(st, 0) + 1
        summary.wall_s = time.perf_counter() - t0
        _write_manifest(self.out_dir, matrix, {
            "state": "interrupted" if summary.interrupted else "finished",
            "executor": executor, "counts": summary.counts,
            "computed_this_run": len(summary.computed), "kept_from_before": len(summary.kept),
            "rows_in_table": len(self.records) + len(self.others),
            "wall_s": summary.wall_s})


def _check_dirs(out_dir: Path, cache_dir: str, jobs: int | None) -> None:
    """The run directory and the cache directory are directories (or absent); ``jobs``
    is a positive integer or None. ``ValueError`` naming the option otherwise."""
    if out_dir.exists() and not out_dir.is_dir():
        raise ValueError(f"run directory (--out) {out_dir}: exists and is not a directory")
    if Path(cache_dir).exists() and not Path(cache_dir).is_dir():
        raise ValueError(f"HF snapshot cache (--cache-dir) {cache_dir}: exists and is not a "
                         "directory")
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        raise ValueError(f"jobs (--jobs) = {jobs!r}: give an integer >= 1")


@contextlib.contextmanager
def _sigterm_as_interrupt():
    """SIGTERM ends the run like Ctrl-C (rows kept, manifest ``interrupted``)."""
    def handler(signum, frame):
        raise KeyboardInterrupt

    try:
        old = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread: leave SIGTERM alone
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


def run_matrix(matrix: Matrix, out_dir: str | Path, executor: str = "processes",
               jobs: int | None = None, registry: Registry | None = None,
               retry: Iterable[str] = (), csv: bool = False,
               cache_dir: str | Path | None = None, progress: bool = True,
               executor_options: dict | None = None) -> RunSummary:
    """Run every case of ``matrix`` not already finished in ``out_dir``.

    One run writes to a run directory at a time (``DIR/.rbbench.lock``; a second one gets
    :class:`~rbbench.bench.guard.RunLockedError`). The table holds every valid case file
    of the directory (also those of other selections); damaged case files are recomputed
    with a warning. If the run's process is killed, a watchdog kills the snapshot
    preparation and marks the manifest ``interrupted`` (also on Ctrl-C and SIGTERM).

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
    reg = registry or default_registry()
    out_dir = Path(out_dir)
    cache_dir = str(cache_dir or ".rbbench_cache")
    _check_dirs(out_dir, cache_dir, jobs)
    retry = _check_retry(retry)
    (out_dir / "cases").mkdir(parents=True, exist_ok=True)
    with RunLock(out_dir), _sigterm_as_interrupt():
        watchdog = Watchdog(out_dir)
        try:
            return _run_locked(matrix, out_dir, executor, jobs, reg, retry, csv, cache_dir,
                               progress, executor_options or {}, watchdog)
        finally:
            watchdog.stop()


def _run_locked(matrix: Matrix, out_dir: Path, executor: str, jobs: int | None,
                reg: Registry, retry: set[str], csv: bool, cache_dir: str, progress: bool,
                executor_options: dict, watchdog: Watchdog) -> RunSummary:
    """:func:`run_matrix` once the run directory is locked."""
    from tqdm.auto import tqdm

    t0 = time.perf_counter()
    done = load_rows(out_dir)
    records, kept, todo = _split_finished(matrix.cases, done, retry)
    selected = {c.key for c in matrix.cases}
    others = {k: v for k, v in done.items() if k not in selected}
    _write_manifest(out_dir, matrix, {"state": "running", "executor": executor})
    run = _Run(records, RunSummary(out_dir, {}, kept=kept), csv,
               tqdm(total=len(matrix.cases), initial=len(kept), desc=f"{matrix.name}",
                    unit="case", disable=not progress, dynamic_ncols=True), others)
    runnable = [c for c in todo if c.status == "run"]
    rb_cases = [c for c in runnable if c.mode == "rb"]
    try:
        for c in todo:
            if c.status != "run":
                run.finish(c, decided_row(c, out_dir.name, executor))
        ex = reg.create("executor", executor, jobs=jobs, **executor_options)
        if runnable:
            prepare_snapshots(rb_cases, cache_dir, jobs, run.stage, reg, watchdog)
            ex.run(runnable, run_id=out_dir.name, cache_dir=cache_dir, registry=reg,
                   on_result=run.finish, on_stage=run.stage)
    except KeyboardInterrupt:
        run.summary.interrupted = True
    finally:
        run.close(matrix, executor, t0)
    if run.summary.interrupted:
        raise KeyboardInterrupt
    return run.summary

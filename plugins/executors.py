"""Executors: where the cases of a run matrix run (serial, local processes, Dask).

Every executor has ``run(cases, run_id, cache_dir, registry, on_result, on_stage)``
and calls ``on_result(case, record)`` once per case, whatever happens to it
(``record`` from :func:`rbbench.bench.execution.execute_case`, or a ``timeout`` /
``error`` row when the case's process was killed or died). Time limits
(``Case.timeout_s``) are enforced by killing the case's process (processes,
dask) or by SIGALRM (serial: Python-level, a long compiled call ends first).
"""

from __future__ import annotations

import ctypes
import multiprocessing as mp
import signal
import sys
import time
import traceback
from collections import deque
from collections.abc import Callable
from multiprocessing.connection import wait
from typing import Any

from rbbench.bench.execution import CaseTimeout, alarm, execute_case, failed_row
from rbbench.bench.matrix import Case
from rbbench.hf.snapshots.compute import n_cpus
from rbbench.runtime.workers import process_context

OnResult = Callable[[Case, dict], None]
OnStage = Callable[[str], None]


def _jobs(jobs: int | None) -> int:
    if jobs is not None:
        if int(jobs) < 1:
            raise ValueError(f"executor: jobs = {jobs}; give an integer >= 1")
        return int(jobs)
    return max(1, n_cpus())


def _timeout_row(case: Case, run_id: str, name: str, killed: bool = True) -> dict:
    """The ``timeout`` row of a case stopped at its time limit."""
    return failed_row(case, run_id, name, "timeout",
                      f"exceeded the case limit of {case.timeout_s:g} s"
                      + (" (killed)" if killed else ""))


class SerialExecutor:
    """One case after the other in this process (debugging; timeouts by SIGALRM)."""

    name = "serial"

    def __init__(self, jobs: int | None = None) -> None:
        self.jobs = 1

    def run(self, cases: list[Case], run_id: str, cache_dir: str, registry: Any,
            on_result: OnResult, on_stage: OnStage) -> None:
        for case in cases:
            try:
                with alarm(case.timeout_s):
                    rec = execute_case(case, run_id, cache_dir, self.name, registry,
                                       lambda m, c=case: on_stage(f"{c.label}: {m}"))
            except CaseTimeout:
                rec = _timeout_row(case, run_id, self.name, killed=False)
            on_result(case, rec)


def _die_with_parent() -> None:
    """Linux: the child gets SIGKILL when its parent dies (a killed run leaves no orphans)."""
    if sys.platform.startswith("linux"):
        try:
            ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except OSError:  # pragma: no cover
            pass


def _child(conn, case: Case, run_id: str, cache_dir: str, registry: Any, name: str) -> None:
    _die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent handles Ctrl-C
    try:
        from threadpoolctl import threadpool_limits

        threadpool_limits(1)  # one BLAS thread per case: jobs cases share the cores
    except Exception:  # noqa: BLE001 - optional
        pass
    try:
        rec = execute_case(case, run_id, cache_dir, name, registry,
                           lambda m: conn.send(("stage", m)))
        conn.send(("result", rec))
    except BaseException:  # noqa: BLE001 - anything left is reported by the parent
        conn.send(("crash", traceback.format_exc()))
    finally:
        conn.close()


def _receive(conn, p) -> tuple[str, Any]:
    """The next message ``(kind, payload)`` from a case's process, or ``("died", exit code)``
    when its pipe closed without one."""
    try:
        return conn.recv()
    except (EOFError, OSError):
        p.join(5)
        return "died", p.exitcode


def _kill(p) -> None:
    p.kill()
    p.join(5)


def _record(kind: str, payload: Any, case: Case, run_id: str, name: str) -> dict:
    """The case's record from the last message of its process: its ``result``, or an
    ``error`` row for a ``crash`` (traceback) or a process that ``died`` (exit code)."""
    if kind == "result":
        return payload
    if kind == "crash":
        return failed_row(case, run_id, name, "error", "the case's process crashed", payload)
    return failed_row(case, run_id, name, "error",
                      f"the case's process died (exit code {payload}; negative: killed by "
                      "that signal, e.g. -9 out of memory)")


class ProcessExecutor:
    """``jobs`` cases at a time, each in its own process (the default).

    A case that passes its time limit is killed and gets a ``timeout`` row; a
    process that dies (segfault, out of memory) gets an ``error`` row with its
    exit code. Ctrl-C kills the running cases (their rows are not written; a
    rerun computes them).
    """

    name = "processes"

    def __init__(self, jobs: int | None = None, start_method: str | None = None) -> None:
        self.jobs = _jobs(jobs)
        self.ctx = process_context(start_method)

    def run(self, cases: list[Case], run_id: str, cache_dir: str, registry: Any,
            on_result: OnResult, on_stage: OnStage) -> None:
        pending = deque(cases)
        running: dict[Any, tuple[Any, Case, float]] = {}
        try:
            while pending or running:
                while pending and len(running) < self.jobs:
                    case = pending.popleft()
                    recv, send = self.ctx.Pipe(duplex=False)
                    p = self.ctx.Process(target=_child, daemon=True,
                                         args=(send, case, run_id, cache_dir, registry,
                                               self.name))
                    p.start()
                    send.close()
                    running[recv] = (p, case, time.monotonic() + case.timeout_s)
                for conn in wait(list(running), timeout=0.25):
                    p, case, _ = running[conn]
                    kind, payload = _receive(conn, p)
                    if kind == "stage":
                        on_stage(f"{case.label}: {payload}")
                        continue
                    del running[conn]
                    conn.close()
                    p.join(5)
                    on_result(case, _record(kind, payload, case, run_id, self.name))
                now = time.monotonic()
                for conn, (p, case, deadline) in list(running.items()):
                    if now > deadline:
                        _kill(p)
                        del running[conn]
                        conn.close()
                        on_result(case, _timeout_row(case, run_id, self.name))
        finally:
            for conn, (p, _, _) in running.items():
                _kill(p)
                conn.close()


def run_isolated(case: Case, run_id: str, cache_dir: str, registry: Any,
                 name: str = "dask", start_method: str = "forkserver") -> dict:
    """Run one case in a child process with its time limit; the record it produced.

    Used inside Dask tasks. If this process may not start children (a daemonic
    Dask worker: set ``DASK_DISTRIBUTED__WORKER__DAEMON=False`` on the workers),
    the case runs in place and the time limit is not enforced; the row's reason
    says so.
    """
    ctx = mp.get_context(start_method)
    recv, send = ctx.Pipe(duplex=False)
    try:
        p = ctx.Process(target=_child, args=(send, case, run_id, cache_dir, registry, name))
        p.start()
    except AssertionError:  # "daemonic processes are not allowed to have children"
        rec = execute_case(case, run_id, cache_dir, name, registry)
        rec["row"]["reason"] = ((rec["row"].get("reason") or "") +
                                " [time limit not enforced: daemonic worker]").strip()
        return rec
    send.close()
    deadline = time.monotonic() + case.timeout_s
    try:
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                _kill(p)
                return _timeout_row(case, run_id, name)
            if recv.poll(min(left, 0.5)):
                kind, payload = _receive(recv, p)
                if kind == "stage":
                    continue
                p.join(5)
                return _record(kind, payload, case, run_id, name)
    finally:
        recv.close()
        if p.is_alive():
            p.kill()


class DaskExecutor:
    """Cases as Dask tasks (extra ``dask``): a LocalCluster by default, or a scheduler.

    Parameters
    ----------
    jobs : int, optional
        Workers x threads of the LocalCluster (default: the CPUs available).
    address : str, optional
        Scheduler address of an existing cluster (``tcp://host:8786``); its workers
        need rbbench installed and the same scene / matrix files, and the cache
        directory on a shared file system.
    processes : bool
        LocalCluster with worker processes (default False: threads in one worker
        process, each case still runs in its own child process with its time limit).
    """

    name = "dask"

    def __init__(self, jobs: int | None = None, address: str | None = None,
                 processes: bool = False) -> None:
        self.jobs = _jobs(jobs)
        self.address = address
        self.processes = bool(processes)

    def run(self, cases: list[Case], run_id: str, cache_dir: str, registry: Any,
            on_result: OnResult, on_stage: OnStage) -> None:
        from dask.distributed import Client, LocalCluster, as_completed

        cluster = None
        if self.address:
            client = Client(self.address)
        else:
            kw = ({"n_workers": self.jobs, "threads_per_worker": 1} if self.processes
                  else {"n_workers": 1, "threads_per_worker": self.jobs})
            cluster = LocalCluster(processes=self.processes, dashboard_address=None, **kw)
            client = Client(cluster)
        try:
            on_stage(f"dask: {len(cases)} cases on {client.dashboard_link or 'a cluster'}")
            futures = {client.submit(run_isolated, c, run_id, cache_dir, registry, self.name,
                                     pure=False): c for c in cases}
            for fut in as_completed(futures):
                case = futures[fut]
                try:
                    rec = fut.result()
                except Exception as exc:  # noqa: BLE001 - lost task: a row, not a lost run
                    rec = failed_row(case, run_id, self.name, "error",
                                     f"dask task failed: {type(exc).__name__}: {exc}")
                on_result(case, rec)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()

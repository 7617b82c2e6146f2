"""Helpers shared by the diagnostics of this folder: the ``--rounds`` / ``--pause``
arguments, and a log of the snapshot workers' tasks (start, end, memory)."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np


def rounds_and_pause(doc: str, rounds: int) -> argparse.Namespace:
    """``--rounds`` (default ``rounds``) and ``--pause`` (default 0.5 s) of the side-by-side
    scripts of this folder; ``doc``: the script's docstring (its first line describes it)."""
    p = argparse.ArgumentParser(description=doc.split("\n")[0])
    p.add_argument("--rounds", type=int, default=rounds)
    p.add_argument("--pause", type=float, default=0.5)
    return p.parse_args()


#: the file, in a call's cache root, where :func:`logged_worker_tasks` logs its tasks
TASK_LOG = "tasks.log"


def _anon_kb() -> int:
    with open("/proc/self/smaps_rollup") as fh:
        return next(int(line.split()[1]) for line in fh if line.startswith("Anonymous:"))


@contextlib.contextmanager
def logged_worker_tasks(memory: bool = False) -> Iterator[None]:
    """Within the block, every snapshot worker task appends ``pid start end kB r0 r1`` to
    :data:`TASK_LOG` in its call's cache root (found from the task's path, so a kept worker
    logs each call in its own place). ``start`` and ``end`` are ``time.perf_counter``: the
    system-wide monotonic clock on Linux, comparable with this process's. With ``memory``,
    a worker's first task in the block also records the anonymous kB it added (``/proc``,
    Linux): ``kB``, read from ``r0`` (before ``start``) to ``r1`` (after ``end``), each read
    ~3-4 ms here, so only once per worker; elsewhere ``kB`` is NaN and ``r0, r1`` are
    ``start, end``. For ``fork`` workers (they inherit the patch) in the side-by-side
    scripts of this folder; read it with :func:`task_log`."""
    from rbbench.hf.snapshots import compute as snapshots

    task = snapshots._worker_task
    measured: set[int] = set()  # the pids whose first task was measured (one per process)

    def logged(mu, path):
        first = memory and os.getpid() not in measured
        measured.add(os.getpid())
        r0 = time.perf_counter()
        a0 = _anon_kb() if first else 0
        t0 = time.perf_counter()
        snap = task(mu, path)
        t1 = time.perf_counter()
        kb = _anon_kb() - a0 if first else math.nan
        r1 = time.perf_counter() if first else t1
        with open(Path(path).parent.parent / TASK_LOG, "a") as fh:  # cache root / key / file
            fh.write(f"{os.getpid()} {t0} {t1} {kb} {r0 if first else t0} {r1}\n")
        return snap

    # pickled by reference to the patched name, which the forked workers share
    logged.__module__, logged.__qualname__ = snapshots.__name__, "_worker_task"
    snapshots._worker_task = logged
    try:
        yield
    finally:
        snapshots._worker_task = task


def task_log(cache_dir: str | os.PathLike) -> tuple[np.ndarray, np.ndarray]:
    """The rows of :data:`TASK_LOG` in ``cache_dir`` by start time (``pid, start, end, kB,
    r0, r1``: :func:`logged_worker_tasks`), and a mask of each worker's first task among
    them."""
    rows = np.loadtxt(Path(cache_dir) / TASK_LOG, ndmin=2)
    rows = rows[np.argsort(rows[:, 1])]
    first = np.zeros(len(rows), dtype=bool)
    first[np.unique(rows[:, 0], return_index=True)[1]] = True
    return rows, first

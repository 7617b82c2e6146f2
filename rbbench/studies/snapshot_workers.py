"""``rbbench studies snapshot-workers``: HF snapshots with 1 and with n worker processes,
interleaved in one process (target: 2 workers >= 1.85x of 1 on 8 parameters).

Every round times, each into a fresh cache directory (so every solve runs), the same
``P`` parameters in three units, ``serial``, ``fresh`` and the ``kept`` block, whose order
turns by one each round (round ``r`` starts with unit ``r mod 3``), so that no case always
follows the same one:

``serial``
    ``n_jobs = 1``, in this process;
``fresh``
    ``n_jobs = n``, a pool started for the call and shut down after it (what a single
    :func:`~rbbench.hf.snapshots.compute.compute_snapshots` call costs);
``kept_1st``, ``kept_2nd``
    two calls inside one :func:`~rbbench.runtime.workers.keep_workers` block: the second
    finds workers that already solved (``rbbench reduce``'s validation call after its
    training call).

This process's components are built once before the first round (one snapshot), as
the asv benchmarks ``SnapshotWorkers`` and ``SnapshotWorkersKept`` do. Before each serial
call, one untimed snapshot in this process (``settle``): a ``fork`` write-protects this
process's pages, and after a pool call its next work takes a page fault on each page it
writes again (measured: 7.5k faults, a serial call 1.232 s right after a fresh pool call
against 1.196 s after a serial one, 8 rounds); without it the serial time, hence every
speed-up, carried the previous unit's cost (about 3 % too high in earlier runs). The
faults of the settling call are reported (``settle_faults``, median): that cost lands on
whatever this process does after a pool call. After the serial
call, the fresh call and the block the study waits ``pause`` seconds (default 0.5),
outside the timing: at the end of a call that started a pool, this process's BLAS pools
are restored (:func:`~rbbench.runtime.threads.capped_for_fork`) and OpenBLAS re-creates its
threads, which spin 2^N cycles idle (``OPENBLAS_THREAD_TIMEOUT``: 2^20, ~0.4 ms, under the
``rbbench`` command, :mod:`rbbench.runtime.openblas_env`; OpenBLAS's default 2^28, ~0.1 s, when
this function is called from Python without it); back to back, they would run into the
next unit's timing. The block's two calls run back to back, as ``rbbench reduce``'s do:
``kept_2nd`` meets the threads of ``kept_1st``'s end. Reported: the
median wall time of each case over the rounds, its interquartile range, and the speed-up
``median(serial) / median(case)``.
"""

from __future__ import annotations

import tempfile
import time
from typing import Any

import numpy as np

from rbbench._compat import deprecated_names

__all__ = ["CASES", "snapshot_workers"]

CASES = ("serial", "fresh", "kept_1st", "kept_2nd")


def snapshot_workers(scene: Any, mus: np.ndarray, n_jobs: int = 2, rounds: int = 15,
                     pause: float = 0.5) -> dict[str, Any]:
    """``{"cases": {case: {"median_s", "iqr_s", "speedup"}}, "settle_faults": n}`` over
    ``rounds`` interleaved rounds (cases: :data:`CASES`; ``speedup`` = median serial time /
    median time of the case; ``pause``: seconds waited, untimed, after the serial call, the
    fresh call and the kept block, whose two calls run back to back; ``settle_faults``: the
    median minor page faults of the untimed snapshot before each serial call)."""
    from rbbench.hf.snapshots.compute import compute_snapshots
    from rbbench.runtime.workers import keep_workers

    def call(jobs: int, wait: float = pause, which: np.ndarray = mus) -> float:
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            compute_snapshots(scene, which, cache_dir=d, n_jobs=jobs, progress=False)
            elapsed = time.perf_counter() - t0
        time.sleep(wait)
        return elapsed

    call(1, 0.0, mus[:1])  # this process's components, built once
    times: dict[str, list[float]] = {c: [] for c in CASES}
    settle_faults: list[int] = []

    def serial() -> None:
        f0 = _minor_faults()
        call(1, 0.0, mus[:1])  # settle: the faults a previous fork left (module docstring)
        settle_faults.append(_minor_faults() - f0)
        times["serial"].append(call(1))

    def kept() -> None:
        with keep_workers():  # back to back, as rbbench reduce's two calls
            times["kept_1st"].append(call(n_jobs, wait=0.0))
            times["kept_2nd"].append(call(n_jobs, wait=0.0))
        time.sleep(pause)

    units = [serial, lambda: times["fresh"].append(call(n_jobs)), kept]
    for r in range(rounds):
        for unit in units[r % 3:] + units[:r % 3]:
            unit()
    serial_s = float(np.median(times["serial"]))
    cases: dict[str, dict[str, float]] = {}
    for case, t in times.items():
        q1, med, q3 = np.percentile(t, [25, 50, 75])
        cases[case] = {"median_s": float(med), "iqr_s": float(q3 - q1),
                       "speedup": serial_s / float(med)}
    return {"cases": cases, "settle_faults": float(np.median(settle_faults))}


def _minor_faults() -> int:
    """This process's minor page faults so far (``getrusage``; 0 where unavailable)."""
    try:
        import resource
    except ImportError:  # pragma: no cover - not POSIX
        return 0
    return int(resource.getrusage(resource.RUSAGE_SELF).ru_minflt)


def markdown(rows: dict[str, dict[str, float]], n_jobs: int) -> str:
    """The result of :func:`snapshot_workers` as a Markdown table."""
    lines = ["| case | workers | median wall (s) | IQR (s) | speed-up vs serial |",
             "|---|---|---|---|---|"]
    for case, r in rows.items():
        jobs = 1 if case == "serial" else n_jobs
        lines.append(f"| {case} | {jobs} | {r['median_s']:.3f} | {r['iqr_s']:.3f} | "
                     f"{r['speedup']:.2f}x |")
    return "\n".join(lines)


__getattr__ = deprecated_names(__name__)  # names that left this module (rbbench._compat)

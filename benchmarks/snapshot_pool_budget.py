"""Diagnostic: where the time of a fresh 2-worker snapshot call goes, against a serial one.

Issue 17, item 4 (2 workers >= 1.85x of 1 on 8 parameters). Each round times, in this
process, one serial call (after an untimed one-parameter call that pays the page faults
the last fork left here, as ``rbbench studies snapshot-workers`` does) and one call that
starts its own ``fork`` pool, each into a fresh cache directory, with an untimed pause after
each. The workers log when each task starts and ends (``time.perf_counter``: the
system-wide monotonic clock on Linux) and the anonymous memory their first task adds
(``/proc/self/smaps_rollup``). Printed, medians over the rounds:

* ``serial``: the call, and one solve in it;
* ``fresh``: the call; ``pre`` (call start to the first task's start: the fork, the
  worker start-up), ``first task`` and ``later tasks`` of a worker, ``post`` (the last
  task's end to the call's end: results, shutdown and join of the workers);
* the fresh memory a worker's first task writes and this machine's rate of first touches
  (64 MB of fresh anonymous memory written once);
* ``balanced bound``: the serial call over ``pre + first + (P / n - 1) later + post``, the
  speed-up of a perfectly balanced call with these parts::

    python -m benchmarks.snapshot_pool_budget --rounds 10

OpenBLAS's idle spin is set as under the ``rbbench`` command (:mod:`rbbench._openblas_env`).
Not an asv benchmark (it patches the worker task and reads ``/proc``: Linux).
"""

from __future__ import annotations

import mmap
import os
import tempfile
import time

from rbbench import _openblas_env  # noqa: F401  (first, as the command: before numpy)

# isort: split
import numpy as np

from rbbench.hf import snapshots

#: the file the workers of the current call log to (set before the fork: inherited)
_LOG: dict[str, str] = {"path": ""}
_task = snapshots._worker_task


def _anon_kb() -> int:
    with open("/proc/self/smaps_rollup") as fh:
        return next(int(line.split()[1]) for line in fh if line.startswith("Anonymous:"))


def logged_task(mu: np.ndarray, path: os.PathLike) -> snapshots.Snapshot:
    """The worker task, logging ``pid start end anon_kb_added``."""
    a0, t0 = _anon_kb(), time.perf_counter()
    snap = _task(mu, path)
    t1 = time.perf_counter()
    with open(_LOG["path"], "a") as fh:
        fh.write(f"{os.getpid()} {t0} {t1} {_anon_kb() - a0}\n")
    return snap


logged_task.__name__ = logged_task.__qualname__ = "logged_task"


def first_touch_us_per_page(nbytes: int = 64 << 20) -> float:
    """Microseconds per 4 kB page to write fresh anonymous memory once."""
    buf = mmap.mmap(-1, nbytes)
    view = np.frombuffer(buf, dtype=np.uint8)
    t0 = time.perf_counter()
    view[::4096] = 1
    elapsed = time.perf_counter() - t0
    del view
    buf.close()
    return elapsed * 1e6 / (nbytes // 4096)


def _fresh_parts(log: str, t0: float, t1: float) -> dict[str, list[float]]:
    rows = np.loadtxt(log, ndmin=2)
    out: dict[str, list[float]] = {"pre": [float(rows[:, 1].min() - t0)],
                                   "post": [float(t1 - rows[:, 2].max())],
                                   "first": [], "later": [], "first_mb": []}
    for pid in np.unique(rows[:, 0]):
        mine = rows[rows[:, 0] == pid]
        mine = mine[np.argsort(mine[:, 1])]
        out["first"].append(float(mine[0, 2] - mine[0, 1]))
        out["first_mb"].append(float(mine[0, 3]) / 1024)
        out["later"] += [float(e - s) for s, e in mine[1:, 1:3]]
    return out


def budget(rounds: int, pause: float, P: int = 8, n_jobs: int = 2) -> dict[str, float]:
    """Medians (s, MB, us) of the parts in the module docstring."""
    from rbbench.scene.loading import load_scene
    from rbbench.scene.sampling import parameter_set

    scene = load_scene("hertz_halfdisks", [])
    mus = parameter_set(scene, "valid", n=P, kind="lhs")
    snapshots._worker_task = logged_task
    parts: dict[str, list[float]] = {"serial": [], "fresh": []}
    solves: list[float] = []
    try:
        with tempfile.TemporaryDirectory() as tmp:
            for r in range(rounds + 1):  # round 0: this process's components, untimed
                with tempfile.TemporaryDirectory() as d:
                    snapshots.compute_snapshots(scene, mus[:1], cache_dir=d, n_jobs=1,
                                                progress=False)
                for jobs in ((1, n_jobs) if r % 2 else (n_jobs, 1)):
                    _LOG["path"] = os.path.join(tmp, f"log{r}_{jobs}")
                    with tempfile.TemporaryDirectory() as d:
                        t0 = time.perf_counter()
                        out = snapshots.compute_snapshots(scene, mus, cache_dir=d,
                                                          n_jobs=jobs, progress=False)
                        t1 = time.perf_counter()
                    time.sleep(pause)
                    if r == 0:
                        continue
                    if jobs == 1:
                        parts["serial"].append(t1 - t0)
                        solves += [float(t) for t in out.times]
                    else:
                        parts["fresh"].append(t1 - t0)
                        for k, v in _fresh_parts(_LOG["path"], t0, t1).items():
                            parts.setdefault(k, []).extend(v)
    finally:
        snapshots._worker_task = _task
    med = {k: float(np.median(v)) for k, v in parts.items()}
    med["serial_solve"] = float(np.median(solves))
    med["first_touch_us"] = first_touch_us_per_page()
    med["bound"] = med["serial"] / (med["pre"] + med["first"] + (P / n_jobs - 1) * med["later"]
                                    + med["post"])
    med["speedup"] = med["serial"] / med["fresh"]
    return med


def main() -> None:
    from benchmarks._common import rounds_and_pause

    args = rounds_and_pause(__doc__, 10)
    m = budget(args.rounds, args.pause)
    print(f"serial call {m['serial']:.3f} s, the HF time of one solve in it "
          f"{m['serial_solve']:.3f} s")
    print(f"fresh call {m['fresh']:.3f} s ({m['speedup']:.2f}x): pre {1e3 * m['pre']:.1f} ms, "
          f"first task {m['first']:.3f} s, later tasks {m['later']:.3f} s, "
          f"post {1e3 * m['post']:.1f} ms")
    print(f"a worker's first task writes {m['first_mb']:.1f} MB of fresh memory; first "
          f"touch here {m['first_touch_us']:.2f} us per 4 kB page "
          f"({m['first_mb'] * 256 * m['first_touch_us'] / 1e3:.1f} ms for that memory)")
    print(f"balanced bound with these parts: {m['bound']:.2f}x")


if __name__ == "__main__":
    main()

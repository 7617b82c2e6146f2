"""Diagnostic: where the time of a fresh 2-worker snapshot call goes, against a serial one.

The snapshot speed-up target (2 workers >= 1.85x of 1 on 8 parameters). Each round times, in this
process, one serial call (after an untimed one-parameter call that pays the page faults
the last fork left here, as ``rbbench studies snapshot-workers`` does) and one call that
starts its own ``fork`` pool, each into a fresh cache directory, with an untimed pause after
each. The workers log when each task starts and ends (``time.perf_counter``: the
system-wide monotonic clock on Linux) and the anonymous memory their first task adds
(``/proc/self/smaps_rollup``). Printed, medians over the rounds:

* ``serial``: the call, and one solve in it;
* ``fresh``: the call; ``pre`` (call start to the first task's start: the fork, the
  worker start-up), ``first task`` and ``later tasks`` of a worker, the time between two
  tasks of a worker (result out, next task in), ``post`` (the last task's end to the
  call's end: results, shutdown and join of the workers). The memory of a worker's first
  task is read around it (``/proc``, ~3-4 ms a read): that time is in the fresh call
  (printed) but in none of the parts;
* the fresh memory a worker's first task writes and this machine's rate of first touches
  (a forked child writing 64 MB of fresh private memory once);
* ``balanced bound``: the serial call over ``pre + first + (P / n - 1) (later + between)
  + post``, the speed-up of a perfectly balanced call with these parts::

    python -m tools.diagnostics.snapshot_pool_budget --rounds 10

OpenBLAS's idle spin is set as under the ``rbbench`` command (:mod:`rbbench.runtime.openblas_env`).
Not an asv benchmark (it patches the worker task and reads ``/proc``: Linux).
"""

from __future__ import annotations

import itertools
import tempfile
import time

from rbbench.runtime import openblas_env as _openblas_env  # noqa: F401  (first, as the command: before numpy)

# isort: split
import numpy as np

from rbbench.hf.snapshots import compute as snapshots
from tools.diagnostics.common import logged_worker_tasks, task_log
from tools.diagnostics.first_touch_fork import in_child


def first_touch_us_per_page(nbytes: int = 64 << 20) -> float:
    """Microseconds per 4 kB page for a forked child to write ``nbytes`` of fresh private
    memory once (4 kB pages: :func:`tools.diagnostics.first_touch_fork.in_child`)."""
    return in_child(nbytes, huge=False)[0] * 1e6 / (nbytes // 4096)


def _fresh_parts(cache_dir: str, t0: float, t1: float) -> dict[str, list[float]]:
    rows, first = task_log(cache_dir)
    pid, start, end, kb, r0, r1 = rows.T
    gaps = [float(start[k] - r1[j]) for w in np.unique(pid)
            for j, k in itertools.pairwise(np.flatnonzero(pid == w))]
    return {"pre": [float(r0.min() - t0)], "post": [float(t1 - r1.max())],
            "first": list(end[first] - start[first]), "first_mb": list(kb[first] / 1024),
            "later": list(end[~first] - start[~first]), "gap": gaps,
            "reads": list((start - r0 + r1 - end)[first])}


def budget(rounds: int, pause: float, P: int = 8, n_jobs: int = 2) -> dict[str, float]:
    """Medians (s, MB, us) of the parts in the module docstring."""
    from rbbench.scene.loading import load_scene
    from rbbench.scene.sampling import parameter_set

    scene = load_scene("hertz_halfdisks", [])
    mus = parameter_set(scene, "valid", n=P, kind="lhs")
    parts: dict[str, list[float]] = {"serial": [], "fresh": []}
    solves: list[float] = []
    with logged_worker_tasks(memory=True):
        for r in range(rounds + 1):  # round 0: this process's components, untimed
            with tempfile.TemporaryDirectory() as d:
                snapshots.compute_snapshots(scene, mus[:1], cache_dir=d, n_jobs=1,
                                            progress=False)
            for jobs in ((1, n_jobs) if r % 2 else (n_jobs, 1)):
                with tempfile.TemporaryDirectory() as d:
                    t0 = time.perf_counter()
                    out = snapshots.compute_snapshots(scene, mus, cache_dir=d, n_jobs=jobs,
                                                      progress=False)
                    t1 = time.perf_counter()
                    if r and jobs == 1:
                        parts["serial"].append(t1 - t0)
                        solves += [float(t) for t in out.times]
                    elif r:
                        parts["fresh"].append(t1 - t0)
                        for k, v in _fresh_parts(d, t0, t1).items():
                            parts.setdefault(k, []).extend(v)
                time.sleep(pause)
    med = {k: float(np.median(v)) for k, v in parts.items()}
    med["serial_solve"] = float(np.median(solves))
    med["first_touch_us"] = first_touch_us_per_page()
    med["bound"] = med["serial"] / (med["pre"] + med["first"]
                                    + (P / n_jobs - 1) * (med["later"] + med["gap"])
                                    + med["post"])
    med["speedup"] = med["serial"] / med["fresh"]
    return med


def main() -> None:
    from tools.diagnostics.common import rounds_and_pause

    args = rounds_and_pause(__doc__, 10)
    m = budget(args.rounds, args.pause)
    print(f"serial call {m['serial']:.3f} s, the HF time of one solve in it "
          f"{m['serial_solve']:.3f} s")
    print(f"fresh call {m['fresh']:.3f} s ({m['speedup']:.2f}x): pre {1e3 * m['pre']:.1f} ms, "
          f"first task {m['first']:.3f} s, later tasks {m['later']:.3f} s, "
          f"between a worker's tasks {1e3 * m['gap']:.1f} ms, post {1e3 * m['post']:.1f} ms")
    print(f"(this script's memory reads around a worker's first task: {1e3 * m['reads']:.1f} ms "
          "in the fresh call, not in the parts)")
    print(f"a worker's first task writes {m['first_mb']:.1f} MB of fresh memory; first "
          f"touch here {m['first_touch_us']:.2f} us per 4 kB page "
          f"({m['first_mb'] * 256 * m['first_touch_us'] / 1e3:.1f} ms for that memory)")
    print(f"balanced bound with these parts: {m['bound']:.2f}x")


if __name__ == "__main__":
    main()

"""Side by side: snapshot workers that inherit the BLAS cap against workers that set it.

The snapshot workers. OpenBLAS re-creates its threads in a ``fork`` child at the child's first
``set_num_threads`` call, and each new thread spins ~0.1 s; since this change a ``fork``
pool's workers inherit the cap from this process (:func:`rbbench.runtime.threads.capped_for_fork`)
and ``threadpoolctl`` is called only on the pools off the limit
(:func:`rbbench.runtime.threads._limit_changed`). ``before`` switches both parts back (no cap
for the fork, every pool set); ``after`` is the code as it is. Each round times, in a fresh
cache directory and in alternating order, the serial call and the 2-worker call of each
mode, with an untimed pause after every call and an untimed one-parameter serial call
before each serial call (as ``rbbench studies snapshot-workers``: it pays the page faults
the previous fork left in this process); the speed-up of a mode is its serial median over
its 2-worker median::

    python -m tools.diagnostics.ab_snapshot_blas_cap --rounds 15 --pause 0.5

Not an asv benchmark (it patches the code it compares); asv times the code as it is
(``bench_hf.SnapshotWorkers``).
"""

from __future__ import annotations

import contextlib
import tempfile
import time

import numpy as np


def ab(rounds: int, pause: float, P: int = 8, n_jobs: int = 2) -> dict[str, float]:
    """Medians (s) of ``serial_<mode>`` and ``pool_<mode>`` and the speed-up of each mode."""
    from rbbench.hf.snapshots import compute as snapshots
    from rbbench.runtime import threads
    from rbbench.scene.loading import load_scene
    from rbbench.scene.sampling import parameter_set

    scene = load_scene("hertz_halfdisks", [])
    mus = parameter_set(scene, "valid", n=P, kind="lhs")
    changed, pool = threads._limit_changed, snapshots.worker_pool

    @contextlib.contextmanager
    def uncapped_pool(*a, blas_cap=0, **kw):
        with pool(*a, blas_cap=0, **kw) as out:
            yield out

    def mode(before: bool) -> None:
        threads._limit_changed = (lambda c, n: c.limit(limits=n)) if before else changed
        snapshots.worker_pool = uncapped_pool if before else pool

    def call(jobs: int, which: np.ndarray = mus, wait: float = pause) -> float:
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            snapshots.compute_snapshots(scene, which, cache_dir=d, n_jobs=jobs,
                                        progress=False)
            elapsed = time.perf_counter() - t0
        time.sleep(wait)
        return elapsed

    call(1, mus[:1], 0.0)  # this process's components, built once
    times: dict[str, list[float]] = {f"{k}_{m}": [] for k in ("serial", "pool")
                                     for m in ("before", "after")}
    try:
        for r in range(rounds):
            for m in (("before", "after") if r % 2 else ("after", "before")):
                mode(m == "before")
                call(1, mus[:1], 0.0)  # settle: the faults the last fork left here
                times[f"serial_{m}"].append(call(1))
                times[f"pool_{m}"].append(call(n_jobs))
    finally:
        mode(False)
    out = {k: float(np.median(v)) for k, v in times.items()}
    for m in ("before", "after"):
        out[f"speedup_{m}"] = out[f"serial_{m}"] / out[f"pool_{m}"]
    return out


def main() -> None:
    from tools.diagnostics.common import rounds_and_pause

    args = rounds_and_pause(__doc__, 15)
    out = ab(args.rounds, args.pause)
    for k, v in out.items():
        print(f"{k:16s} {v:.3f}")


if __name__ == "__main__":
    main()

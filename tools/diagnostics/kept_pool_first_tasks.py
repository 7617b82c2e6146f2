"""Diagnostic: the first tasks of a kept pool's calls, by OpenBLAS's idle-thread spin.

The kept snapshot pool (:mod:`rbbench.runtime.openblas_env`). At the end of the call that starts a
pool this process restores its BLAS pools and OpenBLAS re-creates its threads, which spin
``2^OPENBLAS_THREAD_TIMEOUT`` cycles when idle; the call right after (``rbbench reduce``'s
validation call) meets them. For each value, alternating, a fresh Python process (the
variable is read once, when OpenBLAS loads) runs ``--blocks`` :func:`keep_workers` blocks
of 4 back-to-back calls (8 parameters of Hertz level 0, 2 workers); printed per value: the
range of the workers' first-task times in each call of a block, and of their later
tasks::

    python -m tools.diagnostics.kept_pool_first_tasks --values 28 20 --processes 2 --blocks 3

Not an asv benchmark (it starts processes with their own environment).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys


def _child(blocks: int) -> None:
    """In the process with the variable set: time the blocks, print JSON per call index."""
    import tempfile
    import time

    from rbbench.hf.snapshots import compute as snapshots
    from rbbench.runtime.workers import keep_workers
    from rbbench.scene.loading import load_scene
    from rbbench.scene.sampling import parameter_set
    from tools.diagnostics.common import logged_worker_tasks, task_log

    scene = load_scene("hertz_halfdisks", [])
    mus = parameter_set(scene, "valid", n=8, kind="lhs")
    out: dict[str, list[float]] = {}
    with tempfile.TemporaryDirectory() as tmp, logged_worker_tasks():
        snapshots.compute_snapshots(scene, mus[:1], cache_dir=tmp, n_jobs=1, progress=False)
        for _ in range(blocks):
            with keep_workers():
                for c in range(4):
                    with tempfile.TemporaryDirectory() as d:
                        snapshots.compute_snapshots(scene, mus, cache_dir=d, n_jobs=2,
                                                    progress=False)
                        rows, first = task_log(d)
                    took = rows[:, 2] - rows[:, 1]
                    out.setdefault(f"call{c}_first", []).extend(took[first].tolist())
                    out.setdefault("later", []).extend(took[~first].tolist())
            time.sleep(0.5)
    print(json.dumps(out))


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--values", type=int, nargs="+", default=[28, 20])
    p.add_argument("--processes", type=int, default=2, help="processes per value")
    p.add_argument("--blocks", type=int, default=3, help="blocks per process")
    p.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = p.parse_args()
    if args.child:
        _child(args.blocks)
        return
    got: dict[int, dict[str, list[float]]] = {v: {} for v in args.values}
    for k in range(args.processes):
        for v in (args.values if k % 2 == 0 else args.values[::-1]):
            env = {**os.environ, "OPENBLAS_THREAD_TIMEOUT": str(v)}
            res = subprocess.run([sys.executable, "-m", "tools.diagnostics.kept_pool_first_tasks",
                                  "--child", "--blocks", str(args.blocks)], env=env,
                                 check=True, capture_output=True, text=True)
            for key, times in json.loads(res.stdout.splitlines()[-1]).items():
                got[v].setdefault(key, []).extend(times)
    for v, parts in got.items():
        text = ", ".join(f"{key} {min(t):.3f}-{max(t):.3f} s" for key, t in sorted(parts.items()))
        print(f"OPENBLAS_THREAD_TIMEOUT={v}: {text}")


if __name__ == "__main__":
    main()

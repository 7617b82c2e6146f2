"""Settings shared by the asv suites: the cases, and how each is loaded and reduced.

Every suite goes through the entry points of the CLI (``rbbench solve``:
:func:`rbbench.hf.model.solve_hf`; ``rbbench reduce``: :func:`rbbench.rb.offline.reduce`
and the stage functions it calls) on small settings, so that ``asv run --quick``
takes a few minutes on two cores.

Cases (the ``scene`` parameter of the suites):

* ``membrane_obstacle``: the scene as shipped (289 dofs, 225 multipliers, 2 parameters);
* ``hertz_coarse``: ``hertz_halfdisks`` with :data:`rbbench.testing.HERTZ_COARSE`
  (the contract suite's coarse mesh: 8888 dofs, 64 multipliers);
* ``hertz_default``: ``hertz_halfdisks`` on its default mesh (36910 dofs; HF solve only).

This module holds no benchmark (no ``time_`` / ``track_`` / ``peakmem_`` names).
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from rbbench.scene.loading import Scene, load_scene
from rbbench.testing import HERTZ_COARSE

#: case -> (scene name, overrides as for ``rbbench ... --set``)
CASES: dict[str, tuple[str, tuple[str, ...]]] = {
    "membrane_obstacle": ("membrane_obstacle", ()),
    "hertz_coarse": ("hertz_halfdisks", tuple(HERTZ_COARSE)),
    "hertz_default": ("hertz_halfdisks", ()),
}

#: the cases of the reduced-basis suites (small training / validation sets)
RB_CASES = ["membrane_obstacle", "hertz_coarse"]

#: ``rbbench reduce`` options per RB case; everything else is the CLI default
#: (POD, mCPG, PGA, hyper auto: exact-affine on the membrane, EIM on Hertz).
RB_OPTIONS: dict[str, dict] = {
    "membrane_obstacle": {"n_train": 16, "n_valid": 5},  # 4 x 4 training grid
    "hertz_coarse": {"n_train": 11, "n_valid": 5},
}

#: Timeout (s) of one benchmark and of a setup_cache; generous against a loaded machine.
TIMEOUT = 300.0


def scene(case: str) -> Scene:
    """The scene of ``case``, overrides applied (validated as ``rbbench`` does)."""
    name, overrides = CASES[case]
    return load_scene(name, overrides=list(overrides))


def reduce_config(case: str, cache_dir: str | None = None, **changes):
    """The :class:`~rbbench.rb.offline.ReduceConfig` of ``case``.

    Snapshots in ``cache_dir`` (give a temporary directory whenever snapshots are
    computed) and in this process (``n_jobs = 1``: no process pool inside a benchmark);
    ``changes`` override any field (the tests use tiny sets).
    """
    from rbbench.rb.config import make_config

    opts = {"n_jobs": 1, "online_repeats": 3, **RB_OPTIONS[case]}
    if cache_dir is not None:
        opts["cache_dir"] = str(cache_dir)
    return make_config(**{**opts, **changes})


def reduced_case(case: str, cache_dir: str, **changes) -> dict:
    """Run ``rbbench reduce`` on ``case``; keep what the online suites need (picklable).

    Returns ``{"model": ReducedModel, "mu": default mu, "summary": {...}}`` where
    ``summary`` holds the scalar results of :meth:`ReduceResult.summary`.
    """
    from rbbench.rb.offline import reduce

    sc = scene(case)
    res = reduce(sc, reduce_config(case, cache_dir, **changes))
    if res.model is None:
        raise RuntimeError(f"{case}: reduce() built no ReducedModel (hyper {res.hyper!r})")
    summary = {k: v for k, v in res.summary().items()
               if v is None or isinstance(v, (int, float, str, bool))}
    return {"model": res.model, "mu": sc.default_mu, "summary": summary}


def finite(value, what: str) -> float:
    """``float(value)``, or raise (a failing benchmark) when it is None or not finite."""
    if value is None or not math.isfinite(float(value)):
        raise ValueError(f"{what} is {value!r}: not a finite number")
    return float(value)


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

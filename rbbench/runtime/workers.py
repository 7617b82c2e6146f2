"""Local worker processes of :func:`rbbench.hf.snapshots.compute.compute_snapshots`.

A call starts a pool and shuts it down at its end, unless it runs inside a
:func:`keep_workers` block: there, calls with the same snapshot key, registry, number of
workers, BLAS threads and start method share one pool, shut down when the outermost block
ends. ``rbbench reduce`` computes its training and then its validation snapshots in one
block, so its second call finds workers whose memory is already their own.

Why keep them (measured on Hertz level 0, 8 parameters, 2 workers against 1):
a freshly forked worker's first solve is slower than its later ones. The larger part was
OpenBLAS threads re-created in the worker and spinning ~0.1 s (now avoided: ``blas_cap``
below); what is left is its first touch of ~52-55 MB of fresh memory (the solve's
transients, which the parent keeps in its heap: ~1.9-2.5 us per 4 kB page in a forked
child on this virtual machine, ``python -m tools.diagnostics.first_touch_fork``), 0.18-0.19 s
against 0.155-0.16 s (``python -m tools.diagnostics.snapshot_pool_budget``).
:func:`release_free_heap` before the fork halves those faults; a kept pool has none.

Safety of a kept pool:

* each worker asks the kernel for SIGKILL when its parent dies (:func:`die_with_parent`),
  so no worker outlives a process that ends with ``os._exit`` or is killed;
* a pool is reused only by the process (and the main thread) that started it: a process
  forked inside a block does not inherit it;
* a pool with a dead worker is shut down and not reused; if a worker dies between two
  calls unnoticed, the parameters it loses are solved again in a new pool;
* the pool forks the code and the components of its first call: do not patch the solver
  between calls of one block (tests that patch use no block).

A ``fork`` pool is started with this process's BLAS pools capped at the workers' thread
count (``blas_cap``, :func:`rbbench.runtime.threads.capped_for_fork`), so that the workers
inherit the cap instead of setting it (which re-creates OpenBLAS's spinning threads in
them); the cap is lifted at the end of that call (after the shutdown of a pool not kept),
also when the pool is kept.

A pool is forked from the main thread only (:func:`start_method`; the run matrices'
processes too): forked from another
thread while a SciPy ``SuperLU`` factorisation is alive (SciPy 1.17.1, CPython 3.11.7;
the HF solves and the shape benchmarks keep them), the child gets a pending
``SystemError`` in ``threading``'s fork hook, its ``threading`` state still lists the
parent's threads, and its ``threading._shutdown`` (which a ``multiprocessing`` worker
runs at exit) can wait for ever for one of them, e.g. a process pool's manager thread of
the parent. From the main thread the hook completes.
"""

from __future__ import annotations

import contextlib
import ctypes
import multiprocessing
import os
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from typing import Any

from rbbench.runtime.threads import capped_for_fork

__all__ = ["die_with_parent", "keep_workers", "kept_pool_alive", "release_free_heap",
           "shutdown_kept", "start_method", "worker_pool"]

#: the kept pool: ``owner`` (pid) and ``depth`` of the :func:`keep_workers` blocks,
#: ``ident`` of the calls it serves, ``registry`` (held, so its ``id`` stays unique)
_KEPT: dict[str, Any] = {"owner": None, "depth": 0, "ident": None, "pool": None,
                         "registry": None}


def die_with_parent(sig: int = signal.SIGKILL) -> bool:
    """Linux: ask for ``sig`` when the parent dies (``prctl(PR_SET_PDEATHSIG)``).

    The signal comes when the *thread* that forked this process ends; a kept pool is
    therefore only kept when started from the main thread (:func:`worker_pool`).
    Returns whether the request was made."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        return ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, int(sig)) == 0
    except OSError:  # pragma: no cover - no glibc
        return False


def start_method(mp_context: str | None = None) -> str:
    """The start method of a pool started by this thread: ``mp_context`` (default: the
    platform's), except ``"fork"`` outside the main thread, which becomes ``"forkserver"``
    (``"spawn"`` where there is none): a process forked from another thread may hang at
    its exit (module docstring), and ``PR_SET_PDEATHSIG`` follows the forking thread
    (:func:`die_with_parent`). Its workers build their components themselves."""
    method = mp_context or multiprocessing.get_start_method()
    if method == "fork" and threading.current_thread() is not threading.main_thread():
        return "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() \
            else "spawn"
    return method


def process_context(method: str | None = None) -> multiprocessing.context.BaseContext:
    """The multiprocessing context of processes started by this thread: ``method`` if given,
    else ``fork`` on Linux (:func:`start_method`: ``forkserver`` outside the main thread)
    and ``spawn`` elsewhere."""
    if method is None:
        method = start_method("fork") if sys.platform.startswith("linux") else "spawn"
    return multiprocessing.get_context(method)


def release_free_heap() -> bool:
    """glibc: return the free heap pages to the kernel (``malloc_trim(0)``).

    Called before forking workers: a page the parent freed but kept mapped is shared
    copy-on-write, and a worker's first write to it copies it; a released page is a fresh
    zero page instead. Measured (Hertz level 0, 8 parameters, 2 workers against 1, with
    and without it in 12 interleaved rounds; the final measurement): 1.71x -> 1.84x and
    1.77x -> 1.83x in two runs. Returns whether it ran."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        ctypes.CDLL("libc.so.6").malloc_trim(0)
    except (OSError, AttributeError):  # pragma: no cover - not glibc
        return False
    return True


@contextlib.contextmanager
def keep_workers() -> Iterator[None]:
    """Within the block, :func:`rbbench.hf.snapshots.compute.compute_snapshots` calls that agree
    on key, registry, workers, threads and start method reuse one pool; the outermost
    block shuts it down at its end (also on error). Nested blocks share it. Outside the
    main thread the block does nothing (each call has its own pool): the blocks of other
    threads must not shut down a pool that the main thread is using."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    me = os.getpid()
    if _KEPT["owner"] != me:  # state inherited through fork: not ours
        _forget()
        _KEPT["owner"] = me
    _KEPT["depth"] += 1
    try:
        yield
    finally:
        if _KEPT["owner"] == me == os.getpid():  # not a forked child leaving our block
            _KEPT["depth"] -= 1
            if _KEPT["depth"] == 0:
                shutdown_kept()


def kept_pool_alive() -> bool:
    """Whether this process holds a kept pool now (for tests and diagnostics)."""
    return _KEPT["pool"] is not None and _KEPT["owner"] == os.getpid()


def shutdown_kept() -> None:
    """Shut the kept pool down (its workers finish their task and exit)."""
    pool = _KEPT["pool"] if _KEPT["owner"] == os.getpid() else None
    _KEPT.update(ident=None, pool=None, registry=None)
    if pool is not None:
        pool.shutdown(wait=True, cancel_futures=True)


def _forget() -> None:
    """Drop a pool inherited through fork (its manager thread is not in this process)."""
    _KEPT.update(owner=None, depth=0, ident=None, pool=None, registry=None)


def _keeping() -> bool:
    return (_KEPT["depth"] > 0 and _KEPT["owner"] == os.getpid()
            and threading.current_thread() is threading.main_thread())


@contextlib.contextmanager
def worker_pool(ident: tuple, registry: Any, make: Callable[[], ProcessPoolExecutor],
                fresh: bool = False, blas_cap: int = 0
                ) -> Iterator[tuple[ProcessPoolExecutor, bool]]:
    """``(pool, reused)`` for one call: the kept pool when inside :func:`keep_workers`, its
    ``ident`` and ``registry`` match, no worker of it died and ``fresh`` is false; else
    ``make()``, with this process's BLAS pools capped at ``blas_cap`` threads until the end
    of this call (``0``: not capped; see the module docstring). A pool not kept is shut down
    when the call ends; a kept one too if the call raised or a worker died."""
    keeping = _keeping()
    reused = (keeping and not fresh and _KEPT["ident"] == ident
              and _KEPT["registry"] is registry and not _broken(_KEPT["pool"]))
    if reused:
        pool = _KEPT["pool"]
    elif keeping:
        shutdown_kept()
    # a new pool forks its workers at its first task, inside the cap: they inherit it
    new_cap = blas_cap > 0 and not reused
    with capped_for_fork(blas_cap) if new_cap else contextlib.nullcontext():
        if not reused:
            pool = make()
            if keeping:
                _KEPT.update(ident=ident, pool=pool, registry=registry)
        ok = False
        try:
            yield pool, reused
            ok = not _broken(pool)
        finally:
            if not (keeping and ok):
                if _KEPT["pool"] is pool:
                    _KEPT.update(ident=None, pool=None, registry=None)
                pool.shutdown(wait=True, cancel_futures=True)


def _broken(pool: ProcessPoolExecutor | None) -> bool:
    """Whether a worker of ``pool`` died: ``concurrent.futures`` marks the pool broken
    when its manager thread notices; the workers are also polled, so that a death it has
    not noticed yet does not break the next call."""
    if pool is None or getattr(pool, "_broken", False):
        return True
    processes = getattr(pool, "_processes", None) or {}
    return not all(p.is_alive() for p in list(processes.values()))

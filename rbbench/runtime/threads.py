"""BLAS thread pools: a process-wide cap (snapshot workers) and one BLAS thread per solve.

On a loaded 2-core machine two BLAS threads made ``A^-1 B^T`` 12x
slower (30.8 s against 2.49 s, Hertz level 0); on a quiet one they gain nothing. Every
HF solve (:meth:`rbbench.hf.model.HFModel.solve`) and every timed online loop
(:func:`rbbench.rb.validation.validate`) therefore runs inside :func:`one_blas_thread`.
Both helpers act through ``threadpoolctl`` on every pool it finds (BLAS and OpenMP), and
only on the pools not at the limit already (:func:`_limit_changed`): after a ``fork``,
OpenBLAS re-creates its worker threads on *any* ``set_num_threads`` call, and each new
thread spins about 0.1 s (2^28 cycles) before it sleeps. A forked snapshot worker that set
its cap anew spent 0.02-0.10 s of CPU in those threads during its first solve, on a core
the other worker needed; :func:`capped_for_fork` lets the workers inherit the cap instead.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

__all__ = ["BLAS_THREADS_DEFINITION", "blas_pools", "capped_for_fork", "limit_blas_threads",
           "one_blas_thread"]

_THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
               "BLIS_NUM_THREADS", "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")

#: per process: the cap of :func:`limit_blas_threads`, the nesting depth of
#: :func:`one_blas_thread`, its limiter (to restore) and what it recorded
_STATE: dict[str, Any] = {"process_limit": None, "process_limiter": None, "depth": 0,
                          "limiter": None, "record": None}
_LOCK = threading.Lock()

BLAS_THREADS_DEFINITION = (
    "the thread limit the solve ran under (rbbench.runtime.threads.one_blas_thread): limit 1 on "
    "every BLAS / OpenMP pool threadpoolctl finds; how: 'threadpoolctl' (set for this "
    "solve, restored after it), 'process' (the process was already capped at one thread, "
    "e.g. a snapshot worker) or 'nested' (inside an enclosing limit); outside: the pools' "
    "threads before (library file -> threads)")


def limit_blas_threads(n: int) -> str:
    """Cap the BLAS / OpenMP thread pools of this process at ``n`` threads, for good.

    Several worker processes each running a multithreaded BLAS oversubscribe the
    cores (measured on 2 cores, Hertz scene, 2 workers: 34 s against 2.5 s with one
    thread each). Sets the thread variables for libraries loaded later and caps the
    pools already loaded (numpy's and scipy's BLAS) with ``threadpoolctl``, those not at
    ``n`` already (a ``fork`` child of :func:`capped_for_fork` inherits the OpenBLAS pools
    at ``n``: no call on them, no OpenBLAS threads). Returns what it did:
    ``"threadpoolctl"``, or ``"inherited"`` when every pool was at ``n``. In a snapshot
    worker it is ``"threadpoolctl"`` when MKL is loaded: Intel's OpenMP runtime
    (``libiomp5``) comes back at its default count after a fork (2 here, the parent
    capped at 1), so that pool is set again (measured: 2-4 ms with the scan of the
    loaded libraries; ``tests/runtime/test_threads.py``).
    """
    from threadpoolctl import ThreadpoolController

    for var in _THREAD_ENV:  # for libraries loaded later
        os.environ[var] = str(n)
    import scipy.linalg  # noqa: F401  (load scipy's BLAS before capping it)
    import scipy.sparse.linalg  # noqa: F401

    with _LOCK:
        _STATE["process_limiter"] = _limit_changed(ThreadpoolController(), n)
        _STATE["process_limit"] = int(n)
    return "inherited" if _STATE["process_limiter"] is None else "threadpoolctl"


def _limit_changed(controller: Any, n: int) -> Any:
    """Limit the pools of ``controller`` (a ``threadpoolctl.ThreadpoolController``) that
    are not at ``n`` threads to ``n``; returns the limiter (its ``restore_original_limits``
    restores those), or ``None`` when every pool was at ``n``.

    A pool at ``n`` is left alone because a ``set_num_threads`` call is not free: in a
    ``fork`` child, OpenBLAS (whose fork handler shut its threads down) re-creates its
    threads on any such call, even to the count it has, and they spin ~0.1 s each."""
    paths = [lc.filepath for lc in controller.lib_controllers if lc.num_threads != n]
    return controller.select(filepath=paths).limit(limits=n) if paths else None


@contextmanager
def capped_for_fork(n: int) -> Iterator[str]:
    """Cap this process's BLAS / OpenMP pools at ``n`` threads while it forks children that
    run capped at ``n`` (snapshot workers), restored at the end of the block.

    The children inherit the cap, so their :func:`limit_blas_threads` finds the OpenBLAS
    pools at ``n`` and calls nothing on them: no OpenBLAS threads are re-created in them
    (module docstring; an OpenMP runtime that resets at fork is set again there).
    Measured (Hertz level 0, 8 parameters, 2 fork workers, 1 BLAS thread each; the
    final measurement): every worker had 2 extra OpenBLAS threads with 0.02-0.10 s of CPU after
    its first solve without the block, and 1 thread in all with it. This process pays the
    re-creation instead, once, when its pools are restored after the block (if any pool
    had more than ``n`` threads). Yields ``"threadpoolctl"`` or ``"inherited"`` (nothing
    to cap)."""
    import scipy.linalg  # noqa: F401  (scipy's BLAS loaded, hence capped)
    from threadpoolctl import ThreadpoolController

    limiter = _limit_changed(ThreadpoolController(), n)
    try:
        yield "inherited" if limiter is None else "threadpoolctl"
    finally:
        if limiter is not None:
            limiter.restore_original_limits()


def blas_pools() -> list[dict[str, Any]]:
    """The BLAS pools of this process: ``internal_api``, ``prefix``, ``num_threads``."""
    from threadpoolctl import threadpool_info

    return [{k: p[k] for k in ("internal_api", "prefix", "num_threads")}
            for p in threadpool_info() if p["user_api"] == "blas"]


def _apply() -> dict[str, Any]:
    """Set the limit of the outermost :func:`one_blas_thread` (not when the process is
    capped at one thread already: then nothing to do, no ``threadpoolctl`` scan)."""
    if _STATE["process_limit"] == 1:
        return {"limit": 1, "how": "process", "outside": {}}
    import scipy.linalg  # noqa: F401  (scipy's BLAS loaded, hence limited)
    from threadpoolctl import ThreadpoolController

    controller = ThreadpoolController()  # one scan of the loaded libraries (~0.1-2 ms)
    outside = {os.path.basename(p["filepath"]): p["num_threads"] for p in controller.info()}
    _STATE["limiter"] = _limit_changed(controller, 1)  # None: every pool at 1 already
    return {"limit": 1, "how": "threadpoolctl", "outside": outside}


@contextmanager
def one_blas_thread() -> Iterator[dict[str, Any]]:
    """Run the body with one thread in every BLAS / OpenMP pool, then restore them.

    Yields the record of what was applied (``summary.json`` / ``result.json``
    ``blas_threads``, :data:`BLAS_THREADS_DEFINITION`). Cheap where nothing is to do:
    nested inside another ``one_blas_thread`` (a counter, process-wide and thread-safe:
    the pools are restored when the last one exits) or in a process capped at one thread
    by :func:`limit_blas_threads`. Otherwise one ``threadpoolctl`` scan: enter it once per
    solve or validation loop, not per timed repeat.
    """
    with _LOCK:
        if _STATE["depth"] == 0:
            _STATE["record"] = _apply()
            record = _STATE["record"]
        else:
            record = {**_STATE["record"], "how": "nested"} \
                if _STATE["record"]["how"] != "process" else _STATE["record"]
        _STATE["depth"] += 1
    try:
        yield record
    finally:
        with _LOCK:
            _STATE["depth"] -= 1
            if _STATE["depth"] == 0 and _STATE["limiter"] is not None:
                _STATE["limiter"].restore_original_limits()
                _STATE["limiter"] = None

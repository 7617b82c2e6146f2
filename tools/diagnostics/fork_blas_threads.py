"""Diagnostic: the OpenBLAS threads a ``fork`` child re-creates when it sets a thread limit.

The snapshot workers. OpenBLAS shuts its threads down at a fork; the child's first
``set_num_threads`` call re-creates them (even to the count it has), and each spins about
0.1 s before it sleeps. For each case a child is forked after numpy's and scipy's BLAS
ran with 2 threads, caps itself at 1 thread as a snapshot worker does
(:func:`rbbench.runtime.threads.limit_blas_threads`), then sleeps 0.3 s; printed: the child's
threads and the CPU time it used during the sleep (all of it spinning threads)::

    python -m tools.diagnostics.fork_blas_threads

``set anew``: the parent had 2 threads at the fork (the child sets every pool, as before
the fix of the inherited cap); ``inherited``: the parent forked inside
:func:`rbbench.runtime.threads.capped_for_fork` (the child finds the pools at 1 and sets
nothing). Not an asv benchmark (it forks and reads ``/proc``: Linux).
"""

from __future__ import annotations

import contextlib
import os
import resource
import time


def _child(label: str, write_fd: int) -> None:
    from rbbench.runtime.threads import limit_blas_threads

    how = limit_blas_threads(1)
    r0 = resource.getrusage(resource.RUSAGE_SELF)
    time.sleep(0.3)
    r1 = resource.getrusage(resource.RUSAGE_SELF)
    cpu = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    threads = len(os.listdir("/proc/self/task"))
    os.write(write_fd, f"{label:10s} limit: {how:13s} threads: {threads}  CPU in a 0.3 s "
                       f"sleep: {cpu:.3f} s\n".encode())
    os._exit(0)


def main() -> None:
    import numpy as np
    import scipy.linalg
    from threadpoolctl import threadpool_limits

    from rbbench.runtime.threads import capped_for_fork

    a = np.random.default_rng(0).random((300, 300))
    with threadpool_limits(limits=2):
        a @ a  # numpy's and scipy's OpenBLAS run their threads once
        scipy.linalg.blas.dgemm(1.0, a, a)
        for label, cap in (("set anew", contextlib.nullcontext()),
                           ("inherited", capped_for_fork(1))):
            r, w = os.pipe()
            with cap:
                pid = os.fork()
                if pid == 0:
                    _child(label, w)
            os.waitpid(pid, 0)
            os.close(w)
            print(os.read(r, 4096).decode(), end="")
            os.close(r)


if __name__ == "__main__":
    main()

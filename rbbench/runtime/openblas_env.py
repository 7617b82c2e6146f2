"""Settings of the ``rbbench`` command that OpenBLAS reads once, when it loads.

Imported first by :mod:`rbbench.cli`, before anything loads numpy or scipy (and with them
their OpenBLAS); ``import rbbench`` as a library sets nothing.

``OPENBLAS_THREAD_TIMEOUT`` (default here ``20``, unless already set): an idle OpenBLAS
thread spins 2^N cycles before it sleeps; OpenBLAS's default is 2^28, about 0.1 s. This
command forks (snapshot workers, the runner's case processes), OpenBLAS shuts its threads
down at every fork, and a process re-creates them at its next thread-count change:
each new thread then spins 2^28 cycles on a core that the other process needs. Measured
(Hertz level 0, 8 parameters, a kept pool of 2 workers, 6 blocks per value): the
first tasks of the call right after the one that started the pool (this process restored
its BLAS threads at that call's end) took 0.196-0.258 s with 2^28 cycles and 0.154-0.186 s
with 2^20, against 0.15-0.16 s for later tasks
(``python -m tools.diagnostics.kept_pool_first_tasks``). 2^20 cycles (~0.4 ms) still keeps threads
awake between close BLAS calls of a multithreaded phase.
"""

from __future__ import annotations

import os

#: the value set when the environment has none (OpenBLAS clamps it to [4, 30])
OPENBLAS_THREAD_TIMEOUT = "20"

os.environ.setdefault("OPENBLAS_THREAD_TIMEOUT", OPENBLAS_THREAD_TIMEOUT)

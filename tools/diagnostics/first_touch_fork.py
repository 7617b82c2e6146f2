"""Diagnostic: what a new process pays to write fresh memory once, on this machine.

The snapshot speed-up target (2 workers >= 1.85x of 1 on 8 parameters): a freshly forked snapshot
worker's first task writes ~52 MB of memory that the serial process already holds
(``python -m tools.diagnostics.snapshot_pool_budget``), and that first touch bounds a fresh
2-worker call. Each round forks one child per kind, a pause apart; the child maps ``--mb``
MB of private anonymous memory, writes one byte per 4 kB page and reports the time:

* ``4k``: no advice (4 kB pages: one page fault per page);
* ``thp``: ``MADV_HUGEPAGE`` on the 2 MB-aligned range (transparent huge pages: one fault
  per 2 MB, where the kernel finds a free 2 MB block).

Printed per kind: the median and range over the rounds in us per 4 kB page and in ms for
the whole size, and the huge pages the kernel handed out (``thp_fault_alloc`` of
``/proc/vmstat``). The spread of ``thp`` is the point on a virtual machine that reports
free memory to its host: a 2 MB block the guest freed long enough ago is no longer backed
by the host and costs far more to touch than one freed just before::

    python -m tools.diagnostics.first_touch_fork --rounds 9 --mb 52

Linux only (``fork``, ``/proc``); not an asv benchmark.
"""

from __future__ import annotations

import argparse
import mmap
import os
import time

import numpy as np

_HUGE = 2 << 20


def _thp_allocs() -> int:
    with open("/proc/vmstat") as fh:
        for line in fh:
            if line.startswith("thp_fault_alloc "):
                return int(line.split()[1])
    return 0


def touch_once(nbytes: int, huge: bool) -> float:
    """Seconds to write one byte per 4 kB page of ``nbytes`` of fresh private memory
    (``huge``: advised for transparent huge pages)."""
    buf = mmap.mmap(-1, nbytes + _HUGE, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)
    view = np.frombuffer(buf, dtype=np.uint8)
    start = (-view.ctypes.data) % _HUGE  # the first 2 MB boundary
    if huge:
        buf.madvise(mmap.MADV_HUGEPAGE, start, nbytes)
    t0 = time.perf_counter()
    view[start:start + nbytes:4096] = 1
    elapsed = time.perf_counter() - t0
    del view
    buf.close()
    return elapsed


def in_child(nbytes: int, huge: bool) -> tuple[float, int]:
    """``(seconds, huge pages handed out)`` of :func:`touch_once` in a forked child."""
    r, w = os.pipe()
    before = _thp_allocs()
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child
        try:
            os.write(w, repr(touch_once(nbytes, huge)).encode())
        finally:
            os._exit(0)
    os.close(w)
    with os.fdopen(r) as fh:
        seconds = float(fh.read())
    os.waitpid(pid, 0)
    return seconds, _thp_allocs() - before


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--rounds", type=int, default=9)
    p.add_argument("--mb", type=int, default=52)
    p.add_argument("--pause", type=float, default=1.0, help="seconds between children")
    args = p.parse_args()
    nbytes = args.mb << 20
    pages = nbytes // 4096
    out: dict[str, list[float]] = {"4k": [], "thp": []}
    allocs: dict[str, list[int]] = {"4k": [], "thp": []}
    for r in range(args.rounds):
        for kind in (("4k", "thp") if r % 2 else ("thp", "4k")):
            seconds, n_huge = in_child(nbytes, kind == "thp")
            out[kind].append(seconds)
            allocs[kind].append(n_huge)
            time.sleep(args.pause)
    for kind, t in out.items():
        us = 1e6 * np.array(t) / pages
        print(f"{kind:>3}: {np.median(us):.2f} us per 4 kB page (range {us.min():.2f}-"
              f"{us.max():.2f}), {1e3 * np.median(t):.1f} ms for {args.mb} MB (range "
              f"{1e3 * min(t):.1f}-{1e3 * max(t):.1f}); huge pages per child: "
              f"{int(np.median(allocs[kind]))}")


if __name__ == "__main__":
    main()

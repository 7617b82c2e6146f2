"""The protocol of every online time: its name and definition (written in every results row
and ``result.json``) and the garbage-collector pause of the timed solves. The timing loop
itself is :func:`rbbench.rb.online.timed_online_solves` (no import of numpy or a backend
here: the results schema names the protocol).
"""

from __future__ import annotations

import gc
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["ONLINE_PROTOCOL", "ONLINE_PROTOCOL_DEFINITION", "gc_paused"]

#: the name of the online-time protocol (:func:`rbbench.rb.online.timed_online_solves`), in
#: every results row
ONLINE_PROTOCOL = "warm1-blas1-gcoff-median"
#: what :data:`ONLINE_PROTOCOL` is (result.json definitions, the columns reference)
ONLINE_PROTOCOL_DEFINITION = (
    f"{ONLINE_PROTOCOL}: an online time is the model's own solve time (the solution's time_s: "
    "mu checked, reduced arrays evaluated at mu, reduced problem solved; the reconstruction "
    "of HF vectors is NOT timed), measured with one BLAS thread and the garbage collector "
    "paused during the timed solves, after one untimed warm-up solve per model (the compiled "
    "kernels are loaded or compiled before it, outside any time); `repeats` timed solves at "
    "each validation mu (rbbench reduce and run: --online-repeats, consecutive; "
    "online-scaling: one per round, the levels interleaved; asv: at the scene's default "
    "mu); reported as the median and inter-quartile range over validation mus x repeats, "
    "with the online path (compiled / python) and method that ran")


@contextmanager
def gc_paused() -> Iterator[None]:
    """The garbage collector disabled inside (restored after, if it was enabled), as
    :mod:`timeit` does: a collection of a large heap would land in one solve's time."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()

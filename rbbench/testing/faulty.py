"""Deliberately failing components, for testing runners and executors.

``discover(extra_plugins=(rbbench.testing.faulty,))`` adds dual compressors
that raise (``faulty-raise``), return NaN generators (``faulty-nan``), sleep
past any sensible time limit (``faulty-sleep``), or need a module that does
not exist (``faulty-missing``), and an HF solver that hangs (``faulty-hang``).
Each must become one results row with its status (error / diverged / timeout /
not_installed) while the run goes on.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from rbbench.hookspecs import hookimpl
from rbbench.rb.compressors import CPG
from rbbench.registry import ComponentSpec

_HERE = "rbbench.testing.faulty"


class RaisingDual(CPG):
    """Raises ``RuntimeError`` when called."""

    def __call__(self, LAM: np.ndarray, W: Any, **kw: Any):
        raise RuntimeError("injected failure in a dual compressor")


class NaNDual(CPG):
    """Returns CPG's basis with NaN generators."""

    def __call__(self, LAM: np.ndarray, W: Any, **kw: Any):
        out = super().__call__(LAM, W, **kw)
        out.generators[:] = np.nan
        return out


class SleepingDual(CPG):
    """Sleeps for an hour (a hung component)."""

    def __call__(self, LAM: np.ndarray, W: Any, **kw: Any):
        time.sleep(3600)
        return super().__call__(LAM, W, **kw)


class HangingSolver:
    """An HF solver that never returns (a hung external library)."""

    name = "faulty-hang"

    def solve(self, problem: Any, warm_start: Any = None):
        time.sleep(3600)


@hookimpl
def rbbench_register(registry):
    registry.add(ComponentSpec(name="faulty-hang", role="solver", target=f"{_HERE}:HangingSolver",
                               capabilities={"formulations": ("mixed",)},
                               description="test double: an HF solver that hangs"))
    for name, cls, modules in (("faulty-raise", "RaisingDual", ()),
                               ("faulty-nan", "NaNDual", ()),
                               ("faulty-sleep", "SleepingDual", ()),
                               ("faulty-missing", "RaisingDual", ("no_such_module_rbbench",))):
        registry.add(ComponentSpec(name=name, role="dual", target=f"{_HERE}:{cls}",
                                   modules=modules, extras=("faulty",) if modules else (),
                                   capabilities={"cone": True, "nested": True},
                                   description=f"test double: {name}"))

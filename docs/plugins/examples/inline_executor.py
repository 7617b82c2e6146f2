"""An executor plugin: every case in this process, one after the other, with no time limit
(to run a matrix under a profiler or a debugger)."""

from __future__ import annotations

import traceback
from collections.abc import Callable
from typing import Any

from rbbench.plugin import ComponentSpec, execute_case, failed_row, hookimpl


class InlineExecutor:
    """``run`` calls :func:`rbbench.plugin.execute_case` on each case in turn."""

    name = "inline"

    def __init__(self, jobs: int | None = None) -> None:
        self.jobs = 1  # one case at a time, whatever was asked

    def run(self, cases: list[Any], run_id: str, cache_dir: str, registry: Any,
            on_result: Callable[[Any, dict], None], on_stage: Callable[[str], None]) -> None:
        for case in cases:
            try:
                record = execute_case(case, run_id, cache_dir, self.name, registry,
                                      lambda msg, c=case: on_stage(f"{c.label}: {msg}"))
            except Exception as exc:  # noqa: BLE001 - execute_case reports case failures;
                # anything else still gets its row
                record = failed_row(case, run_id, self.name, "error", repr(exc),
                                    traceback.format_exc())
            on_result(case, record)


@hookimpl
def rbbench_register(registry):
    registry.add(ComponentSpec(
        name="inline", role="executor", target="inline_executor:InlineExecutor",
        capabilities={"isolation": False, "timeout": None},
        description="every case in this process, no time limit (profiling, debugging)",
    ))

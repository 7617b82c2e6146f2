"""Contract of the executor role: every case of a run reported once, as a valid row."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rbbench.registry import ComponentSpec, Registry
from rbbench.scene.loading import load_scene
from rbbench.testing.contract_base import (
    ContractViolation,
    RoleContract,
    instantiate,
    require,
)


def _executor_cases() -> list[Any]:
    """Two tiny membrane cases: dual ``cpg`` (good) and ``faulty-raise`` (raises)."""
    from rbbench.bench.matrix import Case

    sc = load_scene("membrane_obstacle", ["discretization.n_cells=6"])
    params = {"n_train": 4, "n_valid": 2, "online_repeats": 1, "exact_max_r": 3}
    return [Case("membrane_obstacle", ("discretization.n_cells=6",),
                 {"backend": "skfem", "formulation": "mixed", "solver": "ssn",
                  "primal": "pod", "dual": d, "stabilizer": "none", "hyper": "auto"},
                 2, 2, params, 0, 0, 120.0, sc.fingerprint()) for d in ("cpg", "faulty-raise")]


def _check_record(case: Any, rec: Any, label: str) -> None:
    """A valid results row with the case's identity: ``ok`` for the good case, ``error``
    with its traceback for the failing one."""
    from rbbench.bench import schema

    require(isinstance(rec, dict) and "row" in rec, f"{label}: a record is "
            "{'row': ..., 'details': ...}")
    try:
        row = schema.normalise_row(rec["row"])
    except (KeyError, ValueError) as exc:
        raise ContractViolation(f"{label}: invalid results row: {exc}") from None
    require(row["case_id"] == case.case_id and row["run_id"] == "contract",
            f"{label}: the row's identity does not match its case")
    want = "ok" if case.components["dual"] == "cpg" else "error"
    require(row["status"] == want, f"{label}: case with dual "
            f"{case.components['dual']!r}: status {row['status']!r}, expected {want!r} "
            f"({row['reason']})")
    if want == "error":
        require(bool(row["traceback"]), f"{label}: an error row carries its traceback")


def check_executor(factory: Callable[..., Any], name: str | None = None) -> None:
    """Executor contract: every case reported once, as a valid results row.

    Two tiny membrane cases, one of which uses a dual compressor that raises
    (:mod:`rbbench.testing.faulty`): ``run`` must call ``on_result`` exactly
    once per case, with a row of :mod:`rbbench.bench.schema` whose identity matches
    the case; the good case is ``ok``, the failing one ``error`` with its
    traceback; ``on_stage`` receives strings only.
    """
    import tempfile

    from rbbench.registry import discover
    from rbbench.testing import faulty

    label = f"executor {name or getattr(factory, '__name__', '?')}"
    reg = discover(extra_plugins=(faulty,))
    cases = _executor_cases()
    got: list[tuple[Any, dict]] = []
    stages: list[Any] = []
    ex = instantiate(lambda: factory(jobs=2), label)
    with tempfile.TemporaryDirectory() as tmp:
        ex.run(cases, run_id="contract", cache_dir=tmp, registry=reg,
               on_result=lambda c, r: got.append((c, r)), on_stage=stages.append)
    require(sorted(c.key for c, _ in got) == sorted(c.key for c in cases),
            f"{label}: on_result must be called once per case (got "
            f"{[c.key for c, _ in got]})")
    for case, rec in got:
        _check_record(case, rec, label)
    require(all(isinstance(m, str) for m in stages), f"{label}: on_stage takes strings")


def _check_registered(obj: Any, spec: ComponentSpec, registry: Registry, name: str) -> None:
    check_executor(obj, name=name)


CONTRACT = RoleContract("executor", None, _check_registered)

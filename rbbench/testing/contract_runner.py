"""The contract suite without pytest: run it on the components of one package (or all) and
report each as passed, failed or skipped (``rbbench plugins --check``).

A plugin package whose ``rbbench_register`` fails to import or to declare is a failed line
too, so that a broken entry point is not silently missing from the check.
"""

from __future__ import annotations

import re
import time
import traceback
from collections.abc import Callable
from dataclasses import asdict, dataclass

from rbbench.registry import ROLES, ComponentSpec, Registry, default_registry
from rbbench.testing.contract_base import ContractSkipped, ContractViolation
from rbbench.testing.contract_suite import run_contract

__all__ = ["ContractResult", "format_result", "run_contracts", "select_specs", "summary_line"]

STATUSES = ("passed", "failed", "skipped")


@dataclass
class ContractResult:
    """The outcome of one component's contract.

    Attributes
    ----------
    role, name, package, version : str
        The component (for a plugin that failed to load: role ``"?"``, its entry point).
    status : str
        ``"passed"``, ``"failed"`` or ``"skipped"``.
    message : str
        Why it failed (the violated property, or the exception and where it was raised) or
        why it was skipped; empty when it passed.
    seconds : float
        Wall time of the check.
    """

    role: str
    name: str
    package: str
    version: str
    status: str
    message: str = ""
    seconds: float = 0.0

    def as_dict(self) -> dict:
        return asdict(self)


def normalise(package: str) -> str:
    """A distribution name compared as pip does: lower case, ``-``, ``_``, ``.`` alike."""
    return re.sub(r"[-_.]+", "-", package).lower()


def select_specs(registry: Registry, package: str | None = None,
                 role: str | None = None) -> list[ComponentSpec]:
    """The registered components of ``package`` (a distribution name, as ``pip`` writes it)
    and ``role`` (all when None).

    Raises
    ------
    ValueError
        Naming the option and the valid values, when ``role`` is not a role or no
        component (and no broken plugin) comes from ``package``.
    """
    if role is not None and role not in ROLES:
        raise ValueError(f"--role {role!r}: valid roles: {', '.join(ROLES)}")
    specs = [s for s in registry.specs(role)
             if package is None or normalise(s.package) == normalise(package)]
    broken = [b for b in registry.broken if package is None or normalise(b[1]) ==
              normalise(package)]
    if package is not None and not specs and not broken:
        known = sorted({s.package for s in registry.specs(role) if s.package})
        what = f" with role {role!r}" if role else ""
        raise ValueError(f"--package {package!r}: no registered component{what} comes from "
                         f"it; packages with components: {', '.join(known) or 'none'}")
    return specs


def _failure(exc: BaseException) -> str:
    """The message of a failed check: a violation's own, else the exception and the
    innermost frame that raised it."""
    if isinstance(exc, ContractViolation):
        return str(exc)
    frames = traceback.extract_tb(exc.__traceback__)
    where = f" (at {frames[-1].filename}:{frames[-1].lineno} in {frames[-1].name})" \
        if frames else ""
    return f"raised {type(exc).__name__}: {exc}{where}"


def check_one(spec: ComponentSpec, registry: Registry) -> ContractResult:
    """Run one component's contract; never raises (but for KeyboardInterrupt)."""
    t0 = time.perf_counter()
    status, message = "passed", ""
    try:
        run_contract(spec, registry)
    except ContractSkipped as exc:
        status, message = "skipped", str(exc)
    except Exception as exc:  # noqa: BLE001 - any failure of a component is reported
        status, message = "failed", _failure(exc)
    return ContractResult(spec.role, spec.name, spec.package, spec.version, status, message,
                          time.perf_counter() - t0)


def run_contracts(registry: Registry | None = None, package: str | None = None,
                  role: str | None = None,
                  on_result: Callable[[ContractResult], None] | None = None,
                  ) -> list[ContractResult]:
    """The contract of every selected component (:func:`select_specs`), in registry order,
    after one failed line per plugin of ``package`` that failed to load.

    ``on_result(result)`` is called as each check ends (progress).
    """
    reg = registry or default_registry()
    specs = select_specs(reg, package, role)
    results = [ContractResult("?", ep, pkg, "", "failed", msg)
               for ep, pkg, msg in reg.broken
               if role is None and (package is None or normalise(pkg) == normalise(package))]
    for r in results:
        if on_result is not None:
            on_result(r)
    for spec in specs:
        results.append(check_one(spec, reg))
        if on_result is not None:
            on_result(results[-1])
    return results


def format_result(r: ContractResult) -> str:
    """One result as a report line, and the message indented under it when there is one."""
    pkg = f"{r.package} {r.version}".strip() or "?"
    head = f"{r.status.upper():<8}{r.role:<12}{r.name:<22}{pkg:<32}{r.seconds:6.1f} s"
    return head + (f"\n        {r.message}" if r.message else "")


def summary_line(results: list[ContractResult]) -> str:
    """``contracts: N passed, N failed, N skipped``."""
    n = {s: sum(r.status == s for r in results) for s in STATUSES}
    return f"contracts: {n['passed']} passed, {n['failed']} failed, {n['skipped']} skipped"

"""Contract of the hyper-reducer role: a declaration the formulation's offline steps honour.

A hyper-reducer constructs without options (its tolerances are ``ReduceConfig`` fields),
carries its registered name, declares the formulations it applies to in its spec
(``capabilities["formulations"]``) exactly as the object does, and ``check(formulation)``
accepts those and refuses any other formulation with a ValueError naming it.
"""

from __future__ import annotations

from typing import Any

from rbbench.registry import ComponentSpec, Registry
from rbbench.testing.contract_base import ContractViolation, RoleContract, require


def check_hyper(obj: Any, spec: ComponentSpec, registry: Registry, label: str) -> None:
    """Run the hyper-reducer contract on the loaded target ``obj`` (a class)."""
    try:
        hyper = obj()
    except Exception as exc:  # noqa: BLE001 - any failure is a violation
        raise ContractViolation(f"{label}: constructing without options raised {exc!r}") from None
    require(getattr(hyper, "name", None) == spec.name,
            f"{label}: name {getattr(hyper, 'name', None)!r} differs from the registered "
            f"{spec.name!r}")
    declared = tuple(spec.capabilities.get("formulations", ()))
    require(declared, f"{label}: capabilities['formulations'] is empty")
    require(tuple(getattr(hyper, "formulations", ())) == declared,
            f"{label}: the object's formulations {getattr(hyper, 'formulations', None)} "
            f"differ from the declared {declared}")
    for form in declared:
        hyper.check(form)
    try:
        hyper.check("no-such-formulation")
    except ValueError as exc:
        require("no-such-formulation" in str(exc),
                f"{label}: check() of an undeclared formulation must name it: {exc}")
    else:
        raise ContractViolation(f"{label}: check() accepted an undeclared formulation")


CONTRACT = RoleContract("hyper", "check", check_hyper)

"""The contract suite over the registry: the declaration check, one pytest parameter per
registered component, and the dispatch to the role contracts.

Each role's contract lives in its own module ``rbbench.testing.contract_<role>`` and
exposes a :class:`~rbbench.testing.contract_base.RoleContract` named ``CONTRACT``;
adding a role is one such module and one entry in :data:`ROLE_CONTRACTS`.
"""

from __future__ import annotations

import re
from typing import Any

from rbbench.registry import ROLES, ComponentSpec, Registry, default_registry
from rbbench.testing.contract_backend import CONTRACT as BACKEND
from rbbench.testing.contract_base import (
    KNOWN_PHYSICS,
    ContractSkipped,
    ContractViolation,
    RoleContract,
    require,
)
from rbbench.testing.contract_dual import CONTRACT as DUAL
from rbbench.testing.contract_executor import CONTRACT as EXECUTOR
from rbbench.testing.contract_formulation import CONTRACT as FORMULATION
from rbbench.testing.contract_hyper import CONTRACT as HYPER
from rbbench.testing.contract_primal import CONTRACT as PRIMAL
from rbbench.testing.contract_solver import CONTRACT as SOLVER
from rbbench.testing.contract_stabilizer import CONTRACT as STABILIZER

#: The role contracts, by role, in the order ``ROLE_CHECKS`` lists them.
ROLE_CONTRACTS: dict[str, RoleContract] = {c.role: c for c in (
    BACKEND, FORMULATION, SOLVER, PRIMAL, DUAL, STABILIZER, HYPER, EXECUTOR)}

#: Roles with a role-specific contract (the others get the declaration check only).
ROLE_CHECKS = tuple(ROLE_CONTRACTS)

_ROLE_METHOD = {c.role: c.method for c in ROLE_CONTRACTS.values() if c.method}
_IDENT = r"[A-Za-z_][A-Za-z0-9_]*"
_TARGET_RE = re.compile(rf"^{_IDENT}(\.{_IDENT})*:{_IDENT}(\.{_IDENT})*$")


def _check_declaration(spec: ComponentSpec, label: str) -> None:
    """The fields of the spec: name, role, target, capabilities, description, extras,
    modules, declared physics."""
    require(isinstance(spec.name, str) and spec.name.strip(), f"{label}: empty name")
    require(spec.name == spec.name.strip() and " " not in spec.name,
            f"{label}: the name must not contain spaces")
    require(spec.role in ROLES, f"{label}: role {spec.role!r} is not one of {ROLES}")
    require(isinstance(spec.target, str) and _TARGET_RE.match(spec.target),
            f"{label}: target {spec.target!r} must read 'package.module:Attribute'")
    require(isinstance(spec.capabilities, dict),
            f"{label}: capabilities must be a dict, got {type(spec.capabilities).__name__}")
    require(isinstance(spec.description, str) and spec.description.strip(),
            f"{label}: empty description (shown by 'rbbench plugins')")
    for field in ("extras", "modules"):
        value = getattr(spec, field)
        require(isinstance(value, tuple) and all(isinstance(v, str) and v for v in value),
                f"{label}: {field} must be a tuple of non-empty strings, got {value!r}")
    physics = spec.capabilities.get("physics")
    if physics is not None:
        require(isinstance(physics, (tuple, list)) and set(physics) <= set(KNOWN_PHYSICS),
                f"{label}: capabilities['physics'] = {physics!r}; known physics: "
                f"{KNOWN_PHYSICS}")


def _load_target(registry: Registry, spec: ComponentSpec, label: str) -> Any:
    """The loaded target: it resolves, is callable, and a class defines its role's method."""
    try:
        obj = registry.load(spec.role, spec.name)
    except (ImportError, AttributeError) as exc:
        raise ContractViolation(
            f"{label}: target {spec.target!r} does not resolve: {exc!r}") from exc
    require(callable(obj), f"{label}: target {spec.target!r} is not callable")
    method = _ROLE_METHOD.get(spec.role)
    if method and isinstance(obj, type):
        # vars() along the MRO: every class object is callable through its metaclass
        require(callable(getattr(obj, method, None))
                and any(method in vars(c) for c in obj.__mro__),
                f"{label}: class {obj.__name__} has no {method}() method")
    return obj


def check_spec(registry: Registry, spec: ComponentSpec) -> Any:
    """Check a component's declaration; return its loaded target, or None if not installed.

    Role valid, ``target`` reads ``"module:attr"`` (and resolves when the
    component is available), ``capabilities`` is a dict, description non-empty,
    the spec is what the registry returns for its (role, name).
    """
    label = f"{spec.role} {spec.name!r} (package {spec.package or '?'})"
    _check_declaration(spec, label)
    require(registry.get(spec.role, spec.name) == spec,
            f"{label}: the registry returns a different spec for this (role, name)")
    ok, why = registry.availability(spec)
    require(isinstance(ok, bool) and isinstance(why, str),
            f"{label}: availability() must return (bool, str)")
    if not ok:
        require(spec.install_hint in why, f"{label}: unavailable, but the reason {why!r} "
                f"does not give the install hint {spec.install_hint!r}")
        return None
    return _load_target(registry, spec, label)


def component_params(registry: Registry | None = None, roles: tuple[str, ...] | None = None):
    """``pytest.param(spec, id="role:name")`` for every registered component.

    Components whose modules are missing carry a skip mark whose reason is the
    install hint from :meth:`Registry.availability`.
    """
    import pytest

    reg = registry or default_registry()
    params = []
    for spec in reg.specs():
        if roles is not None and spec.role not in roles:
            continue
        ok, why = reg.availability(spec)
        marks = () if ok else (pytest.mark.skip(reason=why),)
        params.append(pytest.param(spec, id=f"{spec.role}:{spec.name}", marks=marks))
    return params


def run_contract(spec: ComponentSpec, registry: Registry | None = None) -> None:
    """Declaration check plus the role-specific contract of one registered component, without
    pytest.

    Raises :class:`~rbbench.testing.contract_base.ContractViolation` naming the property that
    fails, and :class:`~rbbench.testing.contract_base.ContractSkipped` when the component is
    not installed (reason: the install hint), when its role has no specific contract yet,
    or when no installed backend can produce the discretizations a formulation needs.
    """
    reg = registry or default_registry()
    ok, why = reg.availability(spec)
    obj = check_spec(reg, spec)
    if not ok:
        raise ContractSkipped(why)
    if spec.role not in ROLE_CHECKS:
        raise ContractSkipped("no role-specific contract yet")
    name = f"{spec.name} ({spec.package or '?'})"
    ROLE_CONTRACTS[spec.role].check(obj, spec, reg, name)


def check_component(spec: ComponentSpec, registry: Registry | None = None) -> None:
    """:func:`run_contract` in a pytest test: a skip becomes ``pytest.skip`` with its reason."""
    import pytest

    try:
        run_contract(spec, registry)
    except ContractSkipped as exc:
        pytest.skip(str(exc))

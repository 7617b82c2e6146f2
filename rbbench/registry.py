"""Plugin registry: entry-point discovery, cheap declarations, lazy loading.

Each component is a :class:`ComponentSpec`: a name, a role, an import target
``"package.module:Attribute"`` and what it needs. The target is imported only
when a run uses it (:meth:`Registry.load`); whether it *could* be imported is
answered without importing it (:meth:`Registry.availability`).
"""

from __future__ import annotations

import importlib
import importlib.metadata as md
import importlib.util
from dataclasses import dataclass, field
from typing import Any

import pluggy

from rbbench import hookspecs

ROLES = (
    "backend",
    "formulation",
    "solver",
    "primal",
    "dual",
    "stabilizer",
    "hyper",
    "executor",
)

ENTRY_POINT_GROUP = "rbbench"


class UnknownComponentError(KeyError):
    """Raised for a component name that no plugin registered."""

    def __str__(self) -> str:  # KeyError quotes its message; keep it readable
        return str(self.args[0])


class NotInstalledError(ImportError):
    """Raised when a component's extra is missing; carries the install hint."""


@dataclass(frozen=True)
class ComponentSpec:
    """Cheap declaration of one component.

    Parameters
    ----------
    name, role
        Unique name within its role; the role is one of :data:`ROLES`.
    target
        ``"module:attribute"`` imported lazily by :meth:`Registry.load`.
    extras
        Extras of the providing package this component needs (install hint).
    modules
        Top-level modules that must be importable (checked with ``find_spec``).
    capabilities
        Free-form declarations used to prune combinations before importing,
        e.g. ``{"physics": ("elasticity", "poisson"), "friction": ("none",)}``.
    description
        One line shown by ``rbbench plugins``.
    """

    name: str
    role: str
    target: str
    extras: tuple[str, ...] = ()
    modules: tuple[str, ...] = ()
    capabilities: dict[str, Any] = field(default_factory=dict)
    description: str = ""
    package: str = ""
    version: str = ""

    def __post_init__(self) -> None:
        if self.role not in ROLES:
            raise ValueError(
                f"component {self.name!r}: role {self.role!r} is not one of {', '.join(ROLES)}"
            )
        if ":" not in self.target:
            raise ValueError(
                f"component {self.name!r}: target {self.target!r} must read 'module:attribute'"
            )

    @property
    def install_hint(self) -> str:
        if not self.extras:
            return f"pip install {self.package or 'rbbench'}"
        return f'pip install "{self.package or "rbbench"}[{",".join(self.extras)}]"'


class Registry:
    """Holds every declared component, keyed by (role, name)."""

    def __init__(self) -> None:
        self._specs: dict[tuple[str, str], ComponentSpec] = {}
        self._current_package = ("", "")
        #: Plugins that failed to load: (entry point, package, message). Shown by
        #: ``rbbench plugins``; they do not hide the other plugins.
        self.broken: list[tuple[str, str, str]] = []

    # -- declaration -----------------------------------------------------
    def add(self, spec: ComponentSpec) -> None:
        """Declare a component (called from ``rbbench_register`` hooks)."""
        key = (spec.role, spec.name)
        if key in self._specs:
            other = self._specs[key]
            raise ValueError(
                f"{spec.role} {spec.name!r} is registered twice "
                f"(by {other.package or '?'} and {self._current_package[0] or '?'})"
            )
        if not spec.package:
            pkg, ver = self._current_package
            spec = ComponentSpec(**{**spec.__dict__, "package": pkg, "version": ver})
        self._specs[key] = spec

    # -- queries ---------------------------------------------------------
    def names(self, role: str) -> list[str]:
        return sorted(n for (r, n) in self._specs if r == role)

    def specs(self, role: str | None = None) -> list[ComponentSpec]:
        return [s for (r, _), s in sorted(self._specs.items()) if role is None or r == role]

    def get(self, role: str, name: str) -> ComponentSpec:
        if role not in ROLES:
            raise UnknownComponentError(f"unknown role {role!r}; valid roles: {', '.join(ROLES)}")
        try:
            return self._specs[(role, name)]
        except KeyError:
            valid = ", ".join(self.names(role)) or "(none registered)"
            raise UnknownComponentError(
                f"unknown {role} {name!r}; valid {role}s: {valid}"
            ) from None

    def availability(self, spec: ComponentSpec) -> tuple[bool, str]:
        """Whether the modules a component needs are importable, without importing them."""
        missing = [m for m in spec.modules if importlib.util.find_spec(m) is None]
        if missing:
            return False, f"missing {', '.join(missing)}; install with: {spec.install_hint}"
        return True, ""

    def load(self, role: str, name: str) -> Any:
        """Import and return the component's target (class or factory)."""
        spec = self.get(role, name)
        ok, why = self.availability(spec)
        if not ok:
            raise NotInstalledError(f"{role} {name!r} is not installed: {why}")
        module_name, attr = spec.target.split(":", 1)
        module = importlib.import_module(module_name)
        obj = module
        for part in attr.split("."):
            obj = getattr(obj, part)
        return obj

    def create(self, role: str, name: str, **options: Any) -> Any:
        """Load a component and instantiate it with ``options``."""
        return self.load(role, name)(**options)


def _plugin_manager() -> pluggy.PluginManager:
    pm = pluggy.PluginManager(hookspecs.PROJECT)
    pm.add_hookspecs(hookspecs)
    return pm


def discover(extra_plugins: tuple[Any, ...] = (), strict: bool = False) -> Registry:
    """Build a registry from every ``rbbench`` entry point (plus ``extra_plugins``).

    A plugin whose module fails to import (or declares badly) is recorded in
    ``registry.broken`` with a message naming the entry point and package; it
    does not hide the others. With ``strict=True`` the first failure raises.
    """
    registry = Registry()
    pm = _plugin_manager()
    for ep in md.entry_points(group=ENTRY_POINT_GROUP):
        dist = ep.dist
        pkg = dist.metadata["Name"] if dist is not None else ep.value.split(".")[0]
        ver = dist.version if dist is not None else ""
        try:
            plugin = ep.load()
            if getattr(plugin, "rbbench_register", None) is None:
                raise ImportError("it defines no rbbench_register hook")
            registry._current_package = (pkg, ver)
            if pm.is_registered(plugin):
                continue
            pm.register(plugin, name=f"{pkg}:{ep.name}")
            _call_one(pm, plugin, registry)
        except Exception as exc:  # noqa: BLE001 - report, do not hide other plugins
            msg = (f"rbbench plugin entry point {ep.name!r} = {ep.value!r} (package {pkg}) "
                   f"failed to load: {type(exc).__name__}: {exc}")
            if strict:
                raise ImportError(msg) from exc
            registry.broken.append((ep.name, pkg, msg))
    for plugin in extra_plugins:
        registry._current_package = (getattr(plugin, "__name__", "local"), "")
        pm.register(plugin)
        _call_one(pm, plugin, registry)
    registry._current_package = ("", "")
    return registry


def _call_one(pm: pluggy.PluginManager, plugin: Any, registry: Registry) -> None:
    """Call one plugin's hook alone, so each declaration records its package."""
    others = [p for p in pm.get_plugins() if p is not plugin]
    pm.subset_hook_caller("rbbench_register", remove_plugins=others)(registry=registry)


_DEFAULT: Registry | None = None


def default_registry(refresh: bool = False) -> Registry:
    """The process-wide registry (discovered once)."""
    global _DEFAULT
    if _DEFAULT is None or refresh:
        _DEFAULT = discover()
    return _DEFAULT

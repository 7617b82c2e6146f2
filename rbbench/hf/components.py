"""The HF components of a scene: the backend, formulation and solver looked up by name,
checked against the scene (friction law, declared solvers) before any meshing, and built."""

from __future__ import annotations

import importlib.util
import inspect
from typing import Any

from rbbench.interfaces import (
    Discretization,
    FrictionLaw,
)
from rbbench.registry import Registry, default_registry
from rbbench.scene.friction import friction_of, friction_value
from rbbench.scene.linear import is_linear
from rbbench.scene.loading import Scene, SceneError
from rbbench.scene.parameters import FieldError


def make_components(scene: Scene, backend: str = "skfem", formulation: str = "mixed",
                    solver: str | None = None, registry: Registry | None = None,
                    solver_options: dict | None = None,
                    component_options: dict | None = None):
    """Instantiate the three HF roles by name (unknown names list the valid ones).

    ``solver = None``: the formulation's first declared solver (:func:`default_solver`).
    ``component_options``: ``{"backend": {...}, "formulation": {...}}`` constructor
    options (e.g. NGSolve's ``mesh``, Nitsche's ``gamma0``).
    """
    opts = component_options or {}
    bad = set(opts) - {"backend", "formulation"}
    if bad:
        raise ValueError(f"component options: unknown role(s) {sorted(bad)}; valid: backend, "
                         "formulation (solver options are solver_options)")
    reg = registry or default_registry()
    solver = check_names(scene, reg, backend, formulation, solver)
    b = reg.create("backend", backend, scene=scene, **opts.get("backend", {}))
    f = reg.create("formulation", formulation, **opts.get("formulation", {}))
    s = reg.create("solver", solver, **(solver_options or {}))
    return b, f, s


def check_component_options(registry: Registry, role: str, name: str, options: Any) -> None:
    """Refuse, before the component is built (a backend meshes in its constructor), options
    its constructor does not take: a :class:`~rbbench.scene.parameters.FieldError` naming
    them and the valid ones. The valid names are the class's ``OPTIONS`` if it declares
    them, else its constructor's keyword parameters (a constructor with ``**options`` and
    no ``OPTIONS`` is not checked here)."""
    field = f"{role}_options"
    if not isinstance(options, dict):
        raise FieldError("", field, options, "give a table of options (a dict)")
    if not options:
        return
    cls = registry.load(role, name)
    valid = getattr(cls, "OPTIONS", None)
    if valid is None:
        params = inspect.signature(cls).parameters.values()
        if any(p.kind is p.VAR_KEYWORD for p in params):
            return
        valid = tuple(p.name for p in params if p.name != "scene")
    unknown = sorted(k for k in options if k not in valid)
    if unknown:
        raise FieldError("", field, options, f"the {role} {name!r} takes no option "
                         f"{', '.join(map(repr, unknown))}; its options: "
                         f"{', '.join(map(repr, valid)) or 'none'}")


def check_physics_support(scene: Scene, registry: Registry, formulation: str) -> None:
    """A formulation that needs the stress on the contact boundary (``needs`` holds
    ``"stress"``: Nitsche) is refused on a scalar scene, before any solve."""
    needs = getattr(registry.load("formulation", formulation), "needs", frozenset())
    physics = scene.data["scene"]["physics"]
    if "stress" in needs and physics != "elasticity":
        raise SceneError(f"{scene.path}: the {formulation!r} formulation needs the contact "
                         f"stress of an elasticity scene; this scene's physics is {physics!r} "
                         "(use the 'mixed' formulation)")


def check_mesher(scene: Scene) -> None:
    """Refuse, before any work, a 3D scene (``[geometry] kind = 'hemispheres'``) when Netgen,
    its mesher, is not installed (it comes with the ``ngsolve`` extra, whichever backend
    solves): a :class:`SceneError` naming the kind and the install command."""
    if scene.data.get("geometry", {}).get("kind") != "hemispheres":
        return
    if importlib.util.find_spec("netgen") is None:
        raise SceneError(f"{scene.path}: [geometry] kind = 'hemispheres' (3D) is meshed by "
                         "Netgen, which comes with NGSolve and is not installed: "
                         'pip install "rbbench[ngsolve]"')


#: What a formulation may ask of a 3D (``hemispheres``) backend besides the normal contact
#: operators: the slave normal stress (Nitsche).
SURFACE_NEEDS = frozenset({"stress"})


def check_geometry_support(scene: Scene, registry: Registry, backend: str,
                           formulation: str) -> None:
    """Refuse a geometry kind the backend does not declare (``capabilities["geometry"]``;
    undeclared: any), and, on the 3D ``hemispheres``, a formulation that needs more than
    the normal contact operators and the slave normal stress (:data:`SURFACE_NEEDS`): 3D
    is frictionless, mixed or Nitsche."""
    kind = scene.data["geometry"]["kind"]
    kinds = registry.get("backend", backend).capabilities.get("geometry")
    if kinds is not None and kind not in kinds:
        ok = [s.name for s in registry.specs("backend")
              if kind in s.capabilities.get("geometry", (kind,))]
        raise SceneError(f"{scene.path}: [geometry] kind = {kind!r}: the {backend!r} backend "
                         f"supports {', '.join(map(repr, kinds))}; backends for {kind!r}: "
                         + ", ".join(map(repr, ok)))
    needs = getattr(registry.load("formulation", formulation), "needs", frozenset())
    extra = set(needs) - SURFACE_NEEDS
    if kind == "hemispheres" and extra:
        raise SceneError(f"{scene.path}: [geometry] kind = 'hemispheres' (3D) builds the normal "
                         f"contact operators and the slave normal stress only; {formulation!r} "
                         f"needs {', '.join(sorted(extra))} operators (valid formulations: "
                         "'mixed', 'nitsche')")
    check_mesher(scene)


def check_names(scene: Scene, registry: Registry, backend: str, formulation: str,
                solver: str | None) -> str:
    """Check the three HF component names before any meshing (unknown names list the valid
    ones; a friction law the formulation or the solver does not declare is refused) and
    return the solver (``None``: :func:`default_solver` for the scene's friction law).
    A linear scene has no contact components: a :class:`SceneError` naming its solve."""
    if is_linear(scene):
        raise SceneError(f"{scene.path}: a linear scene (no contact) is solved by "
                         "rbbench.hf.linear.solve.solve_linear_hf (rbbench solve, "
                         "rbbench.solve) and reduced by rbbench reduce / rbbench.reduce")
    check_friction_support(scene, registry.get("formulation", formulation))
    check_physics_support(scene, registry, formulation)
    if solver is None:
        solver = default_solver(formulation, registry, friction_of(scene).law)
    for role, name in (("backend", backend), ("formulation", formulation), ("solver", solver)):
        registry.get(role, name)
    check_geometry_support(scene, registry, backend, formulation)
    forms = registry.get("solver", solver).capabilities.get("formulations")
    if not solves(registry, solver, formulation):
        raise SceneError(f"solver {solver!r} solves the {', '.join(map(repr, forms))} "
                         f"formulation(s), not {formulation!r}; solvers of {formulation!r}: "
                         + ", ".join(map(repr, _declared_solvers(formulation, registry))))
    check_friction_support(scene, registry.get("solver", solver), formulation, registry)
    return solver


def check_friction_support(scene: Scene, spec: Any, formulation: str | None = None,
                           registry: Registry | None = None) -> None:
    """Refuse a scene whose ``[friction] law`` the formulation or the solver ``spec`` does
    not declare (``capabilities["friction"]``, default ``("none",)``): never a silently
    frictionless solve of a friction scene. For a solver, ``formulation`` names the
    formulation whose declared solvers supporting the law the message lists."""
    law = friction_of(scene).law
    laws = tuple(spec.capabilities.get("friction", ("none",)))
    if law in laws:
        return
    msg = (f"{scene.path}: [friction] law = {law!r}: the {spec.name!r} {spec.role} "
           f"supports {', '.join(repr(x) for x in laws)} only")
    if formulation is not None:
        ok = _solvers_for(formulation, registry or default_registry(), law)
        msg += (f"; solvers of the {formulation!r} formulation for this law: "
                + (", ".join(map(repr, ok)) or "none"))
    raise SceneError(msg)


def solves(registry: Registry, solver: str, formulation: str) -> bool:
    """Whether ``solver`` takes the problems of ``formulation``: the solver declares the
    formulation (``capabilities["formulations"]``; none declared: any), or the formulation
    declares the solver (``capabilities["solvers"]``, so a plugin's formulation whose
    problems are, e.g., ``ContactProblem`` names the built-in solvers that take them)."""
    forms = registry.get("solver", solver).capabilities.get("formulations")
    declared = registry.get("formulation", formulation).capabilities.get("solvers") or ()
    return forms is None or formulation in forms or solver in declared


def _solvers_for(formulation: str, registry: Registry, law: str) -> list[str]:
    """The solvers a formulation declares whose ``capabilities["friction"]`` hold ``law``."""
    out = []
    for name in _declared_solvers(formulation, registry):
        if name in registry.names("solver"):
            laws = registry.get("solver", name).capabilities.get("friction", ("none",))
            if law in laws:
                out.append(str(name))
    return out


def _declared_solvers(formulation: str, registry: Registry) -> tuple:
    """A formulation's ``capabilities["solvers"]`` (``("ssn",)`` when it declares none)."""
    return registry.get("formulation", formulation).capabilities.get("solvers") or ("ssn",)


def friction_at(scene: Scene, mu: Any) -> FrictionLaw | None:
    """The scene's friction law at ``mu`` (``None`` for a frictionless scene)."""
    fr = friction_of(scene)
    if not fr.active:
        return None
    if fr.law == "tresca":
        return FrictionLaw("tresca", threshold=float(friction_value(scene, "threshold", mu)))
    if fr.coefficient_law is not None:
        return FrictionLaw("coulomb", coefficient_law=fr.coefficient_law)
    return FrictionLaw("coulomb", coefficient=float(friction_value(scene, "coefficient", mu)))


def warm_up(backend: Any) -> None:
    """Build the backend's mu-independent operators now (:meth:`Backend.warm_up`; a backend
    outside that base class: its ``inner_product()``, if any), so that no timed
    discretisation holds that one-off work."""
    build = getattr(backend, "warm_up", None) or getattr(backend, "inner_product", None)
    if callable(build):
        build()


def discretize_for(backend: Any, formulation: Any, mu: Any) -> Discretization:
    """``backend.discretize(mu)`` with the optional operators the formulation declares
    (``Formulation.needs``, e.g. ``{"stress"}`` for Nitsche; none for mixed)."""
    needs = frozenset(getattr(formulation, "needs", frozenset()))
    return backend.discretize(mu, needs=needs) if needs else backend.discretize(mu)


def default_solver(formulation: str, registry: Registry | None = None,
                   law: str = "none") -> str:
    """The first solver a formulation declares (``capabilities["solvers"]``): ``ssn`` for
    mixed, ``newton`` for Nitsche; for a friction ``law``, the first that declares it
    (``friction-ssn`` for mixed), else the first declared (refused later, naming the law)."""
    reg = registry or default_registry()
    ok = _solvers_for(formulation, reg, law) if law != "none" else []
    return ok[0] if ok else str(_declared_solvers(formulation, reg)[0])

"""Which cases of a run matrix apply to a scene: a case the components or the formulation's
reduced model refuse is a skip row with the reason (a component whose modules are missing:
``not_installed``), decided from declared capabilities and the early option checks,
before any HF work."""

from __future__ import annotations

from typing import Any

from rbbench.registry import Registry
from rbbench.scene.friction import friction_of
from rbbench.scene.loading import Scene

#: the roles a registry fills (``hyper`` also has built-in values, ``auto`` among them)
REGISTRY_ROLES = ("backend", "formulation", "solver", "primal", "dual", "stabilizer")


def applicable_roles(registry: Registry | None, comp: dict[str, str]) -> dict[str, str]:
    """``comp`` with the roles its formulation declares unused emptied (``""``: not
    applicable; the formulation's ``capabilities["roles"]``, e.g. the linear formulation:
    no solver, dual nor stabiliser)."""
    if registry is None or comp["formulation"] not in registry.names("formulation"):
        return comp
    roles = registry.get("formulation", comp["formulation"]).capabilities.get("roles")
    if roles is None:
        return comp
    return {r: (v if r in (*roles, "formulation") else "") for r, v in comp.items()}


def compatibility(scene: Scene, comp: dict[str, str],
                  registry: Registry | None) -> tuple[str, str]:
    """``("run" | "skip" | "not_installed", reason)`` from declared capabilities only.

    Nothing is imported: the physics a backend and a formulation declare, the
    formulations a solver declares, online stabilisers against HF-free hyper-reducers,
    and whether each component's modules are importable (``find_spec``).
    """
    stab_online = comp["stabilizer"] == "supremizer"
    roles = [r for r in REGISTRY_ROLES if comp[r]]  # "" = not applicable
    if registry is not None:
        caps = {r: registry.get(r, comp[r]).capabilities for r in roles}
        physics = scene.data["scene"]["physics"]
        for r in ("backend", "formulation"):
            ok = caps[r].get("physics")
            ok = ok if ok is None else (*ok, *caps[r].get("linear_physics", ()))
            if ok is not None and physics not in ok:
                return "skip", f"{r} {comp[r]!r} does not support {physics} (supports {ok})"
        law = friction_of(scene).law
        for r in ("formulation", "solver"):
            laws = caps[r].get("friction", ("none",)) if r in caps else (law,)
            if law not in laws:
                return "skip", (f"{r} {comp[r]!r} does not support the friction law "
                                f"{law!r} (supports {tuple(laws)})")
        forms = caps["solver"].get("formulations") if "solver" in caps else None
        declared = caps["formulation"].get("solvers") or ()  # the formulation's own list
        if forms is not None and comp["formulation"] not in forms \
                and comp["solver"] not in declared:
            return "skip", (f"solver {comp['solver']!r} does not solve the "
                            f"{comp['formulation']!r} formulation (solves {forms})")
        if "stabilizer" in caps:
            stab_online = bool(caps["stabilizer"].get("online_hf", stab_online))
    hyper = comp["hyper"]
    if registry is not None and hyper not in ("", "auto") and hyper in registry.names("hyper"):
        forms = registry.get("hyper", hyper).capabilities.get("formulations")
        if forms is not None and comp["formulation"] not in forms:
            return "skip", (f"hyper {hyper!r} does not apply to the {comp['formulation']!r} "
                            f"formulation (applies to {forms})")
    if stab_online and comp["hyper"] in ("affine", "eim"):
        return "skip", (f"stabilizer {comp['stabilizer']!r} needs the HF B(mu) online: "
                        f"incompatible with hyper {comp['hyper']!r}")
    if registry is not None:
        for r in roles:
            ok, why = registry.availability(registry.get(r, comp[r]))
            if not ok:
                return "not_installed", f"{r} {comp[r]!r}: {why}"
    from rbbench.hf.components import check_mesher
    from rbbench.scene.loading import SceneError

    try:
        check_mesher(scene)  # the scene's own mesher (3D: Netgen, the ngsolve extra)
    except SceneError as exc:
        return "not_installed", str(exc)
    return "run", ""


def reduced_model_check(scene: Scene, comp: dict[str, str], params: dict[str, Any],
                        registry: Registry | None, R: int | None = None) -> tuple[str, str]:
    """``("run", "")``, or ``("skip", reason)`` when the formulation's reduced model refuses
    the case before any HF work: the friction laws its offline steps declare, its options
    (an option of another formulation, e.g. ``S`` on a frictionless scene, or ``R`` for a
    formulation without a dual space) and its early checks (``prepare``, e.g. the
    collocation friction model takes no ``hyper = "eim"``); the reason is their message.
    Without a registry nothing is checked here (the case records any failure itself)."""
    from rbbench.rb.config import make_config
    from rbbench.rb.offline import prepare_config
    from rbbench.scene.loading import SceneError

    if registry is None:
        return "run", ""
    try:
        prepare_config(scene, make_config(**{k: v for k, v in comp.items() if v}, R=R,
                                          **params), registry)
    except (SceneError, ValueError) as exc:
        return "skip", str(exc)
    return "run", ""

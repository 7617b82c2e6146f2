"""Linear scenes without contact: stationary diffusion (``thermal``) and the heat equation
(``heat``).

``physics = "thermal"``: ``-div(kappa(mu) grad u) = f`` on the unit square, ``u = 0`` on the
boundary (pyMOR's thermal block: ``kappa = mu_i`` on block ``i`` of a ``bx x by`` grid).
``physics = "heat"``: Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods:
parametric variational inequalities" (talk), slide "Simple toy example: heat equation":
``du/dt - div(mu grad u) = f``, ``-mu du/dn = h0 u`` on the boundary, ``u(0) = u0``, implicit
Euler in time.

Both are affine in mu (every coefficient is a number or ``"mu.NAME"``): the backend assembles
the parameter-independent terms once (``rbbench_plugins.backends.linear_common``). A linear
scene has no ``[load]``, ``[obstacle]``, ``[material]`` nor ``[friction]``: nothing of the
contact pipeline is built for it.
"""

from __future__ import annotations

from typing import Any

from rbbench.scene import limits
from rbbench.scene.loading import PHYSICS_VALIDATORS, Scene, SceneError, _parameters
from rbbench.scene.schema import SCHEMA, Field, _check_value, _err, _unknown

__all__ = ["LINEAR_PHYSICS", "LINEAR_SCHEMA", "block_parameters", "is_linear", "is_parabolic",
           "validate_linear"]

#: The physics of the linear scenes (no contact operator, no multiplier space).
LINEAR_PHYSICS = ("thermal", "heat")

_DISC_KEYS = ("degree", "n_cells", "level")

LINEAR_SCHEMA: dict[str, dict[str, Field]] = {
    "scene": {
        "name": Field("str", required=True),
        "description": Field("str", default=""),
        "physics": Field("str", required=True, choices=LINEAR_PHYSICS),
    },
    "geometry": {
        "kind": Field("str", required=True, choices=("unit_square",)),
        "blocks": Field("point", default=(1, 1), low=1, high=16,
                        doc="thermal block grid [bx, by]: conductivity mu_i on block i "
                            "(i = ix + bx iy, from the lower left corner)"),
    },
    "thermal": {
        "conductivity": Field("str", default="blocks",
                              doc='"blocks" (one parameter per block, declared in order), '
                                  'or "mu.NAME" (one conductivity)'),
        "source": Field("float", default=1.0, parametric=True, doc="source f (constant)"),
        "robin": Field("float", default=0.0, low=0.0, parametric=True,
                       doc="heat: exchange coefficient h0 of -kappa du/dn = h0 u"),
        "initial": Field("float", default=0.0, doc="heat: initial value u0 (constant)"),
    },
    "time": {
        "final": Field("float", default=1.0, low=0.0, low_open=True, doc="final time T"),
        "steps": Field("int", default=50, low=1, high=100000, doc="implicit Euler steps"),
    },
    "sampling": SCHEMA["sampling"],
    "discretization": {
        **{k: SCHEMA["discretization"][k] for k in _DISC_KEYS},
        "inner_product": Field("str", default="h1_semi", choices=("h1_semi", "h1"),
                               doc="X: the H1_0 seminorm |u|_1 (thermal) or the full H1 norm"),
    },
    "reference": {},
}


def is_linear(scene: Any) -> bool:
    """Whether a scene (or its data) is a linear scene of :data:`LINEAR_PHYSICS`."""
    data = scene.data if isinstance(scene, Scene) else scene
    return data.get("scene", {}).get("physics") in LINEAR_PHYSICS


def is_parabolic(scene: Scene) -> bool:
    """Whether the scene is time dependent (``physics = "heat"``)."""
    return scene.data["scene"]["physics"] == "heat"


def block_parameters(scene: Scene) -> list[str]:
    """The parameter of each conductivity block (``"blocks"``: the declared parameters in
    order, one per block; ``"mu.NAME"``: that parameter on the single block)."""
    raw = scene.data["thermal"]["conductivity"]
    if raw == "blocks":
        return list(scene.param_names)
    return [raw[3:]]


def _fill(data: dict[str, Any], path: str, params: dict) -> None:
    """Check the keys of every section and fill its defaults."""
    for section, table in data.items():
        if section not in LINEAR_SCHEMA and section != "parameters":
            raise _unknown(path, "top level", section, [*LINEAR_SCHEMA, "parameters"])
        if not isinstance(table, dict):
            raise _err(path, f"[{section}]", f"expected a table, got {table!r}")
    for section, fields in LINEAR_SCHEMA.items():
        table = data.setdefault(section, {})
        for key in table:
            if key not in fields:
                raise _unknown(path, f"[{section}]", key, list(fields))
        for key, f in fields.items():
            if key not in table:
                if f.required:
                    raise _err(path, f"[{section}] {key}", f"is required; expected "
                               f"{f.describe()}")
                if f.default is not None:
                    table[key] = f.default
                continue
            table[key] = _check_value(path, f"[{section}] {key}", f, table[key], params)


def _check_blocks(data: dict[str, Any], path: str, params: dict) -> None:
    """The conductivity: one parameter per block, block edges on mesh lines."""
    bx, by = (int(v) for v in data["geometry"]["blocks"])
    data["geometry"]["blocks"] = (bx, by)
    raw = data["thermal"]["conductivity"]
    n = int(data["discretization"]["n_cells"])
    if n % bx or n % by:
        raise _err(path, "[discretization] n_cells", f"{n} is not a multiple of the blocks "
                   f"{bx} x {by}: block edges must lie on mesh lines")
    if raw == "blocks":
        if len(params) != bx * by:
            raise _err(path, "[parameters]", f"conductivity = 'blocks' needs one parameter "
                       f"per block ({bx} x {by} = {bx * by}), found {len(params)}")
    elif not (raw.startswith("mu.") and raw[3:] in params) or bx * by != 1:
        raise _err(path, "[thermal] conductivity", f"{raw!r}: expected 'blocks', or "
                   "'mu.NAME' of a declared parameter with blocks = [1, 1]")
    for p in params.values():
        if p.low <= 0:
            raise _err(path, f"[parameters.{p.name}] range", "a conductivity must be > 0")


def validate_linear(data: dict[str, Any], path: str, overrides: tuple[str, ...] = ()) -> Scene:
    """Validate the raw data of a linear scene (already a private copy); fill defaults."""
    params = _parameters(data, path)
    _fill(data, path, params)
    _check_blocks(data, path, params)
    if data["scene"]["physics"] == "thermal" and data["thermal"]["robin"] != 0.0:
        raise _err(path, "[thermal] robin", "physics 'thermal' has u = 0 on the boundary; "
                   "a Robin coefficient is for physics 'heat'")
    if not limits.check_name(data["scene"]["name"]):
        raise _err(path, "[scene] name", f"{data['scene']['name']!r} is not a valid name; "
                   f"expected {limits.NAME_RULE}")
    too_big = limits.check_size(data)
    if too_big:
        raise _err(path, "[discretization]", too_big)
    return Scene(name=data["scene"]["name"], path=path, data=data,
                 parameters=list(params.values()), overrides=tuple(overrides))


def check_physics(scene: Scene) -> None:
    """Raise :class:`SceneError` unless ``scene`` is linear."""
    if not is_linear(scene):
        raise SceneError(f"{scene.path}: physics {scene.data['scene']['physics']!r} is not "
                         f"linear ({', '.join(LINEAR_PHYSICS)})")


PHYSICS_VALIDATORS.update(dict.fromkeys(LINEAR_PHYSICS, validate_linear))

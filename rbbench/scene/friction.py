"""The friction of a scene: the ``[friction]`` section and the friction loads of ``[load]``.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slides "Coulomb contact problem" and "Tangential
constraints"; model B of the talk "On coupling of complementarity with friction in contact
shape optimization"::

    [friction]
    law = "coulomb"            # "none" (default; an absent section is "none"), "tresca", "coulomb"
    coefficient = 0.2          # Coulomb nu_F: a number >= 0, "mu.NAME", or a coefficient law
                               # of the slip |u_t| ("model_b": F(t) = 0.25 / (t^2 + 1))
    # threshold = 1.0e6        # Tresca s (Pa): a number >= 0 or "mu.NAME"

    [load]
    displacement = 0.05
    tangential_displacement = 0.002   # imposed along +x on the loaded (upper flat) face (m)
    load_steps = [{normal = 1.0}, {normal = 1.0, tangential = 1.0}]   # normal, then shear

A load step scales the two loads: ``normal`` times ``displacement`` and ``tangential``
times ``tangential_displacement`` (each 0 when left out). Without ``load_steps`` there is
one step, ``{normal = 1, tangential = 1}``. Friction is path-dependent: slip is measured
from the previous step. At most :data:`~rbbench.scene.limits.MAX_LOAD_STEPS` steps, each
fraction at most :data:`MAX_STEP_FRACTION` in magnitude.

The scene layer imports nothing above it, so the coefficient laws are named here
(:data:`COEFFICIENT_LAW_NAMES`) and defined in :mod:`rbbench.hf.algebra.friction`
(``COEFFICIENT_LAWS``); a test keeps the two in step. A former name
(:data:`DEPRECATED_COEFFICIENT_LAWS`) still loads, with a :class:`DeprecationWarning`. A
frictionless scene holds none of these keys in its cache key (:func:`key_neutral`).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from rbbench.scene.limits import MAX_LOAD_STEPS
from rbbench.scene.parameters import SceneError

#: the friction laws of ``[friction] law``
LAWS = ("none", "tresca", "coulomb")
#: slip-dependent coefficient laws ``F(|u_t|)`` (``rbbench.hf.algebra.friction.COEFFICIENT_LAWS``)
COEFFICIENT_LAW_NAMES = ("model_b",)
#: former names of the coefficient laws, accepted with a DeprecationWarning until rbbench 0.3
DEPRECATED_COEFFICIENT_LAWS = {"seed001": "model_b"}
#: the keys of ``[friction]``, and the law each of the other keys belongs to
FRICTION_KEYS = ("law", "threshold", "coefficient")
_KEY_LAW = {"threshold": "tresca", "coefficient": "coulomb"}
#: the keys of one load step
STEP_KEYS = ("normal", "tangential")
#: largest magnitude of a load step's fraction of the scene's load
MAX_STEP_FRACTION = 10.0
_COEFFICIENT_WHAT = ('a number >= 0, "mu.NAME" for a declared parameter, or a coefficient '
                     "law of the slip: " + ", ".join(map(repr, COEFFICIENT_LAW_NAMES)))


def _err(path: str, where: str, msg: str) -> SceneError:
    return SceneError(f"{path}: {where}: {msg}")


def _number(path: str, where: str, value: Any, params: dict[str, Any],
            what: str = "a number >= 0", low: float | None = 0.0) -> Any:
    """A finite number ``>= low`` or a ``"mu.NAME"`` reference valid over the whole range."""
    if isinstance(value, str) and value.startswith("mu."):
        name = value[3:]
        if name not in params:
            raise _err(path, where, f"references parameter {name!r}, which is not declared; "
                       f"declared: {', '.join(params) or '(none)'}")
        for end in (params[name].low, params[name].high):
            _number(path, f"{where} (at {name} = {end:g})", end, params, what, low)
        return value
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _err(path, where, f"expected {what}, got {value!r}")
    if not math.isfinite(value):
        raise _err(path, where, f"expected a finite number ({what}), got {value!r}")
    if low is not None and value < low:
        raise _err(path, where, f"{value!r} is out of range; expected {what}")
    return float(value)


def _check_keys(table: dict[str, Any], path: str, law: str) -> None:
    """Every key of ``[friction]`` is known and belongs to the law; the law's own is given."""
    for key in table:
        if key not in FRICTION_KEYS:
            raise _err(path, "[friction]", f"unknown key {key!r}; valid keys: "
                       f"{', '.join(sorted(FRICTION_KEYS))}")
        owner = _KEY_LAW.get(key)
        if owner is not None and owner != law:
            raise _err(path, f"[friction] {key}", f"applies to law = {owner!r} only; this "
                       f"scene has law = {law!r}")
    for key, owner in _KEY_LAW.items():
        if owner == law and key not in table:
            raise _err(path, f"[friction] {key}", f"is required for law = {law!r}; expected "
                       + ("a number >= 0 or \"mu.NAME\"" if key == "threshold" else
                          _COEFFICIENT_WHAT))



def _check_law(data: dict[str, Any], path: str, params: dict[str, Any]) -> str:
    """Check ``[friction]`` (when present) and return its law (``"none"`` when absent)."""
    table = data.get("friction")
    if table is None:
        return "none"
    law = table.get("law", "none")
    if law not in LAWS:
        raise _err(path, "[friction] law", f"{law!r} is not valid; expected one of "
                   + ", ".join(map(repr, LAWS)))
    table["law"] = law
    _check_keys(table, path, law)
    if "threshold" in table:
        table["threshold"] = _number(path, "[friction] threshold", table["threshold"], params,
                                     'a number >= 0 or "mu.NAME" for a declared parameter')
    coef = table.get("coefficient")
    if isinstance(coef, str) and coef in DEPRECATED_COEFFICIENT_LAWS:
        new = DEPRECATED_COEFFICIENT_LAWS[coef]
        warnings.warn(f"{path}: [friction] coefficient {coef!r} is now {new!r} (the old name "
                      "goes in rbbench 0.3)", DeprecationWarning, stacklevel=2)
        coef = table["coefficient"] = new
    if coef is not None and coef not in COEFFICIENT_LAW_NAMES:
        if isinstance(coef, str) and not coef.startswith("mu."):
            raise _err(path, "[friction] coefficient",
                       f"{coef!r} is not valid; expected {_COEFFICIENT_WHAT}")
        table["coefficient"] = _number(path, "[friction] coefficient", coef, params,
                                       _COEFFICIENT_WHAT)
    if law != "none" and (data["geometry"]["kind"] != "halfdisks"
                          or data["scene"]["physics"] != "elasticity"):
        raise _err(path, "[friction] law", f"{law!r} needs a two-body elasticity scene "
                   "(geometry kind 'halfdisks'); use law = 'none' here")
    return law


def _check_steps(steps: Any, path: str, tangential: bool) -> list[dict[str, float]]:
    """``[load] load_steps``: a non-empty list of tables ``{normal, tangential}`` (filled)."""
    where = "[load] load_steps"
    what = ("a non-empty list of tables such as [{normal = 1.0}, {normal = 1.0, "
            "tangential = 1.0}] (fractions of displacement and tangential_displacement)")
    if not isinstance(steps, list) or not steps or not all(isinstance(s, dict) for s in steps):
        raise _err(path, where, f"expected {what}, got {steps!r}"[:400])
    if len(steps) > MAX_LOAD_STEPS:
        raise _err(path, where, f"{len(steps)} steps; at most {MAX_LOAD_STEPS} (each step is "
                   "one nonlinear solve of every snapshot)")
    out = []
    for i, step in enumerate(steps):
        for key in step:
            if key not in STEP_KEYS:
                raise _err(path, f"{where}[{i}]", f"unknown key {key!r}; valid keys: "
                           + ", ".join(STEP_KEYS))
        normal = _number(path, f"{where}[{i}] normal", step.get("normal", 0.0), {},
                         "a finite number >= 0")
        shear = _number(path, f"{where}[{i}] tangential", step.get("tangential", 0.0), {},
                        "a finite number", low=None)
        for key, v in (("normal", normal), ("tangential", shear)):
            if abs(v) > MAX_STEP_FRACTION:
                raise _err(path, f"{where}[{i}] {key}", f"{v!r} is out of range; a step is a "
                           f"fraction of the scene's load, at most {MAX_STEP_FRACTION:g} in "
                           "magnitude")
        if shear != 0.0 and not tangential:
            raise _err(path, f"{where}[{i}] tangential", "a tangential step needs "
                       "[load] tangential_displacement")
        out.append({"normal": normal, "tangential": shear})
    return out


def check_friction(data: dict[str, Any], path: str, params: dict[str, Any]) -> None:
    """Validate ``[friction]`` and the friction loads of ``[load]`` (in place).

    Called by :func:`rbbench.scene.loading.validate` after the schema sections are
    checked (``[load] tangential_displacement`` is already a finite number or a valid
    ``"mu.NAME"``). An absent ``[friction]`` stays absent.

    Raises
    ------
    SceneError
        Naming the file, the key, what was found and what is valid: an unknown law or
        key, a key of another law, ``threshold`` / ``coefficient`` negative, non-finite or
        missing, friction on a scalar scene, a tangential load or load steps without
        friction, ``[reference] mindlin`` without Coulomb friction.
    """
    law = _check_law(data, path, params)
    if data.get("reference", {}).get("mindlin") and law != "coulomb":
        raise _err(path, "[reference] mindlin", "the Cattaneo-Mindlin check needs Coulomb "
                   f"friction ([friction] law = 'coulomb'); this scene has law = {law!r}")
    load = data.get("load", {})
    if law == "none":
        for key in ("tangential_displacement", "load_steps"):
            if key in load:
                raise _err(path, f"[load] {key}", "a tangential load or load steps need "
                           "friction: set [friction] law = 'tresca' or 'coulomb', or "
                           f"remove {key}")
        return
    if "load_steps" in load:
        load["load_steps"] = _check_steps(load["load_steps"], path,
                                          "tangential_displacement" in load)


def key_neutral(data: dict[str, Any]) -> dict[str, Any]:
    """``data`` without a frictionless ``[friction]`` section (``law = "none"`` and nothing
    else), so that cache keys of frictionless scenes do not change (a shallow copy)."""
    table = data.get("friction")
    if isinstance(table, dict) and set(table) <= {"law"} and table.get("law", "none") == "none":
        return {k: v for k, v in data.items() if k != "friction"}
    return data


# ---------------------------------------------------------------------------
# the friction of a validated scene
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Friction:
    """The friction data of a validated scene (raw values: numbers or ``"mu.NAME"``).

    ``coefficient`` is a number, a ``"mu.NAME"`` reference or the name of a
    coefficient law of the slip (:data:`COEFFICIENT_LAW_NAMES`).
    """

    law: str = "none"
    threshold: float | str | None = None
    coefficient: float | str | None = None
    tangential_displacement: float | str | None = None
    steps: tuple[tuple[float, float], ...] = ((1.0, 1.0),)

    @property
    def active(self) -> bool:
        """Whether the scene has friction (``law != "none"``)."""
        return self.law != "none"

    @property
    def coefficient_law(self) -> str | None:
        """The name of the slip-dependent coefficient law, else ``None``."""
        c = self.coefficient
        return c if isinstance(c, str) and c in COEFFICIENT_LAW_NAMES else None


def friction_of(scene: Any) -> Friction:
    """The :class:`Friction` of a validated scene (:class:`rbbench.scene.loading.Scene`)."""
    table = scene.data.get("friction", {})
    load = scene.data.get("load", {})
    steps = load.get("load_steps")
    return Friction(
        law=table.get("law", "none"), threshold=table.get("threshold"),
        coefficient=table.get("coefficient"),
        tangential_displacement=load.get("tangential_displacement"),
        steps=((1.0, 1.0),) if steps is None else
        tuple((s["normal"], s["tangential"]) for s in steps))


def friction_value(scene: Any, key: str, mu: np.ndarray | None = None) -> float | str | None:
    """``[friction] key`` at ``mu`` (``"mu.NAME"`` resolved; a coefficient law's name as is;
    ``None`` when not given)."""
    raw = scene.data.get("friction", {}).get(key)
    if raw is None or raw in COEFFICIENT_LAW_NAMES:
        return raw
    return float(scene.resolve(raw, mu))


def tangential_displacement(scene: Any, mu: np.ndarray | None = None) -> float:
    """``[load] tangential_displacement`` at ``mu`` (m; 0 when not given)."""
    raw = scene.data.get("load", {}).get("tangential_displacement")
    return 0.0 if raw is None else float(scene.resolve(raw, mu))

"""Scene files (``problems/*.toml``): loading, validation, overrides, parameters.

A scene names its geometry, materials, load, contact, parameter domain,
sampling and discretisation defaults, and the reference checks that apply.
Any number that may depend on the parameter is written either as a number or
as ``"mu.NAME"``, a reference to the parameter ``NAME`` declared in
``[parameters.NAME]``.

Every validation error names the file, the key, what was found and what would
be valid (:class:`SceneError`).
"""

from __future__ import annotations

import copy
import hashlib
import json
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from rbbench.scene import limits
from rbbench.scene.friction import check_friction, key_neutral
from rbbench.scene.limits import tomllib  # noqa: F401 - the TOML reader (tomli before 3.11)
from rbbench.scene.parameters import ParameterSpace, SceneError  # noqa: F401 - SceneError lives here
from rbbench.scene.schema import (
    _ELASTIC,
    _KIND_REQUIRES,
    _PARAM_FIELDS,
    HALFDISK_ONLY,
    HEMISPHERE_DEFAULTS,
    SCHEMA,
    Parameter,
    _check_value,
    _err,
    _parameter_ref,
    _unknown,
    check_reduce_section,
)


def _shipped_dir(package: str = "rbbench.problems") -> Path:
    """The directory of the scenes shipped with rbbench (package data on disk).

    Found with :mod:`importlib.resources`, so it is the same in a wheel and in an
    editable install (``pyproject.toml`` maps ``rbbench.problems`` to ``problems/``).
    """
    root = resources.files(package)
    if not isinstance(root, Path):  # e.g. a zip import: scenes are read as files
        raise ImportError(f"{package}: the shipped scenes are not files on disk ({root})")
    return root


#: The shipped scenes (``*.toml``) and run matrices (``matrices/*.toml``).
PROBLEMS_DIR: Path = _shipped_dir()


@dataclass
class Scene:
    """A validated scene: raw data (with defaults filled in) plus its parameters."""

    name: str
    path: str
    data: dict[str, Any]
    parameters: list[Parameter]
    overrides: tuple[str, ...] = ()

    # -- parameters ----------------------------------------------------------
    @property
    def param_names(self) -> list[str]:
        return [p.name for p in self.parameters]

    @property
    def bounds(self) -> np.ndarray:
        return np.array([[p.low, p.high] for p in self.parameters], dtype=float)

    @property
    def default_mu(self) -> np.ndarray:
        return np.array([p.default for p in self.parameters], dtype=float)

    @property
    def parameter_space(self) -> ParameterSpace:
        """The domain D, small and picklable (held by HF and reduced models)."""
        ps = self.parameters
        return ParameterSpace(tuple(p.name for p in ps), tuple(float(p.low) for p in ps),
                              tuple(float(p.high) for p in ps), tuple(p.unit for p in ps),
                              where=str(self.path), scene=self.name)

    def check_mu(self, mu: Any) -> np.ndarray:
        """Return ``mu`` as an array, or raise :class:`SceneError` if out of the domain D."""
        return self.parameter_space.check(mu)

    def mu_dict(self, mu: np.ndarray) -> dict[str, float]:
        return {p.name: float(v) for p, v in zip(self.parameters, np.atleast_1d(mu), strict=True)}

    # -- values --------------------------------------------------------------
    def get(self, section: str, key: str, default: Any = None) -> Any:
        return self.data.get(section, {}).get(key, default)

    def value(self, section: str, key: str, mu: np.ndarray | None = None) -> Any:
        """A scene value at ``mu``, resolving ``"mu.NAME"`` references."""
        raw = self.get(section, key)
        return self.resolve(raw, mu)

    def resolve(self, raw: Any, mu: np.ndarray | None = None) -> Any:
        """A raw scene value at ``mu``: a ``"mu.NAME"`` reference becomes the parameter's
        value (``mu = None``: the default), anything else is returned as is."""
        name = _parameter_ref(raw)
        if name is not None:
            mu = self.default_mu if mu is None else np.atleast_1d(mu)
            return float(mu[self.param_names.index(name)])
        return raw

    def affine(self, raw: Any) -> np.ndarray:
        """A raw scalar scene value as coefficients on ``theta = [1, mu_1, ..., mu_p]``.

        Scene values are constants or ``"mu.NAME"`` references, so each is
        affine in mu; ``resolve(raw, mu) == affine(raw) @ [1, *mu]``.
        """
        coef = np.zeros(1 + len(self.parameters))
        name = _parameter_ref(raw)
        if name is not None:
            coef[1 + self.param_names.index(name)] = 1.0
        else:
            coef[0] = float(raw)
        return coef

    def affine_coefficients(self, section: str, key: str) -> np.ndarray:
        """:meth:`affine` of the value ``[section] key``:
        ``value(section, key, mu) == coefficients @ [1, *mu]``."""
        return self.affine(self.get(section, key))

    def is_parametric(self, section: str, key: str) -> bool:
        return _parameter_ref(self.get(section, key)) is not None

    def material(self, body: str, mu: np.ndarray | None = None) -> tuple[float, float]:
        table = self.data.get("material", {}).get(body)
        if table is None:
            raise SceneError(f"{self.path}: [material.{body}] is missing (E and nu)")
        return float(self.resolve(table["E"], mu)), float(self.resolve(table["nu"], mu))

    # -- identity ------------------------------------------------------------
    def fingerprint(self) -> str:
        """Hash of the validated content (for caches): same content, same key.

        Options added after release that sit at their default are left out
        (:func:`key_data`), so existing caches keep their keys."""
        blob = json.dumps(key_data(self.data), sort_keys=True, default=str).encode()
        return hashlib.sha256(blob).hexdigest()[:16]

    def with_overrides(self, overrides: list[str] | tuple[str, ...]) -> Scene:
        return load_scene(self.path, overrides=tuple(self.overrides) + tuple(overrides))


#: Options added after scenes were first cached: (section, field) -> the default that
#: reproduces the former behaviour. At that default they stay out of cache keys.
KEY_NEUTRAL_DEFAULTS = {("discretization", "normals"): "facet",
                        ("discretization", "contact_integration"): "gauss",
                        ("reference", "mindlin"): False}


def key_data(data: dict) -> dict:
    """``data`` without the :data:`KEY_NEUTRAL_DEFAULTS` fields that hold their default
    (a shallow copy per touched section; ``data`` is not modified)."""
    out = key_neutral(dict(data))  # a frictionless [friction] section
    for (section, field), default in KEY_NEUTRAL_DEFAULTS.items():
        sec = out.get(section)
        if isinstance(sec, dict) and sec.get(field, default) == default and field in sec:
            out[section] = {k: v for k, v in sec.items() if k != field}
    return out


# ---------------------------------------------------------------------------
# loading
# ---------------------------------------------------------------------------
def find_scene(name_or_path: str | Path) -> Path:
    """A scene file by path, or a shipped scene by name (:data:`PROBLEMS_DIR`).

    Parameters
    ----------
    name_or_path : str or Path
        A ``.toml`` file (the user's own scene), or the name of a shipped scene
        (``membrane_obstacle``).

    Returns
    -------
    Path
        The scene file.

    Raises
    ------
    SceneError
        If it is neither; the message lists the shipped scenes.
    """
    path = Path(name_or_path)
    if path.is_dir():
        raise SceneError(f"{path}: is a directory; expected a scene .toml file or the name "
                         "of a shipped scene")
    if path.suffix == ".toml" and path.exists():
        return path
    candidate = PROBLEMS_DIR / f"{name_or_path}.toml"
    if candidate.exists():
        return candidate
    if path.exists():
        return path
    available = sorted(p.stem for p in PROBLEMS_DIR.glob("*.toml"))
    raise SceneError(
        f"no scene {str(name_or_path)!r}: not a file, and not in {PROBLEMS_DIR}; "
        f"available scenes: {', '.join(available) or '(none)'}"
    )


def parse_override(text: str) -> tuple[list[str], Any]:
    """Parse ``section.key=value`` (value as a TOML literal, else a string)."""
    if not isinstance(text, str) or "=" not in text:
        raise SceneError(f"override {text!r}: expected section.key=value")
    key, raw = text.split("=", 1)
    parts = [p for p in key.strip().split(".") if p]
    if len(parts) < 2:
        raise SceneError(
            f"override {text!r}: the key must read section.key (e.g. load.displacement)")
    try:
        value = limits.toml_literal(raw.strip(), f"override {key.strip()!r}")
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    return parts, value


def load_scene(name_or_path: str | Path, overrides: tuple[str, ...] | list[str] = ()) -> Scene:
    """Load and validate a scene, applying ``--set`` style overrides."""
    path = find_scene(name_or_path)
    try:
        data = limits.read_toml(path, "scene")
    except ValueError as exc:  # a directory, too large, unreadable, not UTF-8, not TOML
        raise SceneError(str(exc)) from None
    for text in overrides:
        parts, value = parse_override(text)
        node = data
        for p in parts[:-1]:
            node = node.setdefault(p, {})
            if not isinstance(node, dict):
                raise SceneError(f"{path}: override {text!r}: {p!r} is not a table")
        node[parts[-1]] = value
    try:
        return validate(data, str(path), tuple(overrides))
    except SceneError as exc:
        if overrides:
            raise SceneError(f"{exc} (after overrides: {', '.join(overrides)})") from None
        raise


def _check_sections(data: dict[str, Any], path: str) -> None:
    """Every top-level key is a known section holding a table."""
    valid_sections = sorted(list(SCHEMA) + ["parameters", "friction", "reduce"])
    for section in data:
        if section not in valid_sections:
            raise _unknown(path, "top level", section, valid_sections)
        if not isinstance(data[section], dict):
            raise _err(path, f"[{section}]", f"expected a table, got {data[section]!r}")


def _parameters(data: dict[str, Any], path: str) -> dict[str, Parameter]:
    """The declared parameters (checked; each default filled into ``data``)."""
    raw_params = data.get("parameters", {})
    if not raw_params:
        raise _err(path, "[parameters]", "declare at least one parameter, e.g. "
                   "[parameters.mu] range = [0.7, 1.3]")
    params: dict[str, Parameter] = {}
    for name, table in raw_params.items():
        where = f"[parameters.{name}]"
        if not limits.check_name(name, limits.PARAMETER_PATTERN):
            raise _err(path, f"[parameters] {name!r}", f"not a valid parameter name; "
                       f"expected {limits.PARAMETER_RULE}")
        if not isinstance(table, dict):
            raise _err(path, where, f"expected a table with 'range', got {table!r}")
        for key in table:
            if key not in _PARAM_FIELDS:
                raise _unknown(path, where, key, list(_PARAM_FIELDS))
        if "range" not in table:
            raise _err(path, where, "missing 'range' = [low, high]")
        lo, hi = _check_value(path, f"{where} range", _PARAM_FIELDS["range"], table["range"], {})
        default = table.get("default", 0.5 * (lo + hi))
        default = _check_value(path, f"{where} default", _PARAM_FIELDS["default"], default, {})
        if not lo <= default <= hi:
            raise _err(path, f"{where} default", f"{default:g} is outside range [{lo:g}, {hi:g}]")
        table["default"] = default
        params[name] = Parameter(name, lo, hi, default, str(table.get("unit", "")),
                                 str(table.get("description", "")))
    return params


def _fill_schema(data: dict[str, Any], path: str, params: dict[str, Parameter]) -> None:
    """Check the keys of every :data:`SCHEMA` section and fill their defaults."""
    for section, fields in SCHEMA.items():
        table = data.setdefault(section, {})
        for key in table:
            if key not in fields:
                raise _unknown(path, f"[{section}]", key, list(fields))
        for key, f in fields.items():
            where = f"[{section}] {key}"
            if key not in table:
                if f.required:
                    raise _err(path, where, f"is required; expected {f.describe()}")
                if f.default is not None:
                    table[key] = f.default
                continue
            table[key] = _check_value(path, where, f, table[key], params)


def _check_materials(data: dict[str, Any], path: str, params: dict[str, Parameter]) -> None:
    """Check the elastic tables ``[material.upper]`` / ``[material.lower]`` when given."""
    for body in ("upper", "lower"):
        mat = data["material"].get(body)
        if mat is None:
            continue
        for key in mat:
            if key not in _ELASTIC:
                raise _unknown(path, f"[material.{body}]", key, list(_ELASTIC))
        for key, f in _ELASTIC.items():
            if key not in mat:
                raise _err(path, f"[material.{body}] {key}",
                           f"is required; expected {f.describe()}")
            mat[key] = _check_value(path, f"[material.{body}] {key}", f, mat[key], params)


def _span(raw: Any, params: dict[str, Parameter]) -> tuple[float, float]:
    """The least and the largest value of a validated scene value over the domain (a
    number, or a ``"mu.NAME"`` reference: the parameter's range)."""
    name = _parameter_ref(raw)
    if name is None:
        return float(raw), float(raw)
    return float(params[name].low), float(params[name].high)


def _check_kind(data: dict[str, Any], path: str, params: dict[str, Parameter],
                given: frozenset[str] = frozenset()) -> None:
    """The keys and the physics that the geometry kind requires (``given``: the
    ``[geometry]`` keys the file sets, before defaults)."""
    kind = data["geometry"]["kind"]
    if kind == "hemispheres":
        _fill_hemispheres(data, path, given)
    else:
        for key in set(HEMISPHERE_DEFAULTS) | {"symmetry"}:
            if key in given:
                raise _err(path, f"[geometry] {key}", "is a key of geometry kind "
                           f"'hemispheres' only; this scene's kind is {kind!r}")
    for section, keys in _KIND_REQUIRES[kind].items():
        for key in keys:
            if key not in data[section]:
                what = ("a table with E and nu" if section == "material"
                        else SCHEMA[section][key].describe())
                raise _err(path, f"[{section}] {key}",
                           f"is required for geometry kind {kind!r}; expected {what}")
    if kind == "halfdisks" and data["geometry"]["lower"] == "hemisphere":
        raise _err(path, "[geometry] lower", "'hemisphere' is a 3D body; for geometry kind "
                   "'halfdisks' expected 'half_disk' or 'rigid_flat'")
    if kind in ("halfdisks", "hemispheres"):
        lower = data["geometry"]["lower"]
        if lower != "rigid_flat":
            if "lower" not in data["material"]:
                raise _err(path, "[material.lower]",
                           f"is required when geometry.lower = {lower!r} (a table with E and nu)")
            if "lower_radius" not in data["geometry"]:
                raise _err(path, "[geometry] lower_radius",
                           f"is required when geometry.lower = {lower!r}; expected "
                           + SCHEMA["geometry"]["lower_radius"].describe())
        if data["scene"]["physics"] != "elasticity":
            raise _err(path, "[scene] physics", f"geometry kind {kind!r} needs 'elasticity'")
        d, r1 = data["load"]["displacement"], data["geometry"]["upper_radius"]
        if _span(d, params)[1] >= _span(r1, params)[0]:
            raise _err(path, "[load] displacement", f"{d!r} is out of range; the approach of "
                       "the upper body must stay below its radius [geometry] upper_radius = "
                       f"{r1!r} (over the parameter domain)")
    if kind == "unit_square" and data["scene"]["physics"] != "poisson":
        raise _err(path, "[scene] physics", "geometry kind 'unit_square' needs 'poisson'")


def _fill_hemispheres(data: dict[str, Any], path: str, given: frozenset[str]) -> None:
    """``hemispheres``: refuse the half-disk zone keys (angles of 2D arcs), fill the cap
    defaults (:data:`HEMISPHERE_DEFAULTS`), and keep the caps within the slave's half."""
    geo = data["geometry"]
    for key in HALFDISK_ONLY:
        if key in given:
            raise _err(path, f"[geometry] {key}", "is a key of geometry kind 'halfdisks'; "
                       "for 'hemispheres' use contact_cap and master_cap (polar angle / pi)")
        geo.pop(key, None)
    for key, default in HEMISPHERE_DEFAULTS.items():
        geo.setdefault(key, default)
    if "lower" not in given:
        geo["lower"] = "hemisphere"
    if geo["lower"] == "half_disk":
        raise _err(path, "[geometry] lower", "'half_disk' is a 2D body; for geometry kind "
                   "'hemispheres' expected 'hemisphere' or 'rigid_flat'")
    grading = data["discretization"]["grading"]
    if grading > 1.0:
        raise _err(path, "[discretization] grading", f"{grading!r} is out of range for "
                   "geometry kind 'hemispheres' (Netgen's grading); expected a number > 0 "
                   "and <= 1")
    law = data.get("friction", {}).get("law", "none")
    if law != "none":
        raise _err(path, "[friction] law", "geometry kind 'hemispheres' is frictionless "
                   "for now; expected 'none'")


#: Validators of scene kinds with their own schema, by physics: ``(data, path, overrides)
#: -> Scene`` (registered by :mod:`rbbench.scene.linear` for ``thermal`` and ``heat``).
PHYSICS_VALIDATORS: dict[str, Any] = {}


def validate(data: dict[str, Any], path: str = "<scene>", overrides: tuple[str, ...] = ()) -> Scene:
    """Validate raw scene data; fill defaults; return a :class:`Scene`."""
    data = copy.deepcopy(data)
    physics = data["scene"].get("physics") if isinstance(data.get("scene"), dict) else None
    if physics in PHYSICS_VALIDATORS:  # e.g. the linear scenes (rbbench.scene.linear)
        return PHYSICS_VALIDATORS[physics](data, path, tuple(overrides))
    _check_sections(data, path)
    params = _parameters(data, path)  # first: other keys may reference them
    given = frozenset(data.get("geometry", {}))
    _fill_schema(data, path, params)
    _check_materials(data, path, params)
    _check_kind(data, path, params, given)
    check_friction(data, path, params)  # [friction], tangential load, load steps
    check_reduce_section(data, path)  # the scene's reduction defaults, if any
    if not limits.check_name(data["scene"]["name"]):
        raise _err(path, "[scene] name", f"{data['scene']['name']!r} is not a valid name "
                   f"(it names output files); expected {limits.NAME_RULE}")
    too_big = limits.check_size(data)  # before any meshing
    if too_big:
        raise _err(path, "[discretization]", too_big)
    return Scene(name=data["scene"]["name"], path=path, data=data,
                 parameters=list(params.values()), overrides=tuple(overrides))


from rbbench._compat import deprecated_names  # noqa: E402 - after the module's own names

__getattr__ = deprecated_names(__name__)  # names that left this module (rbbench._compat)

"""The ``shape_coulomb`` scene: data, validation, admissible set.

Model B of the talk "On coupling of complementarity with friction in contact shape optimization".

Read from ``problems/optimize/shape_coulomb.toml``; every invalid field raises
:class:`~rbbench.scene.parameters.SceneError` naming the file and key and what is valid
(the CLI turns it into exit code 2). The admissible set ``omega`` of the talk,

``0 <= alpha_i <= C0``, ``|alpha_{i+1} - alpha_i| <= C1 h``, ``C2 <= meas Omega(alpha) <= C3``,

is a polyhedron: the area is affine in the nodal design (trapezoidal rule, exact for the
piecewise-linear boundary), so it is imposed exactly, not linearised.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from rbbench.optim.shape_mesh import Grid, area, area_weights, elasticity_matrix
from rbbench.scene.limits import NAME_PATTERN, check_name, read_toml, toml_literal
from rbbench.scene.loading import PROBLEMS_DIR
from rbbench.scene.parameters import ParameterSpace, SceneError

SHAPE_DIR = PROBLEMS_DIR / "optimize"


@dataclass(frozen=True)
class ShapeScene:
    """Data of the shape problem; lengths in m, forces in kN per m of depth (plane strain)."""

    name: str = "shape_coulomb"
    a: float = 0.0
    b: float = 2.0
    gamma: float = 1.0
    n_contact: int = 81
    ny: int = 40
    E: float = 1.0e4
    nu: float = 0.3
    pressure: float = 200.0
    traction: float = 20.0
    friction0: float = 0.25
    slip_scale: float = 1.0
    C0: float = 0.75
    C1: float = 3.0
    C2: float = 1.8
    C3: float = 2.0
    initial: str = "parabola"
    initial_height: float = 0.1
    power: int = 6
    source: str = "<defaults>"
    extra: dict = field(default_factory=dict, compare=False)

    @property
    def grid(self) -> Grid:
        return Grid(self.a, self.b, self.gamma, self.n_contact - 1, self.ny)

    @property
    def D(self) -> np.ndarray:
        return elasticity_matrix(self.E, self.nu)

    def friction(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``F(t) = F0 / ((t / l)^2 + 1)`` (model B: F0 = 0.25, l = 1) and ``F'(t)``."""
        s = np.asarray(t) / self.slip_scale
        F = self.friction0 / (s * s + 1.0)
        return F, -2.0 * self.friction0 * s / ((s * s + 1.0) ** 2 * self.slip_scale)

    def uniform_pressure_bound(self) -> float:
        """``J >= I (P / I)^p``: the whole top load ``P = pressure (b - a)`` passes through
        the ``I`` contact nodes (``sum lam = P``), and by Jensen's inequality ``sum lam^p``
        is least when the forces are equal (``summary.json`` ``J_uniform_bound``)."""
        n = self.n_contact
        return n * (self.pressure * (self.b - self.a) / n) ** self.power

    def initial_design(self) -> np.ndarray:
        """``alpha_0``: ``parabola`` (height at the ends, 0 in the middle), ``vee`` or ``flat``."""
        x = self.grid.x1
        r = (x - 0.5 * (self.a + self.b)) / (0.5 * (self.b - self.a))
        shapes = {"parabola": r * r, "vee": np.abs(r), "flat": np.ones_like(r)}
        return self.initial_height * shapes[self.initial]

    def admissible(self) -> dict[str, np.ndarray]:
        """The polyhedron ``lb <= alpha <= ub``, ``cl <= C alpha <= cu`` (the admissible set)."""
        n, h = self.n_contact, self.grid.h
        diff = np.zeros((n - 1, n))
        diff[np.arange(n - 1), np.arange(n - 1)] = -1.0
        diff[np.arange(n - 1), np.arange(1, n)] = 1.0
        full = self.gamma * (self.b - self.a)
        w = area_weights(self.grid)[None, :]
        return {"lb": np.zeros(n), "ub": np.full(n, self.C0),
                "C": np.vstack([diff, w]),
                "cl": np.concatenate([np.full(n - 1, -self.C1 * h), [self.C2 - full]]),
                "cu": np.concatenate([np.full(n - 1, self.C1 * h), [self.C3 - full]])}

    def residuals(self, alpha: np.ndarray) -> dict[str, float]:
        """Largest violation (> 0 means violated) of each group of constraints, raw."""
        h = self.grid.h
        meas = area(self.grid, alpha)
        return {"lower_bound": float(np.max(-alpha)),
                "upper_bound": float(np.max(alpha - self.C0)),
                "slope": float(np.max(np.abs(np.diff(alpha)) - self.C1 * h)),
                "area_min": float(self.C2 - meas), "area_max": float(meas - self.C3)}


_FIELDS = {
    "geometry": {"a": float, "b": float, "gamma": float, "contact_nodes": int, "ny": int},
    "material": {"E": float, "nu": float},
    "load": {"pressure": float, "traction": float},
    "friction": {"coefficient": float, "slip_scale": float},
    "design": {"C0": float, "C1": float, "C2": float, "C3": float, "initial": str,
               "initial_height": float},
    "objective": {"power": int},
}
_RENAME = {"contact_nodes": "n_contact", "coefficient": "friction0"}
#: bounds that keep a run finite in memory and in floating point
MAX_POWER, MAX_NODES, MAX_CELLS = 32, 10_001, 1_000_000
#: largest length (``|a|``, ``|b|``, gamma, m) and friction coefficient F0 (real pairs lie below
#: about 2); the slip scale l lies within SLIP_RATIO^(+-1) times the contact length b - a
MAX_LENGTH, MAX_COEFFICIENT, SLIP_RATIO = 1.0e6, 10.0, 1.0e12


def load_shape_scene(name_or_path: str | Path = "shape_coulomb",
                     overrides: dict[str, object] | None = None) -> ShapeScene:
    """Read and validate a shape scene; ``overrides`` maps ``section.key`` to a value."""
    path = Path(name_or_path)
    if not path.suffix:
        path = SHAPE_DIR / f"{name_or_path}.toml"
    if not path.exists():
        avail = sorted(p.stem for p in SHAPE_DIR.glob("*.toml"))
        raise SceneError(f"shape scene {name_or_path!r}: no file {path}; available: {avail}")
    try:  # a directory, too large, not UTF-8, not TOML, nested too deeply
        data = read_toml(path, "shape scene")
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    for key, value in (overrides or {}).items():
        sec, _, k = key.partition(".")
        data.setdefault(sec, {})[k] = value
    _check_keys(path, data)
    kw: dict[str, object] = {"source": str(path)}
    for sec, keys in _FIELDS.items():
        for k, typ in keys.items():
            if k in data.get(sec, {}):
                kw[_RENAME.get(k, k)] = _typed(path, f"{sec}.{k}", data[sec][k], typ)
    name = data.get("scene", {}).get("name", path.stem)
    if not check_name(name):
        raise SceneError(f"{path}: scene.name = {name!r}: give a name matching "
                         f"{NAME_PATTERN} (it names the output folder)")
    sc = replace(ShapeScene(), name=name, **kw)
    validate(sc, path)
    return sc


#: the keys of the [scene] table (besides the numbered fields of _FIELDS)
_SCENE_KEYS = ("name", "description", "reference")


def _check_keys(path: Path, data: dict) -> None:
    """Refuse an unknown section or key (a typo would be silently ignored), naming the
    valid ones."""
    valid = {"scene": _SCENE_KEYS, **{sec: tuple(keys) for sec, keys in _FIELDS.items()}}
    for sec, table in data.items():
        if sec not in valid:
            raise SceneError(f"{path}: unknown section [{sec}]; a shape scene has "
                             f"{', '.join(f'[{k}]' for k in valid)}")
        if not isinstance(table, dict):
            raise SceneError(f"{path}: [{sec}] must be a table of keys")
        for key in table:
            if key not in valid[sec]:
                raise SceneError(f"{path}: unknown key {sec}.{key}; [{sec}] takes "
                                 f"{', '.join(valid[sec])}")


def _typed(path: Path, key: str, value: object, typ: type) -> object:
    if typ is int and (isinstance(value, bool) or not isinstance(value, int)):
        raise SceneError(f"{path}: {key} = {value!r}: expected an integer")
    if typ is float and (isinstance(value, bool) or not isinstance(value, (int, float))
                         or not math.isfinite(value)):
        raise SceneError(f"{path}: {key} = {value!r}: expected a finite number")
    if typ is str and not isinstance(value, str):
        raise SceneError(f"{path}: {key} = {value!r}: expected a string")
    return typ(value)


def validate(sc: ShapeScene, where: Path | str) -> None:
    """Raise :class:`SceneError` naming the first invalid key, or an infeasible ``alpha_0``."""
    length = sc.b - sc.a
    load = sc.pressure + abs(sc.traction)
    checks = [
        *((f"geometry.{k}", abs(v) <= MAX_LENGTH, f"{v}: need |{k}| <= {MAX_LENGTH:g} m")
          for k, v in (("a", sc.a), ("b", sc.b), ("gamma", sc.gamma))),
        ("geometry.contact_nodes", sc.n_contact >= 2, f"{sc.n_contact}: need I >= 2"),
        ("geometry.ny", sc.ny >= 1, f"{sc.ny}: need >= 1"),
        ("geometry.b", sc.b > sc.a, f"{sc.b}: need b > a = {sc.a}"),
        ("material.E", sc.E > 0, f"{sc.E}: need E > 0"),
        ("material.nu", 0 <= sc.nu < 0.5, f"{sc.nu}: need 0 <= nu < 0.5"),
        ("load.pressure", sc.pressure > 0, f"{sc.pressure}: need > 0 (the load pressing "
         "the body onto the foundation)"),
        ("material.E", load <= sc.E, f"{sc.E}: need E >= pressure + |traction| = {load:g} "
         "(strains of at most 1: linear elasticity)"),
        ("friction.coefficient", 0 <= sc.friction0 <= MAX_COEFFICIENT,
         f"{sc.friction0}: need 0 <= F0 <= {MAX_COEFFICIENT:g}"),
        ("friction.slip_scale", length > 0 and 1 / SLIP_RATIO <= sc.slip_scale / length
         <= SLIP_RATIO, f"{sc.slip_scale}: need l in [1e-12, 1e12] x (b - a) = "
         f"{length:g} m"),
        ("design.C0", 0 < sc.C0 < sc.gamma, f"{sc.C0}: need 0 < C0 < gamma = {sc.gamma}"),
        ("design.C1", sc.C1 > 0, f"{sc.C1}: need C1 > 0"),
        ("design.C2", sc.C2 <= sc.C3, f"{sc.C2} > C3 = {sc.C3}: need C2 <= C3"),
        ("design.initial", sc.initial in ("parabola", "vee", "flat"),
         f"{sc.initial!r}: valid are 'parabola', 'vee', 'flat'"),
        ("objective.power", 2 <= sc.power <= MAX_POWER,
         f"{sc.power}: need an integer in [2, {MAX_POWER}] (J = sum lam^p overflows beyond)"),
        ("geometry.contact_nodes", sc.n_contact <= MAX_NODES,
         f"{sc.n_contact}: need I <= {MAX_NODES}"),
        ("geometry.ny", sc.n_contact * sc.ny <= MAX_CELLS,
         f"{sc.ny}: need (I - 1) x ny <= {MAX_CELLS} cells (I = {sc.n_contact})"),
        ("objective.power", not 2 <= sc.power <= MAX_POWER or sc.n_contact < 2
         or _finite_objective(sc, load * length),
         f"{sc.power}: J >= I (P / I)^p with the load P = (pressure + |traction|) (b - a) "
         f"= {load * length:.3g} overflows; lower the power or the load"),
    ]
    for key, ok, msg in checks:
        if not ok:
            raise SceneError(f"{where}: {key} = {msg}")
    bad = {k: v for k, v in sc.residuals(sc.initial_design()).items() if v > 1e-12}
    if bad:
        worst = max(bad, key=bad.get)
        raise SceneError(f"{where}: design.initial = {sc.initial!r} with design.initial_height "
                         f"= {sc.initial_height}: the initial design is not admissible "
                         f"({worst} violated by {bad[worst]:.3g}; all: {bad})")


def _finite_objective(sc: ShapeScene, total: float) -> bool:
    """Whether ``I (P / I)^p`` (the least J of the load ``P`` on ``I`` nodes, and the scale
    of every J of the run) is a finite number."""
    with np.errstate(over="ignore", invalid="ignore"):
        return bool(np.isfinite(sc.n_contact * (np.float64(total) / sc.n_contact) ** sc.power))


def parse_overrides(items: list[str]) -> dict[str, object]:
    """``SECTION.KEY=VALUE`` overrides of a shape scene (``--set``), values as TOML literals
    (else strings)."""
    out: dict[str, object] = {}
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or "." not in key:
            raise SceneError(f"--set {item!r}: expected SECTION.KEY=VALUE, e.g. geometry.ny=20")
        try:
            out[key] = toml_literal(text, f"--set {key}")
        except ValueError as exc:
            raise SceneError(str(exc)) from None
    return out


def design_space(sc: ShapeScene) -> ParameterSpace:
    """The design box ``lb <= alpha <= ub`` of the admissible set as a parameter domain
    (``alpha_0 .. alpha_{I-1}``, the heights of the contact nodes, m)."""
    box = sc.admissible()
    n = len(box["lb"])
    return ParameterSpace(tuple(f"alpha_{i}" for i in range(n)),
                          tuple(float(x) for x in box["lb"]), tuple(float(x) for x in box["ub"]),
                          ("m",) * n, where=sc.source, scene=sc.name)

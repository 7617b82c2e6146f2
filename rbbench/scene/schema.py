"""The schema of scene files: every section's keys (:class:`Field`: type, default, range,
whether it may reference a parameter, ``"mu.NAME"``), the declared parameters
(:class:`Parameter`), and the check of one value against its field, with messages that name
the file, the key and what is valid."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from rbbench.scene import limits
from rbbench.scene.parameters import SceneError


def _parameter_ref(raw: Any) -> str | None:
    """``NAME`` of a ``"mu.NAME"`` reference, else ``None`` (a constant)."""
    return raw[3:] if isinstance(raw, str) and raw.startswith("mu.") else None


# ---------------------------------------------------------------------------
# schema
# ---------------------------------------------------------------------------
@dataclass(frozen=True)
class Field:
    """One scene key: its type, whether it may reference a parameter, its valid range."""

    kind: str  # "float", "int", "str", "bool", "pair", "table"
    default: Any = None
    required: bool = False
    choices: tuple[Any, ...] | None = None
    low: float | None = None  # inclusive unless low_open
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    parametric: bool = False
    doc: str = ""

    def describe(self) -> str:
        if self.choices is not None:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        parts = {"float": "a number", "int": "an integer", "str": "a string",
                 "bool": "true or false", "pair": "a pair of numbers [a, b] with a < b",
                 "point": "a point [x, y]"}
        text = parts.get(self.kind, self.kind)
        if self.kind in ("pair", "point") and self.low is not None and self.high is not None:
            return text + f" with entries in [{self.low:g}, {self.high:g}]"
        rng = []
        if self.low is not None:
            rng.append(f"{'>' if self.low_open else '>='} {self.low:g}")
        if self.high is not None:
            rng.append(f"{'<' if self.high_open else '<='} {self.high:g}")
        if rng:
            text += " " + " and ".join(rng)
        if self.parametric:
            text += ', or "mu.NAME" for a declared parameter'
        return text


_ELASTIC = {
    "E": Field("float", required=True, low=0, low_open=True, parametric=True,
               doc="Young's modulus (Pa)"),
    "nu": Field("float", required=True, low=0.0, high=0.5, high_open=True, parametric=True,
                doc="Poisson's ratio"),
}


SCHEMA: dict[str, dict[str, Field]] = {
    "scene": {
        "name": Field("str", required=True),
        "description": Field("str", default=""),
        "physics": Field("str", required=True, choices=("elasticity", "poisson", "thermal",
                                                        "heat")),  # the last two: linear.py
        "friction": Field("str", default="none", choices=("none",)),
    },
    "geometry": {
        "kind": Field("str", required=True, choices=("halfdisks", "hemispheres", "unit_square")),
        "upper_radius": Field("float", low=0, low_open=True, parametric=True,
                              doc="radius R1 of the upper half-disk (m)"),
        "lower": Field("str", default="half_disk",
                       choices=("half_disk", "hemisphere", "rigid_flat"),
                       doc="the lower body: an elastic half-disk (2D) or hemisphere (3D), or a "
                           "rigid flat foundation"),
        "lower_radius": Field("float", low=0, low_open=True, parametric=True,
                              doc="radius R2 of the lower half-disk (m)"),
        "initial_gap": Field("float", default=0.0, low=0.0, parametric=True,
                             doc="initial gap g0 between the bodies (m)"),
        "contact_zone": Field("pair", default=(-0.625, -0.375), low=-1.0, high=0.0,
                              doc="potential contact zone on the upper body, theta/pi"),
        "master_zone": Field("pair", default=(0.25, 0.75), low=0.0, high=1.0,
                             doc="candidate master zone on the lower body, theta/pi"),
        # hemispheres (3D); no default here: filled by the kind's check (loading.py)
        "contact_cap": Field("float", low=0.0, high=0.5, low_open=True,
                             doc="potential contact cap on the upper hemisphere: polar "
                                 "angle from its pole, / pi"),
        "master_cap": Field("float", low=0.0, high=0.5, low_open=True,
                            doc="candidate master cap on the lower hemisphere: polar angle "
                                "from its pole, / pi"),
        "symmetry": Field("str", choices=("quarter",),
                          doc="symmetry planes cutting the mesh: 'quarter' keeps x >= 0, "
                              "y >= 0 (zero normal displacement on x = 0 and y = 0)"),
    },
    "material": {
        "plane": Field("str", default="strain", choices=("strain",)),
        "upper": Field("table"),
        "lower": Field("table"),
    },
    "load": {
        "displacement": Field("float", low=0.0, parametric=True,
                              doc="imposed downward displacement d of the upper flat face (m)"),
        "source": Field("float", parametric=True, doc="source term f of -Laplace u = f"),
        "tangential_displacement": Field("float", parametric=True, doc="imposed displacement "
                                         "along +x of the upper flat face (m; friction only)"),
        "load_steps": Field("list", doc="load steps (friction only; rbbench.scene.friction)"),
    },
    "obstacle": {
        "kind": Field("str", default="paraboloid", choices=("paraboloid",)),
        "height": Field("float", parametric=True, doc="obstacle top height"),
        "curvature": Field("float", low=0.0, parametric=True,
                           doc="psi = height - curvature |x - centre|^2"),
        "centre": Field("point", default=(0.5, 0.5), low=0.0, high=1.0),
    },
    "sampling": {
        "train": Field("str", default="uniform", choices=("uniform", "random", "lhs")),
        "n_train": Field("int", default=21, low=1, high=limits.MAX_SAMPLES),
        "valid": Field("str", default="random", choices=("uniform", "random", "lhs")),
        "n_valid": Field("int", default=20, low=1, high=limits.MAX_SAMPLES),
        "seed": Field("int", default=0, low=0),
    },
    "discretization": {
        "degree": Field("int", default=1, choices=(1, 2)),
        "multiplier": Field("str", default="lac", choices=("lac", "p0", "p1", "nodal")),
        "lac_patch": Field("int", default=2, low=1,
                           doc="facets per LAC patch (P0 multiplier per patch)"),
        "h_contact": Field("float", default=0.005, low=0, low_open=True, high=0.5,
                           doc="element size on the contact zones, relative to the radius"),
        "h_max": Field("float", default=0.1, low=0, low_open=True, high=1.0,
                       doc="largest element size, relative to the radius"),
        "grading": Field("float", default=0.15, low=0, low_open=True, high=2.0,
                         doc="growth of the element size with distance to the contact zone"),
        "level": Field("int", default=0, low=0, high=6,
                       doc="uniform refinement level: sizes are divided by 2**level"),
        "n_cells": Field("int", default=16, low=2, doc="cells per side (unit_square)"),
        "quadrature": Field("int", default=0, low=0, high=6,
                            doc="Gauss points per contact facet (0: degree + 1)"),
        "inner_product": Field("str", default="energy", choices=("energy", "h1")),
        "normals": Field("str", default="facet", choices=("facet", "smooth"),
                         doc="slave normal of the pairing: per facet, or interpolated "
                             "between vertex-averaged normals (continuous)"),
        "contact_integration": Field(
            "str", default="gauss", choices=("gauss", "segmented"),
            doc="contact quadrature: the Gauss rule per slave facet (fixed points), or per "
                "piece between master-vertex rays (segment-to-segment; HF only)"),
    },
    "reference": {
        "hertz": Field("bool", default=False,
                       doc="compare with 2D plane-strain Hertz theory"),
        "mindlin": Field("bool", default=False,
                         doc="compare a friction solve with Cattaneo-Mindlin partial slip"),
    },
}


#: The optional ``[reduce]`` section: a scene's own defaults of reduction options, used
#: where the reduction gives none (a value given on the command line or in the API wins).
#: Not filled when absent, and not part of the snapshot key (it cannot change a snapshot).
REDUCE_SECTION = {
    "k_pga_max": Field("int", low=1, high=limits.MAX_SAMPLES,
                       doc="cap on the PGA supremizers K (mixed formulation, stabilizer "
                           "'pga') where the reduction gives no --k-max"),
}


def check_reduce_section(data: dict[str, Any], path: str) -> None:
    """Check the keys and values of an optional ``[reduce]`` section
    (:data:`REDUCE_SECTION`); nothing is filled in."""
    table = data.get("reduce")
    if table is None:
        return
    for key, value in table.items():
        if key not in REDUCE_SECTION:
            raise _unknown(path, "[reduce]", key, list(REDUCE_SECTION))
        table[key] = _check_value(path, f"[reduce] {key}", REDUCE_SECTION[key], value, {})


_PARAM_FIELDS = {
    "range": Field("pair", required=True),
    "default": Field("float"),
    "unit": Field("str", default=""),
    "description": Field("str", default=""),
}


# What each geometry kind needs (key -> required)
_KIND_REQUIRES = {
    "halfdisks": {
        "geometry": ("upper_radius",),
        "load": ("displacement",),
        "material": ("upper",),
    },
    "hemispheres": {
        "geometry": ("upper_radius", "symmetry"),
        "load": ("displacement",),
        "material": ("upper",),
    },
    "unit_square": {"load": ("source",), "obstacle": ("height", "curvature")},
}

#: Defaults of the ``hemispheres`` keys that the other kinds do not have (filled by
#: the kind's check, so the cache keys of the other kinds' scenes do not change).
HEMISPHERE_DEFAULTS = {"contact_cap": 0.1, "master_cap": 0.2}

#: The geometry keys of the other kinds that a ``hemispheres`` scene does not read.
HALFDISK_ONLY = ("contact_zone", "master_zone")


def _err(path: str, where: str, msg: str) -> SceneError:
    return SceneError(f"{path}: {where}: {msg}")


def _check_value(path: str, where: str, f: Field, value: Any, params: dict[str, Parameter]) -> Any:
    name = _parameter_ref(value) if f.parametric else None
    if name is not None:
        if name not in params:
            raise _err(path, where, f"references parameter {name!r}, which is not declared; "
                       f"declared: {', '.join(params) or '(none)'}")
        p = params[name]
        for end in (p.low, p.high):  # the whole parameter range must be valid
            _check_value(path, f"{where} (at {name} = {end:g})", f, end, params)
        return value
    if f.kind == "float":
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise _err(path, where, f"expected {f.describe()}, got {value!r}")
        value = float(value)
        if not math.isfinite(value):  # noqa: SIM102
            raise _err(path, where, f"expected a finite number, got {value!r}")
    elif f.kind == "int":
        if isinstance(value, bool) or not isinstance(value, int):
            raise _err(path, where, f"expected {f.describe()}, got {value!r}")
    elif f.kind == "str":
        if not isinstance(value, str):
            raise _err(path, where, f"expected {f.describe()}, got {value!r}")
    elif f.kind == "bool":
        if not isinstance(value, bool):
            raise _err(path, where, f"expected true or false, got {value!r}")
    elif f.kind in ("pair", "point"):
        ok = (isinstance(value, (list, tuple)) and len(value) == 2
              and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value))
        if not ok or (f.kind == "pair" and not value[0] < value[1]):
            raise _err(path, where, f"expected {f.describe()}, got {value!r}")
        value = (float(value[0]), float(value[1]))
        for v in value:
            if (f.low is not None and v < f.low) or (f.high is not None and v > f.high):
                raise _err(path, where,
                           f"expected values in [{f.low:g}, {f.high:g}], got {value!r}")
        return value
    elif f.kind == "table":
        if not isinstance(value, dict):
            raise _err(path, where, f"expected a table, got {value!r}")
        return value
    if f.choices is not None and value not in f.choices:
        raise _err(path, where, f"{value!r} is not valid; expected {f.describe()}")
    if f.kind in ("float", "int"):
        bad_low = f.low is not None and (value <= f.low if f.low_open else value < f.low)
        bad_high = f.high is not None and (value >= f.high if f.high_open else value > f.high)
        if bad_low or bad_high:
            raise _err(path, where, f"{value!r} is out of range; expected {f.describe()}")
    return value


def _unknown(path: str, where: str, key: str, valid: list[str]) -> SceneError:
    return _err(path, where, f"unknown key {key!r}; valid keys: {', '.join(sorted(valid))}")


# ---------------------------------------------------------------------------
# the Scene
# ---------------------------------------------------------------------------
@dataclass
class Parameter:
    name: str
    low: float
    high: float
    default: float
    unit: str = ""
    description: str = ""

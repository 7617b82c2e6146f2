"""The value checks of run-matrix files (:mod:`rbbench.bench.matrix`), done at load time.

Every value a matrix sets is checked before any case runs, so a bad value is an error
naming the file, the key and what is valid (:class:`MatrixError`, exit status 2 in the
CLI), never an ``error`` row:

* ``[matrix]``: ``name`` (:data:`rbbench.scene.limits.NAME_PATTERN`: it names the default
  output directory), ``scenes`` (a non-empty list of strings), ``repetitions`` (an integer
  in ``[1, MAX_REPETITIONS]``), ``timeout_s`` (a finite number in ``(0, MAX_TIMEOUT_S]``),
  ``seed`` (an integer >= 0), ``mode``;
* ``[components]``: strings; ``[sizes]``: integers in ``[1, MAX_SIZE]``;
* ``[reduce]``, ``--set`` and ``[params.ROLE.NAME]``: the type and range of each
  :class:`~rbbench.rb.offline.ReduceConfig` field (:data:`REDUCE_FIELDS`);
* the number of cases the matrix expands to: at most :data:`MAX_CASES`.
"""

from __future__ import annotations

import math
import re
from typing import Any

from rbbench.rb.friction.options import AUTO, DEPRECATED_DUALS
from rbbench.rb.friction.options import FRICTION_DUALS as _FRICTION_DUALS
from rbbench.scene import limits

__all__ = ["MAX_CASES", "MAX_REPETITIONS", "MAX_SIZE", "MAX_TIMEOUT_S", "REDUCE_FIELDS",
           "MatrixError", "check_reduce_values", "check_strings", "default_name",
           "matrix_header"]

#: Bounds of a matrix's values.
MAX_REPETITIONS = 1_000
MAX_TIMEOUT_S = 604_800.0  # one week per case
MAX_SIZE = limits.MAX_SAMPLES  # N, R, S
MAX_CASES = 100_000
_MODES = ("rb", "hf")


class MatrixError(ValueError):
    """A run-matrix file or selector is invalid; the message names the file and field."""


def _int(lo: int, hi: int | None = None) -> tuple[str, int, int | None]:
    return ("int", lo, hi)


def _pos_float() -> tuple[str, float, None]:
    return ("float", 0.0, None)


def _nonneg_float() -> tuple[str, float, None]:
    return ("float>=", 0.0, None)


#: ``field -> (kind, low, high)`` of the ReduceConfig fields a matrix may set: ``int``
#: (integers in [low, high]), ``float`` (finite numbers > low), ``float>=`` (finite numbers
#: >= low: a tolerance of 0 takes as many terms as the data allow), ``dict`` (a table), or
#: ``("choice", values)``. ``None`` is not valid: leave the field out for its default.
REDUCE_FIELDS: dict[str, tuple] = {
    "n_train": _int(1, limits.MAX_SAMPLES), "n_valid": _int(1, limits.MAX_SAMPLES),
    "S": _int(1, MAX_SIZE), "k_pga_max": _int(1, MAX_SIZE),
    "online_repeats": _int(1, 10_000), "exact_max_r": _int(0, MAX_SIZE),
    "m_eim": _int(1, MAX_SIZE), "n_eim_train": _int(1, limits.MAX_SAMPLES),
    "gcns_per_iteration": _int(1, MAX_SIZE), "gcns_max": _int(1, MAX_SIZE),
    "gcns_patience": _int(1, MAX_SIZE), "bound_pod_max": _int(1, MAX_SIZE),
    "tol_pod": _nonneg_float(), "tol_dual": _nonneg_float(), "tol_eim": _nonneg_float(),
    "delta_pga": _pos_float(),
    "backend_options": ("dict", None, None), "formulation_options": ("dict", None, None),
}


#: the reduced friction dual models (rbbench.rb.friction.options), and their old names
FRICTION_DUALS = (AUTO, *_FRICTION_DUALS, *DEPRECATED_DUALS)


def _online_methods() -> tuple[str, ...]:
    from rbbench.rb.mixed.model import ONLINE_METHODS

    return tuple(ONLINE_METHODS)


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _is_number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _describe(spec: tuple) -> str:
    kind, lo, hi = spec
    if kind == "int":
        return f"an integer in [{lo}, {hi}]"
    if kind == "float":
        return "a finite number > 0"
    if kind == "float>=":
        return "a finite number >= 0"
    return "a table (e.g. {mesh = \"skfem\"})"


def check_reduce_value(key: str, value: Any, where: str) -> None:
    """One ``[reduce]`` / ``--set`` / ``[params.*]`` value, or :class:`MatrixError` naming
    ``where``, the field and what is valid."""
    if key == "friction_dual" and value not in FRICTION_DUALS:
        raise MatrixError(f"{where}: friction_dual = {value!r}; valid: "
                          + ", ".join(FRICTION_DUALS))
    if key == "online_method":
        valid = _online_methods()
        if value not in valid:
            raise MatrixError(f"{where}: online_method = {value!r}; valid: {', '.join(valid)}")
        return
    spec = REDUCE_FIELDS.get(key)
    if spec is None:  # a field without a declared range: the ReduceConfig check applies
        return
    kind, lo, hi = spec
    ok = ((kind == "int" and _is_int(value) and lo <= value <= hi)
          or (kind == "float" and _is_number(value) and math.isfinite(value) and value > lo)
          or (kind == "float>=" and _is_number(value) and math.isfinite(value)
              and value >= lo)
          or (kind == "dict" and isinstance(value, dict)))
    if not ok:
        raise MatrixError(f"{where}: {key} = {value!r}; expected {_describe(spec)}")


def check_reduce_values(d: dict, where: str, grid: bool = False) -> None:
    """Every value of a ``[reduce]`` table (``grid``: of a ``[params.*]`` table, whose
    values are lists of candidates), then the whole as a ReduceConfig (a field that no
    formulation takes is refused here; one that the case's formulation does not take makes
    a skip row, :func:`rbbench.bench.matrix.reduced_model_check`)."""
    from rbbench.rb.config import make_config

    for key, value in d.items():
        for v in (value if grid and isinstance(value, list) else [value]):
            check_reduce_value(key, v, where)
    if not grid:
        try:
            make_config(**d)
        except (TypeError, ValueError) as exc:
            raise MatrixError(f"{where}: {exc}") from None


def check_strings(values: Any, where: str) -> list[str]:
    """A string or a non-empty list of non-empty strings, as a list."""
    items = values if isinstance(values, list) else [values]
    if not items:
        raise MatrixError(f"{where}: empty list; give at least one value")
    for v in items:
        if not isinstance(v, str) or not v or not v.isprintable():
            raise MatrixError(f"{where}: {v!r}; expected a name (a non-empty string) or a "
                              "list of names")
    return items


def default_name(stem: str) -> str:
    """A matrix's name when ``[matrix] name`` is absent: its file's stem, made safe."""
    name = re.sub(r"[^A-Za-z0-9_.-]", "_", stem).lstrip(".-_")[:64]
    return name or "matrix"


def _scenes(raw: Any, where: str) -> list[str]:
    if not isinstance(raw, list) or not raw:
        raise MatrixError(f"{where}: [matrix] scenes = {raw!r}; expected a non-empty list of "
                          "scene names or .toml paths, e.g. [\"membrane_obstacle\"]")
    scenes = check_strings(raw, f"{where}: [matrix] scenes")
    for s in scenes:
        variant = s.split("@", 1)[1] if "@" in s else None
        if variant is not None and not limits.check_name(variant):
            raise MatrixError(f"{where}: [matrix] scenes: {s!r}: the variant {variant!r} is "
                              f"not valid; expected {limits.NAME_RULE}")
    return scenes


def matrix_header(mtab: Any, default: str, where: str) -> dict[str, Any]:
    """The checked values of the ``[matrix]`` table: ``name``, ``scenes``, ``repetitions``,
    ``seed`` (``None``: each scene's own), ``mode``, ``timeout_s``."""
    if not isinstance(mtab, dict):
        raise MatrixError(f"{where}: matrix = {mtab!r}; expected the table [matrix] "
                          "(name, scenes, ...)")
    name = mtab.get("name", default_name(default))
    if not limits.check_name(name):
        raise MatrixError(f"{where}: [matrix] name = {name!r}; it names the output directory: "
                          f"expected {limits.NAME_RULE}")
    reps = mtab.get("repetitions", 1)
    if not _is_int(reps) or not 1 <= reps <= MAX_REPETITIONS:
        raise MatrixError(f"{where}: [matrix] repetitions = {reps!r}; give an integer in "
                          f"[1, {MAX_REPETITIONS}]")
    seed = mtab.get("seed")
    if seed is not None and (not _is_int(seed) or not 0 <= seed < 2**63):
        raise MatrixError(f"{where}: [matrix] seed = {seed!r}; give an integer >= 0")
    mode = mtab.get("mode", "rb")
    if mode not in _MODES:
        raise MatrixError(f"{where}: [matrix] mode = {mode!r}; valid: {', '.join(_MODES)}")
    timeout = mtab.get("timeout_s", 600)
    if not _is_number(timeout) or not (math.isfinite(timeout) and 0 < timeout <= MAX_TIMEOUT_S):
        raise MatrixError(f"{where}: [matrix] timeout_s = {timeout!r}; give seconds: a finite "
                          f"number > 0 and <= {MAX_TIMEOUT_S:g}")
    desc = mtab.get("description", "")
    if not isinstance(desc, str):
        raise MatrixError(f"{where}: [matrix] description = {desc!r}; expected a string")
    return {"name": name, "scenes": _scenes(mtab.get("scenes"), where), "repetitions": reps,
            "seed": seed, "mode": mode, "timeout_s": float(timeout)}


def check_case_count(n: int, where: str) -> None:
    """At most :data:`MAX_CASES` cases (checked before the expansion)."""
    if n > MAX_CASES:
        raise MatrixError(f"{where}: the matrix expands to {n} cases (scenes x components x "
                          f"sizes x parameter grids x repetitions), more than {MAX_CASES}; "
                          "split it or narrow it with selectors (-s ROLE=NAME)")

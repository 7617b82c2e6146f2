"""The choices of one reduction: what every formulation shares (:class:`ReduceConfig`) and the
options that belong to one formulation (each formulation's option dataclass, checked by the
skeleton before any HF work).

``rbbench reduce`` and :func:`rbbench.reduce` take both kinds of fields in one call;
:func:`make_config` splits them, and :func:`parse_options` builds the formulation's option
dataclass, refusing an option the formulation does not take with a :class:`OptionError` that
names the option and the formulations that take it (never a silently ignored option).
"""

from __future__ import annotations

import inspect
import math
import numbers
import os
import typing
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields, is_dataclass
from typing import Any

from rbbench.rb.hyper.reducers import BUILTIN as BUILTIN_HYPER
from rbbench.registry import Registry
from rbbench.scene.limits import MAX_SAMPLES
from rbbench.scene.loading import SceneError
from rbbench.scene.parameters import FieldError

__all__ = ["HYPER", "SHARED_FIELDS", "OptionError", "ReduceConfig", "config_dict",
           "formulation_options", "make_config", "option_owners", "parse_options",
           "reduction_steps"]

#: "auto" (the formulation's rule) and the built-in hyper-reducers; a registered plugin's
#: hyper-reducer is valid too (checked against the registry by the offline skeleton)
HYPER = ("auto", *BUILTIN_HYPER)


@dataclass
class ReduceConfig:
    """What every formulation's reduction shares (``rbbench reduce``, a run matrix's case).

    ``formulation = None``: ``linear`` on a linear scene, else ``mixed``; ``solver = None``:
    the formulation's own HF solver for the scene's friction law
    (:func:`rbbench.hf.components.default_solver`). ``options``: the formulation's own
    options, a dict of its fields until the skeleton parses it into the formulation's
    option dataclass (:func:`parse_options`).
    """

    formulation: str | None = None
    backend: str = "skfem"
    solver: str | None = None
    primal: str = "pod"
    hyper: str = "auto"
    N: int | None = None
    tol_pod: float = 1e-4
    n_train: int | None = None
    n_valid: int | None = None
    n_jobs: int | None = None
    cache_dir: str = ".rbbench_cache"
    online_repeats: int = 20
    backend_options: dict = field(default_factory=dict)  # e.g. NGSolve {"mesh": "skfem"}
    formulation_options: dict = field(default_factory=dict)  # e.g. Nitsche {"gamma0": 1.0}
    options: Any = field(default_factory=dict)

    @property
    def component_options(self) -> dict:
        """``{"backend": ..., "formulation": ...}`` for
        :func:`rbbench.hf.components.make_components`."""
        return {"backend": dict(self.backend_options),
                "formulation": dict(self.formulation_options)}

    def __post_init__(self) -> None:
        # component names are checked against the registry by the skeleton; here only what
        # does not depend on which plugins are installed
        if not isinstance(self.hyper, str) or not self.hyper.strip():
            raise FieldError("reduce", "hyper", self.hyper, "give 'auto' (the formulation's "
                             "rule) or the name of a registered hyper-reducer (rbbench plugins)")
        check_values(self, "reduce")


#: counts and sizes: an integer >= 1 (``None`` where the field allows it: the default rule)
POSITIVE_INTS = frozenset({"N", "R", "S", "n_train", "n_valid", "n_jobs", "online_repeats",
                           "k_pga_max", "m_eim", "n_eim_train", "gcns_per_iteration",
                           "gcns_max", "gcns_patience", "bound_pod_max"})
#: integers that may be 0
NONNEGATIVE_INTS = frozenset({"exact_max_r"})
#: the largest value of an integer field (a run matrix has the same bounds): sample and
#: basis sizes at most :data:`~rbbench.scene.limits.MAX_SAMPLES`, timed repeats and worker
#: processes fewer
MAX_INTS = {**dict.fromkeys(POSITIVE_INTS | NONNEGATIVE_INTS, MAX_SAMPLES),
            "online_repeats": 10_000, "n_jobs": 256}


def check_values(obj: Any, where: str) -> None:
    """Refuse a field value of the dataclass ``obj`` that its type or meaning excludes,
    with a :class:`~rbbench.scene.parameters.FieldError` naming the field and what is
    valid: an integer field given a bool, a float or a string (``N = 3.7``); a count or size
    below 1 (:data:`POSITIVE_INTS`) or above its bound (:data:`MAX_INTS`); a non-finite
    float; a tolerance ``tol*`` outside [0, 1) (relative; 0: as many terms as the data
    allow); ``delta_pga`` outside (0, 1] (it bounds the PGA defect sigma, which lies in
    [0, 1]); a name field that is not a string; a table field that is not a dict. Every
    formulation's options and :class:`ReduceConfig` go through it before any HF work, on
    the command line and in the Python API alike."""
    hints = typing.get_type_hints(type(obj))
    for f in fields(obj):
        v, hint = getattr(obj, f.name), str(hints.get(f.name, ""))
        if v is None or hint in ("typing.Any", ""):
            continue
        if "int" in hint and "float" not in hint:
            low = 0 if f.name in NONNEGATIVE_INTS else 1 if f.name in POSITIVE_INTS else None
            high = MAX_INTS.get(f.name)
            rule = ("give an integer" if low is None else f"give an integer in [{low}, {high}]"
                    if high is not None else f"give an integer >= {low}")
            if (isinstance(v, bool) or not isinstance(v, numbers.Integral)
                    or low is not None and v < low or high is not None and v > high):
                raise FieldError(where, f.name, v, rule)
        elif "float" in hint:
            if (isinstance(v, bool) or not isinstance(v, numbers.Real)
                    or not math.isfinite(v)):
                raise FieldError(where, f.name, v, "give a finite number")
            if f.name.startswith("tol") and not 0 <= v < 1:
                raise FieldError(where, f.name, v, "give a relative tolerance in [0, 1) (0: "
                                 "as many terms as the data allow)")
            if f.name == "delta_pga" and not 0 < v <= 1:
                raise FieldError(where, f.name, v, "give a value in (0, 1] (the PGA defect "
                                 "sigma lies in [0, 1])")
        elif hint == "dict" or hint.startswith("dict"):
            if not isinstance(v, dict):
                raise FieldError(where, f.name, v, "give a table of options (a dict)")
        elif f.name == "cache_dir":
            if not isinstance(v, (str, os.PathLike)):
                raise FieldError(where, f.name, v, "give a directory (a path)")
        elif "str" in hint and (not isinstance(v, str) or not v.strip()):
            raise FieldError(where, f.name, v, "give a name (a non-empty string)")


#: the fields of :class:`ReduceConfig` a caller may give (``options`` is built from the rest)
SHARED_FIELDS = tuple(f.name for f in fields(ReduceConfig) if f.name != "options")


def make_config(**values: Any) -> ReduceConfig:
    """A :class:`ReduceConfig` from one set of fields: the shared ones, and the rest as the
    formulation's options (``None`` or ``""``: the option's default or not applicable;
    checked by :func:`parse_options` against the formulation's options before any HF
    work)."""
    shared = {k: v for k, v in values.items() if k in SHARED_FIELDS}
    options = {k: v for k, v in values.items()
               if k not in SHARED_FIELDS and v is not None and v != ""}
    return ReduceConfig(**shared, options=options)


def config_dict(config: ReduceConfig) -> dict[str, Any]:
    """The configuration as run, flat: the shared fields and the formulation's options
    (``result.json`` ``config``)."""
    opts = config.options
    out = {k: v for k, v in asdict(config).items() if k != "options"}
    out.update(asdict(opts) if is_dataclass(opts) else dict(opts))
    return out


class OptionError(SceneError):
    """An option that the formulation of a reduction does not take.

    ``option``: its name; ``where``: the formulation (and scene kind) refusing it;
    ``valid``: that formulation's options; ``owners``: the formulations that take it.
    """

    def __init__(self, option: str, where: str, valid: list[str], owners: list[str]) -> None:
        self.option, self.where, self.valid, self.owners = option, where, valid, owners
        super().__init__(self.message(repr))

    def message(self, show: Callable[[str], str]) -> str:
        """The message with every option name shown by ``show`` (e.g. its command-line
        flag)."""
        shown = show(self.option)
        takes = (f"{shown} is an option of {', '.join(self.owners)}" if self.owners
                 else f"{shown} is an option of no installed formulation")
        return (f"option {shown}: not an option of {self.where} (its options: "
                f"{', '.join(map(show, self.valid)) or 'none'}); {takes}")


def reduction_steps(config: ReduceConfig, registry: Registry, law: str = "none") -> Any:
    """The offline steps of ``config.formulation`` (its plugin's ``reduction()``; for a
    friction ``law``, ``reduction(friction=law)`` when the plugin takes that keyword)."""
    try:
        form = registry.create("formulation", config.formulation,
                               **dict(config.formulation_options))
    except (TypeError, ValueError) as exc:  # the constructor's own check of its options
        raise FieldError("reduce", "formulation_options", config.formulation_options,
                         str(exc)) from None
    if law != "none" and "friction" in inspect.signature(form.reduction).parameters:
        return form.reduction(friction=law)
    return form.reduction()


def _option_names(steps: Any) -> list[str]:
    cls = getattr(steps, "Options", None)
    return [f.name for f in fields(cls)] if cls is not None else []


def formulation_options(registry: Registry) -> dict[str, list[str]]:
    """``{label: option names}`` of every registered formulation's reduction (on
    frictionless and on friction scenes), in the registry's order."""
    out: dict[str, list[str]] = {}
    for name in registry.names("formulation"):
        for law in ("none", "coulomb"):
            try:
                steps = reduction_steps(ReduceConfig(formulation=name), registry, law)
            except Exception:  # noqa: BLE001 - a plugin without reduced model, or broken
                continue
            out.setdefault(getattr(steps, "label", name), _option_names(steps))
    return out


def option_owners(option: str, registry: Registry) -> list[str]:
    """Every registered formulation (on frictionless and on friction scenes) whose
    reduction takes ``option``, described as in its steps' ``label``."""
    return [label for label, names in formulation_options(registry).items()
            if option in names]


def parse_options(steps: Any, options: Any, registry: Registry) -> Any:
    """The formulation's option dataclass (``steps.Options``) from ``options`` (a dict, or
    already the dataclass); an option it does not take raises :class:`OptionError`, a
    value its dataclass refuses a :class:`~rbbench.scene.loading.SceneError`."""
    cls = steps.Options
    if isinstance(options, cls):
        return options
    values = dict(asdict(options) if is_dataclass(options) else options or {})
    valid = _option_names(steps)
    for key in values:
        if key not in valid:
            raise OptionError(key, getattr(steps, "label", steps.name), valid,
                              option_owners(key, registry))
    where = getattr(steps, "label", steps.name)
    try:
        out = cls(**values)
    except FieldError as exc:
        raise FieldError(where, exc.field, exc.value, exc.rule) from None
    except (TypeError, ValueError) as exc:
        raise SceneError(f"{where}: {exc}") from None
    if is_dataclass(out):
        check_values(out, where)
    return out

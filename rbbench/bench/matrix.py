"""Run-matrix files (``problems/matrices/*.toml``) and the cases they expand to.

A matrix is the product scenes x components x sizes x component parameters x
repetitions. Example (every table but ``[matrix]`` is optional)::

    [matrix]
    name = "quick"
    scenes = ["membrane_obstacle", "hertz_halfdisks"]
    repetitions = 1
    timeout_s = 300            # per case, enforced (the case's process is killed)
    seed = 0                   # of the random parameter sets (default: each scene's)

    [components]               # lists; defaults: the built-in defaults
    dual = ["cpg", "mcpg", "eng"]
    stabilizer = ["none", "supremizer", "pga"]

    [sizes]
    pairs = [[10, 10], [20, 20]]   # (N, R) pairs; or N = [...] and R = [...] (product)

    [reduce]                   # rbbench.rb.offline.ReduceConfig fields for every case
    n_train = 21
    n_valid = 10

    [scene_overrides]          # --set overrides per scene
    hertz_halfdisks = ["discretization.level=-1"]

    [params.stabilizer.pga]    # per-component parameter grid (product), ReduceConfig fields
    k_pga_max = [20, 40]

A model axis (:data:`MODEL_AXES`) is a ReduceConfig field swept like a component:
``[components] friction_dual = ["collocation", "wedge"]`` (friction scenes), with its own
grids ``[params.friction_dual.collocation]``; the value goes to the case's parameters (the
same case as ``[reduce] friction_dual``). Combinations the formulation's reduced model
refuses before any HF work (e.g. the collocation friction model with ``hyper = "eim"``) are
``skip`` rows with its reason.

A scene entry ``name@variant`` is the scene ``name`` under its own
``[scene_overrides]`` entry (e.g. two mesh sizes: ``hertz_halfdisks@fine``).
``[matrix] mode = "hf"`` makes each case an HF solve only (components
backend, formulation, solver; ``[hf] repeats`` solves at the scene's default
mu, timed without meshing): the backend x solver timing tables; there
``[params.solver.NAME]`` sweeps the solver's options (e.g. ``condensation =
["schur", "columns"]``), checked by making the solver with each set.

Selectors (``-s role=a,b``, globs allowed, ``scene`` too) narrow the matrix;
``--set`` overrides ``[reduce]`` fields (``--set n_valid=5``). Every error
names the file and the field and says what would be valid.
"""

from __future__ import annotations

import fnmatch
import hashlib
import itertools
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rbbench.bench import json_text
from rbbench.bench import matrix_checks as checks
from rbbench.bench.applicability import (
    REGISTRY_ROLES,
    applicable_roles,
    compatibility,
    reduced_model_check,
)
from rbbench.bench.matrix_checks import MatrixError
from rbbench.registry import Registry
from rbbench.scene import limits
from rbbench.scene.loading import PROBLEMS_DIR, load_scene

__all__ = ["COMPONENT_ROLES", "MODEL_AXES", "Case", "Matrix", "MatrixError", "compatibility",
           "load_matrix", "reduced_model_check"]

#: The component axes of a case, in table order, with the built-in default of each.
COMPONENT_ROLES = {"backend": "skfem", "formulation": "mixed", "solver": "ssn",
                   "primal": "pod", "dual": "mcpg", "stabilizer": "pga", "hyper": "auto"}
#: Model axes: ReduceConfig fields a matrix may sweep in ``[components]`` (with selectors
#: and ``[params.AXIS.VALUE]`` grids), and their valid values; the value is a case parameter.
MODEL_AXES: dict[str, tuple[str, ...]] = {"friction_dual": checks.FRICTION_DUALS}
#: Axes that name registered components (their registry role has the same name).
_TOP = {"matrix", "components", "sizes", "reduce", "scene_overrides", "params", "hf"}
_MATRIX_KEYS = {"name", "description", "scenes", "repetitions", "timeout_s", "seed", "mode"}
MODES = ("rb", "hf")
_HF_ROLES = ("backend", "formulation", "solver")
#: ReduceConfig fields a matrix may not set (they belong to the case's components or
#: to the runner).
_RESERVED = {"backend", "formulation", "solver", "primal", "dual", "stabilizer", "hyper", "N",
             "R", "cache_dir", "n_jobs"}


@dataclass(frozen=True)
class Case:
    """One case of a matrix (one results row per repetition)."""

    scene: str
    overrides: tuple[str, ...]
    components: dict[str, str]
    N: int | None
    R: int | None
    params: dict[str, Any]  # ReduceConfig fields from [reduce], --set and [params.*]
    repetition: int
    seed: int
    timeout_s: float
    scene_fingerprint: str = ""
    mode: str = "rb"
    status: str = "run"  # "run", or a pre-decided "skip" / "not_installed"
    reason: str = ""
    extras: dict[str, Any] = field(default_factory=dict)

    @property
    def case_id(self) -> str:
        """Hash of everything that determines the case's numbers (not the repetition)."""
        ident = {"scene": self.scene, "fingerprint": self.scene_fingerprint,
                 **({"mode": self.mode} if self.mode != "rb" else {}),
                 "overrides": list(self.overrides), "components": self.components,
                 "N": self.N, "R": self.R, "params": self.params, "seed": self.seed}
        return hashlib.sha256(json.dumps(ident, sort_keys=True, default=str).encode()
                              ).hexdigest()[:16]

    @property
    def key(self) -> str:
        """File stem of the case's row: ``<case_id>-r<repetition>``."""
        return f"{self.case_id}-r{self.repetition}"

    @property
    def solver_options(self) -> dict[str, Any]:
        """Mode hf: the solver's options of the case (``[params.solver.NAME]``)."""
        if self.mode != "hf":
            return {}
        return {k: v for k, v in self.params.items() if k != "hf_repeats"}

    @property
    def base_scene(self) -> str:
        """The scene file's name (``name`` of a ``name@variant`` entry)."""
        return self.scene.split("@", 1)[0]

    @property
    def label(self) -> str:
        c = self.components
        if self.mode == "hf":
            opts = "".join(f" {k}={v}" for k, v in sorted(self.solver_options.items()))
            return f"{self.scene} HF {c['backend']}/{c['formulation']}/{c['solver']}{opts}"
        if not c["dual"]:  # no dual space (linear formulation)
            return (f"{self.scene} {c['backend']}/{c['formulation']}/{c['primal']} N={self.N}"
                    + (f" rep {self.repetition}" if self.repetition else ""))
        fd = self.params.get("friction_dual")
        gcns = "".join(f" {k}={v}" for k, v in self.params.items() if k.startswith("gcns_"))
        return (f"{self.scene} {c['dual']}+{c['stabilizer']}+{c['hyper']}"
                + (f" friction_dual={fd}" if fd else "") + gcns + f" N={self.N} R={self.R}"
                + (f" rep {self.repetition}" if self.repetition else ""))

    def reduce_config(self, cache_dir: str) -> Any:
        """The :class:`~rbbench.rb.config.ReduceConfig` of this case (components that do
        not apply to its formulation, ``""``, are left out)."""
        from rbbench.rb.config import make_config

        comp = {k: v for k, v in self.components.items() if v}
        return make_config(**comp, N=self.N, R=self.R, cache_dir=cache_dir, n_jobs=1,
                           **self.params)


@dataclass
class Matrix:
    """A loaded, expanded matrix."""

    name: str
    path: str
    data: dict[str, Any]
    cases: list[Case]


def _reduce_fields(registry: Registry | None = None) -> set[str]:
    """The fields a matrix may name: the shared ones and every registered formulation's
    options (a case whose formulation does not take one is a skip row)."""
    from rbbench.rb.config import SHARED_FIELDS, formulation_options
    from rbbench.registry import default_registry

    names = set(SHARED_FIELDS)
    for opts in formulation_options(registry or default_registry()).values():
        names.update(opts)
    return names


def _as_list(v: Any, where: str) -> list:
    if isinstance(v, list):
        if not v:
            raise MatrixError(f"{where}: empty list; give at least one value")
        return v
    return [v]


def _check_keys(d: dict, allowed: set, where: str) -> None:
    bad = sorted(set(d) - allowed)
    if bad:
        raise MatrixError(f"{where}: unknown key(s) {bad}; valid: {sorted(allowed)}")


def _parse_value(text: str, key: str = "") -> Any:
    try:
        return json_text.loads(text)
    except json.JSONDecodeError:
        return text
    except ValueError as exc:  # nested too deeply
        raise MatrixError(f"--set {key}: the value is {exc}") from None


def _selectors(selectors: list[str] | tuple[str, ...]) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    valid = ["scene", *COMPONENT_ROLES, *MODEL_AXES, "N", "R"]
    for sel in selectors:
        if "=" not in sel:
            raise MatrixError(f"selector {sel!r}: write ROLE=NAME[,NAME...] (globs allowed); "
                              f"roles: {', '.join(valid)}")
        role, names = sel.split("=", 1)
        role = role.strip()
        if role not in valid:
            raise MatrixError(f"selector {sel!r}: unknown role {role!r}; valid: "
                              f"{', '.join(valid)}")
        out.setdefault(role, []).extend(n.strip() for n in names.split(",") if n.strip())
    return out


def _selected(value: Any, patterns: list[str] | None) -> bool:
    return patterns is None or any(fnmatch.fnmatchcase(str(value), p) for p in patterns)


@dataclass
class _Plan:
    """A matrix file read and checked, before its expansion into cases."""

    name: str
    scenes: list[str]
    repetitions: int
    seed: int | None  # [matrix] seed; None: each scene's own
    mode: str
    timeout_s: float
    axes: dict[str, list[str]] = field(default_factory=dict)
    hf_repeats: Any = 3
    pairs: list[tuple[int | None, int | None]] = field(default_factory=list)
    base: dict[str, Any] = field(default_factory=dict)
    grids: dict[tuple[str, str], list[dict]] = field(default_factory=dict)
    overrides: dict[str, list[str]] = field(default_factory=dict)


def load_matrix(path: str | Path, selectors: list[str] | tuple[str, ...] = (),
                sets: list[str] | tuple[str, ...] = (),
                registry: Registry | None = None) -> Matrix:
    """Read, validate and expand a matrix file (see the module docstring).

    ``registry`` is used to check component names and prune incompatible
    combinations from declared capabilities (nothing is imported).
    """
    path = _find_matrix(path)
    where = str(path)
    data = _read_toml(path, where)
    plan = _matrix_table(data["matrix"], path.stem, where)
    plan.axes, plan.hf_repeats = _component_axes(data, plan.mode, registry, where)
    plan.pairs = _size_pairs(data.get("sizes", {}), where)
    rfields = _reduce_fields(registry)
    plan.base = _base_params(data.get("reduce", {}), sets, rfields, where)
    for axis in set(MODEL_AXES) & set(plan.axes) & set(plan.base):
        raise MatrixError(f"{where}: {axis} is swept in [components] and set in [reduce] / "
                          "--set; give it in one place")
    plan.grids = (_param_grids(data.get("params", {}), plan.axes, rfields, where)
                  if plan.mode == "rb" else
                  _solver_grids(data.get("params", {}), plan.axes, registry, where))
    plan.overrides = _scene_overrides(data.get("scene_overrides", {}), plan.scenes, where)
    checks.check_case_count(_case_count(plan), where)
    sel = _selectors(selectors)
    cases = [case for sname in plan.scenes if _selected(sname, sel.get("scene"))
             for case in _scene_cases(plan, sname, sel, registry, where)]
    if not cases:
        raise MatrixError(f"{where}: no case left after the selectors {list(selectors)}")
    return Matrix(plan.name, str(path), data, cases)


def _case_count(plan: _Plan) -> int:
    """The number of cases before selectors (an upper bound of the expansion)."""
    n = len(plan.scenes) * len(plan.pairs) * plan.repetitions
    for names in plan.axes.values():
        n *= len(names)
    for grid in plan.grids.values():
        n *= max(1, len(grid))
    return n


def _read_toml(path: Path, where: str) -> dict[str, Any]:
    """The matrix file's tables, with the top-level ones and ``[matrix]`` checked."""
    try:  # a directory, too large, unreadable, not UTF-8, not TOML, nested too deeply
        data = limits.read_toml(path, "run matrix")
    except ValueError as exc:
        raise MatrixError(str(exc)) from None
    _check_keys(data, _TOP, where)
    if "matrix" not in data:
        raise MatrixError(f"{where}: missing the [matrix] table (name, scenes)")
    for key in _TOP - {"matrix"}:
        if key in data and not isinstance(data[key], dict):
            raise MatrixError(f"{where}: {key} = {data[key]!r}; expected the table [{key}]")
    return data


def _matrix_table(mtab: dict, default_name: str, where: str) -> _Plan:
    """The ``[matrix]`` table: name, scenes, repetitions, seed, mode and time limit."""
    if isinstance(mtab, dict):
        _check_keys(mtab, _MATRIX_KEYS, f"{where}: [matrix]")
    h = checks.matrix_header(mtab, default_name, where)
    return _Plan(h["name"], h["scenes"], h["repetitions"], h["seed"], h["mode"],
                 h["timeout_s"])


def _hf_repeats(data: dict, mode: str, where: str) -> Any:
    """The ``[hf]`` table's ``repeats`` (checked in mode ``hf``, whose matrices have no
    ``[sizes]``, ``[params]`` nor ``[reduce]``)."""
    if mode == "hf":
        for t in ("sizes", "reduce"):
            if t in data:
                raise MatrixError(f"{where}: [{t}] does not apply to mode 'hf' (HF solves "
                                  "only); remove it")
    hf = data.get("hf", {})
    _check_keys(hf, {"repeats"}, f"{where}: [hf]")
    if mode == "hf":
        reps_hf = hf.get("repeats", 3)
        if not isinstance(reps_hf, int) or isinstance(reps_hf, bool) or not 1 <= reps_hf <= 1000:
            raise MatrixError(f"{where}: [hf] repeats = {reps_hf!r}; give an integer in "
                              "[1, 1000]")
    return hf.get("repeats", 3)


def _component_axes(data: dict, mode: str, registry: Registry | None,
                    where: str) -> tuple[dict[str, list[str]], Any]:
    """The component names per role (``[components]``, checked) and the HF repeats."""
    comps = data.get("components", {})
    _check_keys(comps, set(_HF_ROLES) if mode == "hf" else {*COMPONENT_ROLES, *MODEL_AXES},
                f"{where}: [components] (mode {mode})")
    hf_repeats = _hf_repeats(data, mode, where)
    axes = {role: checks.check_strings(comps.get(role, default), f"{where}: [components] {role}")
            for role, default in COMPONENT_ROLES.items()}
    if mode == "hf":  # the RB roles do not apply: empty names in the rows
        axes.update({r: [""] for r in COMPONENT_ROLES if r not in _HF_ROLES})
    _check_names(axes, mode, registry, where)
    for axis in MODEL_AXES:
        if axis in comps:
            w = f"{where}: [components] {axis}"
            axes[axis] = checks.check_strings(comps[axis], w)
            for v in axes[axis]:
                checks.check_reduce_value(axis, v, w)
    return axes, hf_repeats


def _check_names(axes: dict[str, list[str]], mode: str, registry: Registry | None,
                 where: str) -> None:
    """The registered components' names with a registry (hyper: ``"auto"`` or a registered
    hyper-reducer)."""
    if registry is not None:
        hypers = ("auto", *registry.names("hyper"))
        for h in axes["hyper"]:
            if h not in hypers and not (mode == "hf" and h == ""):
                raise MatrixError(f"{where}: [components] hyper: {h!r}; valid: "
                                  f"{', '.join(hypers)}")
        for role in REGISTRY_ROLES:
            valid = registry.names(role)
            for n in axes[role]:
                if n not in valid and not (mode == "hf" and role not in _HF_ROLES):
                    raise MatrixError(f"{where}: [components] {role}: unknown {role} {n!r}; "
                                      f"valid: {', '.join(valid)}")


def _size_pairs(sizes: dict, where: str) -> list[tuple[int | None, int | None]]:
    """The ``(N, R)`` pairs of ``[sizes]``: its ``pairs``, or the product of ``N`` and ``R``."""
    _check_keys(sizes, {"pairs", "N", "R"}, f"{where}: [sizes]")
    if "pairs" in sizes:
        if "N" in sizes or "R" in sizes:
            raise MatrixError(f"{where}: [sizes]: give either pairs or N / R lists, not both")
        pairs = []
        for p in _as_list(sizes["pairs"], f"{where}: [sizes] pairs"):
            if not (isinstance(p, list) and len(p) == 2):
                raise MatrixError(f"{where}: [sizes] pairs: {p!r}; each pair is [N, R]")
            pairs.append((_size(p[0], where, "pairs: N"), _size(p[1], where, "pairs: R")))
        return pairs
    Ns = [_size(v, where, "N") for v in _as_list(sizes.get("N", [None]), f"{where}: N")]
    Rs = [_size(v, where, "R") for v in _as_list(sizes.get("R", [None]), f"{where}: R")]
    return list(itertools.product(Ns, Rs))


def _base_params(reduce: dict, sets: list[str] | tuple[str, ...], rfields: set[str],
                 where: str) -> dict[str, Any]:
    """The ``[reduce]`` fields of every case, updated by ``--set FIELD=VALUE``."""
    base = dict(reduce)
    for s in sets:
        if "=" not in s:
            raise MatrixError(f"--set {s!r}: write FIELD=VALUE (a [reduce] field)")
        k, v = s.split("=", 1)
        base[k.strip()] = _parse_value(v.strip(), k.strip())
    _check_params(base, rfields, f"{where}: [reduce] / --set")
    checks.check_reduce_values(base, f"{where}: [reduce] / --set")
    return base


def _param_grids(params: dict, axes: dict[str, list[str]], rfields: set[str],
                 where: str) -> dict[tuple[str, str], list[dict]]:
    """``{(role, name): [option dict, ...]}``: the product of each ``[params.role.name]``."""
    _check_keys(params, {*COMPONENT_ROLES, *MODEL_AXES}, f"{where}: [params]")
    grids: dict[tuple[str, str], list[dict]] = {}
    for role, per_name in params.items():
        if not isinstance(per_name, dict):
            raise MatrixError(f"{where}: [params] {role} = {per_name!r}; expected tables "
                              f"[params.{role}.NAME] of field = [values]")
        for cname, grid in per_name.items():
            w = f"{where}: [params.{role}.{cname}]"
            if cname not in axes.get(role, []):
                raise MatrixError(f"{w}: {cname!r} is not in [components] {role} "
                                  f"{axes.get(role, [])}")
            if not isinstance(grid, dict):
                raise MatrixError(f"{w}: {grid!r}; expected a table of field = [values]")
            _check_params(grid, rfields, w)
            checks.check_reduce_values(grid, w, grid=True)
            keys = sorted(grid)
            vals = [_as_list(grid[k], f"{w} {k}") for k in keys]
            grids[(role, cname)] = [dict(zip(keys, combo, strict=True))
                                    for combo in itertools.product(*vals)]
    return grids


def _solver_grids(params: dict, axes: dict[str, list[str]], registry: Registry | None,
                  where: str) -> dict[tuple[str, str], list[dict]]:
    """Mode ``hf``: ``{("solver", name): [options, ...]}``, the product of each
    ``[params.solver.NAME]`` table of solver options (e.g. ``condensation = ["schur",
    "columns"]``); each option set is checked by making the solver with it (an unknown or
    invalid option is an error naming the table, the option and the solver's message)."""
    _check_keys(params, {"solver"}, f"{where}: [params] (mode hf: solver options only)")
    per_name = params.get("solver", {})
    if not isinstance(per_name, dict):
        raise MatrixError(f"{where}: [params] solver = {per_name!r}; expected tables "
                          "[params.solver.NAME] of option = [values]")
    grids: dict[tuple[str, str], list[dict]] = {}
    for cname, grid in per_name.items():
        w = f"{where}: [params.solver.{cname}]"
        if cname not in axes["solver"]:
            raise MatrixError(f"{w}: {cname!r} is not in [components] solver {axes['solver']}")
        if not isinstance(grid, dict):
            raise MatrixError(f"{w}: {grid!r}; expected a table of option = [values]")
        keys = sorted(grid)
        for k in keys:
            for v in _as_list(grid[k], f"{w} {k}"):
                if not isinstance(v, (str, int, float, bool)):
                    raise MatrixError(f"{w}: {k} = {v!r}; expected a string, number or "
                                      "boolean (or a list of them)")
        combos = [dict(zip(keys, c, strict=True))
                  for c in itertools.product(*(_as_list(grid[k], w) for k in keys))]
        if registry is not None and registry.availability(registry.get("solver", cname))[0]:
            for opts in combos:
                try:
                    registry.create("solver", cname, **opts)
                except Exception as exc:  # noqa: BLE001 - any refusal (int(inf): Overflow)
                    raise MatrixError(f"{w}: {opts}: {type(exc).__name__}: {exc}") from None
        grids[("solver", cname)] = combos
    return grids


def _scene_overrides(overrides: dict, scenes: list[str], where: str) -> dict[str, list[str]]:
    """The ``[scene_overrides]`` table, checked against the scenes."""
    for sname, ov in overrides.items():
        if sname not in scenes:
            raise MatrixError(f"{where}: [scene_overrides] {sname!r} is not in [matrix] scenes "
                              f"{scenes}")
        if not isinstance(ov, list) or not all(isinstance(x, str) for x in ov):
            raise MatrixError(f"{where}: [scene_overrides] {sname}: give a list of "
                              "'section.key=value' strings")
    return overrides


def _scene_cases(plan: _Plan, sname: str, sel: dict[str, list[str]],
                 registry: Registry | None, where: str) -> list[Case]:
    """The selected cases of one scene entry: components x sizes x parameter grids x
    repetitions, each with its compatibility status."""
    ov = tuple(plan.overrides.get(sname, ()))
    if plan.seed is not None:
        ov = (*ov, f"sampling.seed={plan.seed}")
    try:
        scene = load_scene(sname.split("@", 1)[0], ov)
    except Exception as exc:  # noqa: BLE001 - name the matrix too
        raise MatrixError(f"{where}: [matrix] scenes: {sname!r}: {exc}") from None
    scene_seed, fingerprint = int(scene.data["sampling"]["seed"]), scene.fingerprint()
    cases: list[Case] = []
    seen: set[tuple] = set()
    for combo in itertools.product(*plan.axes.values()):
        values = dict(zip(plan.axes, combo, strict=True))
        if not all(_selected(v, sel.get(r)) for r, v in values.items()):
            continue
        comp = {r: values[r] for r in COMPONENT_ROLES}
        model = {a: values[a] for a in MODEL_AXES if a in values}
        used = applicable_roles(registry, comp)
        if used != comp:  # roles its formulation does not use, emptied: one case for them
            key = (tuple(used.items()), tuple(model.items()))
            if key in seen:
                continue
            seen.add(key)
            comp = used
        status, reason = compatibility(scene, comp, registry)
        option_sets = [plan.grids.get((r, v), [{}]) for r, v in values.items()]
        for N, R in plan.pairs:  # mode hf: no [sizes], the one pair (None, None)
            if not (_selected(N, sel.get("N")) and _selected(R, sel.get("R"))):
                continue
            if not comp["dual"]:  # no dual space (linear, Nitsche): R does not apply
                R = None
                if (used_key := (tuple(comp.items()), tuple(model.items()), N)) in seen:
                    continue
                seen.add(used_key)
            for opts in itertools.product(*option_sets):
                p = {**_case_params(plan, opts), **model}
                st, why = (status, reason) if status != "run" or plan.mode != "rb" else \
                    reduced_model_check(scene, comp, p, registry, R)
                cases += [Case(sname, ov, comp, N, R, p, rep, scene_seed, plan.timeout_s,
                               fingerprint, plan.mode, st, why)
                          for rep in range(plan.repetitions)]
    return cases


def _case_params(plan: _Plan, opts: tuple[dict, ...]) -> dict[str, Any]:
    """A case's parameters: the ``[reduce]`` fields (mode ``hf``: the HF repeats) updated
    by its component options."""
    p = dict(plan.base) if plan.mode == "rb" else {"hf_repeats": plan.hf_repeats}
    # mode hf: the solver options of [params.solver.NAME] (rbbench.bench.execution)
    for o in opts:
        p.update(o)
    return p


def _size(v: Any, where: str, what: str) -> int | None:
    if v is None:
        return None
    if not isinstance(v, int) or isinstance(v, bool) or not 1 <= v <= checks.MAX_SIZE:
        raise MatrixError(f"{where}: [sizes] {what} = {v!r}; give integers >= 1 and <= "
                          f"{checks.MAX_SIZE}")
    return int(v)


def _check_params(d: dict, rfields: set[str], where: str) -> None:
    for k in d:
        if k in _RESERVED or k not in rfields:
            valid = sorted(set(rfields) - _RESERVED)
            raise MatrixError(f"{where}: unknown field {k!r}; valid: {', '.join(valid)}")


def _find_matrix(path: str | Path) -> Path:
    p = Path(path)
    if p.is_file():
        return p
    if p.is_dir():
        raise MatrixError(f"{p}: is a directory; expected a run-matrix .toml file")
    cand = PROBLEMS_DIR / "matrices" / (p.name if p.suffix == ".toml" else f"{p.name}.toml")
    if cand.is_file():
        return cand
    avail = sorted(x.stem for x in (PROBLEMS_DIR / "matrices").glob("*.toml"))
    raise MatrixError(f"run matrix {str(path)!r} not found (not a file, nor in "
                      f"{PROBLEMS_DIR / 'matrices'}: {', '.join(avail) or 'none'})")



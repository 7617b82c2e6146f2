"""Deprecated import paths of rbbench 0.1 (the flat layout and the first layered one), kept
importable until 0.3, each with a :class:`DeprecationWarning` naming the new path.

* :data:`MOVED`: a module moved whole; the old path gives the new module object itself, so
  ``isinstance`` checks and monkeypatching agree.
* :data:`SPLIT`: a module whose names went to several modules; the old path gives a proxy
  module that looks each name up in the new modules, in order.
* :data:`NAMES`: single names that moved out of a module (old module -> name -> new
  ``module:name``); a module that kept its path but lost names declares
  ``__getattr__ = deprecated_names(__name__)`` (:func:`deprecated_names`).

``tests/system/test_compat.py`` imports every 0.1 module path and every public name it had.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import types
import warnings
from collections.abc import Callable
from typing import Any

_PLUG = "rbbench_plugins"
_SINCE = "goes in rbbench 0.3"

#: old module -> its module now (moved whole)
MOVED = {
    # the flat layout of 0.1
    "rbbench.sampling": "rbbench.scene.sampling",
    "rbbench.hertz": "rbbench.hf.references.hertz",
    "rbbench.snapshots": "rbbench.hf.snapshots",
    "rbbench.nitsche": "rbbench.hf.algebra.nitsche",
    "rbbench.pod": "rbbench.rb.algorithms.pod",
    "rbbench.cones": "rbbench.rb.algorithms.cones",
    "rbbench.pga": "rbbench.rb.algorithms.pga",
    "rbbench.infsup": "rbbench.rb.algorithms.infsup",
    "rbbench.eim": "rbbench.rb.algorithms.eim",
    "rbbench.hyper": "rbbench.rb.hyper.contact_eim",
    "rbbench.compressors": "rbbench.rb.compressors",
    "rbbench.matrix": "rbbench.bench.matrix",
    "rbbench.schema": "rbbench.bench.schema",
    "rbbench.report": "rbbench.bench.report",
    "rbbench.stability_study": "rbbench.studies.beta_dec",
    # the first layered layout of 0.1
    "rbbench.console": "rbbench.cli.console",
    "rbbench.console_linear": "rbbench.cli.console",
    "rbbench._openblas_env": "rbbench.runtime.openblas_env",
    "rbbench.testing.contract": "rbbench.testing",
    "rbbench.studies.cli_studies": "rbbench.cli.studies",
    "rbbench.optim.cli_optimize": "rbbench.cli.optimize",
    "rbbench.hf.facets": "rbbench.hf.geometry.facets",
    "rbbench.hf.facet_chains": "rbbench.hf.geometry.chains",
    "rbbench.hf.pairing": "rbbench.hf.geometry.pairing",
    "rbbench.hf.contact_checks": "rbbench.hf.geometry.checks",
    "rbbench.hf.friction_solvers": "rbbench.hf.solvers.friction",
    "rbbench.hf.friction_lemke": "rbbench.hf.solvers.lemke",
    "rbbench.hf.friction_algebra": "rbbench.hf.algebra.friction",
    "rbbench.hf.nitsche_algebra": "rbbench.hf.algebra.nitsche",
    "rbbench.hf.nitsche_friction": "rbbench.hf.algebra.nitsche_friction",
    "rbbench.hf.mindlin_check": "rbbench.hf.references.mindlin",
    "rbbench.hf.pardiso_schur": "rbbench.hf.condensation.pardiso",
    "rbbench.hf.linear_solve": "rbbench.hf.linear.solve",
    "rbbench.hf.snapshot_key": "rbbench.hf.snapshots.key",
    "rbbench.hf.worker_pool": "rbbench.runtime.workers",
    "rbbench.hf.threads": "rbbench.runtime.threads",
    "rbbench.rb.pod": "rbbench.rb.algorithms.pod",
    "rbbench.rb.eim": "rbbench.rb.algorithms.eim",
    "rbbench.rb.pga": "rbbench.rb.algorithms.pga",
    "rbbench.rb.infsup": "rbbench.rb.algorithms.infsup",
    "rbbench.rb.infsup_zero": "rbbench.rb.algorithms.infsup_zero",
    "rbbench.rb.gcns": "rbbench.rb.algorithms.gcns",
    "rbbench.rb.affine": "rbbench.rb.algorithms.affine",
    "rbbench.rb.cones": "rbbench.rb.algorithms.cones",
    "rbbench.rb.cone_metric": "rbbench.rb.algorithms.cones.metric",
    "rbbench.rb.cone_split": "rbbench.rb.algorithms.cones.split",
    "rbbench.rb.cone_greedy": "rbbench.rb.algorithms.cones.greedy",
    "rbbench.rb.cone_baselines": "rbbench.rb.algorithms.cones.baselines",
    "rbbench.rb.hyper_reducers": "rbbench.rb.hyper.reducers",
    "rbbench.rb.contact_eim": "rbbench.rb.hyper.contact_eim",
    "rbbench.rb.compiled_online": "rbbench.rb.mixed.compiled",
    "rbbench.rb.nitsche_model": "rbbench.rb.nitsche.model",
    "rbbench.rb.nitsche_offline": "rbbench.rb.nitsche.offline",
    "rbbench.rb.friction_eim": "rbbench.rb.friction.eim",
    "rbbench.rb.friction_infsup": "rbbench.rb.friction.infsup",
    "rbbench.rb.friction_profiles": "rbbench.rb.friction.profiles",
    "rbbench.rb.friction_wedge": "rbbench.rb.friction.wedge.model",
    "rbbench.rb.friction_wedge_eim": "rbbench.rb.friction.wedge.hyper",
    "rbbench.rb.friction_wedge_stage": "rbbench.rb.friction.wedge.stage",
    "rbbench.rb.linear_model": "rbbench.rb.linear.model",
    "rbbench.rb.linear_offline": "rbbench.rb.linear.offline",
    f"{_PLUG}.backends.skfem_backend": f"{_PLUG}.backends.skfem.backend",
    f"{_PLUG}.backends.meshes": f"{_PLUG}.backends.skfem.meshes",
    f"{_PLUG}.backends.linear_skfem": f"{_PLUG}.backends.skfem.linear",
    f"{_PLUG}.backends.linear_ngsolve": f"{_PLUG}.backends.ngsolve.linear",
    f"{_PLUG}.backends.ngsolve_fe": f"{_PLUG}.backends.ngsolve.fe",
    f"{_PLUG}.backends.ngsolve_meshes": f"{_PLUG}.backends.ngsolve.meshes",
    f"{_PLUG}.solvers.petsc_solvers": f"{_PLUG}.solvers.petsc",
    f"{_PLUG}.solvers.petsc_common": f"{_PLUG}.solvers.petsc.common",
    f"{_PLUG}.solvers.petsc_vi": f"{_PLUG}.solvers.petsc.vi",
    f"{_PLUG}.solvers.petsc_tao": f"{_PLUG}.solvers.petsc.tao",
}

#: old module -> the modules its names went to (looked up in this order)
SPLIT = {
    "rbbench.contact_geometry": ("rbbench.hf.geometry.operators", "rbbench.hf.geometry.pairing",
                                 "rbbench.hf.geometry.chains", "rbbench.hf.geometry.facets"),
    "rbbench.hf.contact_geometry": ("rbbench.hf.geometry.operators",
                                    "rbbench.hf.geometry.pairing", "rbbench.hf.geometry.chains",
                                    "rbbench.hf.geometry.facets"),
    "rbbench.lcp": ("rbbench.hf.solvers.lcp", "rbbench.hf.condensation.dense"),
    "rbbench.hf.lcp": ("rbbench.hf.solvers.lcp", "rbbench.hf.condensation.dense"),
    "rbbench.output": ("rbbench.hf.output", "rbbench.provenance"),
    "rbbench.reduced": ("rbbench.rb.mixed.model", "rbbench.rb.algorithms.saddle",
                        "rbbench.rb.online", "rbbench.rb.algorithms.affine"),
    "rbbench.rb.mixed_model": ("rbbench.rb.mixed.model", "rbbench.rb.algorithms.saddle",
                               "rbbench.rb.online"),
    "rbbench.nitsche_reduced": ("rbbench.rb.nitsche.model", "rbbench.rb.nitsche.offline"),
    "rbbench.rb_pipeline": ("rbbench.rb.offline", "rbbench.rb.config", "rbbench.rb.compressors",
                            "rbbench.rb.validation", "rbbench.rb.mixed.offline"),
    "rbbench.runner": ("rbbench.bench.runner", "rbbench.bench.execution"),
    "rbbench.rb.mixed_offline": ("rbbench.rb.mixed.offline", "rbbench.rb.compressors"),
    "rbbench.rb.friction_model": ("rbbench.rb.friction.collocation.model",
                                  "rbbench.rb.friction.qp"),
    "rbbench.rb.friction_stage": ("rbbench.rb.friction.collocation.stage",
                                  "rbbench.rb.friction.options"),
    "rbbench.rb.friction_offline": ("rbbench.rb.friction.offline",
                                    "rbbench.rb.friction.collocation.stage",
                                    "rbbench.rb.friction.options",
                                    "rbbench.rb.friction.wedge.stage"),
    "rbbench.rb._kernels": ("rbbench.rb.mixed.kernels", "rbbench.rb.kernels.layout",
                            "rbbench.rb.kernels.pairing"),
    "rbbench.rb._dual_kernels": ("rbbench.rb.mixed.dual_kernels", "rbbench.rb.kernels.nnls",
                                 "rbbench.runtime.numba_cache"),
    f"{_PLUG}.backends.ngsolve_backend": (f"{_PLUG}.backends.ngsolve.backend",
                                          f"{_PLUG}.backends.ngsolve.fe",
                                          f"{_PLUG}.backends.ngsolve.meshes"),
    # renamed after the method (a heat equation with a Robin condition)
    "rbbench.studies.heat_seed": ("rbbench.studies.heat_robin",),
}

_MODEL = "rbbench.hf.model"
_HF_NAMES = {"solve_hf": _MODEL, "HFSolution": _MODEL, "HFModel": _MODEL,
             "ProblemCache": _MODEL, "solve_floor": _MODEL, "floor_metrics": _MODEL,
             "make_components": "rbbench.hf.components", "check_names": "rbbench.hf.components",
             "check_friction_support": "rbbench.hf.components",
             "default_solver": "rbbench.hf.components", "discretize_for": "rbbench.hf.components",
             "friction_at": "rbbench.hf.components", "warm_up": "rbbench.hf.components",
             "contact_metrics": "rbbench.hf.metrics", "DEFINITIONS": "rbbench.hf.metrics",
             "ACTIVE_THRESHOLD": "rbbench.hf.metrics",
             "normal_operators": "rbbench.hf.metrics"}
_CLI = {"cmd_solve": "solve", "cmd_plugins": "solve", "cmd_scenes": "solve",
        "cmd_reduce": "reduce", "cmd_online_scaling": "reduce", "cmd_run": "run",
        "cmd_report": "run", "cmd_compare": "run", "cmd_hertz_table": "studies",
        "cmd_nitsche_table": "studies", "cmd_nitsche_compare": "studies",
        "print_summary": "console"}
_STUDY_CLI = {"pymor_thermal_block": "pymor_thermal_block", "heat_seed": "heat_robin",
              "shape_side_by_side": "shape_side_by_side", "snapshot_workers": "snapshot_workers"}

#: old module -> name -> ``new.module:name`` (a name that moved alone)
NAMES: dict[str, dict[str, str]] = {
    "rbbench.hf": {k: f"{m}:{k}" for k, m in _HF_NAMES.items()},
    _MODEL: {k: f"{m}:{k}" for k, m in _HF_NAMES.items() if m != _MODEL},
    "rbbench.rb.offline": {"ReduceConfig": "rbbench.rb.config:ReduceConfig",
                           "HYPER": "rbbench.rb.config:HYPER",
                           "reduction_steps": "rbbench.rb.config:reduction_steps",
                           "SceneProblems": f"{_MODEL}:ProblemCache",
                           "build_problem": f"{_MODEL}:build_problem"},
    "rbbench.cli": {k: f"rbbench.cli.{m}:{k}" for k, m in _CLI.items()},
    "rbbench.hf.snapshots": {"limit_blas_threads": "rbbench.runtime.threads:limit_blas_threads"},
    "rbbench.studies.scaling": {"gc_paused": "rbbench.runtime.timing:gc_paused"},
    "rbbench.scene": {"Field": "rbbench.scene.schema:Field",
                      "SCHEMA": "rbbench.scene.schema:SCHEMA",
                      "KEY_NEUTRAL_DEFAULTS": "rbbench.scene.loading:KEY_NEUTRAL_DEFAULTS",
                      "key_data": "rbbench.scene.loading:key_data"},
    "rbbench.scene.loading": {"Field": "rbbench.scene.schema:Field"},
    "rbbench.nitsche_reduced": {"reduce_nitsche": "rbbench._compat:reduce_nitsche"},
    "rbbench.rb_pipeline": {"HYPER": "rbbench.rb.config:HYPER"},
    "rbbench.rb.friction_stage": {"friction_dual": "rbbench._compat:friction_dual"},
    "rbbench.rb.friction_offline": {"friction_dual": "rbbench._compat:friction_dual"},
    **{f"rbbench.studies.{old}": {
        "add_parser": f"rbbench.cli.studies:_add_{new}_parser",
        "run": f"rbbench.cli.studies:cmd_{new}"} for old, new in _STUDY_CLI.items()},
    # names of documents replaced by names of methods or by "published"
    "rbbench.hf.algebra.friction": {"SEED001": "rbbench.hf.algebra.friction:MODEL_B"},
    "rbbench.optim.run": {"SEED_J0": "rbbench.optim.run:PUBLISHED_J0",
                          "SEED_J_OPT": "rbbench.optim.run:PUBLISHED_J_OPT"},
    "rbbench.studies.nitsche_eac": {
        "SEED_EAC": "rbbench.studies.published:PUBLISHED_EAC",
        "SEED_H": "rbbench.studies.published:PUBLISHED_H",
        "seed_h_overrides": "rbbench.studies.nitsche_eac:published_h_overrides"},
}
NAMES["rbbench.studies.heat_seed"].update({
    "SEED": "rbbench.studies.heat_robin:PUBLISHED",
    "heat_seed": "rbbench.studies.heat_robin:heat_robin_study",
    "heat_seed_markdown": "rbbench.studies.heat_robin:heat_robin_markdown"})


def _resolve(target: str) -> Any:
    module, _, name = target.partition(":")
    return getattr(importlib.import_module(module), name)


def _warn(old: str, new: str) -> None:
    warnings.warn(f"{old} moved to {new}; the old path {_SINCE}", DeprecationWarning,
                  stacklevel=3)


def deprecated_names(module: str) -> Callable[[str], Any]:
    """A module ``__getattr__`` giving the names that left ``module`` (:data:`NAMES`), each
    with a DeprecationWarning; any other name is an AttributeError."""
    table = NAMES.get(module, {})

    def __getattr__(name: str) -> Any:
        target = table.get(name)
        if target is None:
            raise AttributeError(f"module {module!r} has no attribute {name!r}")
        _warn(f"{module}.{name}", target.replace(":", "."))
        return _resolve(target)

    return __getattr__


class _SplitModule(types.ModuleType):
    """An old module whose names went to several modules: each name looked up on use."""

    def __init__(self, name: str, targets: tuple[str, ...]) -> None:
        super().__init__(name, f"deprecated: the names of {name} are in {', '.join(targets)}")
        self._targets = targets

    def __getattr__(self, attr: str) -> Any:
        if attr.startswith("__"):
            raise AttributeError(attr)
        special = NAMES.get(self.__name__, {}).get(attr)
        if special is not None:
            return _resolve(special)
        for target in self._targets:
            module = importlib.import_module(target)
            if hasattr(module, attr):
                return getattr(module, attr)
        raise AttributeError(f"module {self.__name__!r} has no attribute {attr!r} (its names "
                             f"moved to {', '.join(self._targets)})")


class _Alias(importlib.abc.Loader):
    def __init__(self, fullname: str) -> None:
        self.fullname = fullname

    def create_module(self, spec):
        if self.fullname in MOVED:  # the new module itself, not a copy
            return importlib.import_module(MOVED[self.fullname])
        return _SplitModule(self.fullname, SPLIT[self.fullname])

    def exec_module(self, module) -> None:
        return None


class _MovedFinder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname, path=None, target=None):
        new = MOVED.get(fullname) or (", ".join(SPLIT[fullname]) if fullname in SPLIT
                                      else None)
        if new is None:
            return None
        warnings.warn(f"{fullname} moved to {new}; the old path {_SINCE}", DeprecationWarning,
                      stacklevel=3)
        return importlib.util.spec_from_loader(fullname, _Alias(fullname))


def install() -> None:
    """Put the finder on ``sys.meta_path`` once."""
    if not any(isinstance(f, _MovedFinder) for f in sys.meta_path):
        sys.meta_path.append(_MovedFinder())


# -- names that left without a one-to-one successor ------------------------------------------
def friction_dual(config: Any) -> str:
    """Deprecated: the friction dual model of a configuration (now the option
    ``friction_dual`` of :class:`rbbench.rb.friction.options.FrictionOptions`)."""
    from rbbench.rb.friction.options import DEPRECATED_DUALS, FrictionOptions

    options = getattr(config, "options", config)
    name = getattr(options, "friction_dual", None) or "collocation"
    return FrictionOptions(friction_dual=DEPRECATED_DUALS.get(name, name)).friction_dual


def reduce_nitsche(scene: Any, config: Any, progress: Callable[[str], None] = lambda m: None,
                   snapshot_progress: bool = False, registry: Any = None) -> Any:
    """Deprecated: :func:`rbbench.rb.offline.reduce` with the Nitsche formulation."""
    from dataclasses import replace

    from rbbench.rb.offline import reduce

    return reduce(scene, replace(config, formulation="nitsche"), progress, snapshot_progress,
                  registry)

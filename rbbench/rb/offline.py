"""The offline skeleton of every reduced model (``rbbench reduce``).

scene -> training / validation sets -> HF snapshots (cached, :mod:`rbbench.hf.snapshots.compute`)
-> primal space (a registered primal compressor) -> the formulation's own steps (dual
cone, stabiliser, hyper-reduction: :meth:`rbbench.interfaces.Formulation.reduction`,
e.g. :mod:`rbbench.rb.mixed.offline`, :mod:`rbbench.rb.nitsche.offline`) -> reduced model
(small dense arrays, picklable, ``solve(mu)`` checks mu against D) -> the shared validation
(:mod:`rbbench.rb.validation`: errors, timings, the row).

:func:`offline` builds a reduced model without validating it; :func:`reduce` is
:func:`offline` followed by :func:`rbbench.rb.validation.validate`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from rbbench._compat import deprecated_names
from rbbench.hf.components import (
    check_component_options,
    check_mesher,
    check_physics_support,
    default_solver,
    make_components,
)
from rbbench.hf.model import ProblemCache, ProblemSource
from rbbench.hf.snapshots.cache import SnapshotSet
from rbbench.hf.snapshots.compute import compute_snapshots
from rbbench.rb.config import ReduceConfig, parse_options, reduction_steps
from rbbench.rb.validation import ReducedStage, ReduceResult, validate
from rbbench.registry import Registry, UnknownComponentError, default_registry
from rbbench.runtime.workers import keep_workers
from rbbench.scene.friction import friction_of
from rbbench.scene.linear import is_linear
from rbbench.scene.loading import Scene, SceneError
from rbbench.scene.parameters import FieldError
from rbbench.scene.sampling import parameter_set

__all__ = ["DivergedError", "OfflineContext", "Offline", "ReduceResult", "check_finite",
           "clipped_size", "eim_grid", "eim_training_set", "fixed_contact_points", "offline",
           "prepare_config", "primal_basis", "primal_histories", "reduce", "training_snapshots"]

class DivergedError(RuntimeError):
    """A stage produced non-finite numbers (the runner's ``diverged`` status)."""


def check_finite(what: str, a: np.ndarray) -> None:
    """Raise :class:`DivergedError` if ``a`` has non-finite entries (``what``: the name)."""
    if not np.all(np.isfinite(a)):
        raise DivergedError(f"{what} has {int(np.sum(~np.isfinite(a)))} non-finite entries")


def _progress(msg: str) -> None:
    return None


@dataclass
class OfflineContext:
    """What the shared offline steps hand to a formulation's own steps.

    ``problem_at``: ``mu -> HF problem`` (cached); ``X``: the V inner product on the free
    dofs; ``primal``: the primal basis (``primal.Z``, X-orthonormal); ``valid``: the
    validation snapshots (None when the model is built without validation);
    ``timings``: stage -> seconds, from ``t0``.
    """

    scene: Scene
    config: ReduceConfig
    registry: Registry
    progress: Callable[[str], None]
    backend: Any
    formulation: Any
    problem_at: ProblemCache
    X: Any
    mus_train: np.ndarray
    train: SnapshotSet
    mus_valid: np.ndarray
    valid: SnapshotSet | None
    primal: Any
    t0: float
    timings: dict[str, float] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    @property
    def Z(self) -> np.ndarray:
        return self.primal.Z

    @property
    def options(self) -> Any:
        """The formulation's options (its dataclass, parsed by :func:`prepare_config`)."""
        return self.config.options

    def problem_source(self) -> ProblemSource:
        """``mu -> HF problem`` assembled afresh, on this context's components (picklable:
        the online stage of a model without hyper-reduction)."""
        return ProblemSource(self.scene, self.config.backend, self.config.formulation,
                             self.config.component_options, self.registry,
                             (self.backend, self.formulation))

    def warn(self, message: str) -> None:
        """A warning of this reduction: ``result.json`` ``warnings`` and the console."""
        self.warnings.append(message)
        self.progress(f"WARNING: {message}")


@dataclass
class Offline:
    """A reduced model built offline, with its context (for :func:`validate`)."""

    context: OfflineContext
    stage: ReducedStage

    @property
    def model(self) -> Any:
        return self.stage.model


def check_hyper(config: ReduceConfig, registry: Registry, steps: Any = None) -> None:
    """The hyper-reducer ``config.hyper`` is registered and declares the formulation
    (``"auto"``: the formulation's own rule), and the formulation's offline ``steps`` carry
    it out when they list the ones they do (``steps.hypers``): a plugin's hyper-reducer goes
    with a formulation whose steps read ``config.hyper``."""
    if config.hyper == "auto":
        return
    registry.create("hyper", config.hyper).check(config.formulation)
    carried = getattr(steps, "hypers", None)
    if carried is not None and config.hyper not in carried:
        raise SceneError(f"hyper {config.hyper!r}: {getattr(steps, 'label', steps.name)} "
                         f"carries out {', '.join(map(repr, carried))} or 'auto', not "
                         f"{config.hyper!r}")


def check_hyper_name(config: ReduceConfig, registry: Registry) -> None:
    """``config.hyper`` is ``"auto"`` or a registered hyper-reducer (an
    :class:`~rbbench.registry.UnknownComponentError` listing the valid names otherwise)."""
    valid = ("auto", *registry.names("hyper"))
    if config.hyper not in valid:
        raise UnknownComponentError(f"unknown hyper {config.hyper!r}; valid hypers: "
                                    f"{', '.join(valid)}")


SURFACE_HYPERS = ("auto", "none", "affine", "eim")
"""Hyper-reducers of the 3D (surface contact) reduced model."""


def check_surface_reduction(scene: Scene, config: ReduceConfig) -> None:
    """The 3D scene (``[geometry] kind = 'hemispheres'``) is reduced by the frictionless
    ``mixed`` formulation with the hyper-reducers of :data:`SURFACE_HYPERS`; anything else
    is a :class:`SceneError` naming the option and the valid values."""
    if scene.data.get("geometry", {}).get("kind") != "hemispheres":
        return
    if config.formulation != "mixed":
        raise SceneError(f"{scene.path}: [geometry] kind = 'hemispheres' (3D) is reduced by "
                         f"the formulation 'mixed' only, not {config.formulation!r}")
    if config.hyper not in SURFACE_HYPERS:
        raise SceneError(f"{scene.path}: [geometry] kind = 'hemispheres' (3D): hyper "
                         f"{config.hyper!r} is not available in 3D; valid hypers: "
                         f"{', '.join(map(repr, SURFACE_HYPERS))}")
    check_mesher(scene)


def prepare_config(scene: Scene, config: ReduceConfig, registry: Registry
                   ) -> tuple[Any, ReduceConfig]:
    """The formulation's offline steps and the configuration they will run, checked before
    any HF work: the component names (registered, strings) and the backend's options
    (:func:`~rbbench.hf.components.check_component_options`), the formulation (default:
    ``linear`` on a linear scene, else ``mixed``; one the scene's physics can take),
    the steps support the scene's friction law, the solver (default: the
    formulation's own for that law), the formulation's options (:func:`parse_options`:
    an option of another formulation is an :class:`~rbbench.rb.config.OptionError`),
    the steps' own checks (``prepare``) and the hyper-reducer."""
    law = friction_of(scene).law
    for role in ("formulation", "backend", "primal", "solver"):  # names before anything
        name = getattr(config, role)
        if name is not None:
            if not isinstance(name, str):
                raise FieldError("reduce", role, name, f"give the name of a registered {role}"
                                 " (rbbench plugins)")
            registry.get(role, name)
    check_component_options(registry, "backend", config.backend, config.backend_options)
    if config.formulation is None:
        config = replace(config, formulation="linear" if is_linear(scene) else "mixed")
    elif is_linear(scene) and config.formulation != "linear":
        raise SceneError(f"{scene.path}: a linear scene (no contact) is reduced by the "
                         f"formulation 'linear', not {config.formulation!r}")
    if not is_linear(scene):
        check_physics_support(scene, registry, config.formulation)
    check_surface_reduction(scene, config)
    steps = reduction_steps(config, registry, law)
    laws = getattr(steps, "friction_laws", ("none",))
    if law not in laws:
        raise SceneError(f"{scene.path}: [friction] law = {law!r}: the reduced "
                         f"{steps.name!r} model supports {', '.join(map(repr, laws))}; "
                         "solve the HF friction problem with `rbbench solve`")
    if config.solver is None and getattr(steps, "takes_solver", True):
        config = replace(config, solver=default_solver(config.formulation, registry, law))
    config = replace(config, options=parse_options(steps, config.options, registry))
    check_hyper_name(config, registry)
    config = steps.prepare(scene, config, registry)  # the steps' checks, before any HF work
    check_hyper(config, registry, steps)
    return steps, config


def offline(scene: Scene, config: ReduceConfig, progress: Callable[[str], None] = _progress,
            snapshot_progress: bool = False, registry: Registry | None = None,
            validation_snapshots: bool = True) -> Offline:
    """Build the reduced model of ``config`` (no validation): snapshots, primal space, then
    the formulation's steps. ``validation_snapshots = False`` skips the HF solves at the
    validation parameters (the model is the same: only their values are used offline).
    A formulation with a skeleton of its own (the linear one) is reduced by :func:`reduce`."""
    reg = registry or default_registry()
    steps, config = prepare_config(scene, config, reg)
    if hasattr(steps, "run"):
        raise ValueError(f"{steps.label} runs a skeleton of its own: use reduce()")
    return _build(scene, steps, config, progress, snapshot_progress, reg,
                  validation_snapshots)


def _build(scene: Scene, steps: Any, config: ReduceConfig, progress: Callable[[str], None],
           snapshot_progress: bool, reg: Registry, validation_snapshots: bool) -> Offline:
    """The shared offline skeleton on a prepared configuration (:func:`offline`)."""
    t0 = time.perf_counter()
    timings: dict[str, float] = {}
    mus_train, train, mus_valid, valid = training_snapshots(
        scene, config, config.formulation, config.solver, progress, snapshot_progress, reg,
        validation=validation_snapshots)
    timings["snapshots_s"] = time.perf_counter() - t0
    b, f, _ = make_components(scene, config.backend, config.formulation, config.solver,
                              component_options=config.component_options, registry=reg)
    problem_at = ProblemCache(b, f, scene)
    X = problem_at.X_free(scene.default_mu)
    t1 = time.perf_counter()
    primal = primal_basis(reg, config, train.U, X, progress)
    timings["primal_s"] = time.perf_counter() - t1
    ctx = OfflineContext(scene, config, reg, progress, b, f, problem_at, X, mus_train, train,
                         np.asarray(mus_valid), valid, primal, t0, timings)
    if config.N is not None and primal.Z.shape[1] < config.N:
        ctx.warn(clipped_size("-N", config.N, int(primal.Z.shape[1]), len(mus_train)))
    stage = steps.reduce(ctx)
    stage.model.parameters = scene.parameter_space
    timings["offline_s"] = time.perf_counter() - t0
    return Offline(ctx, stage)


def reduce(scene: Scene, config: ReduceConfig, progress: Callable[[str], None] = _progress,
           snapshot_progress: bool = False, registry: Registry | None = None) -> ReduceResult:
    """Run the offline stage on the training set and validate online (:func:`offline`, then
    :func:`rbbench.rb.validation.validate`): the one dispatch of every reduction (the
    command line, the Python API and the runner call it).

    The components are the registered plugins named in ``config`` (``registry``: default,
    the discovered plugins); the formulation plugin supplies its reduction steps, and a
    formulation with a skeleton of its own (``steps.run``: the linear one) runs it.
    """
    reg = registry or default_registry()
    steps, config = prepare_config(scene, config, reg)
    if hasattr(steps, "run"):
        return steps.run(scene, config, progress, reg)
    off = _build(scene, steps, config, progress, snapshot_progress, reg, True)
    return validate(off.context, off.stage)


def clipped_size(flag: str, requested: int, built: int, n_train: int) -> str:
    """The warning of a basis built smaller than requested (``-N`` is clipped, not an error:
    at most the number of training snapshots, at most their numerical rank)."""
    why = (f"at most the {n_train} training snapshots" if requested > n_train else
           f"the numerical rank of the {n_train} training snapshots")
    return f"{flag} {requested}: the basis built has {built} only ({why}; clipped)"


def fixed_contact_points(scene: Scene, hyper: str, plain_ok: bool = True) -> bool:
    """Whether the contact quadrature points are the same at every mu (hyper-reduction by
    rows or points needs them).

    ``[discretization] contact_integration = "segmented"`` moves them with mu: an explicit
    ``hyper = "eim"`` (or any reduced model when ``plain_ok`` is false: the reduced
    Nitsche model evaluates its contact points at fixed positions) raises a
    :class:`~rbbench.scene.loading.SceneError`; ``"auto"`` falls back to the plain model.
    """
    disc = scene.data.get("discretization", {})
    rule = disc.get("contact_integration", "gauss")
    geo = scene.data.get("geometry", {})
    two_bodies = geo.get("kind") == "halfdisks" and geo.get("lower", "half_disk") == "half_disk"
    if rule == "gauss" or not two_bodies:
        return True  # segmentation needs a master mesh: rigid / obstacle points are fixed
    if hyper == "eim" or not plain_ok:
        what = "the reduced Nitsche model" if not plain_ok else "hyper 'eim'"
        alt = "" if not plain_ok else "use hyper 'auto' or 'none' (plain reduced model), or "
        raise SceneError(f"{scene.path}: [discretization] contact_integration = {rule!r} "
                         f"moves the contact points with mu, so {what} (points fixed "
                         f"offline) cannot be built; {alt}set contact_integration = 'gauss'")
    return False


def eim_grid(scene: Scene, options: Any, n_train: int, per_interval: int = 4
             ) -> np.ndarray:
    """``options.n_eim_train`` parameters (default ``per_interval (n_train - 1) + 1``): a
    uniform grid of D for one parameter, else the scene's training sampling."""
    lo, hi = scene.bounds[:, 0], scene.bounds[:, 1]
    n_grid = options.n_eim_train or per_interval * (n_train - 1) + 1
    if len(lo) == 1:
        return lo + np.linspace(0.0, 1.0, n_grid)[:, None] * (hi - lo)
    return parameter_set(scene, "train", n_grid)


def eim_training_set(scene: Scene, options: Any, mus_train: np.ndarray) -> np.ndarray:
    """The EIM training set: the snapshot parameters plus :func:`eim_grid` (default
    4 (n_train - 1) + 1 points). Only the contact operators are evaluated there (no HF
    solve), so it can be much denser (Benaceur et al.: 61, 150)."""
    return np.vstack([np.asarray(mus_train), eim_grid(scene, options, len(mus_train))])


def primal_basis(reg: Registry, config: ReduceConfig, U: np.ndarray, X: Any,
                 progress: Callable[[str], None] = _progress) -> Any:
    """The registered primal compressor ``config.primal`` on the displacement snapshots
    ``U`` in the X inner product (size ``config.N``, else tolerance ``config.tol_pod``);
    a non-finite basis raises :class:`DivergedError`."""
    progress(f"primal {config.primal}")
    primal = reg.create("primal", config.primal)(
        U, X, tol=None if config.N else config.tol_pod, n=config.N)
    check_finite(f"primal compressor {config.primal!r}: the basis", primal.Z)
    return primal


def primal_histories(primal: Any) -> dict[str, Any]:
    """The primal compressor's history as a stage reports it: ``pod_singular_values`` and
    the rest under ``primal``."""
    return {"pod_singular_values": primal.history.get("singular_values", []),
            "primal": {k: v for k, v in primal.history.items() if k != "singular_values"}}


def training_snapshots(scene: Scene, config: ReduceConfig, formulation: str, solver: str,
                       progress: Callable[[str], None] = _progress,
                       snapshot_progress: bool = False, registry: Registry | None = None,
                       validation: bool = True) -> tuple[np.ndarray, Any, np.ndarray, Any]:
    """``(mus_train, train, mus_valid, valid)``: the training / validation sets of ``config``
    and their HF snapshots (:func:`rbbench.hf.snapshots.compute.compute_snapshots`, cached on disk;
    ``validation = False``: ``valid`` is None)."""
    mus_train = parameter_set(scene, "train", config.n_train)
    mus_valid = parameter_set(scene, "valid", config.n_valid)
    snap_kw = dict(backend=config.backend, formulation=formulation, solver=solver,
                   cache_dir=Path(config.cache_dir), n_jobs=config.n_jobs,
                   progress=snapshot_progress, component_options=config.component_options,
                   registry=registry)
    n_valid = len(mus_valid) if validation else 0
    progress(f"HF snapshots ({formulation}): {len(mus_train)} training, {n_valid} "
             "validation")
    with keep_workers():  # the validation call reuses the training call's workers
        train = compute_snapshots(scene, mus_train, **snap_kw)
        valid = compute_snapshots(scene, mus_valid, **snap_kw) if validation else None
    return mus_train, train, mus_valid, valid


__getattr__ = deprecated_names(__name__)  # names that left this module (rbbench._compat)

"""The Python face of rbbench: thin functions over the layers (``import rbbench``).

``rbbench.load_scene``, :func:`solve`, :func:`reduce`, :func:`run` and
:func:`load_results` are what ``rbbench solve``, ``rbbench reduce``, ``rbbench run`` and
``rbbench report`` do, without the command line. ``rbbench/__init__.py`` imports this
module on first use; each function imports its layer when it is called, so
``import rbbench`` stays cheap and imports no finite-element backend.

Examples
--------
>>> import rbbench
>>> scene = rbbench.load_scene("membrane_obstacle")
>>> sol = rbbench.solve(scene, mu=[0.3, 5.0])
>>> sol.result.converged
True
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rbbench.scene.linear import is_linear
from rbbench.scene.loading import Scene, SceneError, load_scene
from rbbench.scene.parameters import FieldError

if TYPE_CHECKING:
    import pandas as pd

    from rbbench.bench.matrix import Matrix
    from rbbench.bench.runner import RunSummary
    from rbbench.hf.model import HFSolution
    from rbbench.rb.config import ReduceConfig
    from rbbench.rb.offline import ReduceResult
    from rbbench.registry import Registry

__all__ = ["linear_config", "load_results", "load_scene", "reduce", "run", "solve"]


def as_scene(scene: str | Path | Scene) -> Scene:
    """A :class:`~rbbench.scene.loading.Scene` from a shipped scene's name, a scene file or a
    scene (returned as it is)."""
    return scene if isinstance(scene, Scene) else load_scene(scene)


def solve(scene: str | Path | Scene, mu: Any = None, backend: str = "skfem",
          formulation: str = "mixed", solver: str | None = None, *,
          backend_options: dict | None = None, formulation_options: dict | None = None,
          **options: Any) -> HFSolution:
    """One high-fidelity solve (``rbbench solve``).

    Parameters
    ----------
    scene : str, Path or Scene
        A shipped scene's name (``"membrane_obstacle"``), a scene file, or a loaded scene
        (:func:`rbbench.load_scene`, e.g. with overrides).
    mu : array_like or dict, optional
        The parameter, checked against the scene's domain (default: the scene default).
    backend, formulation : str
        Registered backend and formulation (``rbbench plugins``).
    solver : str, optional
        Registered solver (default: the formulation's own, ``ssn`` for mixed, ``newton``
        for Nitsche).
    backend_options, formulation_options : dict, optional
        Constructor options (``--backend-option``, ``--formulation-option``), e.g.
        ``{"mesh": "skfem"}`` for NGSolve, ``{"gamma0": 1.0}`` for Nitsche.
    **options
        Further keywords of :func:`rbbench.hf.model.solve_hf`: ``registry``,
        ``solver_options``, ``progress``.

    Returns
    -------
    HFSolution
        ``.result`` (``u``, ``lam``, ``converged``), ``.metrics`` (the numbers of
        ``summary.json``), ``.disc``, ``.problem``, ``.times``.
        A linear scene (``thermal_block``, ``heat_robin``; no contact):
        :func:`rbbench.hf.linear.solve.solve_linear_hf`, ``.problem`` a
        :class:`~rbbench.hf.linear.model.LinearProblem`, ``.metrics`` without contact fields.

    Raises
    ------
    ValueError
        Before any HF work: ``mu`` outside the domain or not numbers
        (:class:`~rbbench.scene.loading.SceneError`), component options the component does
        not take (:class:`~rbbench.scene.parameters.FieldError`), a solver of another
        formulation.
    rbbench.registry.UnknownComponentError
        Before any HF work, for a component name that is not registered.
    """
    from rbbench.hf.components import check_component_options, check_names, make_components
    from rbbench.hf.model import solve_hf
    from rbbench.registry import default_registry

    sc = as_scene(scene)
    reg = options.get("registry") or default_registry()
    if mu is not None:  # checked before any HF work, as the names and options below
        sc.check_mu(mu)
    check_component_options(reg, "backend", backend, backend_options or {})
    if is_linear(sc):  # no contact: one sparse solve (rbbench.hf.linear.solve)
        from rbbench.hf.linear.solve import solve_linear_hf

        if solver is not None or formulation_options:
            raise SceneError(f"{sc.path}: a linear scene has one direct solve: no solver or "
                             "formulation options")
        return solve_linear_hf(sc, mu, backend, formulation, options.get("registry"),
                               backend_options, options.get("progress", lambda m: None))
    check_names(sc, reg, backend, formulation, solver)
    if formulation_options:
        try:
            reg.create("formulation", formulation, **formulation_options)
        except (TypeError, ValueError) as exc:
            raise FieldError("", "formulation_options", formulation_options, str(exc)) from None
    if backend_options or formulation_options:
        options["components"] = make_components(
            sc, backend, formulation, solver, options.get("registry"),
            options.get("solver_options"),
            component_options={"backend": dict(backend_options or {}),
                               "formulation": dict(formulation_options or {})})
    return solve_hf(sc, mu, backend=backend, formulation=formulation, solver=solver, **options)


def reduce(scene: str | Path | Scene, *, progress: Callable[[str], None] | None = None,
           snapshot_progress: bool = False, registry: Registry | None = None,
           **fields: Any) -> ReduceResult:
    """Build a reduced model offline and validate it (``rbbench reduce``).

    Parameters
    ----------
    scene : str, Path or Scene
        A shipped scene's name, a scene file, or a loaded scene.
    progress : callable, optional
        Receives one line per stage (default: silent).
    snapshot_progress : bool
        Show a progress bar of the HF snapshots (stderr).
    registry : Registry, optional
        The components (default: the discovered plugins).
    **fields
        The fields every formulation shares (:class:`rbbench.rb.config.ReduceConfig`:
        ``formulation``, ``backend``, ``solver``, ``primal``, ``hyper``, ``N``, ``n_train``,
        ``n_valid``, ``online_repeats``, ...) and the formulation's own options (mixed:
        ``dual``, ``R``, ``stabilizer``, ... :class:`rbbench.rb.mixed.options.MixedOptions`;
        on a friction scene :class:`rbbench.rb.friction.options.FrictionOptions`; Nitsche:
        :class:`rbbench.rb.nitsche.options.NitscheOptions`; a linear scene takes none).
        ``formulation`` defaults to ``linear`` on a linear scene, ``mixed`` otherwise;
        ``solver`` to the formulation's own for the scene's friction law.

    Returns
    -------
    ReduceResult
        Errors, inf-sup constants and timings over the validation set (``.summary()``: the
        flat ``result.json``), and the reduced model (``.model``, a
        :class:`rbbench.interfaces.Model`).

    Raises
    ------
    ValueError
        Before any HF work, for an option the formulation does not take
        (:class:`~rbbench.rb.config.OptionError`, naming the option and the formulations
        that take it), a value of the wrong type or outside its range
        (:class:`~rbbench.scene.parameters.FieldError`, naming the field and what is valid)
        or a choice the scene cannot take (:class:`~rbbench.scene.loading.SceneError`).
    rbbench.registry.UnknownComponentError
        Before any HF work, for a component name that is not registered (listing the
        registered ones).
    """
    from rbbench.rb.config import make_config
    from rbbench.rb.offline import reduce as reduce_offline

    kwargs = {"progress": progress} if progress is not None else {}
    return reduce_offline(as_scene(scene), make_config(**fields), registry=registry,
                          snapshot_progress=snapshot_progress, **kwargs)


def linear_config(scene: Scene, **fields: Any) -> ReduceConfig:
    """Deprecated (goes in rbbench 0.3): :func:`rbbench.rb.config.make_config` with
    ``formulation = "linear"``; :func:`reduce` needs neither."""
    import warnings

    from rbbench.rb.config import make_config

    warnings.warn("rbbench.api.linear_config is deprecated: rbbench.reduce(scene, ...) takes "
                  "the fields directly (rbbench.rb.config.make_config builds a ReduceConfig)",
                  DeprecationWarning, stacklevel=2)
    return make_config(**{**fields, "formulation": "linear"})


def run(matrix: str | Path | Matrix, out: str | Path | None = None,
        executor: str = "processes", jobs: int | None = None, *,
        select: Iterable[str] = (), sets: Iterable[str] = (), retry: Iterable[str] = (),
        csv: bool = False, cache_dir: str | Path | None = None, progress: bool = True,
        executor_options: dict | None = None,
        registry: Registry | None = None) -> RunSummary:
    """Run a matrix of cases, one results row each, resumable (``rbbench run``).

    Parameters
    ----------
    matrix : str, Path or Matrix
        A shipped matrix's name (``"quick"``), a matrix file, or a loaded
        :class:`~rbbench.bench.matrix.Matrix`.
    out : str or Path, optional
        The run directory (default ``results/<matrix name>``); finished cases found there
        are kept.
    executor : str
        A registered executor: ``serial``, ``processes``, ``dask``.
    jobs : int, optional
        Concurrent cases (default: the CPUs available).
    select : iterable of str
        ``ROLE=NAME[,NAME]`` filters (``--select``, globs allowed), when loading a file.
    sets : iterable of str
        ``FIELD=VALUE`` overrides of the ``[reduce]`` fields (``--set``), when loading.
    retry : iterable of str
        Recompute finished cases with these statuses (e.g. ``"error"``).
    csv : bool
        Also write ``results.csv``.
    cache_dir : str or Path, optional
        HF snapshot cache (default ``.rbbench_cache``).
    progress : bool
        Show a progress bar.
    executor_options : dict, optional
        Executor options, e.g. ``{"address": ...}`` for a Dask scheduler.
    registry : Registry, optional
        The components (default: the discovered plugins).

    Returns
    -------
    RunSummary
        ``.out_dir`` (read it with :func:`load_results`), counts per status, cases computed
        and kept.
    """
    from rbbench.bench.matrix import Matrix, load_matrix
    from rbbench.bench.runner import run_matrix
    from rbbench.registry import default_registry

    reg = registry or default_registry()
    if not isinstance(matrix, Matrix):
        matrix = load_matrix(matrix, selectors=tuple(select), sets=tuple(sets), registry=reg)
    out_dir = Path(out) if out is not None else Path("results") / matrix.name
    return run_matrix(matrix, out_dir, executor=executor, jobs=jobs, registry=reg,
                      retry=list(retry), csv=csv, cache_dir=cache_dir, progress=progress,
                      executor_options=executor_options)


def load_results(path: str | Path, notes: list[str] | None = None) -> pd.DataFrame:
    """The results table of a run, typed (:func:`rbbench.bench.results.load_results`).

    Parameters
    ----------
    path : str or Path
        A run directory (:func:`run`'s ``out_dir``) or a ``results.parquet`` /
        ``results.csv`` file.
    notes : list of str, optional
        Receives what was odd (e.g. undeclared columns, ignored).

    Returns
    -------
    pandas.DataFrame
        One row per case and repetition, the columns of :data:`rbbench.bench.schema.COLUMNS`
        with their Parquet dtypes (``float64``, ``Int64``, ``boolean``, ``string``).
    """
    from rbbench.bench.results import load_results as load_typed

    return load_typed(path, notes)

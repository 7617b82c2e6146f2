"""HF snapshots ``(u(mu_p), lam(mu_p))``, computed once and cached on disk.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slide "Finite training set and snapshots": every compressor
and stabiliser works on the same snapshots, so they are computed once per *content* and
reused.

The points missing from the cache (:mod:`rbbench.hf.snapshots.cache`, under the key of
:func:`rbbench.hf.snapshots.key.snapshot_key`) are solved in this process or in local worker
processes (:mod:`rbbench.runtime.workers`), one BLAS thread each; every solve that returned is
cached, and a point that failed is a NaN column with its error (:class:`SnapshotError` lists
them unless ``strict=False``).
"""

from __future__ import annotations

import multiprocessing
import os
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rbbench.hf.components import make_components, warm_up
from rbbench.hf.model import hf_vectors, solve_hf
from rbbench.hf.snapshots.cache import (
    Snapshot,
    SnapshotError,
    SnapshotSet,
    assemble_snapshot_set,
    cache_path,
    error_snapshot,
    load_if_complete,
    save_snapshot,
    write_key_file,
)
from rbbench.hf.snapshots.key import key_payload, payload_key
from rbbench.registry import default_registry
from rbbench.runtime.threads import limit_blas_threads
from rbbench.runtime.workers import die_with_parent, release_free_heap, start_method, worker_pool
from rbbench.scene.friction import friction_of

__all__ = ["compute_snapshots", "n_cpus"]


# ---------------------------------------------------------------------------
# solving
# ---------------------------------------------------------------------------
def _solve_one(scene: Any, mu: np.ndarray, names: tuple[str, str, str], components,
               path: Path) -> Snapshot:
    """Solve at ``mu``; store the result unless the solve raised."""
    backend, formulation, solver = names
    t0 = time.perf_counter()
    try:
        sol = solve_hf(scene, mu, backend=backend, formulation=formulation, solver=solver,
                       components=components, floor=False)
    except Exception as exc:  # one failing mu must not lose the others
        return error_snapshot(mu, f"{type(exc).__name__}: {exc}", time.perf_counter() - t0)
    v = hf_vectors(sol)
    snap = Snapshot(mu=np.asarray(mu, dtype=float), u=v.u.copy(), lam=v.lam.copy(),
                    iterations=sol.iterations, stop_reason=str(sol.stop_reason),
                    time_s=sol.time_s, free=np.asarray(sol.problem.free, dtype=np.int64),
                    n_dofs=int(sol.disc.n_dofs),
                    lam_t=np.zeros(0) if v.lam_t is None else v.lam_t.copy())
    save_snapshot(path, snap)  # non-converged solves are deterministic: cached too
    return snap


# one set of components per worker process, built at its start-up (or inherited)
_WORKER: dict[str, Any] = {}

#: the components this process built last (``key``, ``registry``, ``components``): reused
#: by the next call with the same key (reduce: training, then validation snapshots) and,
#: built before a ``fork`` pool starts, inherited by its workers (no meshing in them)
_COMPONENTS: dict[str, Any] = {}


def _components(scene: Any, names: tuple[str, str, str], solver_options: dict | None,
                component_options: dict | None, registry: Any, key: str) -> tuple:
    """The components of ``key`` (:func:`snapshot_key`), meshed and warmed up once per
    process: the last set is kept and reused for the same key and registry.

    Warm-up: :func:`rbbench.hf.components.warm_up` (:meth:`rbbench.interfaces.Backend.warm_up`:
    the mu-independent operators, built at the first discretisation otherwise, e.g. the
    inner product and the reference stiffness terms: 0.28 s at Hertz level 0), so that no
    snapshot's stored ``time_s`` holds that one-off work.
    """
    if _COMPONENTS.get("key") != key or _COMPONENTS.get("registry") is not registry:
        _COMPONENTS.clear()
        comps = make_components(scene, *names, solver_options=solver_options,
                                component_options=component_options, registry=registry)
        warm_up(comps[0])
        _COMPONENTS.update(key=key, registry=registry, components=comps)
    return _COMPONENTS["components"]


def _init_worker(scene: Any, names: tuple[str, str, str], solver_options: dict | None,
                 threads: int | None, component_options: dict | None = None,
                 registry: Any = None, key: str = "", parent: int | None = None) -> None:
    """Worker start-up: die with the parent, cap the BLAS threads, take the components
    inherited from the parent (fork) or build them now, once (spawn, forkserver).
    ``parent``: the pid that started the pool (``None`` with forkserver, whose server is
    the parent); if it has already gone, this worker exits at once."""
    die_with_parent()  # a kept pool's idle workers must not outlive their parent
    if parent is not None and os.getppid() != parent:  # it died before the prctl call
        os._exit(1)
    _WORKER.clear()
    _WORKER.update(scene=scene, names=names, components=None, error="")
    if threads:
        _WORKER["thread_limit"] = limit_blas_threads(threads)
    try:  # a forked worker finds the parent's components under the key: no meshing
        _WORKER["components"] = _components(scene, names, solver_options, component_options,
                                            registry, key)
    except Exception as exc:  # reported by every task: one failure must not break the pool
        _WORKER["error"] = f"building components: {type(exc).__name__}: {exc}"


def _worker_task(mu: np.ndarray, path: Path) -> Snapshot:
    if _WORKER["components"] is None:
        return error_snapshot(mu, _WORKER["error"])
    return _solve_one(_WORKER["scene"], mu, _WORKER["names"], _WORKER["components"], path)


def compute_snapshots(scene: Any, mus: Sequence | np.ndarray, backend: str = "skfem",
                      formulation: str = "mixed", solver: str = "ssn",
                      cache_dir: Path | str = Path(".rbbench_cache"), n_jobs: int | None = None,
                      progress: bool = True, strict: bool = True,
                      solver_options: dict | None = None,
                      mp_context: str | None = None,
                      blas_threads: int | None = None,
                      component_options: dict | None = None,
                      registry: Any = None) -> SnapshotSet:
    """HF snapshots at every row of ``mus``, from the cache where present.

    Parameters
    ----------
    scene : Scene
    mus : (P, p) array_like
        Parameter values (checked against the domain). A 1-D array is read as one
        value per row when the scene has one parameter.
    backend, formulation, solver : str
        Registered component names.
    cache_dir : path
        Root of the cache; the files go to ``cache_dir / snapshot_key(...)``.
    n_jobs : int, optional
        Local worker processes (default: the CPUs available); ``1`` solves in this
        process. Components are built once per process, kept for the next call with the
        same key, inherited by ``fork`` workers (:meth:`_Run.parallel`).
    progress : bool
        Show a tqdm progress bar.
    strict : bool
        If true (default), raise :class:`SnapshotError` after all solves finished when
        any snapshot did not converge: a reduced basis on a non-converged snapshot is
        wrong. Finished snapshots are cached either way.
    solver_options : dict, optional
        Passed to the solver; part of the cache key.
    component_options : dict, optional
        ``{"backend": {...}, "formulation": {...}}`` constructor options
        (:func:`rbbench.hf.components.make_components`); part of the cache key when given.
    registry : Registry, optional
        Where the component names are looked up (default: the discovered plugins).
    mp_context : {"fork", "forkserver", "spawn"}, optional
        Start method (the platform's by default): :func:`rbbench.runtime.workers.start_method`.
    blas_threads : int, optional
        BLAS threads per worker process (default ``cpu_count // n_jobs``, at least 1;
        see :func:`limit_blas_threads`); ``0`` leaves them alone. Not applied with
        ``n_jobs = 1``.

    Returns
    -------
    SnapshotSet
    """
    mus = _parameter_rows(scene, mus)
    names = (backend, formulation, solver)
    payload = key_payload(scene, backend, formulation, solver, solver_options,
                           component_options, registry)
    key = payload_key(payload)  # = snapshot_key(...), from the payload built once
    root = Path(cache_dir)
    write_key_file(root / key, scene, payload)
    paths = [cache_path(root, key, mu) for mu in mus]

    need_t = friction_of(scene).active
    snaps: list[Snapshot | None] = [load_if_complete(p, mu, need_t)
                                    for p, mu in zip(paths, mus, strict=True)]
    todo = [i for i, s in enumerate(snaps) if s is None]
    asked = (n_jobs, blas_threads)  # what a kept pool is matched on (not the capped count)
    n_jobs = max(1, min(n_cpus() if n_jobs is None else int(n_jobs), len(todo)))
    if todo:  # unknown component names fail here, not once per parameter in the workers
        _check_names(registry, names)

    run = _Run(scene, mus, paths, names, solver_options, component_options, registry, progress,
               key)
    if todo and n_jobs == 1:
        run.serial(snaps, todo)
    elif todo:
        threads = max(1, n_cpus() // n_jobs) if blas_threads is None \
            else int(blas_threads)
        run.parallel(snaps, todo, n_jobs, mp_context, threads, asked)

    out = assemble_snapshot_set(mus, snaps, key, root, n_computed=len(todo))
    if strict:
        _raise_failures(scene, mus, snaps, names, root / key, out)
    return out


def _check_names(registry: Any, names: tuple[str, str, str]) -> None:
    """Raise the registry's error for an unknown backend / formulation / solver name."""
    reg = registry or default_registry()
    for role, name in zip(("backend", "formulation", "solver"), names, strict=True):
        reg.get(role, name)


def _raise_failures(scene: Any, mus: np.ndarray, snaps: list[Snapshot | None],
                    names: tuple[str, str, str], where: Path, out: SnapshotSet) -> None:
    """:class:`SnapshotError` listing the snapshots that did not converge, if any."""
    failed = [(mus[i], s.error or s.stop_reason) for i, s in enumerate(snaps)
              if s is not None and not s.converged]
    if failed:
        backend, formulation, solver = names
        lines = "\n".join(f"  mu = {m.tolist()}: {why}" for m, why in failed)
        raise SnapshotError(
            f"{len(failed)} of {len(mus)} HF snapshots did not converge (scene "
            f"{scene.name!r}, {backend}/{formulation}/{solver}); every solve that returned is "
            f"cached under {where}. Pass strict=False to get the set anyway.\n{lines}",
            failed, out)


def _parameter_rows(scene: Any, mus: Sequence | np.ndarray) -> np.ndarray:
    """``mus`` as checked (P, p) rows (a 1-D array: one value per row for one parameter)."""
    mus = np.asarray(mus, dtype=float)
    if mus.size == 0:
        mus = mus.reshape(0, len(scene.parameters))
    elif mus.ndim == 1:
        mus = mus.reshape(-1, 1) if len(scene.parameters) == 1 else mus.reshape(1, -1)
    return np.array([scene.check_mu(m) for m in mus]).reshape(len(mus), len(scene.parameters))


@dataclass
class _Run:
    """The solves of :func:`compute_snapshots` that the cache did not hold, in this process
    or in worker processes; results go into ``snaps[i]`` for ``i`` in ``todo``."""

    scene: Any
    mus: np.ndarray
    paths: list[Path]
    names: tuple[str, str, str]
    solver_options: dict | None
    component_options: dict | None
    registry: Any
    progress: bool
    key: str

    def components(self) -> tuple:
        """This process's components of the key (:func:`_components`)."""
        return _components(self.scene, self.names, self.solver_options,
                           self.component_options, self.registry, self.key)

    def serial(self, snaps: list[Snapshot | None], todo: list[int]) -> None:
        """Solve in this process (one set of components)."""
        bar = None
        try:
            bar = _progress_bar(self.progress, self.scene.name, len(self.mus), len(todo))
            components = self.components()
            for i in todo:
                snaps[i] = _solve_one(self.scene, self.mus[i], self.names, components,
                                      self.paths[i])
                if bar is not None:
                    bar.update()
        finally:
            if bar is not None:
                bar.close()

    def parallel(self, snaps: list[Snapshot | None], todo: list[int], n_jobs: int,
                 mp_context: str | None, threads: int, asked: tuple) -> None:
        """Solve in ``n_jobs`` worker processes, one task per parameter (an idle worker
        takes the next one: balanced), results in their places. The components are built
        once: here before a ``fork`` pool (the workers inherit them; the free heap is
        released first, :func:`~rbbench.runtime.workers.release_free_heap`, and this
        process's BLAS pools are capped at the workers' threads during the call that
        starts the pool, so the workers inherit that too,
        :func:`~rbbench.runtime.threads.capped_for_fork`), else once per worker at its
        start-up. Inside :func:`~rbbench.runtime.workers.keep_workers` the pool serves the
        next call with the same key too; if such a reused pool loses a
        worker, the parameters it lost are solved once more in a new pool, so that a kept
        pool never fails a call that a new one would not. A kept pool is matched on the
        ``asked`` workers and threads, not on ``n_jobs`` (capped at the parameters to
        solve), so it keeps the size of the call that started it."""
        ctx = multiprocessing.get_context(start_method(mp_context))  # fork: main thread only
        ident = (self.key, asked, ctx.get_start_method())
        bar: list = []
        try:
            died, reused = self._in_pool(snaps, todo, ident, ctx, (n_jobs, threads), bar,
                                         fresh=False)
            if died and reused:
                self._in_pool(snaps, died, ident, ctx, (n_jobs, threads), bar, fresh=True)
        finally:
            if bar and bar[0] is not None:
                bar[0].close()

    def _in_pool(self, snaps: list[Snapshot | None], todo: list[int], ident: tuple,
                 ctx: Any, size: tuple[int, int], bar: list, fresh: bool
                 ) -> tuple[list[int], bool]:
        """Solve ``todo`` in a pool (:func:`~rbbench.runtime.workers.worker_pool`; a new one
        has ``size = (workers, BLAS threads)``); returns the indices whose worker died
        (error rows now: also those not submitted because the pool broke meanwhile) and
        whether the pool was reused."""
        died: list[int] = []
        cap = size[1] if ctx.get_start_method() == "fork" else 0  # inherited by the workers
        with worker_pool(ident, self.registry, lambda: self._pool(ctx, *size),
                         fresh=fresh, blas_cap=cap) as (pool, reused):
            futures = {}
            for k, i in enumerate(todo):
                try:
                    futures[pool.submit(_worker_task, self.mus[i], self.paths[i])] = i
                except BrokenProcessPool as exc:  # a worker died before all were submitted
                    for j in todo[k:]:
                        snaps[j] = self._died(j, exc)
                    died.extend(todo[k:])
                    break
            if not bar:  # the bar only after the workers started: no fork with a thread
                bar.append(_progress_bar(self.progress, self.scene.name, len(self.mus),
                                         len(todo)))
            for fut in as_completed(futures):
                i = futures[fut]
                try:
                    snaps[i] = fut.result()
                except BrokenProcessPool as exc:  # a worker died (e.g. killed)
                    snaps[i] = self._died(i, exc)
                    died.append(i)
                    continue
                if bar[0] is not None:
                    bar[0].update()
        return died, reused

    def _died(self, i: int, exc: BaseException) -> Snapshot:
        """The error row of parameter ``i``, lost with a worker process."""
        return error_snapshot(self.mus[i], f"worker process died: {exc}")

    def _pool(self, ctx: Any, n_jobs: int, threads: int) -> ProcessPoolExecutor:
        """A new pool; with ``fork``, this process's components first (inherited)."""
        if ctx.get_start_method() == "fork":
            try:
                self.components()
            except Exception:  # noqa: BLE001 - the workers retry and report it per mu
                _COMPONENTS.clear()
            release_free_heap()
        parent = None if ctx.get_start_method() == "forkserver" else os.getpid()
        return ProcessPoolExecutor(n_jobs, mp_context=ctx, initializer=_init_worker,
                                   initargs=(self.scene, self.names, self.solver_options,
                                             threads, self.component_options,
                                             self.registry, self.key, parent))


def n_cpus() -> int:
    """The number of CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))  # the CPUs this process may use
    except AttributeError:  # pragma: no cover - not on Linux
        return os.cpu_count() or 1


def _progress_bar(progress: bool, name: str, total: int, todo: int):
    if not progress:
        return None
    from tqdm.auto import tqdm

    class _Bar(tqdm):  # no monitor thread: worker processes may be forked later
        monitor_interval = 0

    return _Bar(total=total, initial=total - todo, unit="snapshot", desc=f"HF snapshots {name}")



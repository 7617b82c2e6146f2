"""HF snapshots ``(u(mu_p), lam(mu_p))``, computed once and cached on disk.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slide "Finite training set and snapshots": every compressor
and stabiliser works on the same snapshots, so they are computed once per *content* and
reused.

Cache layout::

    <cache_dir>/<key>/key.json                  what the key stands for
    <cache_dir>/<key>/mu_<repr(mu_1)>_<...>.npz  one file per parameter value

``key`` (:func:`snapshot_key`) is a sha256 over everything that determines a
snapshot: the scene content (its validated data minus the parts that cannot
change a solution: ``[sampling]``, ``[reference]`` and ``scene.description``;
overrides are covered because they change the content), the backend,
formulation and solver names, the solver options and the rbbench version. The
parameter value is in the file name with full (round-trip) precision. A friction
solve also stores the tangential multipliers ``lam_t`` (``SnapshotSet.LAM_T``; the key is
unchanged, a cached friction snapshot without them is recomputed). Files
are written atomically (temporary file + :func:`os.replace`), so an
interrupted run loses nothing that finished and never leaves a partial file.
"""

from __future__ import annotations

import json
import multiprocessing
import os
import tempfile
import time
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rbbench.hf.components import make_components, warm_up
from rbbench.hf.model import hf_vectors, solve_hf
from rbbench.hf.snapshots.key import key_payload, payload_key, snapshot_key
from rbbench.registry import default_registry
from rbbench.runtime.threads import limit_blas_threads
from rbbench.runtime.workers import die_with_parent, release_free_heap, worker_pool
from rbbench.scene.friction import friction_of

__all__ = ["Snapshot", "SnapshotError", "SnapshotSet", "atomic_write", "cache_path",
           "compute_snapshots", "limit_blas_threads", "load_snapshot", "n_cpus",
           "save_snapshot", "snapshot_key"]

class SnapshotError(RuntimeError):
    """Some snapshots did not converge (or raised); ``failed`` lists ``(mu, reason)``."""

    def __init__(self, message: str, failed: list[tuple[np.ndarray, str]],
                 snapshots: SnapshotSet | None = None):
        super().__init__(message)
        self.failed = failed
        self.snapshots = snapshots


@dataclass
class Snapshot:
    """One HF solution: free-dof displacement ``u`` and multipliers ``lam`` at ``mu``
    (a friction solve: ``lam`` = lam_n and ``lam_t`` per collocation node; else empty)."""

    mu: np.ndarray
    u: np.ndarray
    lam: np.ndarray
    iterations: int
    stop_reason: str
    time_s: float
    free: np.ndarray | None = None
    n_dofs: int = 0
    error: str = ""  # exception text when the solve raised (then u, lam are empty)
    lam_t: np.ndarray = field(default_factory=lambda: np.empty(0))

    @property
    def converged(self) -> bool:
        return self.stop_reason == "converged"


def _error_snapshot(mu: np.ndarray, error: str, time_s: float = 0.0) -> Snapshot:
    """The placeholder of a solve that raised or was lost: no data, stop reason "error"."""
    return Snapshot(mu=mu, u=np.empty(0), lam=np.empty(0), iterations=0, stop_reason="error",
                    time_s=time_s, error=error)


@dataclass
class SnapshotSet:
    """Snapshots of a parameter set, column ``p`` for ``mus[p]``.

    Attributes
    ----------
    mus : (P, p)
    U : (n_free, P)
        Free-dof displacements (``problem.free`` gives their global numbers); a
        column is NaN where the solve raised.
    LAM : (m, P)
        Contact multipliers (friction: the normal ones, lam_n).
    LAM_T : (m, P) or None
        Tangential multipliers of a friction solve (None when the solver gives none).
    stop_reasons : list of str
        One of :data:`rbbench.interfaces.STOP_REASONS` per column, or ``"error"``.
    iterations, times : (P,)
        Solver iterations and HF time (discretise + formulate + solve, s).
    n_dofs : int
        Number of HF dofs (all, including Dirichlet).
    free : (n_free,) int
        Global dof numbers of the rows of ``U``.
    key, cache_dir
        Cache key and directory (``cache_dir / key`` holds the files).
    n_computed : int
        How many snapshots this call computed (the rest came from the cache).
    errors : dict
        Column -> exception text for solves that raised.
    """

    mus: np.ndarray
    U: np.ndarray
    LAM: np.ndarray
    stop_reasons: list[str]
    iterations: np.ndarray
    times: np.ndarray
    n_dofs: int
    free: np.ndarray
    key: str
    cache_dir: Path
    n_computed: int = 0
    errors: dict[int, str] = field(default_factory=dict)
    LAM_T: np.ndarray | None = None

    @property
    def P(self) -> int:
        return int(self.mus.shape[0])

    @property
    def n_free(self) -> int:
        return int(self.U.shape[0])

    @property
    def converged(self) -> np.ndarray:
        """Boolean mask of the converged columns."""
        return np.array([r == "converged" for r in self.stop_reasons], dtype=bool)


# ---------------------------------------------------------------------------
# cache files
# ---------------------------------------------------------------------------
def _mu_name(mu: np.ndarray) -> str:
    # repr of a Python float is the shortest string that round-trips exactly
    return "mu_" + "_".join(repr(float(x)) for x in np.atleast_1d(mu)) + ".npz"


def cache_path(cache_dir: Path | str, key: str, mu: np.ndarray) -> Path:
    """The cache file of ``mu`` under ``cache_dir / key``."""
    return Path(cache_dir) / key / _mu_name(mu)


def atomic_write(path: Path, write) -> None:
    """Write ``path`` atomically: ``write(fh)`` fills a temporary file in the same
    directory, flushed to disk, then renamed over ``path`` (removed on failure). The file
    gets the usual permissions (``0o666`` less the umask), as ``open`` would give."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=path.name + ".", suffix=".tmp", dir=path.parent)
    umask = os.umask(0)
    os.umask(umask)
    try:
        os.fchmod(fd, 0o666 & ~umask)
        with os.fdopen(fd, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise


def save_snapshot(path: Path, snap: Snapshot) -> None:
    """Write ``snap`` to ``path`` atomically (``np.savez``)."""

    def write(fh):
        np.savez(fh, mu=np.asarray(snap.mu, dtype=float), u=np.asarray(snap.u, dtype=float),
                 lam=np.asarray(snap.lam, dtype=float), iterations=np.int64(snap.iterations),
                 stop_reason=np.str_(snap.stop_reason), time_s=np.float64(snap.time_s),
                 free=np.asarray(snap.free if snap.free is not None else [], dtype=np.int64),
                 n_dofs=np.int64(snap.n_dofs), lam_t=np.asarray(snap.lam_t, dtype=float))

    atomic_write(path, write)


def load_snapshot(path: Path, need_lam_t: bool = False) -> Snapshot:
    """Read a snapshot file written by :func:`save_snapshot` (``need_lam_t``: a KeyError
    when the file predates the stored ``lam_t``)."""
    with np.load(path, allow_pickle=False) as z:
        if need_lam_t and "lam_t" not in z.files:
            raise KeyError(f"{path}: no lam_t")
        lam_t = z["lam_t"] if "lam_t" in z.files else np.empty(0)
        return Snapshot(mu=z["mu"], u=z["u"], lam=z["lam"], iterations=int(z["iterations"]),
                        stop_reason=str(z["stop_reason"]), time_s=float(z["time_s"]),
                        free=z["free"], n_dofs=int(z["n_dofs"]), lam_t=lam_t)


def _try_load(path: Path, mu: np.ndarray, need_lam_t: bool = False) -> Snapshot | None:
    if not path.exists():
        return None
    try:
        snap = load_snapshot(path, need_lam_t)
    except Exception:  # unreadable, or a friction file without lam_t: recompute
        return None
    return snap if np.array_equal(snap.mu, mu) else None


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
        return _error_snapshot(mu, f"{type(exc).__name__}: {exc}", time.perf_counter() - t0)
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
        return _error_snapshot(mu, _WORKER["error"])
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
        Start method of the worker processes (default: the platform's).
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
    _write_key_file(root / key, scene, payload)
    paths = [cache_path(root, key, mu) for mu in mus]

    need_t = friction_of(scene).active
    snaps: list[Snapshot | None] = [_try_load(p, mu, need_t)
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

    out = _assemble(mus, snaps, key, root, n_computed=len(todo))
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
        ctx = multiprocessing.get_context(mp_context)
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
        return _error_snapshot(self.mus[i], f"worker process died: {exc}")

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


def _write_key_file(folder: Path, scene: Any, payload: dict[str, Any]) -> None:
    """``key.json``: the key's payload, plus where the scene came from."""
    path = folder / "key.json"
    if path.exists():
        return
    payload = {**payload, "scene_path": str(scene.path), "overrides": list(scene.overrides)}
    text = json.dumps(payload, sort_keys=True, indent=1, default=str).encode()
    atomic_write(path, lambda fh: fh.write(text))


def _assemble(mus: np.ndarray, snaps: list[Snapshot | None], key: str, root: Path,
              n_computed: int) -> SnapshotSet:
    ok = [s for s in snaps if s is not None and s.stop_reason != "error"]
    n_free = ok[0].u.size if ok else 0
    m = ok[0].lam.size if ok else 0
    free = ok[0].free if ok else np.empty(0, dtype=np.int64)
    for s in ok:
        if s.u.size != n_free or s.lam.size != m or not np.array_equal(s.free, free):
            raise ValueError(
                f"snapshot at mu = {s.mu.tolist()} has {s.u.size} free dofs and {s.lam.size} "
                f"multipliers, the first one {n_free} and {m}: sizes must not depend on mu")
    P = len(snaps)
    U = np.full((n_free, P), np.nan)
    LAM = np.full((m, P), np.nan)
    has_t = bool(ok) and all(s.lam_t.size == m for s in ok)
    LAM_T = np.full((m, P), np.nan) if has_t else None
    errors: dict[int, str] = {}
    for j, s in enumerate(snaps):
        assert s is not None
        if s.stop_reason == "error":
            errors[j] = s.error
            continue
        U[:, j] = s.u
        LAM[:, j] = s.lam
        if LAM_T is not None:
            LAM_T[:, j] = s.lam_t
    return SnapshotSet(
        mus=mus, U=U, LAM=LAM, stop_reasons=[s.stop_reason for s in snaps],  # type: ignore[union-attr]
        iterations=np.array([s.iterations for s in snaps], dtype=int),  # type: ignore[union-attr]
        times=np.array([s.time_s for s in snaps], dtype=float),  # type: ignore[union-attr]
        n_dofs=ok[0].n_dofs if ok else 0, free=free, key=key, cache_dir=root,
        n_computed=n_computed, errors=errors, LAM_T=LAM_T)

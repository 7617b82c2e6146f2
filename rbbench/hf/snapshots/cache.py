"""The snapshot records and their on-disk cache, gathered into a :class:`SnapshotSet` whose
failed columns are NaN with their error kept.

Cache layout::

    <cache_dir>/<key>/key.json                  what the key stands for
    <cache_dir>/<key>/mu_<repr(mu_1)>_<...>.npz  one file per parameter value

``key`` (:func:`rbbench.hf.snapshots.key.snapshot_key`) is a sha256 over everything that
determines a snapshot: the scene content (its validated data minus the parts that cannot
change a solution: ``[sampling]``, ``[reference]`` and ``scene.description``; overrides are
covered because they change the content), the backend, formulation and solver names, the
solver options and the rbbench version. The parameter value is in the file name with full
(round-trip) precision. A friction solve also stores the tangential multipliers ``lam_t``
(``SnapshotSet.LAM_T``; the key is unchanged, a cached friction snapshot without them is
recomputed). Files are written atomically (temporary file + :func:`os.replace`), so an
interrupted run loses nothing that finished and never leaves a partial file.
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np


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


def error_snapshot(mu: np.ndarray, error: str, time_s: float = 0.0) -> Snapshot:
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


#: the arrays of a snapshot file that its checksum covers, in order
CHECKED = ("mu", "u", "lam", "lam_t", "free", "iterations", "stop_reason", "n_dofs")


def checksum(arrays: dict[str, np.ndarray]) -> str:
    """sha256 over the dtype, shape and bytes of the :data:`CHECKED` arrays."""
    h = hashlib.sha256()
    for name in CHECKED:
        a = np.ascontiguousarray(arrays[name])
        h.update(f"{name}:{a.dtype.str}:{a.shape};".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def save_snapshot(path: Path, snap: Snapshot) -> None:
    """Write ``snap`` to ``path`` atomically (``np.savez``), with the :func:`checksum` of
    its arrays."""
    arrays = {"mu": np.asarray(snap.mu, dtype=float), "u": np.asarray(snap.u, dtype=float),
              "lam": np.asarray(snap.lam, dtype=float),
              "lam_t": np.asarray(snap.lam_t, dtype=float),
              "free": np.asarray(snap.free if snap.free is not None else [], dtype=np.int64),
              "iterations": np.int64(snap.iterations), "stop_reason": np.str_(snap.stop_reason),
              "n_dofs": np.int64(snap.n_dofs)}

    def write(fh):
        np.savez(fh, **arrays, time_s=np.float64(snap.time_s),
                 checksum=np.str_(checksum(arrays)))

    atomic_write(path, write)


def _read(path: Path) -> dict[str, np.ndarray]:
    """Every array of the snapshot file ``path``, read once."""
    with np.load(path, allow_pickle=False) as z:
        return {k: z[k] for k in z.files}


def _snapshot(data: dict[str, np.ndarray], path: Path, need_lam_t: bool) -> Snapshot:
    if need_lam_t and "lam_t" not in data:
        raise KeyError(f"{path}: no lam_t")
    return Snapshot(mu=data["mu"], u=data["u"], lam=data["lam"],
                    iterations=int(data["iterations"]), stop_reason=str(data["stop_reason"]),
                    time_s=float(data["time_s"]), free=data["free"],
                    n_dofs=int(data["n_dofs"]), lam_t=data.get("lam_t", np.empty(0)))


def load_snapshot(path: Path, need_lam_t: bool = False) -> Snapshot:
    """Read a snapshot file written by :func:`save_snapshot` (``need_lam_t``: a KeyError
    when the file predates the stored ``lam_t``)."""
    return _snapshot(_read(path), path, need_lam_t)


def _distrust(data: dict[str, np.ndarray]) -> str | None:
    """Why the arrays of a snapshot file cannot be trusted, or None (:func:`verify`)."""
    if "checksum" not in data:
        return "no checksum (an older cache file)"
    if any(name not in data for name in CHECKED) or checksum(data) != str(data["checksum"]):
        return "its checksum does not match its content (the file was modified)"
    u, lam, free = data["u"], data["lam"], data["free"]
    if not (np.isfinite(u).all() and np.isfinite(lam).all()):
        return "non-finite values"
    if free.size and u.size != free.size:
        return f"u has {u.size} entries for {free.size} free dofs"
    return None


def verify(path: Path) -> str | None:
    """Why the snapshot file ``path`` cannot be trusted, or None: no checksum (written by
    an older rbbench), a checksum that does not match its arrays (the file was modified),
    non-finite values, or arrays whose sizes disagree (``u`` against ``free``)."""
    return _distrust(_read(path))


def load_if_complete(path: Path, mu: np.ndarray, need_lam_t: bool = False) -> Snapshot | None:
    """The cached snapshot at ``path`` for ``mu``, or None (then it is recomputed): no file,
    an unreadable one, a friction file without ``lam_t``, another mu, or a file
    :func:`verify` does not trust (a warning names the file and why, unless it is merely an
    older cache file). The file is read once."""
    if not path.exists():
        return None
    try:
        data = _read(path)
        why = _distrust(data)
        if why is None:
            snap = _snapshot(data, path, need_lam_t)
    except Exception as exc:  # noqa: BLE001 - unreadable, or no lam_t: recompute
        why = f"unreadable ({type(exc).__name__})"
    if why is not None:
        if not why.startswith("no checksum") and not why.startswith("unreadable (KeyError"):
            warnings.warn(f"{path}: cached snapshot not used, recomputed: {why}",
                          RuntimeWarning, stacklevel=2)
        return None
    return snap if np.array_equal(snap.mu, mu) else None


def write_key_file(folder: Path, scene: Any, payload: dict[str, Any]) -> None:
    """``key.json``: the key's payload, plus where the scene came from."""
    path = folder / "key.json"
    if path.exists():
        return
    payload = {**payload, "scene_path": str(scene.path), "overrides": list(scene.overrides)}
    text = json.dumps(payload, sort_keys=True, indent=1, default=str).encode()
    atomic_write(path, lambda fh: fh.write(text))


def assemble_snapshot_set(mus: np.ndarray, snaps: list[Snapshot | None], key: str, root: Path,
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

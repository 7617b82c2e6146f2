"""HF snapshots ``(u(mu_p), lam(mu_p))``, computed once (in worker processes when asked,
:mod:`.compute`) and cached on disk (:mod:`.cache`) under a key of everything that determines
them (:mod:`.key`)."""

from rbbench.hf.snapshots.cache import (
    Snapshot,
    SnapshotError,
    SnapshotSet,
    atomic_write,
    cache_path,
    load_snapshot,
    save_snapshot,
)
from rbbench.hf.snapshots.compute import compute_snapshots, n_cpus
from rbbench.hf.snapshots.key import key_payload, payload_key, snapshot_key

__all__ = ["Snapshot", "SnapshotError", "SnapshotSet", "atomic_write", "cache_path",
    "compute_snapshots", "key_payload", "load_snapshot", "n_cpus", "payload_key",
    "save_snapshot", "snapshot_key"]

from rbbench._compat import deprecated_names  # noqa: E402 - names that left this path

__getattr__ = deprecated_names(__name__)

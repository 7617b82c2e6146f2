"""The cache key of HF snapshots: a sha256 over everything that determines a snapshot
(:mod:`rbbench.hf.snapshots.compute`, where the key is used)."""

from __future__ import annotations

import hashlib
import json
from typing import Any

import rbbench
from rbbench.registry import default_registry
from rbbench.scene.loading import key_data

__all__ = ["key_payload", "payload_key", "snapshot_key"]

#: Parts of the scene data that cannot change a snapshot (excluded from the key; the
#: ``[reduce]`` section holds reduction defaults only).
_NOT_IN_KEY = ("sampling", "reference", "reduce")


def _formulation_params(formulation: str, options: dict | None = None,
                        registry: Any = None) -> dict[str, Any]:
    """The parameters a formulation declares for the cache key (``cache_params()``, e.g.
    Nitsche's ``theta``, ``gamma0``, with ``options`` applied); ``{}`` for mixed."""
    try:
        f = (registry or default_registry()).create("formulation", formulation,
                                                    **(options or {}))
    except Exception:  # noqa: BLE001 - unknown names are reported by compute_snapshots
        return {}
    params = getattr(f, "cache_params", None)
    return dict(params()) if callable(params) else {}


def key_payload(scene: Any, backend: str, formulation: str, solver: str,
                 solver_options: dict | None,
                 component_options: dict | None = None,
                 registry: Any = None) -> dict[str, Any]:
    data = {k: v for k, v in key_data(scene.data).items() if k not in _NOT_IN_KEY}
    if "scene" in data:
        data["scene"] = {k: v for k, v in data["scene"].items() if k != "description"}
    payload = {"scene": data, "backend": backend, "formulation": formulation, "solver": solver,
               "solver_options": dict(sorted((solver_options or {}).items())),
               "rbbench": rbbench.__version__}
    copts = component_options or {}
    params = _formulation_params(formulation, copts.get("formulation"), registry)
    if params:  # only then: the keys of existing (mixed) caches are unchanged
        payload["formulation_params"] = params
    for role in ("backend", "formulation"):  # likewise only when given
        if copts.get(role):
            payload[f"{role}_options"] = dict(sorted(copts[role].items()))
    return payload


def snapshot_key(scene: Any, backend: str = "skfem", formulation: str = "mixed",
                 solver: str = "ssn", solver_options: dict | None = None,
                 component_options: dict | None = None, registry: Any = None) -> str:
    """sha256 (hex, 24 characters) of everything that determines a snapshot.

    Unlike :meth:`Scene.fingerprint`, the ``[sampling]`` and ``[reference]`` tables and
    the scene description are left out: changing the training set size or seed must
    reuse the snapshots already computed.
    """
    return payload_key(key_payload(scene, backend, formulation, solver, solver_options,
                                     component_options, registry))


def payload_key(payload: dict[str, Any]) -> str:
    blob = json.dumps(payload, sort_keys=True, default=str).encode()
    return hashlib.sha256(blob).hexdigest()[:24]

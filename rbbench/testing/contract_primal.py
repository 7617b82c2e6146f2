"""Contract of the primal-compressor role (:class:`rbbench.rb.compressors.PrimalBasis`)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from rbbench.registry import ComponentSpec, Registry
from rbbench.testing.contract_base import (
    EXACT_RTOL,
    ORTH_TOL,
    RoleContract,
    bool_capability,
    component_label,
    instantiate_callable,
    json_ok,
    proj_residual,
    require,
    tridiag_gram,
    unchanged,
    xorth_errors,
)

#: ``capabilities["tol"]`` of a primal compressor: what its ``tol`` bounds.
PRIMAL_TOL_KINDS = ("energy", "max")


def primal_test_data(seed: int = 0, n: int = 40, P: int = 12,
                     rank: int = 6) -> tuple[np.ndarray, sp.csr_matrix, int]:
    """Snapshots ``U`` (n x P) of exact rank ``rank`` (graded 1 .. 1e-4), SPD ``X``."""
    rng = np.random.default_rng(seed)
    U = (rng.standard_normal((n, rank)) * np.logspace(0, -4, rank)) @ rng.standard_normal(
        (rank, P))
    return U, tridiag_gram(n), rank


@dataclass
class _PrimalRun:
    """A primal compressor on :func:`primal_test_data`, with the reference quantities."""

    comp: Any
    label: str
    kind: str
    nested: bool
    U: np.ndarray
    X: Any
    rank: int

    def __post_init__(self) -> None:
        self.U0 = self.U.copy()
        self.unorm = proj_residual(self.U, np.zeros((self.U.shape[0], 0)), self.X)
        self.span_U = np.linalg.svd(self.U, full_matrices=False)[0][:, :self.rank]

    def run(self, what: str, **kw) -> np.ndarray:
        """``Z`` of ``comp(U, X, **kw)``: a PrimalBasis, X-orthonormal, inside the
        snapshots' span, with a JSON history; ``U`` unchanged."""
        from rbbench.rb.compressors import PrimalBasis

        U, X = self.U, self.X
        res = self.comp(U, X, **kw)
        where = f"{self.label}: {what}"
        unchanged(self.U0, U, where)
        require(isinstance(res, PrimalBasis),
                f"{where}: returned {type(res).__name__}, not a PrimalBasis")
        Z = np.asarray(res.Z)
        require(Z.ndim == 2 and Z.shape[0] == U.shape[0] and np.all(np.isfinite(Z)),
                f"{where}: Z must be a finite ({U.shape[0]}, N) array, got shape {Z.shape}")
        err = xorth_errors(Z, X)
        require(err <= ORTH_TOL, f"{where}: Z is not X-orthonormal: max|Z^T X Z - I| = "
                f"{err:.3e}")
        out = np.abs(Z - self.span_U @ (self.span_U.T @ Z)).max(initial=0.0)
        require(out <= EXACT_RTOL * max(np.abs(Z).max(initial=0.0), 1e-300),
                f"{where}: Z leaves the span of the snapshots (max deviation {out:.3e})")
        require(isinstance(res.history, dict), f"{where}: history must be a dict")
        json_ok(res.history, f"{where}: history")
        return Z

    def measure(self, Zk: np.ndarray) -> float:
        """The error ``capabilities["tol"]`` bounds (``"energy"`` or ``"max"``)."""
        r = proj_residual(self.U, Zk, self.X)
        if self.kind == "energy":
            return float(np.linalg.norm(r) / np.linalg.norm(self.unorm))
        return float(r.max() / self.unorm.max())


def _primal_full_rank(p: _PrimalRun) -> None:
    """1. Without ``tol`` and ``n``: ``N = r`` and every snapshot is reproduced."""
    Z = p.run("no tol, no n")
    require(Z.shape[1] == p.rank, f"{p.label}: without tol and n, N = {Z.shape[1]}, expected "
            f"the numerical rank {p.rank} of the snapshots")
    e = proj_residual(p.U, Z, p.X).max()
    require(e <= EXACT_RTOL * p.unorm.max(), f"{p.label}: with N = rank the snapshots are not "
            f"reproduced (max relative error {e / p.unorm.max():.3e})")


def _primal_fixed_size(p: _PrimalRun) -> None:
    """2. ``n = k`` gives ``N = min(k, r)``; 4. nested: the error is non-increasing in n."""
    errs = []
    for k in (1, 2, 3, p.rank, p.rank + 3):
        Z = p.run(f"n={k}", n=k)
        require(Z.shape[1] == min(k, p.rank), f"{p.label}: requested n = {k}, got N = "
                f"{Z.shape[1]} (expected min(n, rank) = {min(k, p.rank)})")
        errs.append(float(np.linalg.norm(proj_residual(p.U, Z, p.X))))
    if p.nested:
        require(bool(np.all(np.diff(errs) <= 1e-12 * np.asarray(errs[:-1]) + 1e-14)),
                f"{p.label}: declared nested, but the snapshot-set error is not non-increasing "
                f"in n: {errs}")


def _primal_tolerance(p: _PrimalRun) -> None:
    """3. ``tol`` is met and, if nested, ``N`` is the first size meeting it."""
    for tol in (0.3, 1e-2, 1e-3):
        Z = p.run(f"tol={tol:g}", tol=tol)
        got = p.measure(Z)
        require(got <= tol * (1 + 1e-9), f"{p.label}: tol = {tol:g} ({p.kind}) not met: "
                f"error {got:.3e} with N = {Z.shape[1]}")
        if p.nested and Z.shape[1] > 0:
            prev = p.measure(Z[:, :-1])
            require(prev > tol, f"{p.label}: tol = {tol:g}: N = {Z.shape[1]} is not the first "
                    f"size meeting the tolerance (N - 1 vectors give {prev:.3e})")


def check_primal(factory: Callable[..., Any], capabilities: dict | None = None,
                 name: str | None = None, seed: int = 0) -> None:
    """Contract of the primal-compressor role (``factory()`` builds it).

    On snapshots of exact rank ``r`` (:func:`primal_test_data`) and a non-diagonal SPD
    ``X``, ``compressor(U, X, tol=..., n=...)`` returns a
    :class:`~rbbench.rb.compressors.PrimalBasis` whose ``Z`` is X-orthonormal, spans a
    subspace of the snapshots, and:

    1. without ``tol`` and ``n``: ``N = r`` and every snapshot is reproduced;
    2. with ``n = k``: ``N = min(k, r)``;
    3. with ``tol``: the declared guarantee ``capabilities["tol"]`` holds (``"energy"``:
       relative Frobenius error of the snapshot set; ``"max"``: largest error relative to
       the largest snapshot) and, if ``capabilities["nested"]``, ``N`` is the first size
       meeting it (``Z[:, :N-1]`` does not);
    4. ``capabilities["nested"]``: the snapshot-set error is non-increasing in ``n``.

    The history is JSON-serialisable and the snapshots are not modified.
    """
    caps = dict(capabilities or {})
    label = f"primal compressor {component_label(factory, name)!r}"
    kind = caps.get("tol")
    require(kind in PRIMAL_TOL_KINDS, f"{label}: capabilities['tol'] = {kind!r}; declare "
            f"what tol bounds, one of {PRIMAL_TOL_KINDS}")
    nested = bool_capability(caps, "nested", label)
    comp = instantiate_callable(factory, label)
    U, X, rank = primal_test_data(seed)
    p = _PrimalRun(comp, label, kind, nested, U, X, rank)
    _primal_full_rank(p)
    _primal_fixed_size(p)
    _primal_tolerance(p)


def _check_registered(obj: Any, spec: ComponentSpec, registry: Registry, name: str) -> None:
    check_primal(obj, spec.capabilities, name=name)


CONTRACT = RoleContract("primal", "__call__", _check_registered)

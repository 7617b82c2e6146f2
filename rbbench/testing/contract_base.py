"""Shared vocabulary of the plugin contract suite (:mod:`rbbench.testing`).

:class:`ContractViolation` and :func:`require`, linear-algebra checks independent of
the code under test (symmetry, definiteness, shapes, index sets), the reference scenes,
small helpers every role uses, and :class:`RoleContract`, the entry of one role in the
suite (:mod:`rbbench.testing.contract_suite`). Imports neither pytest nor a backend.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from rbbench.registry import ComponentSpec, Registry
from rbbench.scene.loading import Scene, load_scene
from rbbench.scene.schema import SCHEMA

#: Overrides making ``hertz_halfdisks`` cheap enough for a contract run.
HERTZ_COARSE = ("discretization.h_contact=0.02", "discretization.h_max=0.2")

KNOWN_PHYSICS = SCHEMA["scene"]["physics"].choices
KNOWN_MULTIPLIERS = SCHEMA["discretization"]["multiplier"].choices
SYM_TOL = 1e-12  # relative asymmetry allowed in A, X, W
DENSE_LIMIT = 2000  # up to this size definiteness is checked with dense eigvalsh
DEF_TOL = 1e-13  # lambda_min (or smallest pivot) relative to the largest diagonal entry
ORTH_TOL = 1e-10  # max |Z^T X Z - I| of an X-orthonormal basis
EXACT_RTOL = 1e-8  # relative projection error of a vector inside a space


class ContractViolation(AssertionError):
    """A component breaks its role's contract; the message says which property."""


class ContractSkipped(Exception):
    """A component's contract cannot run here (not installed, or no installed backend gives
    the discretization it needs); the message says why. :func:`check_component` turns it
    into ``pytest.skip``, ``rbbench plugins --check`` into a ``skipped`` line."""


def require(cond: Any, what: str) -> None:
    """Raise :class:`ContractViolation` with message ``what`` unless ``cond`` holds."""
    if not cond:
        raise ContractViolation(what)


@dataclass(frozen=True)
class RoleContract:
    """The contract of one role, as the suite dispatches it.

    Attributes
    ----------
    role : str
        The registry role.
    method : str or None
        The method a class registered for the role must define (checked by ``check_spec``).
    check : callable
        ``check(obj, spec, registry, name)`` runs the role's contract on a registered,
        loaded component (``obj`` is its target); may raise :class:`ContractSkipped`.
    """

    role: str
    method: str | None
    check: Callable[[Any, ComponentSpec, Registry, str], None]


def component_label(factory: Any, name: str | None) -> Any:
    """The name shown in violation messages: ``name``, else the factory's ``__name__``."""
    return name or getattr(factory, "__name__", factory)


# ---------------------------------------------------------------------------
# linear-algebra helpers (independent of the code under test)
# ---------------------------------------------------------------------------
def as_sparse(M: Any, what: str) -> sp.csr_matrix:
    """``M`` as a finite CSR matrix (a sparse matrix or ndarray is required)."""
    require(sp.issparse(M) or isinstance(M, np.ndarray), f"{what}: expected a sparse matrix "
            f"or ndarray, got {type(M).__name__}")
    M = sp.csr_matrix(M, dtype=float)
    require(np.all(np.isfinite(M.data)), f"{what}: has non-finite entries")
    return M


def check_symmetric(M: sp.csr_matrix, what: str, tol: float = SYM_TOL) -> None:
    """``M`` square and symmetric to ``tol`` relative to its largest entry."""
    require(M.shape[0] == M.shape[1], f"{what}: not square, shape {M.shape}")
    scale = abs(M).max() if M.nnz else 0.0
    asym = abs(M - M.T).max() if M.nnz else 0.0
    require(asym <= tol * max(scale, np.finfo(float).tiny),
            f"{what}: not symmetric: max|M - M^T| = {asym:.3e} > {tol:g} * max|M| "
            f"= {tol * scale:.3e}")


def check_spd(M: sp.csr_matrix, what: str) -> None:
    """Positive definiteness of a symmetric matrix.

    Dense ``eigvalsh`` for small matrices; otherwise an LDL^T-equivalent sparse LU
    with symmetric permutation and diagonal pivots only: a symmetric matrix is
    positive definite iff all those pivots are positive.
    """
    n = M.shape[0]
    if n == 0:
        return
    dmax = float(np.max(np.abs(M.diagonal())))
    require(dmax > 0, f"{what}: zero diagonal")
    if n <= DENSE_LIMIT:
        lam_min = float(np.linalg.eigvalsh(M.toarray())[0])
        require(lam_min > DEF_TOL * dmax,
                f"{what}: not positive definite: smallest eigenvalue {lam_min:.3e} "
                f"(largest diagonal entry {dmax:.3e})")
        return
    try:
        lu = spla.splu(sp.csc_matrix(M), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
    except RuntimeError as exc:  # "Factor is exactly singular"
        raise ContractViolation(f"{what}: not positive definite ({exc})") from None
    require(np.array_equal(lu.perm_r, lu.perm_c),
            f"{what}: not positive definite (LU needed an off-diagonal pivot)")
    piv = lu.U.diagonal()
    require(piv.min() > DEF_TOL * dmax,
            f"{what}: not positive definite: smallest LDL^T pivot {piv.min():.3e} "
            f"(largest diagonal entry {dmax:.3e})")


def vector(v: Any, n: int, what: str) -> np.ndarray:
    """``v`` as a finite float vector of shape ``(n,)``."""
    v = np.asarray(v)
    require(v.shape == (n,), f"{what}: expected shape ({n},), got {v.shape}")
    require(np.issubdtype(v.dtype, np.number) and np.all(np.isfinite(v)),
            f"{what}: not a finite numeric vector")
    return v.astype(float)


def index_set(idx: Any, n: int, what: str) -> np.ndarray:
    """``idx`` as distinct int64 indices in ``[0, n)``."""
    idx = np.asarray(idx)
    require(idx.ndim == 1, f"{what}: expected a 1-d index array, got shape {idx.shape}")
    require(idx.size == 0 or np.issubdtype(idx.dtype, np.integer),
            f"{what}: expected integer indices, got dtype {idx.dtype}")
    idx = idx.astype(np.int64)
    require(np.all((idx >= 0) & (idx < n)), f"{what}: indices outside [0, {n})")
    require(np.unique(idx).size == idx.size, f"{what}: repeated indices")
    return idx


def check_shape(M: Any, shape: tuple[int, int], what: str) -> None:
    """``M.shape == shape``."""
    require(tuple(M.shape) == shape, f"{what}: expected shape {shape}, got {tuple(M.shape)}")


def spd_matrix(rng: np.random.Generator, n: int) -> np.ndarray:
    """A random dense SPD matrix ``M M^T / n + I`` (draws one ``n x n`` normal block)."""
    M = rng.standard_normal((n, n))
    return M @ M.T / n + np.eye(n)


# ---------------------------------------------------------------------------
# subspaces (compressor and stabiliser contracts)
# ---------------------------------------------------------------------------
def tridiag_gram(n: int) -> sp.csr_matrix:
    """SPD, non-diagonal Gram matrix (a 1-D H1-like product): X-orthonormality != orthonormality."""
    return sp.diags([-np.ones(n - 1), 2.5 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1]).tocsr()


def xorth_errors(Z: np.ndarray, X: Any) -> float:
    """``max |Z^T X Z - I|``."""
    G = Z.T @ (X @ Z)
    return float(np.abs(G - np.eye(Z.shape[1])).max(initial=0.0))


def proj_residual(U: np.ndarray, Z: np.ndarray, X: Any) -> np.ndarray:
    """X-norms of ``(I - Pi_Z) u_p`` for an X-orthonormal ``Z``."""
    R = U - Z @ (Z.T @ (X @ U)) if Z.shape[1] else U
    return np.sqrt(np.clip(np.einsum("ij,ij->j", R, X @ R), 0.0, None))


# ---------------------------------------------------------------------------
# components and their outputs
# ---------------------------------------------------------------------------
@functools.cache
def reference_scene(name: str, overrides: tuple[str, ...] = ()) -> Scene:
    """``load_scene(name, overrides)``, cached for the whole contract run."""
    return load_scene(name, overrides)


def json_ok(obj: Any, what: str) -> None:
    """``obj`` is JSON-serialisable (histories go to result.json)."""
    try:
        json.dumps(obj)
    except (TypeError, ValueError) as exc:
        raise ContractViolation(f"{what}: not JSON-serialisable ({exc}): use lists and "
                                "floats (histories go to result.json)") from None


def unchanged(before: np.ndarray, after: Any, what: str) -> None:
    """The input ``after`` still equals its copy ``before``."""
    require(np.array_equal(before, np.asarray(after)), f"{what}: the input was modified")


def bool_capability(caps: dict, key: str, label: str) -> bool:
    """``caps[key]``, which must be declared True or False."""
    require(isinstance(caps.get(key), bool),
            f"{label}: capabilities[{key!r}] must be declared True or False, got "
            f"{caps.get(key)!r}")
    return caps[key]


def instantiate(factory: Callable[..., Any], label: str) -> Any:
    """``factory()``; any failure to build breaks the contract."""
    try:
        return factory()
    except Exception as exc:  # noqa: BLE001 - any failure to build breaks the contract
        raise ContractViolation(f"{label}: factory() raised {type(exc).__name__}: {exc} (the "
                                "target must build the component without arguments)") from exc


def instantiate_callable(factory: Callable[..., Any], label: str) -> Any:
    """:func:`instantiate`, and the result must be callable (a compressor)."""
    comp = instantiate(factory, label)
    require(callable(comp), f"{label}: factory() returned a non-callable {type(comp).__name__}")
    return comp

"""Contract of the stabiliser role (:mod:`rbbench.rb.compressors` protocol): the offline
enrichment, the online basis and the declared inf-sup guarantee.

The guarantees are those of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction
methods: parametric variational inequalities" (talk), slides "Parameter-dependent context" and
"Main result".
"""

from __future__ import annotations

from collections.abc import Callable
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
    instantiate,
    json_ok,
    proj_residual,
    require,
    tridiag_gram,
    unchanged,
    xorth_errors,
)

#: ``capabilities["inf_sup"]`` of a stabiliser: where its primal space is inf-sup stable.
STABILIZER_GUARANTEES = ("not guaranteed", "every mu", "training set")


def stabilizer_test_data(seed: int = 0, n: int = 30, m: int = 6, R: int = 3, N: int = 2,
                         P: int = 4) -> dict[str, Any]:
    """A small saddle-point family with ``N < R``, so that ``beta_dec = 0`` on ``span(Vg)``.

    Keys: ``X`` (sparse SPD), ``x_solve``, ``W`` (identity), ``Vg`` (m x R, non-negative),
    ``Z`` (n x N, X-orthonormal), ``B_train`` (P matrices m x n), ``B_new`` (one more).
    """
    import scipy.linalg as sla

    rng = np.random.default_rng(seed)
    X = tridiag_gram(n)
    cho = sla.cho_factor(X.toarray())
    Z = rng.standard_normal((n, N))
    L = np.linalg.cholesky(Z.T @ (X @ Z))
    Z = sla.solve_triangular(L, Z.T, lower=True).T
    Bs = [sp.csr_matrix(rng.standard_normal((m, n))) for _ in range(P + 1)]
    return {"X": X, "x_solve": lambda rhs: sla.cho_solve(cho, rhs),
            "W": sp.identity(m, format="csr"), "Vg": rng.uniform(0.0, 1.0, (m, R)),
            "Z": Z, "B_train": Bs[:P], "B_new": Bs[P]}


def _beta_span(Y: np.ndarray | None, B: Any, d: dict) -> float:
    """Inf-sup of ``eta^T B v`` over ``span(Vg) x span(Y)`` (``Y`` X-orthonormal; None: all)."""
    import scipy.linalg as sla

    BtV = np.asarray(B.T @ d["Vg"])
    S = BtV.T @ d["x_solve"](BtV) if Y is None else (Y.T @ BtV).T @ (Y.T @ BtV)
    M = d["Vg"].T @ (d["W"] @ d["Vg"])
    return float(np.sqrt(max(sla.eigh(0.5 * (S + S.T), M, eigvals_only=True)[0], 0.0)))


def _check_space(Y: np.ndarray, inner: np.ndarray, X: Any, what: str, label: str) -> None:
    """``Y`` is X-orthonormal and contains ``span(inner)``."""
    err = xorth_errors(Y, X)
    require(err <= ORTH_TOL, f"{label}: {what} is not X-orthonormal: "
            f"max|Y^T X Y - I| = {err:.3e}")
    miss = proj_residual(inner, Y, X).max(initial=0.0)
    require(miss <= EXACT_RTOL, f"{label}: {what} does not contain the space it must "
            f"enrich (relative residual {miss:.3e})")


def _stab_instance(factory: Callable[..., Any], caps: dict, label: str) -> tuple[Any, bool]:
    """The stabiliser and its ``online`` attribute, a bool equal to
    ``capabilities["online_hf"]``."""
    online_hf = bool_capability(caps, "online_hf", label)
    guarantee = caps.get("inf_sup")
    require(guarantee in STABILIZER_GUARANTEES, f"{label}: capabilities['inf_sup'] = "
            f"{guarantee!r}; declare one of {STABILIZER_GUARANTEES}")
    stab = instantiate(factory, label)
    online = getattr(stab, "online", None)
    require(isinstance(online, bool), f"{label}: attribute 'online' must be a bool, got "
            f"{online!r}")
    require(online == online_hf, f"{label}: online = {online} but capabilities['online_hf'] "
            f"= {online_hf}")
    return stab, online


def _stab_offline(stab: Any, d: dict, delta: float, label: str) -> np.ndarray:
    """``offline()`` returns ``(Z_off, history)``: ``Z_off`` finite, X-orthonormal,
    containing ``span Z``; a JSON history; the inputs unchanged. Returns ``Z_off``."""
    X, Z, Vg = d["X"], d["Z"], d["Vg"]
    Z0, V0 = Z.copy(), Vg.copy()
    out = stab.offline(Z, Vg, X, d["x_solve"], list(d["B_train"]), delta)
    require(isinstance(out, tuple) and len(out) == 2,
            f"{label}: offline() must return (Z_off, history)")
    Z_off, hist = np.asarray(out[0]), out[1]
    require(Z_off.ndim == 2 and Z_off.shape[0] == Z.shape[0] and np.all(np.isfinite(Z_off)),
            f"{label}: Z_off must be a finite ({Z.shape[0]}, k) array, got {Z_off.shape}")
    require(isinstance(hist, dict), f"{label}: the offline history must be a dict")
    json_ok(hist, f"{label}: offline history")
    unchanged(Z0, Z, f"{label}: offline() (Z)")
    unchanged(V0, Vg, f"{label}: offline() (Vg)")
    _check_space(Z_off, Z, X, "Z_off (offline)", label)
    return Z_off


def _stab_guarantee(Y: np.ndarray, B: Any, d: dict, guarantee: str, delta: float, i: int,
                    label: str) -> None:
    """The declared inf-sup guarantee at matrix ``i`` (a training matrix for
    ``"training set"``)."""
    b_on, b = _beta_span(None, B, d), _beta_span(Y, B, d)
    if guarantee == "every mu":
        require(abs(b - b_on) <= 1e-8 * b_on, f"{label}: declares 'every mu', but "
                f"beta = {b:.6e} != beta_on = {b_on:.6e} at matrix {i}")
    else:
        bound = np.sqrt(1.0 - delta**2) * b_on
        require(b >= bound * (1 - 1e-9), f"{label}: declares 'training set', but the "
                f"inf-sup {b:.3e} < sqrt(1 - delta^2) beta_on = {bound:.3e} at training "
                f"matrix {i} (delta = {delta:g})")


def _stab_online(stab: Any, online: bool, Z_off: np.ndarray, d: dict, guarantee: str,
                 delta: float, label: str) -> None:
    """``online_basis`` on every training matrix and a new one: X-orthonormal, containing
    ``Z_off`` (exactly ``Z_off`` when not ``online``), and the declared guarantee."""
    X, Vg, n = d["X"], d["Vg"], d["Z"].shape[0]
    n_train = len(d["B_train"])
    for i, B in enumerate(list(d["B_train"]) + [d["B_new"]]):
        Y = np.asarray(stab.online_basis(Z_off, Vg, X, d["x_solve"], B))
        where = f"online_basis at matrix {i}"
        require(Y.ndim == 2 and Y.shape[0] == n and np.all(np.isfinite(Y)),
                f"{label}: {where} must be a finite ({n}, k) array")
        _check_space(Y, Z_off, X, where, label)
        if not online:
            require(Y.shape[1] == Z_off.shape[1], f"{label}: online = False, but {where} "
                    f"has {Y.shape[1]} vectors instead of the {Z_off.shape[1]} of Z_off")
        if guarantee == "not guaranteed" or (guarantee == "training set" and i >= n_train):
            continue
        _stab_guarantee(Y, B, d, guarantee, delta, i, label)


def check_stabilizer(factory: Callable[..., Any], capabilities: dict | None = None,
                     name: str | None = None, seed: int = 0, delta: float = 0.3) -> None:
    """Contract of the stabiliser role (``factory()`` builds it).

    On :func:`stabilizer_test_data` (``N < R``: the decorrelated model is not inf-sup
    stable), ``offline(Z, Vg, X, x_solve, B_train, delta)`` returns ``(Z_off, history)``:

    * ``Z_off`` finite, X-orthonormal, containing ``span Z``; ``history`` a JSON-serialisable
      dict; the inputs are not modified;
    * ``online`` is a bool equal to ``capabilities["online_hf"]``;
      ``online_basis(Z_off, Vg, X, x_solve, B)`` is X-orthonormal and contains ``Z_off``,
      and spans exactly ``Z_off`` when ``online`` is False;
    * the declared guarantee ``capabilities["inf_sup"]`` holds, with the span inf-sup
      ``beta`` of ``b(mu; v, eta) = eta^T B(mu) v`` (a lower bound of the cone value, and
      what Benaceur et al.'s proofs bound): ``"every mu"``: ``beta = beta_on`` (whole primal
      space) on the training matrices and on a new one (Benaceur et al., "Parameter-dependent
      context"); ``"training set"``: ``beta >= sqrt(1 - delta^2) beta_on > 0`` on the
      training matrices (Benaceur et al., "Main result"; the sharper Riesz form of
      :func:`rbbench.rb.algorithms.pga.riesz_lower_bound`); ``"not guaranteed"``: nothing.
    """
    caps = dict(capabilities or {})
    label = f"stabilizer {component_label(factory, name)!r}"
    stab, online = _stab_instance(factory, caps, label)
    d = stabilizer_test_data(seed)
    Z_off = _stab_offline(stab, d, delta, label)
    _stab_online(stab, online, Z_off, d, caps.get("inf_sup"), delta, label)


def _check_registered(obj: Any, spec: ComponentSpec, registry: Registry, name: str) -> None:
    check_stabilizer(obj, spec.capabilities, name=name)


CONTRACT = RoleContract("stabilizer", "offline", _check_registered)

"""Contract of the dual-compressor role (:class:`rbbench.rb.algorithms.cones.DualBasis`).

The error measures are those of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order
reduction methods: parametric variational inequalities" (talk), slide "mCPG algorithm (4/4)".
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp

from rbbench.registry import ComponentSpec, Registry
from rbbench.testing.contract_base import (
    RoleContract,
    bool_capability,
    component_label,
    instantiate_callable,
    require,
    unchanged,
)


def dual_test_data(seed: int = 0, n: int = 40, Q: int = 12) -> tuple[np.ndarray, sp.csr_matrix]:
    """Non-negative bump snapshots ``Theta`` (n x Q), overlapping supports, and a diagonal ``W``."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.0, n)
    c = rng.uniform(0.2, 0.8, Q)
    w = rng.uniform(0.1, 0.3, Q)
    Theta = np.clip(1.0 - ((x[:, None] - c) / w) ** 2, 0.0, None) * rng.uniform(0.5, 2.0, Q)
    return Theta, sp.diags(rng.uniform(0.5, 1.5, n)).tocsr()


@dataclass
class _DualRun:
    """A dual compressor on :func:`dual_test_data`, with the reference quantities."""

    comp: Any
    label: str
    cone: bool
    nested: bool
    Theta: np.ndarray
    W: Any

    def __post_init__(self) -> None:
        self.T0 = self.Theta.copy()
        self.sw = np.sqrt(self.W.diagonal())
        self.CT = self.sw[:, None] * self.Theta
        self.scale = float(np.linalg.norm(self.CT, axis=0).max())

    def proj_error(self, V: np.ndarray, is_cone: bool) -> float:
        """``max_q ||theta_q - Pi theta_q||_W / max_q ||theta_q||_W``, recomputed here (NNLS
        on a cone, least squares on a span)."""
        from scipy.optimize import nnls

        CT = self.CT
        CV = self.sw[:, None] * V
        if is_cone:
            errs = [nnls(CV, CT[:, q])[1] for q in range(CT.shape[1])]
        else:
            c = np.linalg.lstsq(CV, CT, rcond=None)[0]
            errs = np.linalg.norm(CT - CV @ c, axis=0)
        return float(np.max(errs)) / self.scale

    def run(self, what: str, tol: float, r_max: int | None) -> Any:
        """``comp(Theta, W, tol=tol, r_max=r_max)``: a valid DualBasis, ``Theta`` unchanged."""
        from rbbench.rb.algorithms.cones.greedy import DualBasis

        b = self.comp(self.Theta, self.W, tol=tol, r_max=r_max)
        where = f"{self.label}: {what}"
        unchanged(self.T0, self.Theta, where)
        require(isinstance(b, DualBasis), f"{where}: returned {type(b).__name__}, "
                "not a DualBasis")
        R = self._check_generators(b, r_max, where)
        self._check_errors(b, R, where)
        return b

    def _check_generators(self, b: Any, r_max: int | None, where: str) -> int:
        """``1 <= R <= r_max`` finite generators of unit W-norm; a cone's are non-negative.
        Returns ``R``."""
        n = self.Theta.shape[0]
        V = np.asarray(b.generators)
        R = V.shape[1] if V.ndim == 2 else -1
        require(V.ndim == 2 and V.shape[0] == n and np.all(np.isfinite(V)),
                f"{where}: generators must be a finite ({n}, R) array, got "
                f"shape {V.shape}")
        require(R >= 1, f"{where}: no generators")
        require(r_max is None or R <= r_max, f"{where}: R = {R} > r_max = {r_max}")
        nrm = np.linalg.norm(self.sw[:, None] * V, axis=0)
        require(np.allclose(nrm, 1.0, rtol=0, atol=1e-8),
                f"{where}: generators must have unit W-norm, got {nrm.min():.6g} .. "
                f"{nrm.max():.6g}")
        require(bool(b.is_cone) == self.cone,
                f"{where}: is_cone = {b.is_cone}, but capabilities['cone'] = {self.cone}")
        if b.is_cone:
            require(V.min() >= -1e-14 * np.abs(V).max(), f"{where}: a cone generator has a "
                    f"negative entry ({V.min():.3e}): the reduced cone must lie in W+")
        return R

    def _check_errors(self, b: Any, R: int, where: str) -> None:
        """``e_proj``, ``e_orth`` in ``[0, 1]``, one per generator; ``e_proj[-1]`` equal to
        :meth:`proj_error`; nested: ``e_proj`` non-increasing."""
        ep, eo = np.asarray(b.e_proj, dtype=float), np.asarray(b.e_orth, dtype=float)
        require(ep.shape == (R,) and eo.shape == (R,),
                f"{where}: e_proj and e_orth need one entry per generator (R = {R}), got "
                f"{ep.shape[0]} and {eo.shape[0]}")
        require(np.all(np.isfinite(ep)) and ep.min() >= 0 and ep.max() <= 1 + 1e-12,
                f"{where}: e_proj must be finite and in [0, 1], got {ep.tolist()}")
        require(np.all(np.isfinite(eo)) and eo.min() >= -1e-12 and eo.max() <= 1 + 1e-12,
                f"{where}: e_orth must be finite and in [0, 1], got {eo.tolist()}")
        true = self.proj_error(np.asarray(b.generators), b.is_cone)
        require(abs(ep[-1] - true) <= 1e-6 * true + 1e-10,
                f"{where}: e_proj[-1] = {ep[-1]:.6e} does not match the recomputed "
                f"projection error {true:.6e}")
        if self.nested:
            require(np.all(np.diff(ep) <= 1e-12), f"{where}: declared nested, but e_proj "
                    f"increases: {ep.tolist()}")


def _dual_tolerance(d: _DualRun) -> None:
    """With ``tol``: ``R`` is the first size with ``e_proj <= tol``."""
    for tol in (0.3, 0.05):
        b = d.run(f"tol={tol:g}", tol=tol, r_max=None)
        ep = np.asarray(b.e_proj)
        require(ep[-1] <= tol, f"{d.label}: tol = {tol:g} not met: e_proj(R = {b.R}) = "
                f"{ep[-1]:.3e}")
        require(np.all(ep[:-1] > tol), f"{d.label}: tol = {tol:g}: R = {b.R} is not the first "
                f"size meeting the tolerance (e_proj = {ep.tolist()})")


def check_dual(factory: Callable[..., Any], capabilities: dict | None = None,
               name: str | None = None, seed: int = 0) -> None:
    """Contract of the dual-compressor role (``factory()`` builds it).

    On non-negative snapshots ``Theta`` and a diagonal SPD ``W`` (:func:`dual_test_data`),
    ``compressor(Theta, W, tol=..., r_max=...)`` returns a
    :class:`~rbbench.rb.algorithms.cones.DualBasis` with:

    * ``1 <= R <= r_max`` finite generators of unit W-norm, shape ``(n, R)``;
    * ``is_cone == capabilities["cone"]``; a cone's generators are non-negative (the
      reduced cone lies in ``W+``);
    * ``e_proj`` and ``e_orth`` of length ``R`` with values in ``[0, 1]``; ``e_proj[-1]``
      equal to an independent recomputation (NNLS on the cone, least squares on a span) of
      ``max_q ||theta_q - Pi theta_q||_W / max_q ||theta_q||_W`` (Benaceur et al., slide
      "mCPG algorithm (4/4)");
    * ``capabilities["nested"]``: ``e_proj`` non-increasing (to ``1e-12``);
    * with ``tol``: ``R`` is the first size with ``e_proj <= tol`` (``e_proj[:-1] > tol``);
    * the snapshots are not modified.
    """
    caps = dict(capabilities or {})
    label = f"dual compressor {component_label(factory, name)!r}"
    cone = bool_capability(caps, "cone", label)
    nested = bool_capability(caps, "nested", label)
    comp = instantiate_callable(factory, label)
    Theta, W = dual_test_data(seed)
    d = _DualRun(comp, label, cone, nested, Theta, W)
    d.run("tol=0, r_max=6", tol=0.0, r_max=6)
    _dual_tolerance(d)


def _check_registered(obj: Any, spec: ComponentSpec, registry: Registry, name: str) -> None:
    check_dual(obj, spec.capabilities, name=name)


CONTRACT = RoleContract("dual", "__call__", _check_registered)

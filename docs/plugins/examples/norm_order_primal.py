"""A primal compressor plugin: the snapshots in decreasing X-norm, X-orthonormalised one by
one (a greedy without error indicator: cheaper than POD, no optimality)."""

from __future__ import annotations

from typing import Any

import numpy as np

from rbbench.plugin import ComponentSpec, PrimalBasis, hookimpl

#: a residual below this fraction of the largest snapshot norm is in the span already
RANK_RTOL = 1e-10


class NormOrder:
    """``(U, X, *, tol=None, n=None) -> PrimalBasis``; ``tol`` bounds the largest
    projection error relative to the largest snapshot (``capabilities["tol"] = "max"``)."""

    name = "norm-order"

    def __call__(self, U: np.ndarray, X: Any, *, tol: float | None = None,
                 n: int | None = None) -> PrimalBasis:
        U = np.asarray(U, dtype=float)
        R = U.copy()  # residuals (I - Pi_Z) u_p
        norms = np.sqrt(np.einsum("ij,ij->j", U, X @ U))
        top = float(norms.max(initial=0.0))
        Z = np.zeros((U.shape[0], 0))
        errors = [1.0]
        for p in np.argsort(-norms):
            res = np.sqrt(np.clip(np.einsum("ij,ij->j", R, X @ R), 0.0, None))
            if (n is not None and Z.shape[1] >= n) or top == 0.0 \
                    or res.max() <= RANK_RTOL * top \
                    or (tol is not None and res.max() <= tol * top):
                break
            if res[p] <= RANK_RTOL * top:
                continue  # already in the span
            z = R[:, p] / res[p]
            z -= Z @ (Z.T @ (X @ z))  # re-orthogonalise once ("twice is enough")
            z /= np.sqrt(z @ (X @ z))
            Z = np.column_stack([Z, z])
            R -= np.outer(z, z @ (X @ R))
            errors.append(float(np.sqrt(max(np.einsum("ij,ij->j", R, X @ R).max(), 0.0))
                                / top))
        return PrimalBasis(Z=Z, name=self.name, history={"max_error": errors})


@hookimpl
def rbbench_register(registry):
    registry.add(ComponentSpec(
        name="norm-order", role="primal", target="norm_order_primal:NormOrder",
        capabilities={"tol": "max", "nested": True},
        description="snapshots by decreasing X-norm, X-orthonormalised (no indicator)",
    ))

"""A stabiliser plugin: the primal space enriched offline with the supremizers of the cone
generators at one training parameter (the middle one): cheaper than PGA, with no
guarantee."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

from rbbench.plugin import ComponentSpec, NoStabilizer, hookimpl, supremizers, x_orthonormalize


class CenterSupremizer(NoStabilizer):
    """``Z_off = [Z, X-orthonormal basis of (I - Pi_Z) X^{-1} B(mu_c)^T Vg]``, ``mu_c``
    the middle training parameter; ``online_basis`` is ``Z_off`` (an offline stabiliser)."""

    name = "center-supremizer"
    online = False

    def offline(self, Z: np.ndarray, Vg: np.ndarray, X: Any,
                x_solve: Callable[[np.ndarray], np.ndarray], B_train: Iterable[Any],
                delta: float | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        B_list = list(B_train)
        B = B_list[len(B_list) // 2]
        Z = np.asarray(Z, dtype=float)
        extra, _ = x_orthonormalize(supremizers(B, x_solve, Vg), X, U=Z)
        return np.hstack([Z, extra]), {"center_index": len(B_list) // 2,
                                       "K": int(extra.shape[1])}


@hookimpl
def rbbench_register(registry):
    registry.add(ComponentSpec(
        name="center-supremizer", role="stabilizer",
        target="center_supremizer:CenterSupremizer",
        capabilities={"online_hf": False, "inf_sup": "not guaranteed"},
        description="supremizers at the middle training parameter, offline",
    ))

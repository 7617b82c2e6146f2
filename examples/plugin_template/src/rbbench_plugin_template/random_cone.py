"""The ``random-cone`` dual compressor: training multiplier snapshots drawn in a random
(seeded) order become the generators of the reduced cone.

It is the baseline of the greedy cone compressors: ``cpg`` picks, at each step, the
snapshot worst approximated by the current cone; ``random-cone`` picks any. Same cone
structure (normalised snapshots, nested in R, every selected snapshot reproduced exactly),
so the difference in ``e_proj`` and in the reduced errors at equal ``R`` is what the greedy
selection buys.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rbbench.plugin import DualBasis, DualCompressor, as_metric, cone_projection

#: a snapshot (or a new generator) within this fraction of the largest snapshot norm of the
#: current cone adds nothing: it is skipped
INSIDE_RTOL = 1e-10
#: negative entries down to this fraction of the largest |entry| are rounding (set to 0)
NEG_RTOL = 1e-12


def _snapshots(LAM: np.ndarray) -> np.ndarray:
    """The snapshots as a float (m, Q) copy, rounding negatives set to 0."""
    theta = np.array(LAM, dtype=float, copy=True)
    if theta.ndim != 2 or not np.all(np.isfinite(theta)):
        raise ValueError(f"random-cone: the snapshots must be a finite (m, Q) array, got "
                         f"shape {theta.shape}")
    big = float(np.abs(theta).max(initial=0.0))
    if theta.min(initial=0.0) < -NEG_RTOL * big:
        raise ValueError(f"random-cone: the snapshots have negative entries (min "
                         f"{theta.min():.3e}): a cone compressor needs multipliers >= 0")
    return np.clip(theta, 0.0, None)


class RandomCone(DualCompressor):
    """Cone spanned by training snapshots drawn in a random order.

    Parameters
    ----------
    seed : int
        Seed of the order (the same seed, the same cone).

    Notes
    -----
    Step ``r``: the next snapshot ``theta_q`` of the order that lies outside the current
    cone becomes the generator ``v_r = theta_q / ||theta_q||_W``; ``e_orth(r)`` is its
    distance to the previous cone and ``e_proj(r) = max_q ||theta_q - Pi theta_q||_W /
    max_q ||theta_q||_W`` (exact W-projections onto the cone). It stops at the first ``R``
    with ``e_proj(R) <= tol``, at ``r_max`` generators, or when the order is exhausted.
    """

    name = "random-cone"

    def __init__(self, seed: int = 0) -> None:
        super().__init__(seed=int(seed))

    def compress(self, LAM: np.ndarray, W: Any, *, tol: float = 1e-3,
                 r_max: int | None = None, seed: int = 0) -> DualBasis:
        """See the class docstring; ``info["stop"]`` says why it stopped."""
        metric = as_metric(W)
        theta = _snapshots(LAM)
        norms = np.atleast_1d(metric.norm(theta))
        scale = float(norms.max(initial=0.0))
        r_max = theta.shape[1] if r_max is None else int(r_max)
        V = np.zeros((theta.shape[0], 0))
        selected: list[int] = []
        e_proj: list[float] = []
        e_orth: list[float] = []
        info: dict[str, Any] = {"seed": seed, "tol": tol, "r_max": r_max, "skipped": 0,
                                "stop": "exhausted"}
        if scale == 0.0:
            info["stop"] = "zero_snapshots"
            return DualBasis(V, self.name, True, selected, e_proj, e_orth, info)
        for q in np.random.default_rng(seed).permutation(theta.shape[1]):
            if e_proj and e_proj[-1] <= tol:
                info["stop"] = "tol"
                break
            if len(selected) >= r_max:
                info["stop"] = "r_max"
                break
            v = theta[:, q] / norms[q] if norms[q] > INSIDE_RTOL * scale else None
            aperture = 0.0 if v is None else float(cone_projection(v, V, metric)[2])
            if aperture <= INSIDE_RTOL:  # a zero snapshot, or one the cone holds already
                info["skipped"] += 1
                continue
            V = np.column_stack([V, v])
            selected.append(int(q))
            e_orth.append(min(aperture, 1.0))
            e_proj.append(float(np.max(cone_projection(theta, V, metric)[2])) / scale)
        return DualBasis(V, self.name, True, selected, e_proj, e_orth, info)

"""Contact profiles of a reduced friction model against the HF snapshots.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slide "RB solutions": ``lam_t`` of the HF and of the reduced
solution against ``x`` on the contact zone, with the Coulomb bounds ``+- F lam_n``, at
``mu = 0.7, 1, 1.3``.
The profiles are taken at the training parameters nearest to the lower bound, the middle
and the upper bound of the parameter box (the HF values are then the snapshots themselves:
no extra HF solve); ``mu`` records the parameters actually used.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

__all__ = ["PROFILE_DEFINITION", "lam_t_profiles", "profile_parameters"]

PROFILE_DEFINITION = (
    "per mu (the training parameters nearest to the lower bound, the middle and the upper "
    "bound of the parameter box; HF values are the training snapshots): x (m) of the "
    "contact (collocation) nodes in ascending order, lam_t_hf / lam_t_rb (Pa, nodal P1 "
    "values of the HF and the reconstructed reduced tangential multiplier), lam_n_hf / "
    "lam_n_rb (Pa), bound_hf = F lam_n of the HF solution (Pa): Benaceur et al.'s figure 'RB "
    "solutions'")


def profile_parameters(mus_train: np.ndarray, bounds: np.ndarray) -> list[int]:
    """Indices of the training parameters nearest (scaled by the box) to the lower bound,
    the centre and the upper bound of ``bounds`` (P x 2 rows ``[low, high]``), without
    repeats."""
    mus = np.atleast_2d(np.asarray(mus_train, float))
    lo, hi = np.asarray(bounds, float).T
    width = np.where(hi > lo, hi - lo, 1.0)
    picks: list[int] = []
    for target in (lo, (lo + hi) / 2, hi):
        j = int(np.argmin(np.linalg.norm((mus - target) / width, axis=1)))
        if j not in picks:
            picks.append(j)
    return picks


def lam_t_profiles(mus_train: np.ndarray, bounds: np.ndarray, LAM: np.ndarray,
                   LAM_T: np.ndarray, solve: Callable[[np.ndarray], tuple[np.ndarray,
                                                                          np.ndarray]],
                   nodes_x: Callable[[np.ndarray], np.ndarray],
                   coefficient: Callable[[np.ndarray], np.ndarray]) -> dict[str, Any]:
    """The HF and reduced contact profiles (:data:`PROFILE_DEFINITION`).

    Parameters
    ----------
    mus_train, LAM, LAM_T : the training parameters and their HF nodal multipliers
        (columns in the order of ``mus_train``).
    solve : ``mu -> (lam_n, lam_t)`` of the reduced model, reconstructed at the HF nodes.
    nodes_x : ``mu -> x`` of the collocation nodes (same order as the multipliers).
    coefficient : ``mu -> F`` per node (the friction coefficient).
    """
    out: dict[str, list] = {k: [] for k in ("mu", "x", "lam_t_hf", "lam_t_rb", "lam_n_hf",
                                            "lam_n_rb", "bound_hf")}
    mus = np.atleast_2d(np.asarray(mus_train, float))
    for j in profile_parameters(mus, bounds):
        mu = mus[j]
        ln, lt = solve(mu)
        x = np.asarray(nodes_x(mu), float)
        order = np.argsort(x)
        F = np.broadcast_to(np.asarray(coefficient(mu), float), x.shape)
        cols = {"x": x, "lam_t_hf": LAM_T[:, j], "lam_t_rb": lt, "lam_n_hf": LAM[:, j],
                "lam_n_rb": ln, "bound_hf": F * LAM[:, j]}
        out["mu"].append(mu.tolist())
        for k, v in cols.items():
            out[k].append(np.asarray(v, float)[order].tolist())
    return out

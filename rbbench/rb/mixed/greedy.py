"""A weak greedy driven by the certified bound: HF solves only at the parameters it selects.

Weak greedy (Veroy, Prud'homme, Rovas & Patera 2003; for variational inequalities Haasdonk,
Salomon & Wohlmuth 2012, Section 5): start from the centre of D; at each step solve the
reduced model and evaluate the bound ``Delta_u(mu) / ||u_N(mu)||_X``
(:class:`rbbench.rb.mixed.bounds.MixedBound`) over a large training set, stop when its
maximum is at most ``tol``, else solve the HF problem at the maximiser and add its
displacement to the primal space and its multiplier to the cone (normalised, non-negative:
the cone stays in M). Every multiplier snapshot's supremizer ``X^{-1} B^T lam`` joins the
primal space too: with a mu-independent ``B`` (the bound's own requirement) the reduced
saddle point then has inf-sup constant 1 in the natural multiplier norm, so no PGA is needed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rbbench.rb.mixed.bounds import MixedBound, build_mixed_bound
from rbbench.rb.mixed.model import ReducedModel, build_affine_model, projector

__all__ = ["BoundGreedy", "bound_greedy", "x_orthonormal"]


@dataclass
class BoundGreedy:
    """The greedy's reduced model and bound, and its history: ``picks`` (training indices,
    the first -1 for the centre), ``max_bound`` (max over the training set of ``Delta_u /
    ||u_N||_X`` before each addition, the last one after the last), ``n_hf`` (HF solves)."""

    model: ReducedModel
    bound: MixedBound
    Z: np.ndarray
    Vg: np.ndarray
    picks: list[int] = field(default_factory=list)
    max_bound: list[float] = field(default_factory=list)
    n_hf: int = 0
    stop: str = ""


def x_orthonormal(U: np.ndarray, X: Any, rtol: float = 1e-10) -> np.ndarray:
    """An X-orthonormal basis of span(U): Gram-Schmidt in X, twice per column (norms, not
    squared norms: a direction 1e-8 of the column is kept); a column whose remainder is
    below ``rtol`` of its norm is dropped."""
    Q = np.zeros_like(U, dtype=float)
    k = 0
    for j in range(U.shape[1]):
        v = np.array(U[:, j], dtype=float)
        n0 = float(np.sqrt(max(v @ (X @ v), 0.0)))
        for _ in range(2):
            v -= Q[:, :k] @ (Q[:, :k].T @ (X @ v))
        nv = float(np.sqrt(max(v @ (X @ v), 0.0)))
        if n0 > 0 and nv > rtol * n0:
            Q[:, k] = v / nv
            k += 1
    return Q[:, :k]


def _spaces(U: list, L: list, B: Any, X: Any, x_solve: Callable) -> tuple[np.ndarray, ...]:
    lam = [v / np.linalg.norm(v) for v in L if np.linalg.norm(v) > 0]
    Vg = np.stack(lam, axis=1) if lam else np.zeros((B.shape[0], 0))
    sup = np.asarray(x_solve(np.asfortranarray(B.T @ Vg))).reshape(-1, Vg.shape[1])
    return x_orthonormal(np.column_stack([np.stack(U, axis=1), sup]), X), Vg


def bound_greedy(problem_at: Callable[[np.ndarray], Any],
                 hf_solve: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]],
                 X: Any, x_solve: Callable, bounds: np.ndarray, train: np.ndarray,
                 tol: float, n_max: int,
                 progress: Callable[[str], None] = lambda m: None,
                 on_step: Callable[[BoundGreedy], None] | None = None) -> BoundGreedy:
    """Run the greedy (module docstring) on the training parameters ``train`` (P, p).

    ``hf_solve(mu) -> (u on the free dofs, lam)``; ``tol``: on ``max Delta_u / ||u_N||_X``;
    ``n_max``: the most HF solves; ``on_step``: called with the state after each step (e.g.
    to measure the error on a validation set: not part of the algorithm)."""
    bounds = np.asarray(bounds, dtype=float)
    mu = bounds.mean(axis=1)
    U, L, picks, hist = [], [], [-1], []
    B = problem_at(mu).B
    while True:
        u, lam = hf_solve(mu)
        U.append(u)
        L.append(np.maximum(lam, 0.0))
        Z, Vg = _spaces(U, L, B, X, x_solve)
        model = build_affine_model(projector(problem_at, Z, Vg), bounds)
        bound = build_mixed_bound(problem_at, Z, Vg, X, x_solve, bounds)
        est = np.empty(len(train))
        for j, m in enumerate(train):
            res = model.solve(m, path="python", method="daqp")
            un = float(np.linalg.norm(res.c))  # ||Z c||_X: Z is X-orthonormal
            est[j] = bound(m, res.c, res.alpha).delta_u / un if un > 0 else np.inf
        j = int(np.argmax(est))
        hist.append(float(est[j]))
        progress(f"bound greedy: {len(U)} HF solves, max bound {est[j]:.3g}")
        stop = ("tolerance" if est[j] <= tol else "n_max" if len(U) >= n_max else "")
        state = BoundGreedy(model, bound, Z, Vg, list(picks), list(hist), len(U), stop)
        if on_step is not None:
            on_step(state)
        if stop:
            return state
        picks.append(j)
        mu = np.asarray(train[j], dtype=float)

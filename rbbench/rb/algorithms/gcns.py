"""Greedy Collocation Node Selection (GCNS) as a plain function on arrays.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slides "Greedy Collocation Node Selection (GCNS)" and "GCNS
algorithm".

The reduced friction problem (:mod:`rbbench.rb.friction.collocation.model`) imposes the tangential
constraint ``|lam_S^tau(c_s)| <= nu_F lam_R^n(c_s)`` at a subset ``C(q)`` of the HF
collocation nodes only. GCNS grows that subset:

* ``C(0) = {}`` (no friction constraint);
* iteration ``q``: with the reduced solutions ``lam_R^{n,q}(mu)``, ``lam_S^{tau,q}(mu)`` of
  every training mu at ``C(q)``, the violation ``[|lam_S^tau| - nu_F lam_R^n]_+`` at ALL
  HF nodes; ``mu_q`` = the training mu of the largest violation (``e_GCNS^{n tau}(q)``,
  its max norm), and the ``per_iteration`` nodes of largest violation at ``mu_q`` join
  ``C(q + 1)`` (the talk reports ``S_q = 40`` nodes in ``q = 20``: 2 per iteration);
* ``e_GCNS(q) = max_mu ||lam^tau - lam_S^{tau,q}||_{Gamma_c(mu)} / ||lam^tau||_{Gamma_c(mu)}``
  (HF snapshots against the reduced solution);
* stop when ``e_GCNS(q) > e_GCNS(q - 1)`` (the previous set is kept), when no node is
  violated (outside ``C(q)``), when every node is selected, or after ``max_iterations``
  additions. ``patience = k > 1`` relaxes Benaceur et al.'s rule (our option): stop after ``k``
  consecutive iterations above the best ``e_GCNS`` so far and keep the best set. Measured
  on hertz_friction P1 with full-rank bases (7 training mu): ``e_GCNS`` rises at q = 4
  (S_q = 8) before falling to 1e-13 at S_q = 26, so Benaceur et al.'s rule stops at q = 3.

Measured on hertz_friction P1, default mesh (513 nodes, 41 training mu, N = 30, R = S = 20,
PGA to dim 70): ``C(0) = {}`` leaves lam_t unconstrained (stick everywhere,
``e_GCNS(0) = 32``); their rule stops at q = 12 (S_q = 24, ``e_GCNS = 6.4``); past it
``e_GCNS`` reaches 1.0 at S_q ~ 48 and stays there: a node open at some mu pins
``(Vt theta)_r = 0`` there (``s_r = nu_F lam_n,R = 0``), and once the pinned rows span
``X_S`` the reduced lam_t of that mu is 0 (relative error exactly 1).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["GCNSResult", "gcns", "tangential_violation"]

#: ``nodes -> (LT, BOUND)``: reduced lam_t and its bound (Coulomb ``nu_F lam_R^n``, Tresca
#: ``s``) at every HF node (m x P), one column per training mu, with the tangential
#: constraint at ``nodes`` only.
SolveAll = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass
class GCNSResult:
    """Output of :func:`gcns`.

    ``nodes``: the selected HF node indices (in the order added); ``history``: one entry
    per computed set ``C(q)``, ``q = 0, 1, ...``, with ``q``, ``S_q`` (its size),
    ``e_nt`` (``e_GCNS^{n tau}(q)``, Pa), ``e_nt_rel`` (the same relative to the largest
    HF ``lam_n``), ``e_gcns`` and ``mu_index`` (the training column ``mu_q``);
    ``stop``: why the loop ended; ``iterations``: the ``q`` of the kept set (the set of the
    smallest ``e_gcns``).
    """

    nodes: np.ndarray
    history: list[dict[str, Any]] = field(default_factory=list)
    stop: str = ""
    iterations: int = 0

    @property
    def S_q(self) -> int:
        return int(self.nodes.size)


def tangential_violation(LT: np.ndarray, bound: np.ndarray) -> np.ndarray:
    """``[|lam_t| - bound]_+`` per node and column, ``bound = nu_F lam_n`` (Coulomb) or ``s``
    (Tresca); raw values (a negative reduced ``lam_n`` counts as a violation)."""
    return np.maximum(np.abs(LT) - bound, 0.0)


def _rel_errors(LAM_T: np.ndarray, LT: np.ndarray, W: Sequence[Any]) -> np.ndarray:
    """``||lam_t - LT||_W / ||lam_t||_W`` per column (``W[p]``: the Gram matrix at mu_p)."""
    out = np.empty(LAM_T.shape[1])
    for p in range(LAM_T.shape[1]):
        d, t = LAM_T[:, p] - LT[:, p], LAM_T[:, p]
        den = float(t @ (W[p] @ t))
        out[p] = np.sqrt(max(float(d @ (W[p] @ d)), 0.0) / den) if den > 0 else 0.0
    return out


def gcns(solve_all: SolveAll, LAM_T: np.ndarray, W: Sequence[Any], per_iteration: int = 2,
         max_iterations: int | None = None, lam_scale: float | None = None,
         patience: int = 1, tol: float = 1e-10) -> GCNSResult:
    """Greedy Collocation Node Selection (module docstring).

    Parameters
    ----------
    solve_all : callable
        ``nodes -> (LT, BOUND)``: the reduced lam_t at every HF node for every training mu
        and its bound (Coulomb: ``nu_F`` times the reduced lam_n), the tangential
        constraint imposed at ``nodes`` only.
    LAM_T : (m, P)
        HF tangential multipliers of the training set.
    W : sequence of (m, m)
        The L2(Gamma_c(mu_p)) Gram matrix of the nodal multipliers per training mu.
    per_iteration : int
        Nodes added per iteration (default 2, the published ``S_q / q``).
    max_iterations : int, optional
        Cap on the number of additions (default: until a stop rule or all nodes).
    lam_scale : float, optional
        Scale of ``e_nt_rel`` (default: the largest ``|lam_t|`` snapshot value).
    patience : int
        Consecutive increases of ``e_GCNS`` over its best that stop the loop (1: Benaceur
        et al.'s rule ``e_GCNS(q) > e_GCNS(q - 1)``).
    tol : float
        ``e_nt <= tol * lam_scale`` counts as no violation (solver round-off).
    """
    m = LAM_T.shape[0]
    scale = lam_scale or float(np.abs(LAM_T).max(initial=0.0)) or 1.0
    nodes = np.zeros(0, dtype=int)
    res = GCNSResult(nodes)
    q, best, bad = 0, np.inf, 0
    while True:
        LT, bound = solve_all(nodes)
        viol = tangential_violation(LT, bound)
        col = int(np.argmax(viol.max(axis=0))) if viol.size else 0
        e_nt = float(viol[:, col].max(initial=0.0))
        e = float(_rel_errors(LAM_T, LT, W).max(initial=0.0))
        res.history.append({"q": q, "S_q": int(nodes.size), "e_nt": e_nt,
                            "e_nt_rel": e_nt / scale, "e_gcns": e, "mu_index": col})
        if e > best:
            bad += 1
            if bad >= patience:
                res.stop = "e_gcns increased"  # res.nodes: the best set so far
                break
        else:
            best, bad = e, 0
            res.nodes, res.iterations = nodes, q
        if e_nt <= tol * scale:
            res.stop = "no violation"
            break
        if nodes.size == m or (max_iterations is not None and q >= max_iterations):
            res.stop = "all nodes" if nodes.size == m else "max_iterations"
            break
        cand = viol[:, col].copy()
        cand[nodes] = -1.0  # selected nodes are not picked again (their violation is ~0)
        order = np.argsort(-cand, kind="stable")
        new = [int(i) for i in order[:per_iteration] if cand[i] > 0.0]
        if not new:  # the violation sits at selected nodes only (solver tolerance)
            res.stop = "no violation outside C(q)"
            break
        nodes = np.concatenate([nodes, np.array(new, dtype=int)])
        q += 1
    return res

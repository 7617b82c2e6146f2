"""The mixed contact problem condensed on its contact unknowns with one factorisation of
the stiffness (the dense columns of ``A^{-1} B^T``): the Delassus operator of the LCP
solved by :mod:`rbbench.hf.solvers.lcp`.

The HF mixed problem::

    A u + B^T lam = F,  lam >= 0,  s := G - B u >= 0,  lam . s = 0

gives, with ``u = u0 - A^{-1} B^T lam`` and ``u0 = A^{-1} F``, the linear complementarity
problem LCP(q, D): ``s = q + D lam``, ``q = G - B u0``, ``D = B A^{-1} B^T``. The Schur
complement of the KKT matrix gives the same ``D`` without the dense columns
(:mod:`rbbench.hf.condensation.schur`).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from rbbench.interfaces import Factorize


@dataclass
class Condensed:
    """Result of :func:`condense`: everything needed to solve and recover ``u``."""

    u0: np.ndarray  # A^{-1} F
    AinvBt: np.ndarray  # A^{-1} B^T (n x m, dense)
    D: np.ndarray  # B A^{-1} B^T (m x m)
    q: np.ndarray  # G - B u0
    t_factor: float
    t_condense: float
    solve: Callable[[np.ndarray], np.ndarray] | None = None  # A^{-1}, for further loads
    B: sp.csr_matrix | None = None
    info: dict = field(default_factory=dict)

    def displacement(self, lam: np.ndarray) -> np.ndarray:
        return self.u0 - self.AinvBt @ lam

    def load(self, F: np.ndarray, G: np.ndarray) -> Condensed:
        """The same ``D`` with another load: ``u0 = A^{-1} F``, ``q = G - B u0``."""
        u0 = self.solve(np.asarray(F, dtype=float))
        return replace(self, u0=u0, q=np.asarray(G - self.B @ u0, dtype=float).ravel())


def factorize(A: sp.spmatrix):
    """Sparse LU of the SPD stiffness (SuperLU, symmetric mode: see pitfalls.md)."""
    return spla.splu(sp.csc_matrix(A), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                     options={"SymmetricMode": True})


def _scipy_solver(A: sp.spmatrix) -> Callable[[np.ndarray], np.ndarray]:
    return factorize(A).solve


def condense(A: sp.spmatrix, F: np.ndarray, B: sp.spmatrix, G: np.ndarray,
             factorize: Factorize | None = None) -> Condensed:
    """Factorise ``A`` once and form the Delassus operator ``D = B A^{-1} B^T``.

    ``factorize(A)`` returns ``solve(b)`` for ``b`` of shape (n,) or (n, k): a
    backend's direct solver (``ContactProblem.factorize``); ``None`` uses
    SuperLU (:func:`factorize`).
    """
    t0 = time.perf_counter()
    solve = (factorize or _scipy_solver)(A)
    t1 = time.perf_counter()
    u0 = solve(np.asarray(F, dtype=float))
    B = sp.csr_matrix(B)
    Bt = np.asarray(B.T.toarray())
    AinvBt = solve(Bt) if Bt.shape[1] else np.zeros((A.shape[0], 0))
    D = np.asarray(B @ AinvBt)
    D = 0.5 * (D + D.T)
    q = np.asarray(G - B @ u0).ravel()
    return Condensed(u0, AinvBt, D, q, t1 - t0, time.perf_counter() - t1, solve, B,
                     {"condensation": "columns"})


def delassus_scaling(D: np.ndarray) -> float:
    d = np.diag(D)
    return 1.0 / float(np.mean(d)) if d.size and np.mean(d) > 0 else 1.0

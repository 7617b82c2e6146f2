"""The Delassus operator as a Schur complement of the KKT matrix.

:func:`rbbench.hf.condensation.dense.condense` forms ``D = B A^{-1} B^T`` from ``A^{-1} B^T``, one
triangular solve pair per multiplier (512 dense right-hand sides at level 1 of
``hertz_halfdisks``: 88 % of the HF time). Here ``D`` is read off one sparse LU of the
saddle-point matrix with the multipliers eliminated last::

    K = [[A, B^T], [B, 0]],    K / A = -B A^{-1} B^T = -D

(the Schur complement of ``A`` in ``K``; e.g. Benzi, Golub, Liesen, Acta Numerica 2005,
eq. 3.1). With ``P K P^T = L U`` and the multipliers in the last positions, the trailing
block of the factors is that Schur complement: ``L_22 U_22 = -D``. The work is that of
one factorisation whose fill reaches the multiplier rows (``L^{-1} B^T`` restricted to the
elimination-tree paths of the contact dofs) instead of ``m`` dense solves.

Ordering without a new dependency: SuperLU's minimum degree (``MMD_AT_PLUS_A``) on ``K``
with the multiplier block stored as an explicit dense block of zeros (a clique: its
``m - 1`` neighbours make the multipliers the last to be eliminated). A few contact-zone
dofs may still come after the first multiplier: the trailing block then holds the Schur
complement on the multipliers and those ``k`` dofs, and they are eliminated from it densely
(``S_MM - S_MO S_OO^{-1} S_OM``). Multipliers whose row of ``B`` is zero (no quadrature
point in their support) are left out of ``K``: their rows and columns of ``D`` are zero,
as in :func:`~rbbench.hf.condensation.dense.condense`.

The load (``q``) and the displacement (``u``) come from solves with ``K``: with
``K [x; y] = [F; G]``, ``y = -D^{-1} q`` so ``q = -D y``; and for any multipliers ``lam``,
``u = u0 - A^{-1} B^T lam`` is the first block of ``K^{-1} [F; G - q - D lam]``.
"""

from __future__ import annotations

import dataclasses
import time
import types
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from rbbench.hf.condensation.dense import condense

#: ``condensation`` option of the condensed solvers: Schur complement of the KKT matrix, or
#: today's dense ``A^{-1} B^T`` (:func:`rbbench.hf.condensation.dense.condense`, the reference)
CONDENSATIONS = ("schur", "columns")
#: ``linear_solver`` option: the sparse direct solver of the condensation; ``"auto"``:
#: the backend's own solver when it gives one (``problem.factorize``, with ``"columns"``,
#: as before), else PARDISO when ``pypardiso`` is installed, else SuperLU
LINEAR_SOLVERS = ("auto", "superlu", "pardiso")


@dataclass
class SchurFactor:
    """One factorisation of the KKT matrix: ``D`` on the kept multipliers and ``K^{-1}``."""

    D: np.ndarray  # B_k A^{-1} B_k^T on the kept rows ``keep`` (m_k x m_k)
    solve: Callable[[np.ndarray], np.ndarray]  # K^{-1}, K of size n + m_k
    info: dict[str, Any] = field(default_factory=dict)
    #: PARDISO: K^{-1} in two halves around the Schur block (``forward``, ``backward``:
    #: :class:`rbbench.hf.condensation.pardiso.SchurSolves`), else None
    halves: Any = None


def kkt_matrix(A: sp.spmatrix, B: sp.spmatrix, lower: bool = False) -> sp.csc_matrix:
    """``K = [[A, B^T], [B, Z]]`` in CSC, ``Z`` an explicit dense block of zeros (module).

    ``lower``: only the lower triangle (its CSC arrays are the CSR arrays of the upper
    triangle, PARDISO's symmetric input), ``Z`` its explicit zero diagonal only (PARDISO
    keeps the multipliers last through its Schur rows, not through a clique). Built from the
    arrays directly (no COO sort).
    """
    n, m = A.shape[0], B.shape[0]
    Ac = sp.csc_matrix(sp.tril(A) if lower else A)
    Ac.sort_indices()
    Bc, Br = sp.csc_matrix(B), sp.csr_matrix(B)
    Bc.sort_indices()
    Br.sort_indices()
    nb = 0 if lower else Br.nnz  # B^T in the multiplier columns (upper part)
    left = Ac.indptr + Bc.indptr  # column j < n: A's entries, then B's (rows n + i)
    nnz_left = int(left[-1])
    clique = np.arange(m) if not lower else None
    zcount = np.full(m, m) if not lower else np.ones(m, dtype=int)
    right_cnt = (np.diff(Br.indptr) if not lower else np.zeros(m, int)) + zcount
    indptr = np.concatenate([left, nnz_left + np.cumsum(right_cnt)])
    indices = np.empty(int(indptr[-1]), dtype=np.int32)
    data = np.zeros(indices.size)
    pos = np.arange(Ac.nnz) + Bc.indptr[np.repeat(np.arange(n), np.diff(Ac.indptr))]
    indices[pos], data[pos] = Ac.indices, Ac.data
    pos = np.arange(Bc.nnz) + Ac.indptr[1:][np.repeat(np.arange(n), np.diff(Bc.indptr))]
    indices[pos], data[pos] = Bc.indices + n, Bc.data
    start = indptr[n:-1]
    if nb:
        rows = np.repeat(np.arange(m), np.diff(Br.indptr))
        pos = start[rows] + np.arange(nb) - Br.indptr[rows]
        indices[pos], data[pos] = Br.indices, Br.data
    col = np.repeat(np.arange(m), zcount)  # the zero block: all rows, or the diagonal
    first = np.cumsum(zcount) - zcount
    offset = np.arange(col.size) - first[col]
    zrow = offset if clique is not None else col + offset
    head = np.diff(Br.indptr)[col] if nb else 0
    indices[start[col] + head + offset] = n + zrow
    return sp.csc_matrix((data, indices, indptr), shape=(n + m, n + m))


def _trailing_schur(lu: Any, n: int, m: int) -> tuple[np.ndarray, int]:
    """``D`` from the trailing block of ``P K P^T = L U`` (symmetric pivoting checked).

    Returns ``(D, k)`` with ``k`` the number of displacement dofs eliminated after the
    first multiplier (condensed densely here).
    """
    N = n + m
    if not np.array_equal(lu.perm_r, lu.perm_c):
        raise np.linalg.LinAlgError("KKT LU pivoted off the diagonal")
    first = int(lu.perm_c[n:].min()) if m else N
    L = lu.L.tocsc()[:, first:].tocsr()[first:]
    U = lu.U.tocsc()[:, first:].tocsr()[first:]
    S = L.toarray() @ U.toarray()  # Schur complement of K on the trailing positions
    var = np.argsort(lu.perm_c)[first:]  # the variable at each trailing position
    mult = var >= n
    order = np.argsort(var[mult])  # multipliers back to their own order
    M, O = np.flatnonzero(mult)[order], np.flatnonzero(~mult)
    D = -S[np.ix_(M, M)]
    if O.size:  # displacement dofs after the first multiplier: eliminate them
        cho = sla.cho_factor(S[np.ix_(O, O)])
        D += S[np.ix_(M, O)] @ sla.cho_solve(cho, S[np.ix_(O, M)])
    return 0.5 * (D + D.T), int(O.size)


def _splu_symmetric(K: sp.csc_matrix, permc_spec: str) -> Any:
    return spla.splu(K, permc_spec=permc_spec, diag_pivot_thresh=0.0,
                     options={"SymmetricMode": True})


def _multipliers_last(K: sp.csc_matrix, perm_c: np.ndarray, n: int) -> Any:
    """SuperLU of ``K`` in the order of ``perm_c`` with the multipliers moved to the end;
    returns an object with ``L``, ``U``, ``solve``, ``nnz`` and the composed permutations."""
    by_position = np.argsort(perm_c)
    order = np.concatenate([by_position[by_position < n], np.arange(n, K.shape[0])])
    lu = _splu_symmetric(K[order][:, order].tocsc(), "NATURAL")
    inv = np.argsort(order)
    pos, pos_r = lu.perm_c[inv], lu.perm_r[inv]

    def solve(b: np.ndarray) -> np.ndarray:
        x = np.empty_like(b, dtype=float)
        x[order] = lu.solve(np.asarray(b, dtype=float)[order])
        return x

    return types.SimpleNamespace(L=lu.L, U=lu.U, perm_c=pos, perm_r=pos_r, solve=solve,
                                 nnz=lu.nnz)


def schur_superlu(A: sp.spmatrix, B: sp.spmatrix) -> SchurFactor:
    """SuperLU (symmetric mode, diagonal pivots) of the KKT matrix, ``D`` from its factors.

    Minimum degree on ``K`` first; when it pivoted or left more than ``max(m, 256)``
    displacement dofs after the first multiplier, a second factorisation in its order with
    the multipliers moved to the end. Raises ``RuntimeError`` when the factorisation fails
    (singular ``K``) and ``numpy.linalg.LinAlgError`` when it still pivoted.
    """
    n, m = A.shape[0], B.shape[0]
    K = kkt_matrix(A, B)
    lu = _splu_symmetric(K, "MMD_AT_PLUS_A")
    late = n + m - int(lu.perm_c[n:].min()) - m if m else 0
    reordered = not np.array_equal(lu.perm_r, lu.perm_c) or late > max(m, 256)
    if reordered:
        lu = _multipliers_last(K, lu.perm_c, n)
    D, k = _trailing_schur(lu, n, m)
    info = {"linear_solver": "superlu", "kkt_size": n + m, "dofs_after_multipliers": k,
            "factor_nnz": int(lu.nnz), "reordered": reordered}
    return SchurFactor(D, lu.solve, info)


def check_options(condensation: str, linear_solver: str) -> None:
    """ValueError naming a ``condensation`` / ``linear_solver`` option and the valid values."""
    for name, value, valid in (("condensation", condensation, CONDENSATIONS),
                               ("linear_solver", linear_solver, LINEAR_SOLVERS)):
        if value not in valid:
            raise ValueError(f"option {name} = {value!r} is not valid; expected one of "
                             + ", ".join(map(repr, valid)))


def schur_factor(A: sp.spmatrix, B: sp.spmatrix, linear_solver: str = "superlu"
                 ) -> SchurFactor:
    """The :class:`SchurFactor` of ``(A, B)`` with ``linear_solver`` (``"superlu"`` or
    ``"pardiso"``, which needs ``pypardiso``: :mod:`rbbench.hf.condensation.pardiso`)."""
    if linear_solver != "pardiso":
        return schur_superlu(A, B)
    from rbbench.hf.condensation.pardiso import schur_pardiso

    n, m = A.shape[0], B.shape[0]
    Kl = kkt_matrix(A, B, lower=True)  # its CSC arrays: the CSR of the upper triangle
    S, solves, info = schur_pardiso(sp.csr_matrix((Kl.data, Kl.indices, Kl.indptr),
                                                  shape=Kl.shape), m)
    D = S.T + S
    D *= -0.5
    return SchurFactor(D, solves.solve, {"linear_solver": "pardiso", "kkt_size": n + m,
                                         **info}, halves=solves)


def _pardiso_available() -> bool:
    try:
        from rbbench.hf.condensation.pardiso import available
    except ImportError:  # pragma: no cover - the module itself imports without pypardiso
        return False
    return available()


@dataclass
class SchurCondensed:
    """The condensed problem of :func:`condense_schur`, the interface of
    :class:`rbbench.hf.condensation.dense.Condensed` (``D``, ``q``, ``displacement``, ``load``,
    times)."""

    D: np.ndarray  # m x m, zero rows / columns for zero rows of B
    q: np.ndarray
    t_factor: float
    t_condense: float
    factor: SchurFactor
    keep: np.ndarray  # multipliers in K (non-zero rows of B)
    F: np.ndarray
    G: np.ndarray
    info: dict[str, Any] = field(default_factory=dict)
    #: with ``factor.halves``: the forward substitution of ``[F; G]`` (``load``)
    forward: np.ndarray | None = None

    @property
    def n(self) -> int:
        return int(self.F.size)

    def _kkt_solve(self, F: np.ndarray, g: np.ndarray) -> np.ndarray:
        return self.factor.solve(np.concatenate([F, g[self.keep]]))

    def load(self, F: np.ndarray, G: np.ndarray) -> SchurCondensed:
        """The same factorisation with another load: ``q = -D y``, ``K [x; y] = [F; G]``;
        with ``factor.halves``, ``q = G - B A^{-1} F`` is read off the forward substitution
        of ``[F; G]`` (its multiplier rows), kept for :meth:`displacement`."""
        F, G = np.asarray(F, float).ravel(), np.asarray(G, float).ravel()
        q = np.array(G, dtype=float)  # rows of B that are zero: q = G
        if self.factor.halves is not None:
            w = self.factor.halves.forward(np.concatenate([F, G[self.keep]]))
            q[self.keep] = w[F.size:]
            return dataclasses.replace(self, q=q, F=F, G=G, forward=w)
        y = self._kkt_solve(F, G)[F.size:]
        q[self.keep] = -(self.factor.D @ y)
        return dataclasses.replace(self, q=q, F=F, G=G)

    def displacement(self, lam: np.ndarray) -> np.ndarray:
        """``u = A^{-1} (F - B^T lam)``: the first block of ``K^{-1} [F; G - q - D lam]``;
        with ``factor.halves``, the backward substitution of the forward one of ``[F; G]``
        with ``lam`` in its multiplier rows (the Schur unknowns)."""
        lam = np.asarray(lam, float)
        if self.forward is not None:
            w = self.forward.copy()
            w[self.n:] = lam[self.keep]
            return self.factor.halves.backward(w)[: self.n]
        s = self.q + self.D @ lam
        return self._kkt_solve(self.F, self.G - s)[: self.n]


def _nonzero_rows(B: sp.csr_matrix) -> np.ndarray:
    """Rows of ``B`` with a non-zero entry."""
    Bc = sp.csr_matrix(B, copy=True)
    Bc.eliminate_zeros()
    return np.flatnonzero(np.diff(Bc.indptr) > 0)


def _check_definite(D: np.ndarray, rtol: float = 1e-12) -> None:
    """``numpy.linalg.LinAlgError`` unless ``D`` is numerically positive definite: its
    Cholesky pivots ``>= rtol max diag(D)`` (dependent rows of ``B`` make ``K`` singular;
    its solves, hence ``q`` and ``u``, would be meaningless)."""
    if D.size == 0:
        return
    piv = np.diag(np.linalg.cholesky(D)) ** 2  # LinAlgError when not positive definite
    if piv.min() < rtol * float(np.diag(D).max()):
        raise np.linalg.LinAlgError(f"D is singular to {rtol:g} (dependent rows of B)")


def condense_schur(A: sp.spmatrix, F: np.ndarray, B: sp.spmatrix, G: np.ndarray,
                   linear_solver: str = "superlu") -> SchurCondensed:
    """Condense ``A u + B^T lam = F`` on ``lam`` by the Schur complement of the KKT matrix.

    Same ``D`` and ``q`` as :func:`rbbench.hf.condensation.dense.condense` (to rounding) without
    ``A^{-1} B^T``; ``t_factor`` is the factorisation of ``K`` with the extraction of
    ``D``, ``t_condense`` the solve for ``q``.
    """
    B = sp.csr_matrix(B)
    F, G = np.asarray(F, float).ravel(), np.asarray(G, float).ravel()
    m = B.shape[0]
    keep = _nonzero_rows(B)
    t0 = time.perf_counter()
    fac = schur_factor(A, B[keep], linear_solver if keep.size else "superlu")
    _check_definite(fac.D)
    t1 = time.perf_counter()
    D = np.zeros((m, m))
    D[np.ix_(keep, keep)] = fac.D
    cond = SchurCondensed(D, np.array(G), t1 - t0, 0.0, fac, keep, F, G,
                          {**fac.info, "condensation": "schur"})
    cond = cond.load(F, G)
    cond.t_condense = time.perf_counter() - t1
    return cond


def condense_problem(A: sp.spmatrix, F: np.ndarray, B: sp.spmatrix, G: np.ndarray,
                     condensation: str = "schur", linear_solver: str = "auto",
                     factorize: Any = None) -> Any:
    """The condensed problem (``D``, ``q``, ``displacement``, ``load``) by the chosen method.

    ``"columns"``, or ``"auto"`` with a backend solver ``factorize``:
    :func:`rbbench.hf.condensation.dense.condense` (dense ``A^{-1} B^T``, the reference). Otherwise
    :func:`condense_schur` with PARDISO (``"pardiso"``, or ``"auto"`` when ``pypardiso`` is
    installed) or SuperLU. PARDISO missing: SuperLU; a Schur factorisation that fails
    (singular ``K``, a pivot off the diagonal or perturbed): the columns. Each fallback is
    said in ``info["fallback"]``; ``info`` also names the method and the solver used.
    """

    check_options(condensation, linear_solver)
    if condensation == "columns" or (linear_solver == "auto" and factorize is not None):
        cond = condense(A, F, B, G, factorize=factorize)
        cond.info["linear_solver"] = "backend" if factorize is not None else "superlu"
        return cond
    info: dict[str, Any] = {}
    chosen = linear_solver
    if linear_solver in ("auto", "pardiso"):
        chosen = "pardiso" if _pardiso_available() else "superlu"
        if linear_solver == "pardiso" and chosen != "pardiso":
            info["fallback"] = "superlu (pypardiso / MKL not installed)"
    try:
        cond = condense_schur(A, F, B, G, linear_solver=chosen)
    except (RuntimeError, np.linalg.LinAlgError) as exc:
        cond = condense(A, F, B, G, factorize=factorize)
        info["fallback"] = f"columns ({chosen} Schur complement failed: {exc})"
    cond.info.update(info)
    return cond

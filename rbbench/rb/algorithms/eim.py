"""Empirical interpolation (EIM / DEIM) of parameter-dependent vectors and sparse matrices.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slide "Affine parametric decomposition":
``B(mu) ~ E(mu) = sum_j alpha_j(mu) B_j``
with ``alpha(mu)`` fixed by interpolation at ``J`` "magic" entries (Barrault,
Maday, Nguyen, Patera 2004), so that the online stage needs only those
entries of ``B(mu)``. Errors follow their "EIM errors" slide::

    e_EIM = max_mu ||B(mu) - E(mu)||_{l_inf(ij)} / max_mu ||B(mu)||_{l_inf(ij)}

(a ratio of maxima over the parameter set, not a maximum of ratios).

Matrices are vectorised on the *union* sparsity pattern of the training
matrices, because the pattern changes with mu when the contact pairing does.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

__all__ = ["EIMResult", "MatrixEIM", "deim", "eim_error", "eim_error_curve", "matrix_eim"]

#: Stop when the largest residual entry is below this fraction of the largest snapshot entry:
#: the snapshots are then reproduced to rounding error (the numerical rank is reached).
RANK_TOL = 1e-11


@dataclass
class EIMResult:
    """An empirical interpolant ``I v = Q Q[magic]^{-1} v[magic]``.

    Attributes
    ----------
    Q : (n, m)
        Basis (greedy EIM: residuals normalised to 1 at their magic point, so
        ``Q[magic]`` is unit lower triangular; DEIM: orthonormal POD modes).
    magic : (m,) int
        Magic (interpolation) indices.
    errors : (m,)
        ``errors[k]``: relative max-norm interpolation error over the training
        snapshots with the first ``k + 1`` basis vectors (Benaceur et al.'s definition, above).
    picks : list of int
        Training columns selected by the greedy EIM (empty for DEIM).
    method : {"eim", "deim"}
    """

    Q: np.ndarray
    magic: np.ndarray
    errors: np.ndarray
    picks: list[int] = field(default_factory=list)
    method: str = "eim"
    tol: float | None = None

    def __post_init__(self) -> None:
        self.magic = np.asarray(self.magic, dtype=np.int64)
        self._lu = sla.lu_factor(self.Q[self.magic]) if self.m else None

    @property
    def m(self) -> int:
        return int(self.magic.size)

    def coefficients(self, values: np.ndarray) -> np.ndarray:
        """``theta`` with ``(Q theta)[magic] = values``; ``values`` (m,) or (m, k)."""
        values = np.asarray(values, dtype=float)
        if values.shape[0] != self.m:
            raise ValueError(f"expected {self.m} values at the magic points, got "
                             f"{values.shape[0]}")
        if self._lu is None:
            return np.zeros_like(values)
        return sla.lu_solve(self._lu, values)

    def interpolate(self, values: np.ndarray) -> np.ndarray:
        """The interpolant ``Q theta`` from the values at the magic points."""
        return self.Q @ self.coefficients(values)

    def approximate(self, vectors: np.ndarray) -> np.ndarray:
        """Interpolant of full vectors (n,) or (n, k): ``interpolate(vectors[magic])``."""
        return self.interpolate(np.asarray(vectors, dtype=float)[self.magic])


def deim(snapshots: np.ndarray, tol: float | None = None, m_max: int | None = None,
         method: str = "eim", rank_tol: float = RANK_TOL, groups: np.ndarray | None = None,
         threshold: float = 1.0, paid: np.ndarray | None = None) -> EIMResult:
    """Empirical interpolation of the columns of ``snapshots`` (n x P).

    Parameters
    ----------
    snapshots : (n, P)
    tol : float, optional
        Stop at the first size whose relative max-norm training error is ``<= tol``.
    m_max : int, optional
        Largest number of terms.
    method : {"eim", "deim"}
        ``"eim"`` (default): greedy EIM of Barrault-Maday-Nguyen-Patera (Benaceur et
        al., slide "Affine parametric decomposition"): pick the snapshot with the largest max-norm
        interpolation error, its largest residual entry is the next magic point, and the
        residual normalised to 1 there is the next basis vector. ``"deim"``: POD (SVD)
        basis with the DEIM index selection of Chaturantabut-Sorensen.
    rank_tol : float
        Stop when the residual is below ``rank_tol`` times the largest snapshot entry.
    groups : (n,) int, optional
        Greedy EIM only: the group of every entry (3D contact: the multiplier row of an
        entry of ``B(mu) Z``, whose quadrature points an online evaluation pays for once
        for all its entries). With ``threshold < 1`` the magic entry of each step is the
        largest residual entry in a group already *paid* for (``paid``, or holding an
        earlier magic entry), provided it is at least ``threshold`` times the largest
        residual entry of the picked snapshot; else the largest entry (row-aware
        selection, :func:`_pivot`).
    threshold : float in (0, 1]
        The relative pivot threshold of the row-aware selection (1: plain greedy EIM).
    paid : (k,) int, optional
        Groups paid for before the first step (e.g. the rows another EIM evaluates).
    """
    S = np.asarray(snapshots, dtype=float)
    if S.ndim == 1:
        S = S[:, None]
    n, P = S.shape
    m_max = min(n, P) if m_max is None else min(int(m_max), n, P)
    scale = float(np.abs(S).max()) if S.size else 0.0
    if scale == 0.0 or m_max == 0:
        return EIMResult(np.zeros((n, 0)), np.zeros(0, dtype=np.int64), np.zeros(0),
                         method=method, tol=tol)
    if not 0.0 < threshold <= 1.0:
        raise ValueError(f"threshold = {threshold!r}: expected a float in (0, 1]")
    if groups is not None:
        groups = np.asarray(groups, dtype=np.int64)
        if groups.shape != (n,):
            raise ValueError(f"groups: expected one group per entry ({n},), got shape "
                             f"{groups.shape}")
        if method != "eim":
            raise ValueError("groups (row-aware selection) needs method = 'eim'")
    if method == "eim":
        return _greedy_eim(S, scale, tol, m_max, rank_tol, groups, threshold, paid)
    if method == "deim":
        return _pod_deim(S, scale, tol, m_max, rank_tol)
    raise ValueError(f"method = {method!r}: expected 'eim' or 'deim'")


def _pivot(r: np.ndarray, groups: np.ndarray | None, threshold: float,
           paid: np.ndarray | None) -> int:
    """The magic entry of one greedy step in the residual ``r`` of the picked snapshot.

    Plain greedy EIM (Barrault-Maday-Nguyen-Patera 2004): ``argmax |r|``. Row-aware
    (``groups``, ``threshold < 1``): the largest ``|r_i|`` among the entries whose group is
    ``paid`` (a boolean mask over groups), if it is at least ``threshold max |r|``; else
    ``argmax |r|``. This is threshold partial pivoting (Duff, Erisman & Reid, "Direct
    Methods for Sparse Matrices", 1986: accept any pivot within a factor ``u`` of the
    column's largest entry to limit fill-in; here the "fill" is a new multiplier row to
    pair online): the new basis vector ``q = r / r_i`` is then bounded by
    ``1 / threshold`` instead of 1 in the max norm, so ``Q[magic]`` stays unit lower
    triangular with entries at most ``1 / threshold`` and the Lebesgue-constant bound
    ``2^M - 1`` of the greedy EIM (Maday, Nguyen, Patera & Pau, CPAA 8 (2009) 383-404)
    becomes ``(1 + 1 / threshold)^M - 1``. In the matrix DEIM of Negri, Manzoni &
    Amsallem (J. Comput. Phys. 303 (2015) 431-454) the online cost is the assembly on the
    reduced mesh, the elements supporting the magic entries, not the entries themselves
    (here: the quadrature points of the multiplier rows holding them); Chaturantabut &
    Sorensen's DEIM (SIAM J. Sci. Comput. 32 (2010) 2737-2764) picks the same
    ``argmax |r|`` as the plain greedy step.
    """
    a = np.abs(r)
    i = int(np.argmax(a))
    if groups is None or threshold >= 1.0 or paid is None or not paid.any():
        return i
    ok = paid[groups]
    if not ok.any():
        return i
    j = int(np.flatnonzero(ok)[np.argmax(a[ok])])
    return j if a[j] >= threshold * a[i] else i


def _greedy_eim(S: np.ndarray, scale: float, tol: float | None, m_max: int,
                rank_tol: float, groups: np.ndarray | None = None, threshold: float = 1.0,
                paid: np.ndarray | None = None) -> EIMResult:
    n, _ = S.shape
    paid_mask = None
    if groups is not None:
        paid_mask = np.zeros(int(groups.max(initial=-1)) + 1, dtype=bool)
        if paid is not None:
            pg = np.asarray(paid, dtype=np.int64)
            paid_mask[pg[pg < paid_mask.size]] = True
    R = np.array(S, dtype=float, order="F", copy=True)  # residuals s - I_k s
    Q = np.zeros((n, m_max), order="F")
    magic: list[int] = []
    picks: list[int] = []
    errors: list[float] = []
    dger = sla.get_blas_funcs("ger", (R,))

    def col_max(M: np.ndarray) -> np.ndarray:  # max |entry| per column, no n x P temporary
        return np.maximum(M.max(axis=0), -M.min(axis=0))

    col_err = col_max(R)
    for k in range(m_max):
        p = int(np.argmax(col_err))
        if col_err[p] <= rank_tol * scale:
            break
        i = _pivot(R[:, p], groups, threshold, paid_mask)
        if paid_mask is not None:
            paid_mask[groups[i]] = True
        q = R[:, p] / R[i, p]
        q[magic] = 0.0  # exact zeros at the previous magic points (rounding only)
        q[i] = 1.0
        Q[:, k] = q
        magic.append(i)
        picks.append(p)
        # BMNP recursion r_k = r_{k-1} - r_{k-1}[i_k] q_k, in place (BLAS rank-1 update)
        R = dger(-1.0, q, R[i, :].copy(), a=R, overwrite_a=True)
        R[magic, :] = 0.0
        col_err = col_max(R)
        errors.append(float(col_err.max()) / scale)
        if tol is not None and errors[-1] <= tol:
            break
    m = len(magic)
    return EIMResult(Q[:, :m].copy(), np.array(magic, dtype=np.int64), np.array(errors),
                     picks, "eim", tol)


def _pod_deim(S: np.ndarray, scale: float, tol: float | None, m_max: int,
              rank_tol: float) -> EIMResult:
    Uq, s, _ = np.linalg.svd(S, full_matrices=False)
    r = int(np.sum(s > rank_tol * s[0]))
    Uq = Uq[:, : min(r, m_max)]
    magic: list[int] = []
    errors: list[float] = []
    for k in range(Uq.shape[1]):
        u = Uq[:, k]
        if k:
            c = np.linalg.solve(Uq[magic, :k], u[magic])
            u = u - Uq[:, :k] @ c
        magic.append(int(np.argmax(np.abs(u))))
        Qk = Uq[:, : k + 1]
        theta = np.linalg.solve(Qk[magic], S[magic])
        errors.append(float(np.abs(S - Qk @ theta).max()) / scale)
        if tol is not None and errors[-1] <= tol:
            break
    m = len(magic)
    return EIMResult(Uq[:, :m].copy(), np.array(magic, dtype=np.int64), np.array(errors),
                     [], "deim", tol)


# ---------------------------------------------------------------------------
# sparse matrices
# ---------------------------------------------------------------------------
@dataclass
class MatrixEIM:
    """EIM of a family of sparse matrices ``B(mu) ~ sum_j theta_j(mu) B_j``.

    Attributes
    ----------
    eim : EIMResult
        The vector EIM of the entry vectors on the union pattern.
    shape : (m, n)
    rows, cols : (nnz,) int
        Union sparsity pattern of the training matrices (row-major order).
    magic_rows, magic_cols : (J,) int
        Magic entries: the online stage needs ``B(mu)[magic_rows, magic_cols]`` only.
    basis : list of csr_matrix
        ``B_j`` on the union pattern.
    """

    eim: EIMResult
    shape: tuple[int, int]
    rows: np.ndarray
    cols: np.ndarray
    magic_rows: np.ndarray
    magic_cols: np.ndarray
    basis: list[sp.csr_matrix]

    @property
    def m(self) -> int:
        return self.eim.m

    @property
    def errors(self) -> np.ndarray:
        return self.eim.errors

    def entries(self, mat) -> np.ndarray:
        """Entries of a (sparse or dense) matrix at the magic positions (0 if not stored)."""
        if sp.issparse(mat):
            return np.asarray(sp.csr_matrix(mat)[self.magic_rows, self.magic_cols],
                              dtype=float).ravel()
        return np.asarray(mat, dtype=float)[self.magic_rows, self.magic_cols]

    def coefficients(self, magic_entries: np.ndarray) -> np.ndarray:
        """``theta(mu)`` from the entries of ``B(mu)`` at the magic (row, col) positions."""
        return self.eim.coefficients(magic_entries)

    def assemble(self, theta: np.ndarray) -> sp.csr_matrix:
        """``sum_j theta_j B_j`` as a sparse matrix."""
        vals = self.eim.Q @ np.asarray(theta, dtype=float)
        return sp.csr_matrix((vals, (self.rows, self.cols)), shape=self.shape)

    def approximate(self, mat) -> sp.csr_matrix:
        """``E(mu)`` for a full matrix ``B(mu)`` (uses only its magic entries)."""
        return self.assemble(self.coefficients(self.entries(mat)))


def _union_pattern(mats: list) -> tuple[tuple[int, int], np.ndarray, list[np.ndarray],
                                        list[sp.coo_matrix]]:
    shape = mats[0].shape
    coos = []
    for j, M in enumerate(mats):
        if M.shape != shape:
            raise ValueError(f"matrix {j} has shape {M.shape}, the first {shape}")
        C = sp.coo_matrix(M)
        C.sum_duplicates()
        coos.append(C)
    keys = [C.row.astype(np.int64) * shape[1] + C.col.astype(np.int64) for C in coos]
    union = np.unique(np.concatenate(keys)) if keys else np.zeros(0, dtype=np.int64)
    return shape, union, [np.searchsorted(union, k) for k in keys], coos


def matrix_eim(mats: list, tol: float | None = None, m_max: int | None = None,
               method: str = "eim") -> MatrixEIM:
    """EIM of sparse matrices ``mats`` (all m x n, one per training parameter).

    The entries are vectorised on the union of the sparsity patterns (the pattern
    changes with mu with the contact pairing; an entry missing from one matrix is
    zero there) and :func:`deim` is run on the entry vectors.
    """
    if not mats:
        raise ValueError("matrix_eim needs at least one matrix")
    shape, union, positions, coos = _union_pattern(list(mats))
    S = np.zeros((union.size, len(coos)))
    for j, (pos, C) in enumerate(zip(positions, coos, strict=True)):
        S[pos, j] = C.data
    res = deim(S, tol=tol, m_max=m_max, method=method)
    rows, cols = np.divmod(union, shape[1])
    basis = [sp.csr_matrix((res.Q[:, k], (rows, cols)), shape=shape) for k in range(res.m)]
    return MatrixEIM(res, (int(shape[0]), int(shape[1])), rows, cols, rows[res.magic],
                     cols[res.magic], basis)


def eim_error(result: EIMResult | MatrixEIM, mats) -> float:
    """Benaceur et al.'s ``e_EIM``: ``max_mu ||B - E||_{l_inf(ij)} / max_mu ||B||_{l_inf(ij)}``.

    ``mats`` is a list of sparse matrices for a :class:`MatrixEIM`, and an (n, P)
    array (or a list of vectors) for an :class:`EIMResult`. Entries outside the
    training union pattern count in the error (they are not represented).
    """
    if isinstance(result, MatrixEIM):
        num = den = 0.0
        for M in mats:
            M = sp.csr_matrix(M)
            D = M - result.approximate(M)
            num = max(num, float(abs(D).max()) if D.nnz else 0.0)
            den = max(den, float(abs(M).max()) if M.nnz else 0.0)
        return num / den if den > 0 else 0.0
    S = np.asarray(mats, dtype=float)
    if isinstance(mats, list):
        S = S.T
    if S.ndim == 1:
        S = S[:, None]
    den = float(np.abs(S).max()) if S.size else 0.0
    num = float(np.abs(S - result.approximate(S)).max()) if S.size else 0.0
    return num / den if den > 0 else 0.0


def eim_error_curve(result: EIMResult, snapshots: np.ndarray) -> dict[str, np.ndarray]:
    """Errors of the nested interpolants ``I_k`` (the first ``k`` terms, ``k = 1 .. m``) of a
    greedy :class:`EIMResult` on the columns of ``snapshots`` (n, P), e.g. a validation set.

    Returns ``{"ratio": Benaceur et al.'s e_EIM, max_mu ||s - I_k s||_inf / max_mu ||s||_inf,
    "max_rel": max_mu ||s - I_k s||_inf / ||s||_inf}`` (zero columns skipped), each (m,).
    Greedy EIM only (its ``Q[magic]`` is unit lower triangular, so the first ``k`` terms
    are an interpolant); a DEIM result raises ``ValueError``.
    """
    if result.method != "eim":
        raise ValueError("eim_error_curve: nested interpolants need the greedy EIM")
    S = np.asarray(snapshots, dtype=float)
    S = S[:, None] if S.ndim == 1 else S
    norms = np.abs(S).max(axis=0) if S.size else np.zeros(0)
    den, nz = float(norms.max(initial=0.0)), norms > 0
    ratio, max_rel = np.zeros(result.m), np.zeros(result.m)
    R = S.copy()
    for k in range(result.m):  # BMNP recursion: r_k = r_{k-1} - r_{k-1}[i_k] q_k
        R -= np.outer(result.Q[:, k], R[result.magic[k]])
        err = np.abs(R).max(axis=0)
        ratio[k] = float(err.max(initial=0.0)) / den if den > 0 else 0.0
        max_rel[k] = float((err[nz] / norms[nz]).max(initial=0.0))
    return {"ratio": ratio, "max_rel": max_rel}

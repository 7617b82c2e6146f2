"""The KKT Schur complement with Intel MKL PARDISO (``linear_solver = "pardiso"``).

PARDISO computes the dense Schur complement of a sparse matrix on the rows marked in
``perm`` during its factorisation (``iparm[35] = 1``: the Schur complement and the
factors of the rest, the Schur block itself left unfactorised; oneMKL developer
reference, "pardiso iparm parameter"). ``K = [[A, B^T], [B, 0]]`` is symmetric
indefinite (``mtype = -2``, upper triangle), its Schur complement on the multipliers is
``-D`` (:mod:`rbbench.hf.condensation.schur`). Solves with ``K`` go in two halves around the
Schur block (:class:`SchurSolves`): the forward substitution (phase 331) leaves the Schur
right-hand side ``G - B A^{-1} F`` in the multiplier rows, the backward substitution
(phase 333) takes the multiplier values put there and returns ``A^{-1} (F - B^T y)``.
MKL comes from ``pypardiso`` (PyPI wheels with ``mkl``); without it :func:`available` is
False and the callers fall back to SuperLU.
Loading it sets MKL (used here by PARDISO only) to one thread, the rule of every HF solve
(:mod:`rbbench.runtime.threads`). A factorisation that perturbed a pivot (``iparm[13] > 0``) is
refused (``numpy.linalg.LinAlgError``): the Schur complement would not be exact.
"""

from __future__ import annotations

import ctypes
import weakref
from typing import Any

import numpy as np
import scipy.sparse as sp

_LIB: dict[str, Any] = {}
_MTYPE = -2  # real symmetric indefinite (the KKT matrix)
_SPD = 2  # real symmetric positive definite (Cholesky: the floor's stiffness)


def _pardiso() -> Any:
    """MKL's ``pardiso`` through ``pypardiso``'s library lookup (ImportError without it)."""
    if "f" not in _LIB:
        from pypardiso.pardiso_wrapper import PyPardisoSolver

        lib = PyPardisoSolver().libmkl
        lib.MKL_Set_Num_Threads(1)  # one thread per HF solve (rbbench.runtime.threads)
        f = lib.pardiso
        i32 = ctypes.POINTER(ctypes.c_int32)
        f.argtypes = [ctypes.POINTER(ctypes.c_int64), i32, i32, i32, i32, i32,
                      ctypes.c_void_p, i32, i32, i32, i32, i32, i32, ctypes.c_void_p,
                      ctypes.c_void_p, i32]
        f.restype = None
        _LIB["f"] = f
    return _LIB["f"]


def available() -> bool:
    """Whether PARDISO (``pypardiso`` and MKL's runtime) can be loaded."""
    try:
        _pardiso()
    except (ImportError, OSError):
        return False
    return True


def warm_up() -> bool:
    """Load MKL and run PARDISO once on a 2 x 2 matrix, once per process (False when
    PARDISO is not available). The first PARDISO call of a process costs about 0.6 s
    (library loading and initialisation, measured at level 0 of hertz_halfdisks: a 0.9 s
    solve, 0.32 s from the second on): a per-process cost like an import, paid at solver
    construction (``times_s.setup_s``), not inside a timed solve."""
    if "warm" not in _LIB:
        if not available():
            return False
        factorized(sp.csr_matrix(np.array([[2.0, 1.0], [1.0, 2.0]])))(np.ones(2))
        _LIB["warm"] = True
    return True


class _Handle:
    """One PARDISO factorisation (``pt``, ``iparm`` and the CSR arrays it refers to)."""

    def __init__(self, U: sp.csr_matrix, schur_rows: np.ndarray, mtype: int = _MTYPE) -> None:
        self.n, self.mtype = U.shape[0], mtype
        self.a = np.ascontiguousarray(U.data, dtype=np.float64)
        self.ia = np.ascontiguousarray(U.indptr, dtype=np.int32)
        self.ja = np.ascontiguousarray(U.indices, dtype=np.int32)
        self.pt = np.zeros(64, dtype=np.int64)
        self.iparm = np.zeros(64, dtype=np.int32)
        # iparm[23] = 1: the two-level factorisation, faster than the classic one on both
        # the KKT matrix and the floor's A (measured: level 2 of hertz_halfdisks, analysis
        # included; level 0 even), exact as the classic one (no approximation)
        self.iparm[[0, 1, 7, 9, 17, 20, 23, 34, 35]] = [1, 2, 0, 13, -1, 1, 1, 1,
                                                        1 if len(schur_rows) else 0]
        self.perm = np.zeros(self.n, dtype=np.int32)
        self.perm[schur_rows] = 1
        self._finalizer = weakref.finalize(self, _release, self.pt, self.iparm, self.n, mtype)

    def call(self, phase: int, b: np.ndarray, x: np.ndarray, nrhs: int = 1) -> None:
        """One ``pardiso`` call; ``RuntimeError`` on a non-zero error code."""
        err = ctypes.c_int32(0)
        i32 = ctypes.c_int32
        _pardiso()(self.pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
                   ctypes.byref(i32(1)), ctypes.byref(i32(1)), ctypes.byref(i32(self.mtype)),
                   ctypes.byref(i32(phase)), ctypes.byref(i32(self.n)),
                   self.a.ctypes.data, self.ia.ctypes.data_as(ctypes.POINTER(i32)),
                   self.ja.ctypes.data_as(ctypes.POINTER(i32)),
                   self.perm.ctypes.data_as(ctypes.POINTER(i32)), ctypes.byref(i32(nrhs)),
                   self.iparm.ctypes.data_as(ctypes.POINTER(i32)), ctypes.byref(i32(0)),
                   b.ctypes.data, x.ctypes.data, ctypes.byref(err))
        if err.value != 0:
            raise RuntimeError(f"PARDISO phase {phase}: error {err.value}")

    def solve(self, b: np.ndarray, phase: int = 33) -> np.ndarray:
        """``K^{-1} b`` for ``b`` of shape (n,) or (n, k) (``phase`` 331 / 333: one half)."""
        b = np.asarray(b, dtype=np.float64)
        rhs = np.asfortranarray(b.reshape(self.n, -1))
        x = np.zeros_like(rhs, order="F")
        self.call(phase, rhs, x, nrhs=rhs.shape[1])
        return x.reshape(b.shape)


class SchurSolves:
    """Solves with ``K`` factorised with its Schur complement ``S`` on the last ``m`` rows
    (``iparm[35] = 1``), in the halves of the substitution around the Schur block.

    ``forward(b)``: the forward substitution (phase 331; ``[b1; b2]`` of size ``N``); its
    last ``m`` entries are the Schur right-hand side ``b2 - K21 K11^{-1} b1``.
    ``backward(w)``: the backward substitution (phase 333) of a forward result whose last
    ``m`` entries were replaced by ``y``: ``[K11^{-1} (b1 - K12 y); y]``. ``solve(b)``:
    ``K^{-1} b`` (the two halves with ``S y = w2`` solved densely between them).
    """

    def __init__(self, handle: _Handle, S: np.ndarray) -> None:
        self.handle, self.S, self.m = handle, S, S.shape[0]
        self._lu: Any = None

    def forward(self, b: np.ndarray) -> np.ndarray:
        return self.handle.solve(b, 331)

    def backward(self, w: np.ndarray) -> np.ndarray:
        return self.handle.solve(w, 333)

    def solve(self, b: np.ndarray) -> np.ndarray:
        import scipy.linalg as sla

        if self._lu is None:
            self._lu = sla.lu_factor(self.S)
        w = self.forward(b)
        w[w.shape[0] - self.m:] = sla.lu_solve(self._lu, w[w.shape[0] - self.m:])
        return self.backward(w)


def _release(pt: np.ndarray, iparm: np.ndarray, n: int, mtype: int = _MTYPE) -> None:
    """Free PARDISO's memory of one handle (phase -1)."""
    if not pt.any() or "f" not in _LIB:
        return
    err, i32 = ctypes.c_int32(0), ctypes.c_int32
    dummy = np.zeros(1)
    idx = np.zeros(1, dtype=np.int32)
    _LIB["f"](pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(i32(1)),
              ctypes.byref(i32(1)), ctypes.byref(i32(mtype)), ctypes.byref(i32(-1)),
              ctypes.byref(i32(n)), dummy.ctypes.data, idx.ctypes.data_as(ctypes.POINTER(i32)),
              idx.ctypes.data_as(ctypes.POINTER(i32)), idx.ctypes.data_as(ctypes.POINTER(i32)),
              ctypes.byref(i32(1)), iparm.ctypes.data_as(ctypes.POINTER(i32)),
              ctypes.byref(i32(0)), dummy.ctypes.data, dummy.ctypes.data, ctypes.byref(err))


def schur_pardiso(K_upper: sp.csr_matrix, m: int) -> tuple[np.ndarray, SchurSolves, dict]:
    """PARDISO's factorisation of the symmetric ``K`` (its upper triangle ``K_upper``,
    sorted CSR) with the Schur complement on its last ``m`` rows.

    Returns ``(S, solves, info)``: the dense Schur complement, the :class:`SchurSolves`
    with ``K`` and a record (``factor_nnz``, ``perturbed_pivots``). With ``K`` the KKT
    matrix, ``S = -D`` (:func:`rbbench.hf.condensation.schur.schur_factor`).
    """
    N = K_upper.shape[0]
    h = _Handle(K_upper, np.arange(N - m, N))
    S = np.zeros((m, m))
    h.call(12, np.zeros(1), S)  # analysis + factorisation; S: the Schur complement
    if h.iparm[13] > 0:
        raise np.linalg.LinAlgError(f"PARDISO perturbed {int(h.iparm[13])} pivots")
    info = {"factor_nnz": int(h.iparm[17]), "perturbed_pivots": int(h.iparm[13])}
    return S, SchurSolves(h, S), info


def factorized(A: sp.spmatrix) -> Any:
    """``solve = factorized(A)``: PARDISO's factorisation of a symmetric ``A`` (its upper
    triangle; no Schur complement) and ``solve(b) = A^{-1} b`` (:data:`rbbench.interfaces.
    Factorize`), e.g. the floor of a PARDISO solve.

    Cholesky (``mtype = 2``) first: a stiffness is SPD, and the floor should be the fastest
    plain factorisation PARDISO offers (measured on hertz_halfdisks levels 0-2: 5-8 %
    faster than ``LDL^T``; minimum-degree ordering instead of METIS: within 2 %); a
    matrix Cholesky refuses is factorised as symmetric indefinite."""
    U = sp.triu(A, format="csr")
    U.sort_indices()
    try:
        h = _Handle(U, np.zeros(0, dtype=int), mtype=_SPD)
        h.call(12, np.zeros(1), np.zeros(1))
    except RuntimeError:  # not positive definite (PARDISO error -4)
        h = _Handle(U, np.zeros(0, dtype=int))
        h.call(12, np.zeros(1), np.zeros(1))
    return h.solve

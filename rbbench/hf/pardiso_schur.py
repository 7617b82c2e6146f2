"""The KKT Schur complement with Intel MKL PARDISO (``linear_solver = "pardiso"``).

PARDISO computes the dense Schur complement of a sparse matrix on the rows marked in
``perm`` during its factorisation (``iparm[35] = 2``: the Schur complement and the
factors of the whole matrix, so the solve phase still solves with ``K``; oneMKL developer
reference, "pardiso iparm parameter"). ``K = [[A, B^T], [B, 0]]`` is symmetric
indefinite (``mtype = -2``, upper triangle), its Schur complement on the multipliers is
``-D`` (:mod:`rbbench.hf.condensation`). MKL comes from ``pypardiso`` (PyPI wheels with
``mkl``); without it :func:`available` is False and the callers fall back to SuperLU.
Loading it sets MKL (used here by PARDISO only) to one thread, the rule of every HF solve
(:mod:`rbbench.hf.threads`). A factorisation that perturbed a pivot (``iparm[13] > 0``) is refused
(``numpy.linalg.LinAlgError``): the Schur complement would not be exact.
"""

from __future__ import annotations

import ctypes
import weakref
from typing import Any

import numpy as np
import scipy.sparse as sp

_LIB: dict[str, Any] = {}
_MTYPE = -2  # real symmetric indefinite


def _pardiso() -> Any:
    """MKL's ``pardiso`` through ``pypardiso``'s library lookup (ImportError without it)."""
    if "f" not in _LIB:
        from pypardiso.pardiso_wrapper import PyPardisoSolver

        lib = PyPardisoSolver().libmkl
        lib.MKL_Set_Num_Threads(1)  # one thread per HF solve (rbbench.hf.threads)
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

    def __init__(self, U: sp.csr_matrix, schur_rows: np.ndarray) -> None:
        self.n = U.shape[0]
        self.a = np.ascontiguousarray(U.data, dtype=np.float64)
        self.ia = np.ascontiguousarray(U.indptr, dtype=np.int32)
        self.ja = np.ascontiguousarray(U.indices, dtype=np.int32)
        self.pt = np.zeros(64, dtype=np.int64)
        self.iparm = np.zeros(64, dtype=np.int32)
        self.iparm[[0, 1, 7, 9, 17, 20, 34, 35]] = [1, 2, 0, 13, -1, 1, 1,
                                                    2 if len(schur_rows) else 0]
        self.perm = np.zeros(self.n, dtype=np.int32)
        self.perm[schur_rows] = 1
        self._finalizer = weakref.finalize(self, _release, self.pt, self.iparm, self.n)

    def call(self, phase: int, b: np.ndarray, x: np.ndarray, nrhs: int = 1) -> None:
        """One ``pardiso`` call; ``RuntimeError`` on a non-zero error code."""
        err = ctypes.c_int32(0)
        i32 = ctypes.c_int32
        _pardiso()(self.pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
                   ctypes.byref(i32(1)), ctypes.byref(i32(1)), ctypes.byref(i32(_MTYPE)),
                   ctypes.byref(i32(phase)), ctypes.byref(i32(self.n)),
                   self.a.ctypes.data, self.ia.ctypes.data_as(ctypes.POINTER(i32)),
                   self.ja.ctypes.data_as(ctypes.POINTER(i32)),
                   self.perm.ctypes.data_as(ctypes.POINTER(i32)), ctypes.byref(i32(nrhs)),
                   self.iparm.ctypes.data_as(ctypes.POINTER(i32)), ctypes.byref(i32(0)),
                   b.ctypes.data, x.ctypes.data, ctypes.byref(err))
        if err.value != 0:
            raise RuntimeError(f"PARDISO phase {phase}: error {err.value}")

    def solve(self, b: np.ndarray) -> np.ndarray:
        """``K^{-1} b`` for ``b`` of shape (n,) or (n, k)."""
        b = np.asarray(b, dtype=np.float64)
        rhs = np.asfortranarray(b.reshape(self.n, -1))
        x = np.zeros_like(rhs, order="F")
        self.call(33, rhs, x, nrhs=rhs.shape[1])
        return x.reshape(b.shape)


def _release(pt: np.ndarray, iparm: np.ndarray, n: int) -> None:
    """Free PARDISO's memory of one handle (phase -1)."""
    if not pt.any() or "f" not in _LIB:
        return
    err, i32 = ctypes.c_int32(0), ctypes.c_int32
    dummy = np.zeros(1)
    idx = np.zeros(1, dtype=np.int32)
    _LIB["f"](pt.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), ctypes.byref(i32(1)),
              ctypes.byref(i32(1)), ctypes.byref(i32(_MTYPE)), ctypes.byref(i32(-1)),
              ctypes.byref(i32(n)), dummy.ctypes.data, idx.ctypes.data_as(ctypes.POINTER(i32)),
              idx.ctypes.data_as(ctypes.POINTER(i32)), idx.ctypes.data_as(ctypes.POINTER(i32)),
              ctypes.byref(i32(1)), iparm.ctypes.data_as(ctypes.POINTER(i32)),
              ctypes.byref(i32(0)), dummy.ctypes.data, dummy.ctypes.data, ctypes.byref(err))


def schur_pardiso(K_upper: sp.csr_matrix, m: int) -> tuple[np.ndarray, Any, dict]:
    """PARDISO's factorisation of the symmetric ``K`` (its upper triangle ``K_upper``,
    sorted CSR) with the Schur complement on its last ``m`` rows.

    Returns ``(S, solve, info)``: the dense Schur complement, ``K^{-1}`` and a record
    (``factor_nnz``, ``perturbed_pivots``). With ``K`` the KKT matrix, ``S = -D``
    (:func:`rbbench.hf.condensation.schur_factor`).
    """
    N = K_upper.shape[0]
    h = _Handle(K_upper, np.arange(N - m, N))
    S = np.zeros((m, m))
    h.call(12, np.zeros(1), S)  # analysis + factorisation; S: the Schur complement
    if h.iparm[13] > 0:
        raise np.linalg.LinAlgError(f"PARDISO perturbed {int(h.iparm[13])} pivots")
    return S, h.solve, {"factor_nnz": int(h.iparm[17]), "perturbed_pivots": int(h.iparm[13])}


def factorized(A: sp.spmatrix) -> Any:
    """``solve = factorized(A)``: PARDISO's factorisation of a symmetric ``A`` (its upper
    triangle; no Schur complement) and ``solve(b) = A^{-1} b`` (:data:`rbbench.interfaces.
    Factorize`), e.g. the floor of a PARDISO solve."""
    U = sp.triu(A, format="csr")
    U.sort_indices()
    h = _Handle(U, np.zeros(0, dtype=int))
    h.call(12, np.zeros(1), np.zeros(1))
    return h.solve

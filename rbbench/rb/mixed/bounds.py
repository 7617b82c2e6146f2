"""The certified error bound of the mixed reduced contact model, offline-online.

The bound is :mod:`rbbench.rb.algorithms.bounds` (Haasdonk, Salomon & Wohlmuth 2012, in the
natural multiplier norm ``||eta||_* = ||B^T eta||_X'``: no inf-sup constant enters). Here its
terms are split offline-online for a model whose HF operators are affine in mu
(``theta = [1, mu]``, probed by :func:`rbbench.rb.algorithms.affine.affine_decomposition`):

* ``rho = ||F - A Z c - B^T Vg alpha||_X'`` and ``l_N = ||B^T Vg alpha||_X'``: the Riesz
  representers of the non-zero affine pieces ``F_q``, ``A_q Z``, ``B_q^T Vg``, orthonormalised
  in X offline (:func:`~rbbench.rb.algorithms.bounds.riesz_factor`); online ``||T w||`` with
  ``w = [theta_F, -theta_A (x) c, -theta_B (x) alpha]``: cost independent of the HF size;
* ``d = B Z c - G`` on the m contact rows (``B_q Z``, ``G_q`` offline), ``sigma = ||[d]_+||_*'``
  through ``D^{-1}``, ``D = B X^{-1} B^T`` (B independent of mu: factorised once; ``B``
  square and diagonal, as the membrane's lumped nodal multipliers: ``D^{-1} = B^{-1} X
  B^{-1}``, sparse), ``kappa = (Vg alpha) . [-d]_+``. This part costs O(m N) online
  (the positive part is not affine): like HSW's bound, the decomposition is partial, O(m)
  on the contact rows (on the membrane every interior node is a contact row).
* ``alpha_LB``, ``gamma_UB``: the extreme eigenvalues of ``(A, X)`` when ``A`` does not
  depend on mu (exact; both scenes: the membrane's Laplacian, and Hertz's stiffness, which a
  dilation of one body leaves invariant). A mu-dependent ``A`` has no bound here
  (:class:`BoundUnsupported`).

A model whose constraint is not affine has no online bound here: on a two-body scene with
the contact EIM, :mod:`rbbench.rb.mixed.contact_bound` evaluates the contact rows online
instead; elsewhere :func:`hf_bound` evaluates the same theorem with the HF operators at mu
(rigorous, HF cost).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from rbbench.rb.algorithms.affine import LinearInMu, NotAffineError, affine_decomposition
from rbbench.rb.algorithms.bounds import (
    BoundTerms,
    VIBound,
    coercivity_constants,
    delassus,
    hf_bound_terms,
    natural_dual,
    riesz_factor,
    vi_bound,
)

__all__ = ["BoundUnsupported", "MixedBound", "build_mixed_bound", "constant_in_mu", "hf_bound"]


class BoundUnsupported(ValueError):
    """The online bound cannot be built for this model (the message says why)."""


@dataclass
class MixedBound:
    """Online evaluator of the bound (module docstring): small arrays and the contact rows.

    ``T`` (k, q): the X-orthonormal Riesz coordinates of the pieces; ``qF``, ``qA``, ``qB``:
    the theta indices of the non-zero F, A, B terms; ``C`` (len(qC), m, N'), ``Gq``
    (len(qG), m): the contact rows of ``B_q Z`` and ``G_q``; ``Vg`` (m, R); ``Dinv``: sparse
    ``D^{-1}`` or ``Lchol`` the lower Cholesky factor of D.
    """

    T: np.ndarray
    qF: np.ndarray
    qA: np.ndarray
    qB: np.ndarray
    qC: np.ndarray
    qG: np.ndarray
    C: np.ndarray
    Gq: np.ndarray
    Vg: np.ndarray
    alpha: float
    gamma: float
    p: int
    Dinv: Any = None
    Lchol: np.ndarray | None = None

    def __post_init__(self) -> None:
        nF, N, R = len(self.qF), self.C.shape[-1], self.Vg.shape[1]
        self._b0 = nF + len(self.qA) * N
        self._TB = np.ascontiguousarray(self.T[:, self._b0:self._b0 + len(self.qB) * R])
        self._theta = LinearInMu(self.p)

    def terms(self, mu: np.ndarray, c: np.ndarray, a: np.ndarray) -> BoundTerms:
        """The terms (1)-(4) by numpy (the reference of :meth:`terms_compiled`)."""
        th = self._theta(mu)
        wB = -(th[self.qB, None] * a[None, :]).ravel()
        w = np.concatenate([th[self.qF], -(th[self.qA, None] * c[None, :]).ravel(), wB])
        rho = float(np.linalg.norm(self.T @ w))
        lam_norm = float(np.linalg.norm(self._TB @ wB))
        d = np.tensordot(th[self.qC], self.C, axes=1) @ c - th[self.qG] @ self.Gq
        dp = np.maximum(d, 0.0)
        if self.Dinv is not None:
            sigma = float(np.sqrt(max(float(dp @ (self.Dinv @ dp)), 0.0)))
        else:
            sigma = float(np.linalg.norm(sla.solve_triangular(self.Lchol, dp, lower=True)))
        kappa = float((self.Vg @ a) @ np.maximum(-d, 0.0))
        return BoundTerms(rho, sigma, kappa, lam_norm)

    def terms_compiled(self, mu: np.ndarray, c: np.ndarray, a: np.ndarray
                       ) -> BoundTerms | None:
        """The terms by the numba kernel (:mod:`rbbench.rb.mixed.bound_kernels`); None
        without numba."""
        args = self.__dict__.get("_kernel_args")
        if args is None:
            try:
                from rbbench.rb.mixed.bound_kernels import bound_terms
            except ImportError:  # pragma: no cover - numba absent
                self._kernel_args = False
                return None
            sparse = self.Dinv is not None
            Dv = sp.csr_matrix(self.Dinv) if sparse else sp.csr_matrix((0, 0))
            L = self.Lchol if not sparse else np.zeros((0, 0))
            i64 = lambda x: np.ascontiguousarray(x, dtype=np.int64)  # noqa: E731
            args = self._kernel_args = (
                bound_terms, np.ascontiguousarray(self.T), i64(self.qF), i64(self.qA),
                i64(self.qB), self.C, i64(self.qC), self.Gq, i64(self.qG), self.Vg,
                i64(Dv.indptr), i64(Dv.indices), np.ascontiguousarray(Dv.data, dtype=float),
                np.ascontiguousarray(L), sparse)
        if args is False:
            return None
        kern, T, qF, qA, qB, C, qC, Gq, qG, Vg, ip, ix, dv, L, sparse = args
        out = kern(mu, T, qF, qA, qB, C, qC, Gq, qG, Vg,
                   _vec(c), _vec(a), ip, ix, dv, L, sparse)
        return BoundTerms(*out)

    def __call__(self, mu: np.ndarray, c: np.ndarray, a: np.ndarray,
                 compiled: bool = True) -> VIBound:
        """The bound (5)-(6) of :mod:`rbbench.rb.algorithms.bounds` at mu for ``u_N = Z c``,
        ``lam_N = Vg a`` (``a >= 0``); ``compiled``: the numba kernel where available."""
        mu = _vec(mu)
        t = self.terms_compiled(mu, c, a) if compiled else None
        if t is None:
            t = self.terms(mu, np.asarray(c, dtype=float), np.asarray(a, dtype=float))
        return vi_bound(t, self.alpha, self.gamma)

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state.pop("_kernel_args", None)
        return state


def _vec(x: Any) -> np.ndarray:
    """``x`` as a contiguous float64 vector (no copy when it already is one)."""
    if isinstance(x, np.ndarray) and x.dtype == np.float64 and x.ndim == 1 \
            and x.flags.c_contiguous:
        return x
    return np.ascontiguousarray(x, dtype=float).ravel()


def _nonzero_terms(terms: np.ndarray, rtol: float = 1e-12) -> np.ndarray:
    """Indices of the affine terms (first axis) that are not zero relative to the largest."""
    mags = np.array([np.abs(t).max() if t.size else 0.0 for t in terms])
    top = mags.max() if mags.size else 0.0
    return np.flatnonzero(mags > rtol * top) if top > 0 else np.zeros(0, dtype=int)


def build_mixed_bound(problem_at: Callable[[np.ndarray], Any], Z: np.ndarray, Vg: np.ndarray,
                      X: Any, x_solve: Callable[[np.ndarray], np.ndarray], bounds: np.ndarray
                      ) -> MixedBound:
    """The offline stage of the bound for the basis ``Z`` (N' columns) and the cone
    generators ``Vg``; :class:`BoundUnsupported` when an operator is not affine in mu, ``A``
    or ``B`` depends on mu, or ``B^T`` is not injective."""
    bounds = np.asarray(bounds, dtype=float)
    N = Z.shape[1]
    try:
        hf_terms = affine_decomposition(lambda mu: _hf_columns(problem_at(mu), Z, Vg), bounds)
        row_terms = affine_decomposition(lambda mu: _row_columns(problem_at(mu), Z), bounds)
    except NotAffineError as exc:
        raise BoundUnsupported(f"the HF operators are not affine in mu ({exc}): no online "
                               "bound (use the HF-evaluated bound)") from None
    if not constant_in_mu(lambda mu: problem_at(mu).A, bounds):
        raise BoundUnsupported("a(.,.; mu) depends on mu: no rigorous coercivity lower bound "
                               "is implemented for it (min-theta needs positive "
                               "semi-definite terms)")
    if not constant_in_mu(lambda mu: problem_at(mu).B, bounds):
        raise BoundUnsupported("B depends on mu: the natural multiplier norm's D = B X^-1 "
                               "B^T would too (no online dual norm of the constraint residual)")
    qF = _nonzero_terms(hf_terms[:, :, 0])
    qA = _nonzero_terms(hf_terms[:, :, 1:1 + N])
    qB = _nonzero_terms(hf_terms[:, :, 1 + N:])
    qC = _nonzero_terms(row_terms[:, :, :N])
    qG = _nonzero_terms(row_terms[:, :, N])
    pieces = [hf_terms[q, :, :1] for q in qF]
    pieces += [hf_terms[q, :, 1:1 + N] for q in qA]
    pieces += [hf_terms[q, :, 1 + N:] for q in qB]
    T = riesz_factor(np.hstack(pieces), X, x_solve)
    p0 = problem_at(bounds.mean(axis=1))
    alpha, gamma = coercivity_constants(p0.A, X)
    kw = _dual_factor(p0.B, X, x_solve)
    return MixedBound(T=T, qF=qF, qA=qA, qB=qB, qC=qC, qG=qG,
                      C=np.ascontiguousarray(row_terms[qC][:, :, :N]),
                      Gq=np.ascontiguousarray(row_terms[qG][:, :, N]),
                      Vg=np.ascontiguousarray(Vg), alpha=alpha, gamma=gamma,
                      p=bounds.shape[0], **kw)


def constant_in_mu(op_at: Callable[[np.ndarray], Any], bounds: np.ndarray,
                   seed: int = 0) -> bool:
    """Whether the HF matrix ``op_at(mu)`` is independent of mu: the affine decomposition of
    ``op_at(mu) V`` (three random vectors V) has no term beyond the constant one (relative
    1e-12; a matrix that is not affine in mu is not constant)."""
    bounds = np.asarray(bounds, dtype=float)
    M0 = op_at(bounds.mean(axis=1))
    V = np.random.default_rng(seed).standard_normal((M0.shape[1], 3))
    try:
        terms = affine_decomposition(lambda mu: op_at(mu) @ V, bounds)
    except NotAffineError:
        return False
    return bool(np.abs(terms[1:]).max(initial=0.0) <= 1e-12 * np.abs(terms[0]).max())


def _hf_columns(p: Any, Z: np.ndarray, Vg: np.ndarray) -> np.ndarray:
    return np.column_stack([p.F, p.A @ Z, p.B.T @ Vg])


def _row_columns(p: Any, Z: np.ndarray) -> np.ndarray:
    return np.column_stack([p.B @ Z, p.G])


def _dual_factor(B: Any, X: Any, x_solve: Callable[[np.ndarray], np.ndarray]) -> dict:
    """``D^{-1}`` sparse when B is square and diagonal, else the Cholesky factor of D."""
    Bs = sp.csr_matrix(B)
    if Bs.shape[0] == Bs.shape[1] and (Bs - sp.diags(Bs.diagonal())).count_nonzero() == 0:
        b = Bs.diagonal()
        if np.all(b != 0):
            Di = sp.diags(1.0 / b)
            return {"Dinv": sp.csr_matrix(Di @ sp.csr_matrix(X) @ Di)}
        raise BoundUnsupported("B has a zero row: B^T is not injective")
    try:
        L = np.linalg.cholesky(delassus(Bs, x_solve))
    except np.linalg.LinAlgError:
        raise BoundUnsupported("B X^-1 B^T is not positive definite: B^T is not injective "
                               "(the HF inf-sup condition fails)") from None
    return {"Lchol": L}


def hf_bound(p: Any, X: Any, x_solve: Callable[[np.ndarray], np.ndarray], u_N: np.ndarray,
             lam_N: np.ndarray, alpha: float, gamma: float) -> VIBound:
    """The bound with the HF operators of the problem ``p`` at mu (rigorous for any reduced
    model; HF cost: m solves with X for ``D``)."""
    dual = natural_dual(p.B, x_solve)
    return vi_bound(hf_bound_terms(p.A, p.F, p.B, p.G, x_solve, dual, u_N, lam_N),
                    alpha, gamma)

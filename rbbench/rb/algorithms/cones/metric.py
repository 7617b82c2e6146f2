"""The multiplier-space metric ``W`` and exact W-orthogonal projections onto cones and spans.

Part of the dual compressors (:mod:`rbbench.rb.algorithms.cones` holds the setting and the error
measures): :class:`WMetric` factors ``W = C^T C``; :func:`cone_projection` is the exact
``Pi^W_{W_R^+}`` (an ``R x R`` NNLS on the triangular factor of ``C V``);
:func:`span_projection` the linear one (POD baseline).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.optimize import lsq_linear, nnls

__all__ = ["ConeGram", "WMetric", "as_metric", "cone_gram", "cone_projection", "span_projection"]


# --------------------------------------------------------------------------- metric
@dataclass(frozen=True)
class WMetric:
    """The multiplier-space metric ``W = C^T C`` and its factor ``C``.

    Diagonal ``W`` (the common case: lumped boundary mass, P0 multipliers):
    ``C = diag(sqrt(w))``. Any other SPD ``W``: a dense Cholesky factor
    ``W = L L^T``, ``C = L^T`` (``O(n^3)`` once; fine for ``n`` up to a few
    thousand, which covers contact boundaries).
    """

    n: int
    sqrt_diag: np.ndarray | None  # sqrt(w) when W is diagonal
    chol: np.ndarray | None  # lower Cholesky factor L otherwise

    @property
    def is_diagonal(self) -> bool:
        return self.sqrt_diag is not None

    @property
    def diagonal(self) -> np.ndarray:
        """``diag(W)`` (exact for a diagonal ``W``)."""
        if self.sqrt_diag is not None:
            return self.sqrt_diag**2
        return np.einsum("ij,ij->i", self.chol, self.chol)

    def factor(self, X: np.ndarray) -> np.ndarray:
        """``C X`` with ``C^T C = W`` (so that ``||x||_W = ||C x||_2``)."""
        X = np.asarray(X, dtype=float)
        if self.sqrt_diag is not None:
            return self.sqrt_diag[:, None] * X if X.ndim == 2 else self.sqrt_diag * X
        return self.chol.T @ X

    def unfactor(self, Y: np.ndarray) -> np.ndarray:
        """``C^{-1} Y``."""
        Y = np.asarray(Y, dtype=float)
        if self.sqrt_diag is not None:
            return Y / self.sqrt_diag[:, None] if Y.ndim == 2 else Y / self.sqrt_diag
        return sla.solve_triangular(self.chol.T, Y, lower=False)

    def norm(self, X: np.ndarray) -> np.ndarray | float:
        """``||x||_W`` of a vector, or of each column of a matrix."""
        Y = self.factor(X)
        return np.linalg.norm(Y, axis=0) if Y.ndim == 2 else float(np.linalg.norm(Y))

    def inner(self, X: np.ndarray, Y: np.ndarray) -> np.ndarray:
        """``X^T W Y``."""
        return self.factor(X).T @ self.factor(Y)


def as_metric(W: Any) -> WMetric:
    """Build a :class:`WMetric` from a dense/sparse SPD matrix or diagonal weights.

    Parameters
    ----------
    W : WMetric, (n,) array, (n, n) ndarray or scipy sparse matrix
        The multiplier-space Gram matrix (a 1-D array means ``diag(W)``).

    Returns
    -------
    WMetric
    """
    if isinstance(W, WMetric):
        return W
    if sp.issparse(W):
        W = sp.csr_matrix(W, dtype=float)
        d = W.diagonal()
        if (W - sp.diags(d)).count_nonzero() == 0:
            return _diag_metric(d)
        dense = W.toarray()
    else:
        dense = np.asarray(W, dtype=float)
        if dense.ndim == 1:
            return _diag_metric(dense)
        if dense.ndim != 2 or dense.shape[0] != dense.shape[1]:
            raise ValueError(f"W must be square, got shape {dense.shape}")
        d = np.diag(dense).copy()
        if np.count_nonzero(dense - np.diag(d)) == 0:
            return _diag_metric(d)
    sym = 0.5 * (dense + dense.T)
    try:
        L = np.linalg.cholesky(sym)
    except np.linalg.LinAlgError as exc:
        raise ValueError("W is not symmetric positive definite") from exc
    return WMetric(n=sym.shape[0], sqrt_diag=None, chol=L)


def _diag_metric(d: np.ndarray) -> WMetric:
    d = np.asarray(d, dtype=float)
    if not np.all(d > 0):
        raise ValueError("diagonal W must have positive entries")
    return WMetric(n=d.size, sqrt_diag=np.sqrt(d), chol=None)


# ------------------------------------------------------------------ cone projection
@dataclass(frozen=True)
class ConeGram:
    """Precomputed data for projecting onto ``Span^+(columns of V)`` in ``W``.

    ``CV = C V = Qf Rf`` (thin QR), so that for any ``theta``
    ``||theta - V alpha||_W^2 = ||Qf^T C theta - Rf alpha||^2 + const``: the cone
    projection is an ``R x R`` NNLS with the triangular ``Rf``, whose
    conditioning is that of ``C V`` (not squared, as with the normal equations
    ``G = V^T W V = Rf^T Rf``).
    """

    V: np.ndarray
    metric: WMetric
    CV: np.ndarray
    Qf: np.ndarray
    Rf: np.ndarray

    @property
    def R(self) -> int:
        return int(self.V.shape[1])

    @property
    def G(self) -> np.ndarray:
        """W-Gram matrix of the generators, ``V^T W V``."""
        return self.CV.T @ self.CV

    def cond(self) -> float:
        """2-norm condition number of the W-Gram matrix ``G`` (``= cond(C V)^2``)."""
        if self.R == 0:
            return 1.0
        s = np.linalg.svd(self.Rf, compute_uv=False)
        return float((s[0] / s[-1]) ** 2) if s[-1] > 0 else float("inf")


def cone_gram(V: np.ndarray, W: Any) -> ConeGram:
    """Precompute ``C V`` and its thin QR for repeated :func:`cone_projection` calls.

    Parameters
    ----------
    V : (n, R) array
        Cone generators (columns); ``R = 0`` is the trivial cone ``{0}``.
    W : metric (see :func:`as_metric`)

    Returns
    -------
    ConeGram
    """
    M = as_metric(W)
    V = np.asarray(V, dtype=float)
    if V.ndim == 1:
        V = V[:, None]
    if V.shape[0] != M.n:
        raise ValueError(f"V has {V.shape[0]} rows, W is {M.n} x {M.n}")
    CV = M.factor(V)
    if V.shape[1] == 0:
        Qf = np.zeros((M.n, 0))
        Rf = np.zeros((0, 0))
    else:
        Qf, Rf = np.linalg.qr(CV, mode="reduced")
    return ConeGram(V=V, metric=M, CV=CV, Qf=Qf, Rf=np.ascontiguousarray(Rf))


def _nnls_exact(Rf: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``argmin_{a >= 0} ||Rf a - rhs||``: Lawson-Hanson (scipy), KKT-checked.

    Falls back on the bounded-variable active set (``lsq_linear(method="bvls")``)
    if the C Lawson-Hanson hits its iteration limit or its output fails the KKT
    test. Both are finite active-set methods: exact up to rounding at termination.
    """
    R = Rf.shape[1]
    try:
        a, _ = nnls(Rf, rhs, maxiter=max(50, 20 * R))
    except RuntimeError:
        a = None
    if a is not None:
        g = Rf.T @ (Rf @ a - rhs)  # gradient = G a - b
        scale = 1e-9 * max(np.linalg.norm(Rf) * np.linalg.norm(rhs), 1e-300)
        free = a > 0
        if np.all(g[~free] >= -scale) and np.all(np.abs(g[free]) <= scale):
            return a
    return lsq_linear(Rf, rhs, bounds=(0.0, np.inf), method="bvls", tol=1e-14).x


def cone_projection(
    theta: np.ndarray,
    V: np.ndarray | None = None,
    W: Any = None,
    gram: ConeGram | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | float]:
    """W-orthogonal projection onto the cone ``Span^+(columns of V)``.

    Implements ``Pi^W_{W_R^+}`` of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order
    reduction methods: parametric variational inequalities" (talk) (slides "CPG algorithm" and
    "mCPG algorithm (4/4)"): ``alpha = argmin_{alpha >= 0} ||theta - V alpha||_W``.
    Solved as an exact active-set NNLS (Lawson-Hanson) on the ``R x R``
    triangular factor of ``C V`` (see :class:`ConeGram`), one small solve per
    column; the ``n``-sized work (``C theta``, ``Qf^T C theta``, residuals) is
    done once for the whole batch.

    Parameters
    ----------
    theta : (n,) or (n, k) array
        Vector(s) to project.
    V : (n, R) array, optional
        Generators (ignored when ``gram`` is given).
    W : metric, optional
        See :func:`as_metric` (ignored when ``gram`` is given).
    gram : ConeGram, optional
        ``cone_gram(V, W)``, precomputed once for repeated calls.

    Returns
    -------
    alpha : (R,) or (R, k) array
        Non-negative coefficients.
    proj : (n,) or (n, k) array
        ``V alpha``.
    err : float or (k,) array
        ``||theta - V alpha||_W``, computed from the explicit residual.
    """
    if gram is None:
        if V is None or W is None:
            raise ValueError("give V and W, or gram")
        gram = cone_gram(V, W)
    th = np.asarray(theta, dtype=float)
    single = th.ndim == 1
    T = th[:, None] if single else th
    X = gram.metric.factor(T)
    k = T.shape[1]
    if gram.R == 0:
        alpha = np.zeros((0, k))
        proj = np.zeros_like(T)
        err = np.linalg.norm(X, axis=0)
    else:
        rhs = gram.Qf.T @ X
        alpha = np.empty((gram.R, k))
        for j in range(k):
            alpha[:, j] = _nnls_exact(gram.Rf, rhs[:, j])
        proj = gram.V @ alpha
        err = np.linalg.norm(X - gram.CV @ alpha, axis=0)
    if single:
        return alpha[:, 0], proj[:, 0], float(err[0])
    return alpha, proj, err


def span_projection(
    theta: np.ndarray, V: np.ndarray, W: Any
) -> tuple[np.ndarray, np.ndarray, np.ndarray | float]:
    """W-orthogonal projection onto the linear span of the columns of ``V``.

    Returns ``(coeffs, proj, err)`` shaped as in :func:`cone_projection`
    (least squares in ``C V``; used for the non-cone POD baseline).
    """
    M = as_metric(W)
    V = np.asarray(V, dtype=float)
    th = np.asarray(theta, dtype=float)
    single = th.ndim == 1
    T = th[:, None] if single else th
    X = M.factor(T)
    CV = M.factor(V)
    if V.shape[1] == 0:
        c = np.zeros((0, T.shape[1]))
    else:
        c = np.linalg.lstsq(CV, X, rcond=None)[0]
    proj = V @ c
    err = np.linalg.norm(X - CV @ c, axis=0)
    if single:
        return c[:, 0], proj[:, 0], float(err[0])
    return c, proj, err


"""Inf-sup and boundedness constants of ``b(mu; v, eta) = eta^T B(mu) v``, over spans and cones.

Setting (algebraic, free dofs; science.md section 3; Benaceur, Drouet, Ehrlacher, Ern & Niakh,
"Model order reduction methods: parametric variational inequalities" (talk), slides
"Enhancement by supremizers" and "Projected Greedy Algorithm (2/2)"):

* ``X`` (n x n, sparse SPD): Gram matrix of the primal inner product, ``||v||_V^2 = v^T X v``;
* ``W`` (m x m SPD, often diagonal): Gram matrix of the multiplier inner product;
* ``B`` (m x n, sparse): ``b(mu; v, eta) = eta^T B v``;
* ``Z`` (n x N): a primal reduced basis, ``Y = span(Z)`` (``Z = None``: ``Y`` = whole HF space);
* ``Vg`` (m x R, non-negative columns): cone generators, ``eta = Vg y``.

For a set ``K`` of multipliers and a primal space ``Y``::

    beta(K, Y) = inf_{eta in K, eta != 0} sup_{v in Y} eta^T B v / (||v||_X ||eta||_W).

With ``P = X^{-1}`` (``Y`` = whole space) or ``P = Z (Z^T X Z)^{-1} Z^T`` (``Y = span Z``) the
inner sup equals ``sqrt(eta^T B P B^T eta) / ||eta||_W``. Writing ``B P B^T = H H^T``
(:func:`supremizer_operator`) and ``C = H^T Vg`` (:func:`cone_coupling`)::

    beta(K, Y)^2 = inf_{y in K'} (y^T S y) / (y^T M y),  S = C^T C = Vg^T B P B^T Vg,
                                                         M = Vg^T W Vg,

with ``K' = R^R \\ {0}`` for the span of the generators (a generalised eigenvalue problem:
:func:`infsup_span`, exact, and a lower bound of the cone value) and ``K' = R^R_+ \\ {0}``
for the cone ``Span+(Vg)`` (a non-convex problem: :func:`infsup_cone`, exact by face
enumeration for small ``R``, else a multistart upper estimate). ``beta = 0`` on the cone
iff ``C alpha = 0`` for some ``alpha >= 0, sum(alpha) = 1``: :func:`beta_zero_test`
(:mod:`rbbench.rb.algorithms.infsup_zero`: an SVD bound, else an LP).

Which number is which (Benaceur et al., slide "Projected Greedy Algorithm (2/2)"), for one ``mu``:

* ``beta_HF``: ``Z = None``, generators = all HF multiplier dofs (``Vg = I_m``; on the HF
  cone ``W^+`` this is a span *lower bound*, the cone value is not computed for ``m`` large);
* ``beta_dec``: ``Z = V_N`` basis, ``Vg`` = reduced cone generators;
* ``beta_on``: ``Z = [V_N, T(mu)]`` with ``T(mu) = X^{-1} B(mu)^T Vg`` (online supremizers,
  :func:`rbbench.rb.algorithms.pga.supremizers`); equals the ``Z = None`` value with the same
  ``Vg``;
* ``beta_off``: ``Z = [V_N, S_PGA]`` (:func:`rbbench.rb.algorithms.pga.pga`);
* ``c_HF``: :func:`boundedness_constant` with ``Z = None`` and ``Vg = I_m``.
"""

from __future__ import annotations

import itertools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.optimize import minimize

from rbbench.rb.algorithms.infsup_zero import beta_zero_certificate, beta_zero_test, zero_test

__all__ = [
    "InfSup",
    "beta_zero_certificate",
    "beta_zero_test",
    "boundedness_constant",
    "cone_coupling",
    "infsup_cone",
    "infsup_span",
    "make_solver",
    "quotient_matrices",
    "span_constants",
    "supremizer_operator",
    "zero_test",
]

Solver = Callable[[np.ndarray], np.ndarray]

#: Default relative eigenvalue cut-off for Gram matrices (see :func:`supremizer_operator`).
GRAM_RTOL = 1e-13


def make_solver(X) -> Solver:
    """Return a callable ``solve(rhs)`` for ``X y = rhs`` (``rhs`` of shape (n,) or (n, k)).

    Parameters
    ----------
    X : sparse matrix, ndarray, object with a ``solve`` method, or callable
        A sparse matrix is factorised once, by PARDISO's Cholesky when ``pypardiso`` is
        installed (:func:`rbbench.hf.condensation.pardiso.factorized`), else by SuperLU in
        symmetric mode (:func:`rbbench.hf.condensation.dense.factorize`); a dense one with a
        Cholesky factorisation; an existing factorisation (``scipy.sparse.linalg.splu``
        result, ...) is used through its ``solve`` method; a callable is returned unchanged.

    Notes
    -----
    Matrix right-hand sides are passed in Fortran order (SuperLU's layout). Measured at
    n = 35k (2D vector Laplacian, 173k non-zeros, SuperLU): factorise 0.05 s, 256
    right-hand sides 0.4 s. The energy product of ``hertz_sphere`` level 1 (n = 29,488, 1.2M
    non-zeros, 3D P1), one thread: PARDISO 1.0 s, SuperLU 7.9 s (27M non-zeros in L + U).
    """
    if sp.issparse(X):
        from rbbench.hf.condensation import pardiso

        if pardiso.available():  # the HF solves' default too; SuperLU fills far more in 3D
            return pardiso.factorized(X)
        from rbbench.hf.condensation.dense import factorize

        lu = factorize(X)
        return lambda rhs: lu.solve(np.asfortranarray(rhs, dtype=float))
    if isinstance(X, np.ndarray):
        cho = sla.cho_factor(np.asarray(X, dtype=float))
        return lambda rhs: sla.cho_solve(cho, rhs)
    if hasattr(X, "solve"):
        return lambda rhs: X.solve(np.asfortranarray(rhs, dtype=float))
    if callable(X):
        return X
    raise TypeError(f"cannot make a solver from {type(X).__name__}")


def _matmul(A, V: np.ndarray) -> np.ndarray:
    return np.asarray(A @ V, dtype=float)


def _sym(A: np.ndarray) -> np.ndarray:
    return 0.5 * (A + A.T)


def _psd_factor(G: np.ndarray, rtol: float) -> np.ndarray:
    """``H`` with ``H H^T ~= G`` (G symmetric PSD), dropping eigenvalues ``<= rtol * max``."""
    w, V = np.linalg.eigh(_sym(G))
    if w.size == 0 or w[-1] <= 0:
        return np.zeros((G.shape[0], 0))
    keep = w > rtol * w[-1]
    return V[:, keep] * np.sqrt(w[keep])


def supremizer_operator(B, X, Z: np.ndarray | None = None, *,
                        gram_rtol: float = GRAM_RTOL) -> np.ndarray:
    """Factor ``H`` (m x k) of the "supremizer operator": ``H H^T = B P B^T``.

    ``P = X^{-1}`` when ``Z is None`` (primal space = whole HF space) and
    ``P = Z (Z^T X Z)^{-1} Z^T`` (the X-orthogonal projection onto ``span Z``, composed with
    ``X^{-1}``) otherwise. ``eta^T H H^T eta = sup_{v in Y} (eta^T B v)^2 / ||v||_X^2`` is the
    squared dual norm of ``b(mu; ., eta)`` on ``Y``. ``H`` does not depend on the cone
    generators: compute it once per ``mu`` and reuse it for every ``Vg``
    (:func:`cone_coupling`, :func:`quotient_matrices`).

    Parameters
    ----------
    B : (m, n) sparse or dense
        Constraint matrix ``B(mu)``.
    X : see :func:`make_solver` (``Z is None``) or (n, n) matrix (``Z`` given)
        With ``Z is None`` a factorisation (or a solver callable) is enough and avoids
        refactorising; with ``Z`` given ``X`` must support ``X @ Z``.
    Z : (n, N) ndarray, optional
        Primal basis (need not be X-orthonormal; dependent columns are tolerated).
    gram_rtol : float
        Eigenvalues of ``Z^T X Z`` (resp. of ``B X^{-1} B^T``) at or below ``gram_rtol`` times
        the largest are treated as zero: those directions are dropped (dependent columns of
        ``Z``; numerically rank-deficient ``B``). ``1e-13`` is what a Gram matrix formed in
        double precision can resolve; it can lower ``beta^2`` by at most ``gram_rtol * c^2``.

    Returns
    -------
    H : (m, k) ndarray
        ``k = rank(Z)`` (Z given) or ``k = rank(B)`` (Z None). ``Z`` given:
        ``H = B Z V diag(w)^{-1/2}`` with ``Z^T X Z = V diag(w) V^T``; ``Z`` None:
        ``H = U diag(g)^{1/2}`` with ``B X^{-1} B^T = U diag(g) U^T`` (m sparse solves).
    """
    m, n = B.shape
    if Z is None:
        solve = make_solver(X)
        Bt = np.asfortranarray(B.T.toarray() if sp.issparse(B) else np.asarray(B).T, dtype=float)
        if m == 0:
            return np.zeros((0, 0))
        Y = np.asarray(solve(Bt), dtype=float).reshape(n, m)
        return _psd_factor(_matmul(B, Y), gram_rtol)
    Z = np.asarray(Z, dtype=float)
    if Z.ndim != 2 or Z.shape[0] != n:
        raise ValueError(f"Z must be (n={n}, N), got {Z.shape}")
    if Z.shape[1] == 0:
        return np.zeros((m, 0))
    if callable(X) and not sp.issparse(X) and not isinstance(X, np.ndarray):
        raise TypeError("with Z given, X must be the Gram matrix (X @ Z), not a solver")
    w, V = np.linalg.eigh(_sym(Z.T @ _matmul(X, Z)))
    if w[-1] <= 0:
        return np.zeros((m, 0))
    keep = w > gram_rtol * w[-1]
    return _matmul(B, Z) @ (V[:, keep] / np.sqrt(w[keep]))


def cone_coupling(H: np.ndarray, Vg: np.ndarray) -> np.ndarray:
    """``C = H^T Vg`` (k x R): ``||C y||_2 = sup_{v in Y} b(Vg y, v) / ||v||_X``.

    ``S = C^T C``; ``C`` is the matrix of the exact ``beta = 0`` test (:func:`beta_zero_test`):
    its null space is that of ``Z^T B^T Vg`` (``Z`` given) or ``B^T Vg`` (``Z`` None).
    """
    return np.asarray(H, dtype=float).T @ np.asarray(Vg, dtype=float)


def _gram(W, Vg: np.ndarray) -> np.ndarray:
    W = W if sp.issparse(W) else np.asarray(W, dtype=float)
    if not sp.issparse(W) and W.ndim == 1:
        return _sym(Vg.T @ (W[:, None] * Vg))
    return _sym(Vg.T @ _matmul(W, Vg))


def quotient_matrices(B, X, Vg: np.ndarray, W, Z: np.ndarray | None = None, *,
                      H: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The two R x R matrices of the inf-sup quotient over ``eta = Vg y``.

    Returns
    -------
    S : (R, R) ndarray
        ``Vg^T B P B^T Vg`` (``P`` as in :func:`supremizer_operator`): ``y^T S y`` is the
        squared dual norm, on ``Y``, of ``b(mu; ., Vg y)``. Symmetric PSD.
    M : (R, R) ndarray
        ``Vg^T W Vg``: ``y^T M y = ||Vg y||_W^2``. SPD iff the generators are independent.

    Notes
    -----
    ``beta^2 = inf y^T S y / y^T M y`` over ``y != 0`` (span) or ``y >= 0, y != 0`` (cone).
    ``W`` may be a 1-D array (a diagonal Gram matrix). Pass ``H`` (from
    :func:`supremizer_operator`) to skip the solves; ``B``, ``X``, ``Z`` are then unused.
    """
    Vg = np.asarray(Vg, dtype=float)
    if H is None:
        H = supremizer_operator(B, X, Z)
    C = cone_coupling(H, Vg)
    return _sym(C.T @ C), _gram(W, Vg)


def _unit_diagonal(S: np.ndarray, M: np.ndarray
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``d = sqrt(diag M)`` and the pencil scaled to ``M_ii = 1``: ``(d, S / d d^T, M / d d^T)``.

    The scaling preserves the orthant; a zero (or negative) diagonal entry of ``M`` means a
    zero generator and is refused.
    """
    d = np.sqrt(np.clip(np.diag(M), 0.0, None))
    if np.any(d <= 0):
        raise ValueError("M has a non-positive diagonal entry: a zero cone generator")
    dd = np.outer(d, d)
    return d, S / dd, M / dd


def _reduced_pencil(S: np.ndarray, M: np.ndarray, rtol: float) -> np.ndarray:
    """``T^T S T`` with ``T^T M T = I`` on the range of ``M`` (after diagonal scaling)."""
    S = _sym(np.asarray(S, dtype=float))
    M = _sym(np.asarray(M, dtype=float))
    _, Ss, Ms = _unit_diagonal(S, M)
    w, Q = np.linalg.eigh(Ms)
    keep = w > rtol * w[-1]
    T = Q[:, keep] / np.sqrt(w[keep])
    return _sym(T.T @ Ss @ T)


def _pencil_eigenvalues(S: np.ndarray, M: np.ndarray, rtol: float) -> np.ndarray:
    """Eigenvalues (ascending) of the pencil ``(S, M)`` on the range of ``M``."""
    A = _reduced_pencil(S, M, rtol)
    return np.linalg.eigvalsh(A) if A.size else np.zeros(0)


def _span_from(w: np.ndarray) -> float:
    """:func:`infsup_span` from the pencil eigenvalues ``w`` (ascending)."""
    if w.size == 0:
        return float("inf")
    if w[0] <= SPAN_ROUNDOFF * max(w[-1], 0.0):
        return 0.0
    return float(np.sqrt(w[0]))


def infsup_span(S: np.ndarray, M: np.ndarray, *, rtol: float = GRAM_RTOL) -> float:
    """Inf-sup constant over the *span* of the generators: ``sqrt(lambda_min(S, M))``.

    ``= inf_{eta in span(Vg), eta != 0} sup_{v in Y} b(v, eta) / (||v||_X ||eta||_W)``,
    exact (a generalised symmetric eigenvalue problem). Since ``Span+(Vg)`` is a subset of
    ``span(Vg)`` it is a LOWER BOUND of the cone value (:func:`infsup_cone`).

    Linearly dependent generators are allowed: directions ``y`` with
    ``y^T M y <= rtol * ||M||`` (after scaling ``M`` to unit diagonal) are not multipliers
    (``Vg y ~ 0``) and are removed before the eigensolve. An eigenvalue ratio
    ``lambda_min / lambda_max <= SPAN_ROUNDOFF`` (1e-12, a few hundred machine epsilons: the
    eigensolver's absolute accuracy is ``O(eps lambda_max)``) is zero to round-off and
    reported as 0, not as a positive bound (seen: a membrane beta_dec at a ratio of
    3e-16 was reported as 1.5e-9).
    """
    return _span_from(_pencil_eigenvalues(S, M, rtol))


#: eigenvalue ratio below which the span inf-sup constant is zero to round-off
SPAN_ROUNDOFF = 1e-12


def boundedness_constant(S: np.ndarray, M: np.ndarray, *, rtol: float = GRAM_RTOL) -> float:
    """Continuity constant ``sqrt(lambda_max(S, M))`` of ``b`` on ``Y x span(Vg)``.

    ``c = sup_{eta in span(Vg)} sup_{v in Y} b(v, eta) / (||v||_X ||eta||_W)``. With
    ``S, M`` built for ``Z = None`` and ``Vg = I_m`` (all HF multiplier dofs) it is
    ``c_HF(mu)``, the boundedness constant of ``b(mu; ., .)`` on ``V x W`` used by the PGA
    theorem (:func:`rbbench.rb.algorithms.pga.theorem_lower_bound`). Over the cone ``Span+(Vg)`` the
    sup can only be smaller, so ``c`` is also a valid continuity constant there.
    """
    return span_constants(S, M, rtol=rtol)[1]


def span_constants(S: np.ndarray, M: np.ndarray, *, rtol: float = GRAM_RTOL
                   ) -> tuple[float, float]:
    """``(infsup_span(S, M), boundedness_constant(S, M))`` from one eigensolve.

    Their ratio ``beta / c`` is dimensionless: invariant under a rescaling of ``X`` (e.g.
    the Young modulus of the energy inner product) and of ``W`` (Benaceur et al.: ``delta_PGA =
    sup beta_HF / c_HF``).
    """
    w = _pencil_eigenvalues(S, M, rtol)
    c = float(np.sqrt(max(w[-1], 0.0))) if w.size else 0.0
    return _span_from(w), c


# --------------------------------------------------------------------------- cone


@dataclass(frozen=True)
class InfSup:
    """Inf-sup constant of ``b`` over the cone ``Span+(Vg)`` and a primal space ``Y``.

    Attributes
    ----------
    value : float
        ``sqrt(q(y*))`` where ``q(y) = y^T S y / y^T M y`` and ``y* = argmin`` below, a
        feasible point (``y* >= 0``), so ``value`` is always attained, hence an upper bound
        of the true cone constant. ``kind = "cone-exact"``: it *is* the cone constant (up to
        rounding); ``kind = "cone-upper"``: best local minimum found, an UPPER ESTIMATE.
    kind : str
        ``"cone-exact"`` (face enumeration, ``R <= exact_max_r``) or ``"cone-upper"``.
    span : float
        :func:`infsup_span`, the inf-sup over ``span(Vg)``: a LOWER BOUND of the cone value.
        The true cone constant lies in ``[span, value]``.
    is_zero : bool or None
        Outcome of the exact test :func:`beta_zero_test`: the cone constant is 0 (some
        non-zero ``eta`` in the cone is annihilated by ``B^T`` on ``Y``); None: undecided
        (no LP method returned a usable point, the reason in ``zero_note``).
    argmin : (R,) ndarray
        ``y* >= 0`` with ``sum(y*) = 1`` attaining ``value`` (the minimising multiplier is
        ``Vg @ argmin``).
    """

    value: float
    kind: str
    span: float
    is_zero: bool | None
    argmin: np.ndarray
    zero_note: str = ""


def _quotients(Y: np.ndarray, S: np.ndarray, M: np.ndarray) -> np.ndarray:
    """Rayleigh quotients of the rows of ``Y``."""
    num = np.einsum("ci,ij,cj->c", Y, S, Y)
    den = np.einsum("ci,ij,cj->c", Y, M, Y)
    return num / den


def _face_candidates(S: np.ndarray, M: np.ndarray, max_k: int, sign_rtol: float = 1e-9):
    """Best feasible stationary point over all faces of size ``<= max_k`` (batched).

    On a face ``F`` (support of ``y``) an interior local minimiser of the quotient is a
    generalised eigenvector of ``(S_FF, M_FF)`` with entries of one sign. Every accepted
    eigenvector is clipped to ``>= 0`` and its quotient re-evaluated with the full ``S, M``,
    so the returned value is attained at a feasible point.
    """
    R = S.shape[0]
    best_q, best_y = np.inf, None
    for k in range(1, max_k + 1):
        faces = np.array(list(itertools.combinations(range(R), k)), dtype=int)
        Mk = M[faces[:, :, None], faces[:, None, :]]
        # Conic Caratheodory: every cone point is a non-negative combination of linearly
        # independent generators, so faces with dependent generators can be skipped.
        ev = np.linalg.eigvalsh(Mk)
        independent = ev[:, 0] > 1e-12 * ev[:, -1]
        faces, Mk = faces[independent], Mk[independent]
        if faces.size == 0:
            continue
        Sk = S[faces[:, :, None], faces[:, None, :]]
        L = np.linalg.cholesky(Mk)
        A = np.linalg.solve(L, np.linalg.solve(L, Sk).swapaxes(1, 2))
        A = 0.5 * (A + A.swapaxes(1, 2))
        _, U = np.linalg.eigh(A)
        V = np.linalg.solve(L.swapaxes(1, 2), U)  # columns: pencil eigenvectors
        V *= np.where(V.sum(axis=1, keepdims=True) < 0, -1.0, 1.0)
        vmax = np.abs(V).max(axis=1)
        ok = V.min(axis=1) >= -sign_rtol * vmax  # (n_faces, k): one-signed eigenvectors
        f_idx, j_idx = np.nonzero(ok)
        if f_idx.size == 0:
            continue
        Y = np.zeros((f_idx.size, R))
        rows = np.repeat(np.arange(f_idx.size), k)
        Y[rows, faces[f_idx].ravel()] = np.clip(V[f_idx, :, j_idx], 0.0, None).ravel()
        q = _quotients(Y, S, M)
        i = int(np.argmin(q))
        if q[i] < best_q:
            best_q, best_y = float(q[i]), Y[i]
    return best_q, best_y


def _local_min(S: np.ndarray, M: np.ndarray, y0: np.ndarray) -> np.ndarray:
    """SLSQP local minimisation of the quotient on the simplex, started at ``y0``."""
    R = S.shape[0]

    def fun(y):
        Sy, My = S @ y, M @ y
        den = y @ My
        q = (y @ Sy) / den
        return q, 2.0 * (Sy - q * My) / den

    res = minimize(fun, y0, jac=True, method="SLSQP", bounds=[(0.0, None)] * R,
                   constraints=[{"type": "eq", "fun": lambda y: y.sum() - 1.0,
                                 "jac": lambda y: np.ones_like(y)}],
                   options={"maxiter": 200, "ftol": 1e-14})
    return np.clip(res.x, 0.0, None)


def _polish(S: np.ndarray, M: np.ndarray, y: np.ndarray, sign_rtol: float = 1e-9):
    """Candidates from the pencil restricted to the support of ``y`` (exact on that face)."""
    F = np.nonzero(y > 1e-8 * y.max())[0]
    try:
        w, V = sla.eigh(S[np.ix_(F, F)], M[np.ix_(F, F)])
    except (np.linalg.LinAlgError, sla.LinAlgError):  # dependent generators on this face
        return []
    V = V * np.where(V.sum(axis=0) < 0, -1.0, 1.0)
    out = []
    for j in range(F.size):
        v = V[:, j]
        if v.min() >= -sign_rtol * np.abs(v).max():
            z = np.zeros_like(y)
            z[F] = np.clip(v, 0.0, None)
            out.append(z)
    return out


def _cone_multistart(S: np.ndarray, M: np.ndarray, n_starts: int, seed: int):
    R = S.shape[0]
    best_q, best_y = _face_candidates(S, M, min(3, R))
    rng = np.random.default_rng(seed)
    try:
        _, V = sla.eigh(S, M)
        v = V[:, 0]
    except (np.linalg.LinAlgError, sla.LinAlgError):  # dependent generators
        v = np.zeros(R)
    starts = [np.full(R, 1.0 / R)] + list(np.eye(R))
    for s in (np.clip(v, 0, None), np.clip(-v, 0, None)):
        if s.sum() > 0:
            starts.append(s / s.sum())
    starts += list(rng.dirichlet(np.ones(R), size=n_starts))
    for y0 in starts:
        y = _local_min(S, M, y0)
        if y.sum() <= 0:
            continue
        cands = np.array([y] + _polish(S, M, y))
        q = _quotients(cands, S, M)
        i = int(np.argmin(q))
        if q[i] < best_q:
            best_q, best_y = float(q[i]), cands[i]
    return best_q, best_y


def infsup_cone(S: np.ndarray, M: np.ndarray, *, C: np.ndarray | None = None,
                exact_max_r: int = 12, n_starts: int = 32, seed: int = 0,
                zero_rtol: float | None = None) -> InfSup:
    """Inf-sup constant over the cone ``Span+(Vg)``: ``sqrt(min_{y >= 0, y != 0} q(y))``.

    ``q(y) = y^T S y / y^T M y`` (:func:`quotient_matrices`). Non-convex; computed on the
    diagonally rescaled pencil (``M_ii = 1``, which preserves the orthant).

    * ``R <= exact_max_r``: exact, by face enumeration. At a minimiser with support ``F``,
      ``y_F > 0`` is an interior stationary point of the quotient on that face, i.e. a
      generalised eigenvector of ``(S_FF, M_FF)`` with entries of one sign. All
      ``2^R - 1`` supports are enumerated (batched eigensolves: ~0.1 s at R = 12, doubling
      per extra generator), the one-signed eigenvectors kept, and the smallest quotient
      taken. (A degenerate eigenvalue whose eigenspace holds a positive vector also holds
      one on a smaller face, where it is found.) ``kind = "cone-exact"``.
    * else: best of (exact enumeration of faces of size <= 3) and SLSQP local minimisations
      on the simplex from the barycentre, the R vertices, the clipped span minimiser (both
      signs) and ``n_starts`` uniform random points (``seed``), each polished by the exact
      eigen-solution on its support. ``kind = "cone-upper"``: an UPPER ESTIMATE.

    Parameters
    ----------
    S, M : (R, R) ndarray
        From :func:`quotient_matrices`. ``M`` may be singular (dependent generators, as a
        cone often needs more generators than its dimension): faces with dependent
        generators are skipped, which loses nothing by the conic Caratheodory theorem.
    C : (k, R) ndarray, optional
        :func:`cone_coupling` (``S = C^T C``) for the ``is_zero`` test. Without it ``C`` is
        recovered from the eigendecomposition of ``S`` (eigenvalues ``<= R eps ||S||``
        dropped), which is only accurate to ``~sqrt(eps)``; hence the looser default
        ``zero_rtol``.
    zero_rtol : float, optional
        Tolerance of :func:`beta_zero_test`; default ``1e-9`` with ``C``, ``1e-6`` without.

    Returns
    -------
    InfSup
        ``value`` (exact or upper), ``kind``, ``span`` (lower bound), ``is_zero``, ``argmin``.
    """
    S = _sym(np.asarray(S, dtype=float))
    M = _sym(np.asarray(M, dtype=float))
    R = S.shape[0]
    if R == 0:
        raise ValueError("empty cone (R = 0)")
    span = infsup_span(S, M)
    # M may be singular: a cone in a space of dimension < R needs dependent generators.
    # The quotient stays defined on the orthant when y >= 0, y != 0 implies Vg y != 0
    # (true for non-negative generators); a zero generator (M_ii = 0) is refused.
    d, Ss, Ms = _unit_diagonal(S, M)
    if R <= exact_max_r:
        q, z = _face_candidates(Ss, Ms, R)
        kind = "cone-exact"
    else:
        q, z = _cone_multistart(Ss, Ms, n_starts, seed)
        kind = "cone-upper"
    y = z / d
    y /= y.sum()
    if C is None:
        C = _psd_factor(S, R * np.finfo(float).eps).T  # S = C^T C
        rtol = 1e-6 if zero_rtol is None else zero_rtol
    else:
        rtol = 1e-9 if zero_rtol is None else zero_rtol
    zero = zero_test(C, rtol=rtol)
    return InfSup(value=float(np.sqrt(max(q, 0.0))), kind=kind, span=span,
                  is_zero=zero.is_zero, argmin=y, zero_note=zero.note)

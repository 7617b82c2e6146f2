"""Inf-sup constants and PGA of the combined friction form ``b = b^n + b^tau``.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slide "Preliminaries" (2: "Stabilization using PGA
algorithm")::

    b(mu; v, eta) = b^n(mu; v, eta^n) + b^tau(mu; v, eta^tau),   eta = (eta^n, eta^tau)

Algebraically ``b(v, eta) = eta^T B v`` with ``B = [Bn; Bt]`` (2m x n, free dofs, P1 nodal
rows) and ``||eta||_W^2 = eta^T blockdiag(W, W) eta`` (``W = Wt``, the L2(Gamma_c) Gram
matrix of the nodal multipliers). The dual set is a cone in the normal part and a space in
the tangential one: HF ``R^m_+ x R^m``; reduced ``{(Vn c, Vt theta) : c >= 0}``, i.e. the
generators ``blockdiag(Vn, Vt)`` with only the first ``R`` coefficients signed. So::

    beta^2 = inf_{y = (c, theta), c >= 0, y != 0} y^T S y / y^T M y

with ``S``, ``M`` of :func:`rbbench.rb.algorithms.infsup.quotient_matrices`. Numbers computed here:

* span value (:func:`rbbench.rb.algorithms.infsup.infsup_span`, all of ``y`` free): exact over the
  span and a LOWER BOUND of the mixed cone value;
* mixed cone value (:func:`mixed_cone_infsup`): exact by enumerating the normal faces
  (``R <= exact_max_r``; the tangential block joins every face), else an UPPER estimate;
* zero test (:func:`mixed_zero_test`): exact LP after projecting out the tangential range;
* ``c_HF``: the continuity constant of the combined HF form (:func:`hf_constants`).

Normalisation: the raw values carry units (``X`` is the energy inner product, so
``beta ~ 1 / sqrt(E)``). The dimensionless value reported beside them is ``beta / c_HF(mu)``,
Benaceur et al.'s own ratio (``delta_PGA = sup beta_HF / c_HF``): invariant under any rescaling
of ``X``, ``W`` or the multiplier units, and in ``[0, 1]`` for ``beta <= c_HF``.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.optimize import minimize

from rbbench.rb.algorithms import infsup as inf
from rbbench.rb.algorithms.pga import PGAResult, pga, supremizers

__all__ = ["CombinedInfSup", "combined_b", "combined_generators", "combined_pga",
           "combined_supremizers", "combined_w", "hf_constants", "mixed_cone_infsup",
           "mixed_zero_test", "reduced_constants", "set_constants",
           "coupling_constants", "hf_continuity", "validation_constants", "HF_ROWS_MAX"]


def combined_b(Bn, Bt) -> sp.csr_matrix:
    """``B = [Bn; Bt]`` (2m x n)."""
    return sp.vstack([sp.csr_matrix(Bn), sp.csr_matrix(Bt)]).tocsr()


def combined_w(W) -> sp.csr_matrix:
    """``blockdiag(W, W)``: the Gram matrix of ``(eta^n, eta^tau)``."""
    return sp.block_diag([sp.csr_matrix(W)] * 2).tocsr()


def combined_generators(Vn: np.ndarray, Vt: np.ndarray) -> np.ndarray:
    """``blockdiag(Vn, Vt)`` (2m x (R + S)): ``eta = (Vn c, Vt theta)``."""
    return sla.block_diag(np.asarray(Vn, float), np.asarray(Vt, float))


def combined_supremizers(Bn, Bt, x_solve: Any, Vn: np.ndarray, Vt: np.ndarray) -> np.ndarray:
    """``T(mu) = X^{-1} [Bn^T Vn, Bt^T Vt]`` (n x (R + S)): the PGA input of one mu
    (:func:`rbbench.rb.algorithms.pga.supremizers` on the combined form)."""
    return supremizers(combined_b(Bn, Bt), x_solve, combined_generators(Vn, Vt))


def combined_pga(problems: Sequence[Any], Z: np.ndarray, X: Any, x_solve: Any,
                 Vn: np.ndarray, Vt: np.ndarray, delta: float,
                 max_dim: int | None = None) -> PGAResult:
    """:func:`rbbench.rb.algorithms.pga.pga` on the combined supremizers of the training
    ``problems``
    (anything with ``Bn``, ``Bt``); ``V_off = [Z, result.basis]``."""
    T_list = [combined_supremizers(p.Bn, p.Bt, x_solve, Vn, Vt) for p in problems]
    return pga(T_list, Z, X, delta, max_dim=max_dim)


def mixed_zero_test(C: np.ndarray, R: int, *, rtol: float = 1e-9) -> bool | None:
    """Exact test of ``beta = 0``: is there ``y = (c, theta) != 0``, ``c >= 0``, ``C y = 0``?

    ``C`` (k x (R + S)) is the coupling (:func:`rbbench.rb.algorithms.infsup.cone_coupling`). Yes if
    the tangential columns are rank deficient (relative singular value ``<= rtol``);
    otherwise iff ``P C_n`` has a non-negative null vector, ``P`` the orthogonal projector
    onto the complement of ``range(C_t)`` (the LP of
    :func:`rbbench.rb.algorithms.infsup.beta_zero_test`); ``None`` when that test is undecided.
    """
    C = np.asarray(C, dtype=float)
    Cn, Ct = C[:, :R], C[:, R:]
    if Ct.shape[1]:
        U, s, _ = np.linalg.svd(Ct, full_matrices=False)
        if s.size < Ct.shape[1] or s[-1] <= rtol * max(s[0], np.finfo(float).tiny):
            return True
        Cn = Cn - U @ (U.T @ Cn)
    if R == 0:
        return False
    zero = inf.beta_zero_test(Cn, rtol=rtol)
    return None if zero is None else bool(zero)


def _face_values(S: np.ndarray, M: np.ndarray, R: int, faces: Sequence[tuple[int, ...]],
                 sign_rtol: float = 1e-9) -> tuple[float, np.ndarray | None]:
    """Best feasible stationary point over the given normal faces (the tangential block
    joins each): generalised eigenvectors of the face pencil whose normal part is
    one-signed, re-evaluated with the full ``S``, ``M``."""
    n = S.shape[0]
    tang = tuple(range(R, n))
    best_q, best_y = np.inf, None
    for face in faces:
        idx = np.array(face + tang, dtype=int)
        if idx.size == 0:
            continue
        Mf = M[np.ix_(idx, idx)]
        ev = np.linalg.eigvalsh(Mf)
        if ev[0] <= 1e-12 * ev[-1]:  # dependent generators: a smaller face has it
            continue
        _, V = sla.eigh(S[np.ix_(idx, idx)], Mf)
        k = len(face)
        for j in range(V.shape[1]):
            v = V[:, j] * (-1.0 if k and V[:k, j].sum() < 0 else 1.0)
            if k and v[:k].min() < -sign_rtol * np.abs(v[:k]).max():
                continue
            y = np.zeros(n)
            y[idx] = v
            y[:R] = np.clip(y[:R], 0.0, None)
            q = float(y @ S @ y) / float(y @ M @ y)
            if q < best_q:
                best_q, best_y = q, y
    return best_q, best_y


def _local_min(S: np.ndarray, M: np.ndarray, R: int, y0: np.ndarray) -> np.ndarray:
    """SLSQP: ``min y^T S y`` subject to ``y^T M y = 1``, ``y[:R] >= 0``, from ``y0``."""
    n = S.shape[0]
    y0 = y0 / np.sqrt(max(float(y0 @ M @ y0), np.finfo(float).tiny))
    res = minimize(lambda y: (y @ S @ y, 2.0 * S @ y), y0, jac=True, method="SLSQP",
                   bounds=[(0.0, None)] * R + [(None, None)] * (n - R),
                   constraints=[{"type": "eq", "fun": lambda y: y @ M @ y - 1.0,
                                 "jac": lambda y: 2.0 * M @ y}],
                   options={"maxiter": 300, "ftol": 1e-15})
    y = res.x.copy()
    y[:R] = np.clip(y[:R], 0.0, None)
    return y


def mixed_cone_infsup(S: np.ndarray, M: np.ndarray, R: int, *, C: np.ndarray | None = None,
                      exact_max_r: int = 10, n_starts: int = 16, seed: int = 0
                      ) -> inf.InfSup:
    """``beta`` over ``{y = (c, theta): c >= 0}`` (module docstring), ``R`` signed entries.

    ``R <= exact_max_r``: exact, every normal face ``F`` (``2^R`` of them, the tangential
    block always free): a minimiser with normal support ``F`` is a generalised eigenvector
    of the ``(F + tangential)`` pencil with a positive normal part (``kind = "cone-exact"``).
    Else the faces with ``|F| <= 2`` and SLSQP from ``n_starts`` random points and the
    clipped span minimiser, each polished on its support (``"cone-upper"``, an upper
    estimate). ``span`` is the lower bound; ``is_zero`` the LP test
    (:func:`mixed_zero_test`, on ``C`` or a factor of ``S``). ``R = 0``: the span value.
    """
    S, M = inf._sym(np.asarray(S, float)), inf._sym(np.asarray(M, float))
    n = S.shape[0]
    span = inf.infsup_span(S, M)
    d, Ss, Ms = inf._unit_diagonal(S, M)
    exact = R <= exact_max_r
    sizes = range(R + 1) if exact else range(min(R, 2) + 1)
    faces = [f for k in sizes for f in itertools.combinations(range(R), k)]
    q, z = _face_values(Ss, Ms, R, faces)
    if not exact:
        rng = np.random.default_rng(seed)
        _, V = sla.eigh(Ss, Ms)
        starts = [V[:, 0], -V[:, 0]] + list(rng.standard_normal((n_starts, n)))
        for y0 in starts:
            y0 = np.asarray(y0, float).copy()
            y0[:R] = np.abs(y0[:R])
            y = _local_min(Ss, Ms, R, y0)
            F = tuple(int(i) for i in np.nonzero(y[:R] > 1e-8 * np.abs(y).max())[0])
            for qq, yy in (_face_values(Ss, Ms, R, [F]),
                           (float(y @ Ss @ y) / float(y @ Ms @ y), y)):
                if yy is not None and qq < q:
                    q, z = qq, yy
    y = z / d
    Cm = inf._psd_factor(S, n * np.finfo(float).eps).T if C is None else C
    return inf.InfSup(value=float(np.sqrt(max(q, 0.0))),
                      kind="cone-exact" if exact else "cone-upper", span=span,
                      is_zero=mixed_zero_test(Cm, R, rtol=1e-9 if C is not None else 1e-6),
                      argmin=y / np.abs(y).max())


@dataclass(frozen=True)
class CombinedInfSup:
    """Inf-sup of the combined form at one mu over a primal space and a dual set.

    ``value``: ``kind`` says what it is (``"cone-exact"``, ``"cone-upper"`` estimate,
    ``"span-lower-bound"``); ``span``: the span lower bound; ``is_zero``: the exact LP test;
    ``c``: the continuity constant on the same spaces; ``value_rel``, ``span_rel``:
    divided by ``c_hf`` (module docstring; NaN when no ``c_hf`` was given).
    """

    value: float
    kind: str
    span: float
    is_zero: bool | None
    c: float
    value_rel: float
    span_rel: float

    def as_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


def hf_constants(Bn, Bt, W, x_solve: Any) -> CombinedInfSup:
    """``beta_HF`` and ``c_HF`` of the combined form on ``V x (R^m_+ x R^m)`` (2m solves).

    ``value = span`` is the exact value over ``R^{2m}``, a LOWER BOUND of the HF value
    (the normal cone is not enumerated at this size); ``is_zero`` is the exact LP test on the
    HF set; ``c = c_HF``, ``value_rel = beta_HF / c_HF`` (Benaceur et al.'s ratio).
    """
    H = inf.supremizer_operator(combined_b(Bn, Bt), x_solve)
    return _hf_from_factor(H, combined_w(W).toarray(), int(Bn.shape[0]))


def _hf_from_factor(H: np.ndarray, Wd: np.ndarray, m: int) -> CombinedInfSup:
    """:func:`hf_constants` from the factor ``H`` (``H H^T = B X^{-1} B^T``)."""
    S = H @ H.T
    span, c = inf.infsup_span(S, Wd), inf.boundedness_constant(S, Wd)
    zero = mixed_zero_test(H.T, m)
    return CombinedInfSup(span, "span-lower-bound", span, zero, c, span / c, span / c)


def set_constants(H: np.ndarray, W2: Any, Vg: np.ndarray, n_signed: int,
                  c_hf: float | None = None, exact_max_r: int = 10,
                  cone: bool = True) -> CombinedInfSup:
    """Inf-sup of the combined form over the primal space of ``H`` (``H H^T = B P B^T``,
    :func:`rbbench.rb.algorithms.infsup.supremizer_operator`) and the dual set
    ``{Vg y : y[:n_signed] >= 0}`` (``W2`` the Gram matrix of ``(eta^n, eta^tau)``).

    ``cone = False`` (or ``n_signed = 0``): the span lower bound is the value; else
    :func:`mixed_cone_infsup`. ``c``: the continuity constant on the same spaces;
    ``value_rel = value / c_hf``.
    """
    return coupling_constants(inf.cone_coupling(H, Vg), inf._gram(W2, Vg), n_signed, c_hf,
                              exact_max_r, cone)


def coupling_constants(C: np.ndarray, M: np.ndarray, n_signed: int,
                       c_hf: float | None = None, exact_max_r: int = 10,
                       cone: bool = True) -> CombinedInfSup:
    """:func:`set_constants` from the coupling ``C`` (``||C y|| = sup_v b(v, Vg y) /
    ||v||_X``) and the dual Gram matrix ``M = Vg^T W2 Vg``."""
    S = inf._sym(C.T @ C)
    c = inf.boundedness_constant(S, M)
    if cone and n_signed:
        r = mixed_cone_infsup(S, M, n_signed, C=C, exact_max_r=exact_max_r)
        value, kind, span, zero = r.value, r.kind, r.span, r.is_zero
    else:
        span = inf.infsup_span(S, M)
        value, kind, zero = span, "span-lower-bound", mixed_zero_test(C, n_signed)
    rel = float("nan") if not c_hf else 1.0 / c_hf
    return CombinedInfSup(value, kind, span, zero, c, value * rel, span * rel)


#: the whole HF rows (2m solves per validation mu) only up to this many combined multipliers
HF_ROWS_MAX = 400


def hf_continuity(B: Any, W2: Any, x_solve: Any, *, tol: float = 1e-8) -> float:
    """``c_HF = sqrt(lambda_max(B X^{-1} B^T, W2))`` by Lanczos (ARPACK ``eigsh``; one
    ``X`` solve per iteration instead of the ``2m`` of :func:`hf_constants`)."""
    from scipy.sparse.linalg import LinearOperator, eigsh

    B = sp.csr_matrix(B)
    op = LinearOperator(2 * (B.shape[0],), dtype=float,
                        matvec=lambda y: B @ np.ravel(x_solve(B.T @ np.ravel(y))))
    lam = eigsh(op, k=1, M=sp.csc_matrix(W2), which="LA", tol=tol,
                return_eigenvectors=False, v0=np.ones(B.shape[0]))
    return float(np.sqrt(max(float(lam[0]), 0.0)))


def validation_constants(Bn, Bt, W, x_solve: Any, X: Any, Vg: np.ndarray, n_signed: int,
                         Z: np.ndarray, exact_max_r: int = 10) -> dict[str, CombinedInfSup]:
    """The combined inf-sup constants of one validation mu:

    * ``dec``: whole V against the reduced dual set ``{Vg y: y[:n_signed] >= 0}``
      (``R + S`` solves: ``C^T C = (B^T Vg)^T X^{-1} (B^T Vg)``);
    * ``off``: ``span Z`` (the offline-stabilised primal space) against the same set;
    * ``hf``: whole V against the HF set (:func:`hf_constants`, span lower bound), only when
      ``2m <= HF_ROWS_MAX`` (2m solves).

    ``value_rel`` / ``span_rel`` are divided by ``c_HF(mu)`` (:func:`hf_continuity`, or
    exact with the ``hf`` row).
    """
    B, W2 = combined_b(Bn, Bt), combined_w(W)
    out: dict[str, CombinedInfSup] = {}
    if B.shape[0] <= HF_ROWS_MAX:
        out["hf"] = _hf_from_factor(inf.supremizer_operator(B, x_solve), W2.toarray(),
                                    int(Bn.shape[0]))
        c_hf = out["hf"].c
    else:
        c_hf = hf_continuity(B, W2, x_solve)
    BV = np.asarray(B.T @ Vg)
    C = inf._psd_factor(inf._sym(BV.T @ np.asarray(x_solve(BV)).reshape(BV.shape)),
                        inf.GRAM_RTOL).T
    M = inf._gram(W2, Vg)
    out["dec"] = coupling_constants(C, M, n_signed, c_hf, exact_max_r)
    out["off"] = set_constants(inf.supremizer_operator(B, X, Z), W2, Vg, n_signed, c_hf,
                               exact_max_r)
    return out


def reduced_constants(Bn, Bt, W, X: Any, Vn: np.ndarray, Vt: np.ndarray,
                      Z: np.ndarray | None = None, c_hf: float | None = None,
                      exact_max_r: int = 10, cone: bool = True) -> CombinedInfSup:
    """Inf-sup of the combined form over ``span Z`` (``None``: all of V; then ``X`` may be a
    solver) and the reduced dual set ``{(Vn c, Vt theta): c >= 0}``.

    ``cone = False`` (or ``R = 0``) returns the span lower bound as the value; else
    :func:`mixed_cone_infsup`. ``c`` is the continuity constant on the same spaces;
    ``c_hf`` (from :func:`hf_constants`) gives the normalised values.
    """
    R = int(np.asarray(Vn).shape[1])
    H = inf.supremizer_operator(combined_b(Bn, Bt), X, Z)
    return set_constants(H, combined_w(W), combined_generators(Vn, Vt), R, c_hf, exact_max_r,
                         cone)

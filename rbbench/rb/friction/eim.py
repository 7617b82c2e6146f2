"""Hyper-reduction of the friction constraint: EIM of ``Bn(mu) Z``, ``Bt(mu) Z`` and ``Gn(mu)``.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slides "Preliminaries" (3: "Dependence of the RB problem on
the HF dimensions -> EIM") and "EIM errors" (``B^n(mu)``, ``B^tau(mu)``). The friction rows
are the P1 nodal ones (:class:`rbbench.interfaces.FrictionProblem`): ``Bn = Mt^T diag(w) Un``,
``Bt = Mt^T diag(w) Ut``, ``Gn = Mt^T diag(w) gap`` with ``Mt`` the hat functions of the slave
contact nodes. As in the frictionless case (:mod:`rbbench.rb.hyper.contact_eim`, whose docstring
gives the reasons), the greedy EIM interpolates the smooth reduced quantities, not the
entries of ``B(mu)``::

    C^n(mu) = Bn(mu) Z ~ sum_k theta_k(mu) C^n_k,   theta from M_n magic entries of C^n(mu)
    C^t(mu) = Bt(mu) Z ~ sum_k phi_k(mu) C^t_k,     phi from M_t magic entries of C^t(mu)
    Gn(mu)             ~ sum_k eta_k(mu) G_k,       eta from M_G magic rows of Gn(mu)

so ``Bn_N(mu) = Vn^T C^n(mu)``, ``Bt_N(mu) = Vt^T C^t(mu)``, ``Gn_N(mu) = Vn^T Gn(mu)``
come from the precomputed ``Vn^T C^n_k``, ``Vt^T C^t_k``, ``Vn^T G_k``. Online, one
:class:`~rbbench.rb.hyper.contact_eim.RowEvaluator` on the P1 layout pairs only the slave facets
of the magic rows (both directions share the pairing): the work depends on ``M_n + M_t +
M_G``, not on the HF size. The tangential jump of the Dirichlet lifting (``gt``) vanishes
because the contact rows have no Dirichlet column (checked).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from rbbench.hf.geometry.operators import contact_operators
from rbbench.hf.geometry.pairing import ContactLayout
from rbbench.rb.algorithms.affine import AffineOperator, LinearInMu, affine_decomposition
from rbbench.rb.algorithms.eim import EIMResult, deim, eim_error_curve
from rbbench.rb.friction.collocation.model import FrictionArrays
from rbbench.rb.hyper.contact_eim import (
    HyperReductionError,
    RowEvaluator,
    build_row_evaluator,
    column_eim,
    local_free_rows,
    tangent,
)

__all__ = ["FrictionEIM", "FrictionOperators", "eim_histories", "friction_eim",
           "friction_layout", "friction_operators", "friction_training_operators",
           "reduced_eim_errors"]


def friction_layout(layout: ContactLayout) -> ContactLayout:
    """The contact layout with the P1 nodal multipliers of friction (``Mt``) as its rows."""
    return replace(layout, multiplier="p1")


def friction_training_operators(layout: ContactLayout, mus: np.ndarray, free: np.ndarray
                                ) -> tuple[list[sp.csr_matrix], list[sp.csr_matrix], np.ndarray]:
    """``(Bn list, Bt list, Gn (m, P))`` at the rows of ``mus`` on the free dofs, from the
    layout alone (no HF solve: the EIM training set can be dense, published: 61, 150).

    Raises :class:`HyperReductionError` when a contact row has a Dirichlet column (then
    ``Gn`` and the tangential lifting ``ut_lift`` would depend on the lifting).
    """
    dirichlet = np.setdiff1d(np.arange(layout.n_dofs), free)
    Bn, Bt, G = [], [], []
    for mu in np.atleast_2d(np.asarray(mus, dtype=float)):
        c = contact_operators(layout, mu, tangential=True)
        bn, bt = c.B_nodal(), c.Bt()
        if bn[:, dirichlet].nnz or bt[:, dirichlet].nnz:
            raise HyperReductionError("the friction contact rows touch Dirichlet dofs; the "
                                      "friction EIM assumes the contact zone is away from "
                                      "the Dirichlet boundary")
        Bn.append(bn[:, free].tocsr())
        Bt.append(bt[:, free].tocsr())
        G.append(c.G_nodal())
    return Bn, Bt, np.stack(G, axis=1)


@dataclass
class _Terms:
    """One interpolated matrix ``C(mu) = B(mu) Z``: entry ``e`` is ``C[rows[pos[e]], col[e]]``;
    ``lu`` factors ``Q[magic]``, ``T[k] = V^T C_k``; ``support`` from
    :meth:`RowEvaluator.support`."""

    pos: np.ndarray
    col: np.ndarray
    lu: tuple
    T: np.ndarray
    support: tuple = ()

    def reduced(self, ev: RowEvaluator, p: Any, direction: np.ndarray,
                Z_loc: np.ndarray) -> np.ndarray:
        """``V^T C(mu)`` from the magic entries at the pairing ``p``."""
        vals = ev.jump_entries(p, direction, Z_loc, *self.support, self.col)
        return np.tensordot(sla.lu_solve(self.lu, vals), self.T, axes=1)


@dataclass
class FrictionEIM:
    """Hyper-reduced friction constraint ``mu -> (Bn_N, Gn_N, Bt_N)`` (module docstring).

    Attributes
    ----------
    evaluator : RowEvaluator
        The magic rows of ``Bn``, ``Bt``, ``Gn`` on the P1 layout (:func:`friction_layout`).
    normal, tangential : _Terms
        The EIM of ``C^n = Bn Z`` (``T``: (M_n, R, N)) and ``C^t = Bt Z`` ((M_t, S, N)).
    pos_G : (M_G,)
        Positions in ``evaluator.rows`` of Gn's magic rows.
    lu_G : LU factors of Gn's ``Q[magic]``.
    T_G : (M_G, R)
        ``Vn^T G_k``.
    Z_loc : (n_local, N)
        The primal basis on the evaluator's local dofs.
    info : dict
        Sizes (``M_n``, ``M_t``, ``M_G``, rows, local dofs), training error curves,
        validation curves when asked (:func:`friction_eim`).
    """

    evaluator: RowEvaluator
    normal: _Terms
    tangential: _Terms
    pos_G: np.ndarray
    lu_G: tuple
    T_G: np.ndarray
    Z_loc: np.ndarray
    info: dict = field(default_factory=dict)
    slip: _Terms | None = None

    def __post_init__(self) -> None:
        for part in (self.normal, self.tangential) + ((self.slip,) if self.slip else ()):
            part.support = self.evaluator.support(part.pos)

    def with_slip_rows(self, mu: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """``(Bn_N, Gn_N, Bt_N, (Bt(mu) Z)[slip rows])`` from one pairing: the slip rows
        (``slip_rows`` of :func:`friction_eim`) are evaluated exactly, not interpolated."""
        ev = self.evaluator
        p = ev.pairing(mu)
        t = tangent(p.nrm)
        Bn = self.normal.reduced(ev, p, p.nrm, self.Z_loc)
        Bt = self.tangential.reduced(ev, p, t, self.Z_loc)
        eta = sla.lu_solve(self.lu_G, ev.gap_rows(p, self.pos_G))
        rows = np.zeros((0, self.Z_loc.shape[1]))
        if self.slip is not None:
            rows = ev.jump_entries(p, t, self.Z_loc, *self.slip.support, self.slip.col)
            rows = rows.reshape(-1, self.Z_loc.shape[1])
        return Bn, eta @ self.T_G, Bt, rows

    def __call__(self, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(Bn_N (R, N), Gn_N (R,), Bt_N (S, N))`` at mu (one windowed pairing)."""
        ev = self.evaluator
        p = ev.pairing(mu)
        Bn = self.normal.reduced(ev, p, p.nrm, self.Z_loc)
        Bt = self.tangential.reduced(ev, p, tangent(p.nrm), self.Z_loc)
        eta = sla.lu_solve(self.lu_G, ev.gap_rows(p, self.pos_G))
        return Bn, eta @ self.T_G, Bt

    @property
    def R(self) -> int:
        return int(self.T_G.shape[1])

    @property
    def S(self) -> int:
        return int(self.tangential.T.shape[1])


def friction_eim(layout: ContactLayout, Bn_train: Sequence, Bt_train: Sequence,
                 Gn_train: np.ndarray, Z: np.ndarray, Vn: np.ndarray, Vt: np.ndarray,
                 free: np.ndarray, mus_sample: np.ndarray, tol: float = 1e-8,
                 m_max: int | None = None, valid: tuple | None = None,
                 slip_rows: np.ndarray | None = None) -> FrictionEIM:
    """Build :class:`FrictionEIM` from training friction operators.

    Parameters
    ----------
    layout : ContactLayout
        The backend's reference contact layout (any multiplier; the P1 rows are used).
    Bn_train, Bt_train : sequences of (m, n_free) sparse
        ``Bn(mu)``, ``Bt(mu)`` on the free dofs per EIM training mu
        (:func:`friction_training_operators`).
    Gn_train : (m, P)
        ``Gn(mu)`` (nodal gaps; no lifting term, see the module docstring).
    Z : (n_free, N)
        Primal basis (after stabilisation).
    Vn, Vt : (m, R), (m, S)
        Normal cone generators and tangential modes.
    free : (n_free,)
        Global dof of each free dof.
    mus_sample : (P', p)
        Dense sample of D for the master windows (include the corners of D).
    tol, m_max
        EIM stopping (relative max-norm training error; largest size), each of the three.
    valid : (Bn_valid, Bt_valid, Gn_valid), optional
        Validation operators: ``info["valid_curves"]`` gets Benaceur et al.'s e_EIM and the max
        relative error of each nested interpolant
        (:func:`rbbench.rb.algorithms.eim.eim_error_curve`).
    slip_rows : (M_s,) int, optional
        Nodes whose whole rows of ``Bt(mu) Z`` are evaluated online
        (:meth:`FrictionEIM.with_slip_rows`; the wedge model's slip DEIM nodes).
    """
    res_n, row_n, col_n, T_n = column_eim(list(Bn_train), Z, Vn, tol, m_max)
    res_t, row_t, col_t, T_t = column_eim(list(Bt_train), Z, Vt, tol, m_max)
    res_G = deim(np.asarray(Gn_train), tol=tol, m_max=m_max)
    if min(res_n.m, res_t.m, res_G.m) == 0:
        raise HyperReductionError("friction EIM found no term: a training Bn Z, Bt Z or Gn "
                                  "is zero")
    p1 = friction_layout(layout)
    slip = np.zeros(0, np.int64) if slip_rows is None else np.asarray(slip_rows, np.int64)
    ev = build_row_evaluator(p1, np.concatenate([row_n, row_t, res_G.magic, slip]),
                             mus_sample)
    loc = local_free_rows(ev, free, layout.n_dofs)
    info = {"M_n": res_n.m, "M_t": res_t.m, "M_G": res_G.m, "rows": int(ev.rows.size),
            "n_local_dofs": ev.n_local, "n_free": int(free.size), "m": int(Gn_train.shape[0]),
            "n_eim_train": int(np.asarray(Gn_train).shape[1]), "tol": tol,
            "errors_n": res_n.errors.tolist(), "errors_t": res_t.errors.tolist(),
            "errors_G": res_G.errors.tolist()}
    if valid is not None:
        info["valid_curves"] = _valid_curves((res_n, res_t, res_G), valid, Z)
    return FrictionEIM(ev, _Terms(np.searchsorted(ev.rows, row_n), col_n,
                                  sla.lu_factor(res_n.Q[res_n.magic]), T_n),
                       _Terms(np.searchsorted(ev.rows, row_t), col_t,
                              sla.lu_factor(res_t.Q[res_t.magic]), T_t),
                       np.searchsorted(ev.rows, res_G.magic),
                       sla.lu_factor(res_G.Q[res_G.magic]), (Vn.T @ res_G.Q).T,
                       np.ascontiguousarray(Z[loc]), info,
                       None if slip_rows is None else _slip_terms(ev, slip, Z.shape[1]))


def eim_histories(feim: FrictionEIM) -> dict[str, list[float]]:
    """The training error curves of a friction EIM as a stage's histories: ``eim_error``
    (``C^n = Bn Z``, the normal contact rows, as the frictionless EIM's), ``eim_error_t``
    (``Bt Z``), ``eim_error_G`` (``Gn``); relative max-norm after each term."""
    return {"eim_error": list(feim.info["errors_n"]), "eim_error_t": list(feim.info["errors_t"]),
            "eim_error_G": list(feim.info["errors_G"])}


def _slip_terms(ev: RowEvaluator, rows: np.ndarray, N: int) -> _Terms:
    """All ``N`` entries of each row ``rows`` of ``Bt Z`` (row-major; no interpolation)."""
    pos = np.repeat(np.searchsorted(ev.rows, rows), N)
    return _Terms(pos, np.tile(np.arange(N), rows.size), (), np.zeros(0))


def _valid_curves(results: tuple[EIMResult, ...], valid: tuple, Z: np.ndarray
                  ) -> dict[str, dict[str, list[float]]]:
    """Validation error curves of the three nested EIMs (``C^n``, ``C^t``, ``Gn``)."""
    Bn_v, Bt_v, Gn_v = valid
    snaps = [np.stack([np.asarray(B @ Z).ravel() for B in mats], axis=1)
             for mats in (Bn_v, Bt_v)] + [np.asarray(Gn_v)]
    return {name: {k: v.tolist() for k, v in eim_error_curve(res, S).items()}
            for name, res, S in zip(("Cn", "Ct", "Gn"), results, snaps, strict=True)}


def reduced_eim_errors(feim: FrictionEIM, mus: np.ndarray, Bn: Sequence, Bt: Sequence,
                       Gn: np.ndarray, Z: np.ndarray, Vn: np.ndarray, Vt: np.ndarray
                       ) -> dict[str, float]:
    """Benaceur et al.'s ratio of maxima over ``mus`` of the max-norm error of the reduced arrays
    ``Bn_N``, ``Bt_N``, ``Gn_N`` (EIM against the projection of the exact operators)."""
    num, den = np.zeros(3), np.zeros(3)
    for j, mu in enumerate(np.atleast_2d(np.asarray(mus, dtype=float))):
        exact = (Vn.T @ (Bn[j] @ Z), Vn.T @ np.asarray(Gn)[:, j], Vt.T @ (Bt[j] @ Z))
        for i, (e, a) in enumerate(zip(exact, feim(mu), strict=True)):
            num[i] = max(num[i], float(np.abs(e - a).max()))
            den[i] = max(den[i], float(np.abs(e).max()))
    rel = np.divide(num, den, out=np.zeros(3), where=den > 0)
    return {"e_eim_BnN": float(rel[0]), "e_eim_GnN": float(rel[1]), "e_eim_BtN": float(rel[2])}


@dataclass
class FrictionOperators:
    """``mu -> FrictionArrays`` with no HF-size work: affine ``A_N``, ``F_N``
    (:func:`rbbench.rb.algorithms.affine.affine_decomposition`, exact, verified by probing) and the
    friction EIM; ``gt = 0`` (no Dirichlet column in the contact rows); ``law_values`` the
    per-node law data (constant in mu, checked by :func:`friction_operators`)."""

    A: AffineOperator
    F: AffineOperator
    coefficients: Callable[[np.ndarray], np.ndarray]
    eim: FrictionEIM
    law_values: np.ndarray

    def __call__(self, mu: np.ndarray) -> FrictionArrays:
        th = self.coefficients(mu)
        Bn, Gn, Bt = self.eim(mu)
        return FrictionArrays(A=self.A(th), F=self.F(th), Bn=Bn, Gn=Gn, Bt=Bt,
                              gt=np.zeros(Bt.shape[0]), law_values=self.law_values)


def friction_operators(problem_at: Callable[[np.ndarray], Any], bounds: np.ndarray,
                       feim: FrictionEIM, Z: np.ndarray, rtol: float = 1e-10
                       ) -> FrictionOperators:
    """:class:`FrictionOperators` from a FrictionProblem factory (one load step): ``A_N``,
    ``F_N`` decomposed exactly (``NotAffineError`` otherwise), the law data taken at the
    domain centre and checked equal at the probes."""
    cache: dict[bytes, Any] = {}

    def at(mu):
        key = np.asarray(mu, dtype=float).tobytes()
        if key not in cache:
            p = problem_at(mu)
            law = p.threshold if p.law == "tresca" else p.coefficient
            cache[key] = (Z.T @ (p.A @ Z), Z.T @ p.steps[-1].F, np.asarray(law, float))
        return cache[key]

    bounds = np.asarray(bounds, dtype=float)
    ops = [AffineOperator(affine_decomposition(lambda mu, k=k: at(mu)[k], bounds, rtol=rtol))
           for k in range(2)]
    laws = [v[2] for v in cache.values()]
    if any(not np.array_equal(laws[0], law) for law in laws[1:]):
        raise HyperReductionError("the friction law data depend on mu: not hyper-reduced")
    return FrictionOperators(ops[0], ops[1], LinearInMu(bounds.shape[0]), feim, laws[0])

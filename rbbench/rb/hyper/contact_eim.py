"""Hyper-reduction of the contact constraint: EIM of ``B(mu) Z`` and ``G(mu)`` (``hyper = "eim"``).

Why not the entries of ``B(mu)``. On a parametrised geometry (Benaceur, Drouet, Ehrlacher, Ern
& Niakh, "Model order reduction methods: parametric variational inequalities" (talk), slide
"Affine parametric decomposition") ``B(mu)`` is not affine: every slave
quadrature point slides along the master polygon as mu changes, so each
*entry* of ``B(mu)`` is a hat-shaped function of mu, and the entrywise EIM
of Benaceur et al. generalises badly (its ``e_EIM`` is still reported, see
:func:`entrywise_eim_error`: on ``hertz_halfdisks`` with 21 training
parameters it interpolates the training set and misses the validation set
by 69 %). Interpolating the columns of ``C(mu) = B(mu) Z`` over the multiplier
index (a row DEIM) needed about 190 of the 256 rows for a 1e-6 error (the
PGA modes make those columns rich), so its online cost grows with the mesh.

What the reduced model needs is ``B_N(mu) = Vg^T C(mu)`` and
``G_N(mu) = Vg^T G(mu)``, and ``C(mu)`` (the normal jump of the primal modes,
integrated against each multiplier) and ``G(mu)`` are smooth in mu. So the
greedy EIM of Barrault-Maday-Nguyen-Patera (:func:`rbbench.rb.algorithms.eim.deim`) is
applied to the *matrices* ``C(mu)`` (entries of the dense m x N matrix) and
to the vectors ``G(mu)``::

    C(mu) ~ sum_k theta_k(mu) C_k,  theta from C(mu) at M_B magic entries (i_k, n_k)
    G(mu) ~ sum_k eta_k(mu) G_k,    eta from G(mu) at M_G magic rows

so ``B_N(mu) = sum_k theta_k(mu) Vg^T C_k`` with the ``Vg^T C_k`` precomputed.
Online, only the few magic rows of ``B(mu)`` and ``G(mu)`` are computed:
:class:`RowEvaluator` pairs the slave facets of those rows against a
window of master facets, from a restricted
:class:`~rbbench.hf.geometry.operators.ContactLayout` (small arrays, no backend).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from rbbench.hf.geometry.facets import multiplier_basis, point_support, window_tangent_ranges
from rbbench.hf.geometry.pairing import ContactLayout, pair
from rbbench.rb.algorithms.eim import EIMResult, deim, eim_error, matrix_eim

__all__ = ["ContactEIM", "HyperReductionError", "RowEvaluator", "build_row_evaluator",
           "column_eim", "contact_eim", "entrywise_eim_error", "local_free_rows",
           "pair_in_windows", "restrict_layout", "tangent"]


class HyperReductionError(ValueError):
    """The hyper-reduced evaluator cannot represent this case (the message says why)."""


@dataclass
class RowEvaluator:
    """Rows ``rows`` of ``B(mu)`` (on the local dofs) and of ``G(mu)``, HF-size independent.

    Attributes
    ----------
    layout : ContactLayout
        Restricted: the slave facets of the rows, the master facets of their
        windows, dofs renumbered to ``0 .. n_local - 1``.
    rows : (M,)
        Global multiplier indices.
    windows : (lo, hi, ranges) or None
        Per quadrature point, the range of master facets (indices into the
        contiguous chain ``layout.master``) hit over a dense sample of D,
        widened by a margin, and the range of facet directions in it; searched
        by bisection where the chain is monotone along the ray
        (:func:`~rbbench.hf.geometry.operators.ray_cast_window`).
    local_dofs : (n_local,)
        Global dofs behind the local numbering.
    Mrows : (M, nq)
        Multiplier basis of the rows at the quadrature points (mu-independent).
    """

    layout: ContactLayout
    rows: np.ndarray
    windows: tuple[np.ndarray, ...] | None
    local_dofs: np.ndarray
    Mrows: np.ndarray

    def pairing(self, mu: np.ndarray):
        """The pairing of the rows' quadrature points at mu, in their windows."""
        return pair_in_windows(self.layout, mu, self.windows, "a magic row's quadrature point")

    def __call__(self, mu: np.ndarray, tangential: bool = False
                 ) -> tuple[np.ndarray, np.ndarray]:
        """``(B(mu)[rows][:, local_dofs] (M x n_local) dense, G(mu)[rows] (M,))``; with
        ``tangential`` the rows of ``Bt(mu)`` (the jump along ``t = (-n_y, n_x)``) instead."""
        p = self.pairing(mu)
        Mw = self.Mrows * p.w
        d = tangent(p.nrm) if tangential else p.nrm
        return Mw @ p.jump(d, self.n_local).toarray(), Mw @ p.gap

    def support(self, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Quadrature points of the rows ``rows[pos]``, padded: ``(points, values)``, each
        (len(pos), P), with ``values`` the multiplier basis there (0 on padding)."""
        return point_support(self.Mrows, pos)

    def entries(self, mu: np.ndarray, Z_loc: np.ndarray, pts: np.ndarray, vals: np.ndarray,
                cols: np.ndarray, pos_G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Entries ``(B(mu) Z)[rows_e, cols_e]`` and ``G(mu)[rows[pos_G]]``, from the local
        basis ``Z_loc``.

        Entry ``e`` is ``sum_q vals[e, q] w_q sum_j coef[q, j] Z_loc[dof[q, j], cols[e]]``
        over its row's points ``pts[e]`` (:meth:`support`): O(entries x points x dofs
        per point) work, neither the rows nor the full ``B(mu) Z`` is formed.
        """
        p = self.pairing(mu)
        return self.jump_entries(p, p.nrm, Z_loc, pts, vals, cols), self.gap_rows(p, pos_G)

    def jump_entries(self, p, direction: np.ndarray, Z_loc: np.ndarray, pts: np.ndarray,
                     vals: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """The entries of :meth:`entries` for the jump along ``direction`` (n_q, 2) at the
        points of the pairing ``p`` (:meth:`pairing`): ``p.nrm`` gives ``B Z``,
        :func:`tangent` of it ``Bt Z``."""
        col = np.asarray(cols)[:, None, None]
        acc = np.zeros(pts.shape)
        for c, d in p.jump_terms(direction):
            acc += np.einsum("epj,epj->ep", c[pts], Z_loc[d[pts], col])
        return np.einsum("ep,ep->e", vals * p.w[pts], acc)

    def gap_rows(self, p, pos: np.ndarray) -> np.ndarray:
        """``G(mu)[rows[pos]]`` from the pairing ``p`` at mu."""
        return (self.Mrows[pos] * p.w) @ p.gap

    @property
    def n_local(self) -> int:
        return int(self.local_dofs.size)

    @property
    def window_max_width(self) -> int:
        """The most master facets in one point's window (0 for a rigid plane)."""
        return 0 if self.windows is None else int((self.windows[1] - self.windows[0]).max()) + 1

    @property
    def n_master(self) -> int:
        """Master facets of the restricted layout (0 for a rigid plane)."""
        return 0 if self.layout.master is None else int(self.layout.master.n)


def tangent(nrm: np.ndarray) -> np.ndarray:
    """``t = (-n_y, n_x)`` per row of ``nrm`` (the tangent of ``Ut``,
    :func:`rbbench.hf.geometry.operators.contact_operators`)."""
    return np.stack([-nrm[:, 1], nrm[:, 0]], axis=1)


def pair_in_windows(layout: ContactLayout, mu: np.ndarray,
                    windows: tuple[np.ndarray, ...] | None, what: str):
    """:func:`~rbbench.hf.geometry.operators.pair` in the master windows sampled offline; a point
    that left its window raises :class:`HyperReductionError` (``what`` names it)."""
    try:
        return pair(layout, mu, windows=windows)
    except ValueError as exc:
        raise HyperReductionError(f"mu = {np.atleast_1d(mu).tolist()}: {what} left the master "
                                  f"window sampled offline ({exc})") from None


def restrict_layout(layout: ContactLayout, facets: np.ndarray, mus: np.ndarray,
                    margin: int = 2, with_stress: bool = False
                    ) -> tuple[ContactLayout, tuple[np.ndarray, ...] | None, np.ndarray]:
    """``layout`` restricted to the slave ``facets``: ``(small, windows, local_dofs)``.

    ``small`` holds those slave facets, the contiguous master chain their windows span
    (and, with ``with_stress``, the slave stress data), dofs renumbered to
    ``0 .. n_local - 1`` (``local_dofs`` maps them back). ``windows = (lo, hi, ranges)``:
    per quadrature point the master facets it hits over ``mus`` (a dense sample of D,
    including its corners), widened by ``margin`` each side, and the facet directions in
    that window (:func:`~rbbench.hf.geometry.operators.window_tangent_ranges`, once: a
    similarity map keeps them). ``None`` for a rigid plane.

    Raises ``ValueError`` for ``integration = "segmented"`` (mu-dependent points), and
    with ``with_stress`` when the layout has no slave stress data.
    """
    if with_stress and layout.stress is None:
        raise ValueError("the contact layout has no slave stress data (Snn)")
    if layout.integration != "gauss" and layout.master is not None:
        raise ValueError("hyper-reduction (EIM / ECSW rows) needs fixed contact points: "
                         f"[discretization] contact_integration = {layout.integration!r} "
                         "moves them with mu; use 'gauss', or hyper = 'none'")
    slave = layout.slave.subset(facets)
    stress = layout.stress.subset(facets) if with_stress else None
    master, windows = None, None
    if layout.master is not None:
        segs = np.stack([pair(layout, mu, slave=slave).master_seg for mu in mus])
        lo = np.maximum(segs.min(axis=0) - margin, 0)
        hi = np.minimum(segs.max(axis=0) + margin, layout.master.n - 1)
        first = int(lo.min())
        master = layout.master.subset(np.arange(first, int(hi.max()) + 1))  # contiguous chain
        lo, hi = lo - first, hi - first
        windows = (lo, hi, window_tangent_ranges(master.a, master.b, lo, hi))
    dofs = [c.dofs.reshape(-1) for c in (slave, stress, master) if c is not None]
    local = np.unique(np.concatenate(dofs))

    def renumber(part):
        return None if part is None else replace(part, dofs=np.searchsorted(local, part.dofs))

    small = ContactLayout(slave=renumber(slave), master=renumber(master), degree=layout.degree,
                          n_gauss=layout.n_gauss, multiplier=layout.multiplier,
                          patch=layout.patch, n_facets=layout.n_facets, n_dofs=local.size,
                          stress=renumber(stress))
    return small, windows, local


def build_row_evaluator(layout: ContactLayout, rows: np.ndarray, mus: np.ndarray,
                        margin: int = 2) -> RowEvaluator:
    """Restrict ``layout`` to the multiplier ``rows``.

    The master window of each quadrature point is the range of master facets
    it hits over ``mus`` (a dense sample of D, including its corners),
    widened by ``margin`` facets each side; online, a point leaving its
    window raises :class:`HyperReductionError` rather than pairing wrongly.
    """
    rows = np.unique(np.asarray(rows, dtype=np.int64))
    small, windows, local = restrict_layout(layout, layout.facets_of_rows(rows), mus, margin)
    p = pair(small, mus[0], windows=windows)
    M = multiplier_basis(layout.multiplier, layout.n_facets, small.slave.ids[p.fq], p.sq,
                         layout.patch).tocsc()
    Mrows = M[:, rows].T.toarray()
    return RowEvaluator(small, rows, windows, local, Mrows)


@dataclass
class ContactEIM:
    """Hyper-reduced constraint ``mu -> (B_N(mu), G_N(mu))`` (module docstring).

    Attributes
    ----------
    evaluator : RowEvaluator
        The magic rows of ``B(mu)`` and ``G(mu)``.
    pos_B : (n_rows_B,)
        Positions in ``evaluator.rows`` of the rows holding C's magic entries.
    entry_row, entry_col : (M_B,)
        Each magic entry of C as (index into ``pos_B``, column of Z).
    pos_G : (M_G,)
        Positions in ``evaluator.rows`` of G's magic rows.
    Z_loc : (n_local, N)
        The primal basis on the local dofs.
    lu_B, lu_G : LU factors of ``Q[magic]`` (unit lower triangular for the greedy EIM).
    T_B : (M_B, R, N)
        ``Vg^T C_k``.
    T_G : (M_G, R)
        ``Vg^T G_k``.
    info : dict
        Sizes, EIM training errors and tolerances.
    """

    evaluator: RowEvaluator
    pos_B: np.ndarray
    entry_row: np.ndarray
    entry_col: np.ndarray
    pos_G: np.ndarray
    Z_loc: np.ndarray
    lu_B: tuple
    lu_G: tuple
    T_B: np.ndarray
    T_G: np.ndarray
    info: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._support = self.evaluator.support(self.pos_B[self.entry_row])

    def __call__(self, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        C, g = self.evaluator.entries(mu, self.Z_loc, *self._support, self.entry_col,
                                      self.pos_G)
        theta = sla.lu_solve(self.lu_B, C)
        eta = sla.lu_solve(self.lu_G, g)
        return np.tensordot(theta, self.T_B, axes=1), eta @ self.T_G

    @property
    def R(self) -> int:
        return int(self.T_G.shape[1])


def contact_eim(layout: Any, B_train: list, G_train: np.ndarray,
                Z: np.ndarray, Vg: np.ndarray, free: np.ndarray, mus_sample: np.ndarray,
                tol: float = 1e-8, m_max: int | None = None,
                row_evaluator: Callable | None = None, row_threshold: float = 1.0
                ) -> ContactEIM:
    """Build :class:`ContactEIM` from the training constraint operators.

    Parameters
    ----------
    layout : ContactLayout or SurfaceLayout
        The backend's reference contact data (2D chains, or 3D triangulated surfaces with
        ``row_evaluator`` :func:`~rbbench.rb.hyper.surface_eim.build_surface_row_evaluator`).
    B_train : list of (m, n_free) sparse
        ``B(mu)`` on the free dofs (the formulation's), one per training mu.
    G_train : (m, P)
        ``G(mu)`` (the formulation's, lifted).
    Z : (n_free, N)
        Primal basis (after stabilisation).
    Vg : (m, R)
        Dual generators.
    free : (n_free,)
        Global dof of each free dof.
    mus_sample : (S, p)
        Dense sample of D for the master windows (:func:`build_row_evaluator`).
    tol, m_max
        EIM stopping: relative max-norm training error, and largest size.
    row_evaluator : callable, optional
        ``(layout, rows, mus_sample) -> evaluator`` of the magic rows (default
        :func:`build_row_evaluator`, 2D).
    row_threshold : float in (0, 1]
        Row-aware selection of the magic entries (:func:`rbbench.rb.algorithms.eim.deim`
        ``groups``): a magic entry of ``B(mu) Z`` in a multiplier row already evaluated is
        preferred when its residual is at least this fraction of the largest, and G's magic
        rows prefer the rows of B's entries. 1 (default): the plain greedy EIM.
    """
    res_B, e_row, e_col, T_B = column_eim(B_train, Z, Vg, tol, m_max, row_threshold)
    m = np.asarray(G_train).shape[0]
    res_G = deim(np.asarray(G_train), tol=tol, m_max=m_max,
                 **({} if row_threshold >= 1.0 else
                    {"groups": np.arange(m), "threshold": row_threshold,
                     "paid": np.unique(e_row)}))
    if res_B.m == 0 or res_G.m == 0:
        raise HyperReductionError("EIM found no term: the training B(mu) Z or G(mu) is zero")
    rows_B = np.unique(e_row)
    ev = (row_evaluator or build_row_evaluator)(layout, np.concatenate([rows_B, res_G.magic]),
                                                mus_sample)
    # homogeneous Dirichlet dofs in the rows (3D symmetry planes): zero rows of Z
    loc = local_free_rows(ev, free, layout.n_dofs, dirichlet_ok=True)
    Z_loc = np.where((loc >= 0)[:, None], Z[np.maximum(loc, 0)], 0.0)
    T_G = (Vg.T @ res_G.Q).T
    info = {"M_B": res_B.m, "M_G": res_G.m, "rows": int(ev.rows.size),
            "n_local_dofs": ev.n_local, "tol": tol,
            "errors_B": res_B.errors.tolist(), "errors_G": res_G.errors.tolist(),
            "window_max_width": ev.window_max_width, "master_facets": ev.n_master}
    return ContactEIM(ev, np.searchsorted(ev.rows, rows_B),  # ev.rows: sorted, unique
                      np.searchsorted(rows_B, e_row), e_col,
                      np.searchsorted(ev.rows, res_G.magic),
                      np.ascontiguousarray(Z_loc), sla.lu_factor(res_B.Q[res_B.magic]),
                      sla.lu_factor(res_G.Q[res_G.magic]), T_B, T_G, info)


def column_eim(B_train: list, Z: np.ndarray, Vg: np.ndarray, tol: float | None,
               m_max: int | None, row_threshold: float = 1.0
               ) -> tuple[EIMResult, np.ndarray, np.ndarray, np.ndarray]:
    """Greedy EIM of the entries of ``C(mu) = B(mu) Z`` (m x N) over the training
    ``B_train``: ``(result, entry rows, entry columns, T)`` with ``T[k] = Vg^T C_k``
    (R x N; empty when no term). ``row_threshold < 1``: row-aware selection, the entries
    grouped by their row of ``C`` (:func:`rbbench.rb.algorithms.eim.deim` ``groups``)."""
    m, N = B_train[0].shape[0], Z.shape[1]
    S = np.stack([np.asarray(B @ Z).ravel() for B in B_train], axis=1)  # (m N, P)
    rows = {} if row_threshold >= 1.0 else {"groups": np.arange(m * N) // N,
                                             "threshold": row_threshold}
    res = deim(S, tol=tol, m_max=m_max, **rows)
    e_row, e_col = np.divmod(res.magic, N)
    if res.m == 0:
        return res, e_row, e_col, np.zeros((0, Vg.shape[1], N))
    return res, e_row, e_col, np.stack([Vg.T @ res.Q[:, k].reshape(m, N)
                                        for k in range(res.m)])


def local_free_rows(ev: RowEvaluator, free: np.ndarray, n_dofs: int,
                    dirichlet_ok: bool = False) -> np.ndarray:
    """Position among the free dofs of each local dof of ``ev`` (a
    :class:`HyperReductionError` when one is a Dirichlet dof; with ``dirichlet_ok``, -1
    there: the caller has checked that those dofs are homogeneous)."""
    free_of = np.full(n_dofs, -1, dtype=np.int64)
    free_of[free] = np.arange(free.size)
    loc = free_of[ev.local_dofs]
    if np.any(loc < 0) and not dirichlet_ok:
        raise HyperReductionError(
            f"{int(np.sum(loc < 0))} dof(s) of the magic contact rows are Dirichlet dofs; "
            "the contact EIM assumes the contact zone is away from the Dirichlet boundary")
    return loc


def entrywise_eim_error(B_train: list, B_valid: list, tol: float = 1e-8,
                        m_max: int | None = None) -> dict:
    """Benaceur et al.'s entrywise EIM of ``B(mu)`` (slide "EIM errors"), for comparison.

    Returns the training error curve and the validation ``e_EIM`` at the
    final size (ratio of maxima over the validation set).
    """
    res = matrix_eim([sp.csr_matrix(B) for B in B_train], tol=tol, m_max=m_max)
    return {"M": res.m, "errors_train": res.errors.tolist(),
            "e_eim_valid": eim_error(res, B_valid)}

"""The online error bound of the mixed reduced model on a two-body scene with a moving contact
(``hyper = "eim"``: ``B(mu)`` is not affine in mu).

The bound is :mod:`rbbench.rb.algorithms.bounds` (Haasdonk, Salomon & Wohlmuth 2012, SIAM J.
Numer. Anal. 50, 2656-2676, Section 4, re-derived in the natural multiplier norm; equation
numbers (1)-(6) of that module). Its terms at mu, for ``u_N = Z c`` and ``lam_N = Vg a``:

* the contact rows of ``B(mu)`` (all ``m`` of them, on the ``n_c`` contact dofs) and
  ``G(mu)`` are evaluated exactly online from the restricted contact layout
  (:class:`~rbbench.rb.hyper.contact_eim.RowEvaluator`, O(m) work, no HF vector): so
  ``d = B(mu) Z c - G(mu)`` (``sigma``, ``kappa``: (2), (3)) and ``b = B(mu)^T lam_N`` (on the
  contact dofs) are exact. Off the master chain ``B(mu) = s_r(mu) B(mu_0)`` (below): the
  slave half of ``d`` is ``s_r (B_S(mu_0) Z) c`` and of ``b`` is ``s_r B_S(mu_0)^T Vg a``,
  both from offline arrays; the master half ``b_M`` is non-zero only where ``lam_N`` is;
* ``rho = ||F - A Z c - P b||_X'`` (1), ``P`` the contact dofs among the free ones: ``b_M`` is
  split into ``U g`` (``U``: at most ``pod_max`` l2-orthonormal modes on the master dofs,
  :func:`master_modes`: leading eigenvectors of ``P_M^T X^{-1} P_M`` interleaved with the
  POD of the training vectors ``B_M(mu)^T Vg``; ``g = U^T b_M``) and the remainder
  ``e = b_M - U g``.
  The Riesz representers of ``F``, ``A Z``, ``P_S B_S(mu_0)^T Vg`` and ``P_M U`` are
  orthonormalised offline (:func:`~rbbench.rb.algorithms.bounds.riesz_factor`): ``||F - A Z c
  - P_S b_S - P_M U g||_X' = ||T w||``; the remainder by ``||P_M e||_X' <= lambda_c^(1/2)
  ||e||_2``, ``lambda_c`` the largest eigenvalue of ``P_M^T X^{-1} P_M`` on the
  l2-complement of ``U``, where ``e`` lies (Lanczos, with the margin of the coercivity
  constants). By the triangle inequality ``rho <= ||T w|| +
  lambda_c^(1/2) ||e||_2``: the compression leaves nothing out, it only loosens the bound
  by the remainder term, which is reported (``bound_eim_residual``);
* ``sigma = ||[d]_+||_*'`` without ``D(mu)^{-1} = (B(mu) X^{-1} B(mu)^T)^{-1}``: any ``v`` with
  ``B(mu) v = [d]_+`` gives ``||[d]_+||_*' <= ||v||_X`` (``sup_eta eta^T B v /
  ||B^T eta||_X' <= ||v||_X``). On the dofs off the master chain ``B(mu)`` is the slave
  term alone, ``s(mu) M`` with a fixed ``M`` (checked offline: a uniform dilation of the
  slave body scales it by the radius); the X-smallest such ``v`` there gives ``sigma <=
  ||L^{-1} [d]_+||_2 / |s(mu)|``, ``L L^T = M X_SS^{-1} M^T`` (m x m, offline);
* ``alpha_LB``, ``gamma_UB``: the extreme eigenvalues of ``(A, X)`` (``A`` mu-independent,
  checked: a dilation leaves the 2D stiffness invariant).

Online (:func:`rbbench.rb.mixed.bound_kernels.moving_contact_terms`, one numba call; the
numpy evaluation from the Python pairing is the reference): O(m N + n_p N + n_l K + k q),
``n_p`` the master dofs of the facets paired at mu, ``n_l`` those under a non-zero
multiplier, ``T`` (k x q) used as upper trapezoidal: independent of the HF size.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from rbbench.rb.algorithms.affine import NotAffineError, affine_decomposition
from rbbench.rb.algorithms.bounds import (
    EIG_MARGIN,
    BoundTerms,
    VIBound,
    coercivity_constants,
    lanczos_start,
    riesz_factor,
    vi_bound,
)
from rbbench.rb.mixed.bounds import BoundUnsupported, constant_in_mu
from rbbench.rb.mixed.options import BOUND_POD_MAX

__all__ = ["ContactBound", "build_contact_bound", "contact_rows"]

#: Relative singular-value cut of the POD of the training vectors ``B(mu)^T Vg``
POD_RTOL = 1e-9
#: The leading eigenvectors of ``P_M^T X^{-1} P_M`` computed offline for the modes of
#: :func:`master_modes` (they alternate with the POD modes, so a cap of ``k`` uses at most
#: ``ceil(k / 2)`` of them)
EIG_MODES = 64
#: The share of those eigenvectors among the modes (:func:`master_modes`)
EIG_SHARE = 0.5
#: POD modes of the master half computed at a time (:func:`master_modes`)
POD_BLOCK = 16


@dataclass
class ContactBound:
    """Online evaluator of the bound (module docstring).

    ``ev``: all contact rows, restricted layout; ``Msp`` (m, nq): the multiplier basis at
    its quadrature points; ``Z_loc`` (n_c, N), ``U`` (n_c, K); ``T`` (k, 1 + N + K);
    ``lam_c``: ``lambda_c``; ``Linv``: the inverse of the lower Cholesky factor ``L`` of
    ``M X_SS^{-1} M^T``; ``s_terms``: ``s(mu) = theta(mu) . s_terms``, ``theta = [1, mu]``.
    """

    ev: Any
    Msp: sp.csr_matrix
    Z_loc: np.ndarray
    Vg: np.ndarray
    U: np.ndarray
    T: np.ndarray
    lam_c: float
    Linv: np.ndarray
    s_terms: np.ndarray
    alpha: float
    gamma: float
    #: ``Cs`` (m, N): the slave part of ``B(mu) Z`` over ``s_r(mu)``
    Cs: np.ndarray | None = None
    #: the local master dofs (``U`` is zero on the others)
    mloc: np.ndarray | None = None
    #: rows of ``T`` used in each column (Gram-Schmidt: ``T`` is upper trapezoidal)
    kj: np.ndarray | None = None
    #: ``lambda_c^(1/2) ||e||_2`` of the last evaluation (the remainder in ``rho``)
    last_remainder: float = 0.0
    #: the packed arrays of the numba pairing (:func:`compiled_plan`), None without numba
    plan: dict | None = None
    #: the free-dof index of each master dof (``mloc``), and the number of free dofs: the
    #: operator ``P_M^T X^{-1} P_M`` of ``lambda_c``
    mfree: np.ndarray | None = None
    n_free: int = 0

    def __post_init__(self) -> None:
        self.MspT = sp.csr_matrix(self.Msp.T)
        self._work: dict | None = None

    def rows(self, mu: np.ndarray) -> tuple[sp.csr_matrix, np.ndarray]:
        """``(B(mu), G(mu))`` on the contact rows and dofs (exact)."""
        return contact_rows(self.ev, self.Msp, mu)

    def residuals(self, mu: np.ndarray, c: np.ndarray, a: np.ndarray, compiled: bool = True
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(d, b, lam)``: ``d = B(mu) Z c - G(mu)`` (m), ``b = B(mu)^T lam`` (contact dofs),
        ``lam = Vg a``; by the numba kernels where available (the Python pairing otherwise,
        and wherever the kernels decline: it raises the reference's error)."""
        lam = self.Vg @ a
        uz = self.Z_loc @ c
        if compiled and self.plan is not None:
            out = _compiled_residuals(self.plan, mu, uz, lam, self.Msp.shape[0], uz.size)
            if out is not None:
                return out[0], out[1], lam
        p = self.ev.pairing(mu)
        terms = p.jump_terms(p.nrm)
        ju = sum(np.einsum("qj,qj->q", cf, uz[dof]) for cf, dof in terms)
        d = self.Msp @ (p.w * (ju - p.gap))
        lq = p.w * (self.MspT @ lam)
        b = sum(np.bincount(dof.ravel(), weights=(cf * lq[:, None]).ravel(), minlength=uz.size)
                for cf, dof in terms)
        return d, b, lam

    def s_ratio(self, mu: np.ndarray) -> float:
        """``s_r(mu)``: ``B(mu)`` off the master chain is ``s_r(mu)`` times its value at the
        centre of D."""
        return float(np.concatenate([[1.0], mu]) @ self.s_terms)

    def terms(self, mu: np.ndarray, c: np.ndarray, a: np.ndarray, compiled: bool = True
              ) -> BoundTerms:
        """The terms (1)-(4), ``rho`` with the remainder (module docstring): by one numba
        kernel (:func:`rbbench.rb.mixed.bound_kernels.moving_contact_terms`) where
        available, else (``compiled=False``, or where the kernel declines) by numpy from the
        Python pairing, the reference."""
        if self.Cs is None:
            raise RuntimeError("this error bound was built by an earlier rbbench (its pieces "
                               "are laid out differently): rebuild the reduced model")
        mu = np.atleast_1d(np.asarray(mu, dtype=float))
        out = self._fast_terms(mu, c, a) if compiled and self.plan is not None else None
        if out is not None:
            rho_t, lam_t, bb, gg, sigma, kappa = out.tolist()
        else:
            d, b, lam = self.residuals(mu, c, a, compiled=False)
            sr = self.s_ratio(mu)
            bm = b[self.mloc]
            g = self.U[self.mloc].T @ bm
            bb, gg = float(bm @ bm), float(g @ g)
            w = np.concatenate([[1.0], -c, -sr * a, -g])
            jl = 1 + c.size
            rho_t = float(np.linalg.norm(self.T @ w))
            lam_t = float(np.linalg.norm(self.T[:, jl:] @ w[jl:]))
            up = np.flatnonzero(d > 0)  # the violated rows
            sigma = float(np.linalg.norm(self.Linv[:, up] @ d[up])) / abs(sr)
            kappa = max(float(lam @ np.maximum(-d, 0.0)), 0.0)
        # ||b_M - U g||_2 by Pythagoras (U orthonormal): one product with U instead of two
        rem = math.sqrt(self.lam_c * max(bb - gg, 0.0))
        self.last_remainder = rem
        return BoundTerms(rho_t + rem, sigma, kappa, lam_t + rem)

    def _fast_terms(self, mu: np.ndarray, c: np.ndarray, a: np.ndarray
                    ) -> np.ndarray | None:
        """The kernel's ``[||T w||, ||T_lam w_lam||, ||b_M||^2, ||g||^2, sigma, kappa]`` (its
        output buffer: read it before the next call); None where it declines (mu outside
        D, a point leaving its window). The arguments that do not change between calls are
        gathered once."""
        k = self._work if self._work is not None else self._make_work(c.size)
        status = k["kernel"](mu, *k["head"], np.ascontiguousarray(a, dtype=float),
                             *k["mid"], np.ascontiguousarray(c, dtype=float), *k["tail"])
        return k["out"] if status == k["ok"] else None

    def _make_work(self, N: int) -> dict:
        """The kernel, its work arrays and its fixed arguments (:meth:`_fast_terms`)."""
        from rbbench.rb.kernels import layout
        from rbbench.rb.mixed.bound_kernels import moving_contact_terms

        pl = self.plan
        nq, n_c = pl["n_hat"].shape[0], self.Z_loc.shape[0]
        out = np.zeros(6)
        work = (np.empty(nq), np.empty(nq), np.zeros((nq, pl["k"])),
                np.zeros(nq, dtype=np.int64), np.zeros(n_c, dtype=np.int64), np.zeros(n_c),
                np.zeros(n_c), np.zeros(n_c, dtype=np.int64), np.zeros(self.Cs.shape[0]), out)
        self._work = {"kernel": moving_contact_terms, "ok": layout.OK, "out": out,
                      "head": (pl["fb"], pl["ib"], pl["meta"], pl["n_hat"], pl["mdofs"],
                               pl["rows"], self.s_terms, self.Vg),
                      "mid": (self.Cs, self.Z_loc),
                      "tail": (self.U, self.T, self.kj, 1 + N, self.Linv, *work)}
        return self._work

    def __call__(self, mu: np.ndarray, c: np.ndarray, a: np.ndarray,
                 compiled: bool = True) -> VIBound:
        """The bound (5)-(6) at mu for ``u_N = Z c``, ``lam_N = Vg a`` (``a >= 0``);
        ``compiled``: the numba pairing where available."""
        return vi_bound(self.terms(mu, np.asarray(c, float), np.asarray(a, float), compiled),
                        self.alpha, self.gamma)

    def with_modes(self, k: int, x_solve: Callable[[np.ndarray], np.ndarray]
                   ) -> ContactBound:
        """The bound built with at most ``k`` modes of ``b_M``, from this one without
        rebuilding the rest: the modes of :func:`master_modes` do not depend on the cap, so
        a smaller cap keeps the first columns of ``U``, and the Riesz factor is a
        Gram-Schmidt with the modes last, so its first columns and rows are those of the
        smaller build (the same numbers up to round-off); ``lambda_c`` on the complement of
        the fewer modes is computed again (``x_solve``: solves with X, offline). ``k`` >=
        the modes held: this bound."""
        if isinstance(k, bool) or not isinstance(k, (int, np.integer)) or k < 1:
            raise ValueError(f"bound_pod_max {k!r}: give an integer >= 1")
        if self.mfree is None:
            raise RuntimeError("this error bound was built by an earlier rbbench (no master "
                               "dof map): rebuild the reduced model")
        K = self.U.shape[1]
        if k >= K:
            return self
        q = self.T.shape[1] - (K - k)
        # the directions of the first q pieces: a piece that added one has kj = the count so
        # far + 1; a dropped piece used all rows, here those of the smaller build (its
        # components on later directions are below the cut of the Gram-Schmidt)
        rank = 0
        for kk in self.kj[:q]:
            rank += int(kk == rank + 1)
        kj = np.minimum(self.kj[:q], rank)
        Um = self.U[self.mloc, :k]
        lam_c = _local_dual_max(self.mfree, self.n_free, x_solve, Um)
        state = {**self.__getstate__(), "U": np.ascontiguousarray(self.U[:, :k]),
                 "lam_c": lam_c,
                 "T": np.asfortranarray(self.T[:rank, :q]),
                 "kj": np.ascontiguousarray(kj, dtype=np.int64), "last_remainder": 0.0}
        out = ContactBound.__new__(ContactBound)
        out.__setstate__(state)
        return out

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state.pop("MspT", None)
        state.pop("_work", None)
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self.__post_init__()


def contact_rows(ev: Any, Msp: sp.csr_matrix, mu: np.ndarray) -> tuple[sp.csr_matrix,
                                                                          np.ndarray]:
    """``B(mu)`` (m x n_c, sparse) and ``G(mu)`` (m,) from the row evaluator ``ev`` of all
    contact rows and its multiplier basis ``Msp`` (m x nq)."""
    p = ev.pairing(mu)
    Mw = Msp @ sp.diags(p.w)
    return (Mw @ p.jump(p.nrm, ev.n_local)).tocsr(), Mw @ p.gap


def build_contact_bound(layout: Any, problem_at: Callable[[np.ndarray], Any], Z: np.ndarray,
                        Vg: np.ndarray, X: Any, x_solve: Callable[[np.ndarray], np.ndarray],
                        bounds: np.ndarray, mus_sample: np.ndarray,
                        progress: Callable[[str], None] = lambda m: None,
                        pod_max: int = BOUND_POD_MAX) -> ContactBound:
    """The offline stage (module docstring): ``mus_sample`` a dense sample of D (the master
    windows and the POD of ``B(mu)^T Vg``, at most ``pod_max`` modes: online cost
    O(n_l pod_max + pod_max^2)). :class:`BoundUnsupported` when ``A`` or ``F``
    depends on mu, the rows touch Dirichlet dofs, or ``B`` off the master chain is not
    ``s(mu) M``."""
    from rbbench.rb.hyper.contact_eim import build_row_evaluator, local_free_rows

    bounds = np.asarray(bounds, dtype=float)
    if layout.master is None:
        raise BoundUnsupported("a rigid master: B(mu) is affine there, use hyper 'affine'")
    if not constant_in_mu(lambda mu: problem_at(mu).A, bounds):
        raise BoundUnsupported("a(.,.; mu) depends on mu: no coercivity lower bound")
    if not constant_in_mu(lambda mu: problem_at(mu).F[:, None], bounds):
        raise BoundUnsupported("F depends on mu: its Riesz representer is not offline")
    m = Vg.shape[0]
    ev = build_row_evaluator(layout, np.arange(m), mus_sample)
    p0 = problem_at(bounds.mean(axis=1))
    free = np.asarray(p0.free)
    try:
        loc = local_free_rows(ev, free, layout.n_dofs)
    except ValueError as exc:
        raise BoundUnsupported(str(exc)) from None
    pr = ev.pairing(np.asarray(mus_sample[0], dtype=float))
    from rbbench.hf.geometry.facets import multiplier_basis
    Msp = sp.csr_matrix(multiplier_basis(layout.multiplier, layout.n_facets,
                                         ev.layout.slave.ids[pr.fq], pr.sq, layout.patch)
                        .tocsc()[:, ev.rows].T)
    # the exact rows against the formulation's operators (a wrong dof map fails here)
    Bc, Gc = contact_rows(ev, Msp, bounds.mean(axis=1))
    Bfull = sp.csr_matrix(p0.B)
    Bref = Bfull[:, loc]
    top = abs(Bref).max()
    err = max(abs(Bref - Bc).max() / top, np.abs(p0.G - Gc).max() / np.abs(p0.G).max(),
              abs(abs(Bfull).sum() - abs(Bref).sum()) / abs(Bfull).sum())
    if not err <= 1e-10:
        raise BoundUnsupported(f"the contact rows evaluated online differ from the HF B, G "
                               f"(max relative deviation {err:.3g}): no online bound")
    Linv, s_terms = _slave_lifting(problem_at, layout, free, X, bounds)
    # the slave part of B(mu) (local dofs off the master chain) is s_r(mu) times its value
    # at the centre of D: exact affine pieces; the master part is compressed
    mloc = np.unique(np.asarray(ev.layout.master.dofs).ravel())
    sloc = np.setdiff1d(np.arange(ev.n_local), mloc)
    s0 = float(np.concatenate([[1.0], bounds.mean(axis=1)]) @ s_terms)
    BS = sp.csr_matrix(Bc[:, sloc]) / s0
    Cs = np.ascontiguousarray(BS @ Z[loc][sloc])
    n = free.size
    mfree = loc[mloc]
    progress("error bound: modes of the master half (eigenvectors of P_M^T X^-1 P_M, POD of "
             "B_M(mu)^T Vg)")
    S = np.hstack([np.asarray(contact_rows(ev, Msp, mu)[0][:, mloc].T @ Vg)
                   for mu in mus_sample])
    Um = master_modes(S, _dual_eigenvectors(mfree, n, x_solve, EIG_MODES), pod_max,
                      EIG_SHARE)
    U = np.zeros((ev.n_local, Um.shape[1]))
    U[mloc] = Um

    def embed(V: np.ndarray, at: np.ndarray) -> np.ndarray:
        out = np.zeros((n, V.shape[1]))
        out[loc[at]] = V
        return out

    q = 1 + Z.shape[1] + Vg.shape[1] + U.shape[1]
    progress(f"error bound: Riesz representers ({q} pieces)")
    T, kj = riesz_factor(np.hstack([p0.F[:, None], p0.A @ Z,
                                    embed(np.asarray(BS.T @ Vg), sloc), embed(Um, mloc)]),
                         X, x_solve, return_ranks=True)
    lam_c = _local_dual_max(mfree, n, x_solve, Um)
    alpha, gamma = coercivity_constants(p0.A, X)
    return ContactBound(ev=ev, Msp=Msp, Z_loc=np.ascontiguousarray(Z[loc]),
                        Vg=np.ascontiguousarray(Vg), U=U, T=np.asfortranarray(T),
                        lam_c=lam_c, Linv=np.asfortranarray(Linv), s_terms=s_terms,
                        alpha=alpha, gamma=gamma, Cs=Cs, mloc=mloc,
                        kj=np.ascontiguousarray(kj, dtype=np.int64),
                        plan=compiled_plan(ev, Msp, bounds), mfree=mfree,
                        n_free=n)


def compiled_plan(ev: Any, Msp: sp.csr_matrix, bounds: np.ndarray) -> dict | None:
    """The arrays of the numba pairing of all contact rows
    (:func:`rbbench.rb.kernels.pairing.pair_points`, the compiled online solve's) and of
    :func:`rbbench.rb.mixed.bound_kernels.contact_jumps`; None without numba or with
    multipliers that are not one per point (P1)."""
    try:
        from rbbench.rb.kernels import layout  # imports numba
        from rbbench.rb.kernels.plan import master_plan, pack, reference_points
    except ImportError:  # pragma: no cover - numba absent
        return None
    lay = ev.layout
    MT = sp.csr_matrix(Msp.T)
    if lay.master is None or not np.all(np.diff(MT.indptr) == 1) or np.any(MT.data != 1):
        return None
    x_hat, n_hat, w_hat, sphi = reference_points(lay)
    one_f, one_i = np.zeros((1, 1)), np.zeros((1, 1), dtype=np.int64)
    arrays = {**dict.fromkeys(layout.FLOATS, one_f), **dict.fromkeys(layout.INTS, one_i)}
    arrays.update({"mu_lo": bounds[:, 0], "mu_hi": bounds[:, 1],
                   "s_scale": lay.slave.map.scale, "s_shift": lay.slave.map.shift,
                   "m_scale": lay.master.map.scale, "m_shift": lay.master.map.shift,
                   "x_hat": x_hat, "n_hat": n_hat, "w_hat": w_hat,
                   "dims": np.array([lay.degree, 1, 0])})
    arrays.update(master_plan(SimpleNamespace(evaluator=ev, Z_loc=np.zeros((lay.n_dofs, 1))),
                               n_hat))
    fb, ib, meta = pack(arrays)
    nq = x_hat.shape[0]
    i64 = lambda x: np.ascontiguousarray(x, dtype=np.int64)  # noqa: E731
    return {"fb": fb, "ib": ib, "meta": meta, "sphi": sphi, "n_hat": n_hat,
            "sdofs": i64(lay.slave.dofs[np.arange(nq) // lay.n_gauss]),
            "mdofs": i64(lay.master.dofs), "rows": i64(MT.indices), "k": lay.degree + 1}


def _compiled_residuals(plan: dict, mu: np.ndarray, uz: np.ndarray, lam: np.ndarray, m: int,
                        n_c: int) -> tuple[np.ndarray, np.ndarray] | None:
    """``(d, b)`` of :meth:`ContactBound.residuals` by the numba kernels; None where they
    decline (mu outside D, a point leaving its window)."""
    from rbbench.rb.kernels import layout, pairing
    from rbbench.rb.mixed.bound_kernels import contact_jumps

    fb, ib, meta = plan["fb"], plan["ib"], plan["meta"]
    status, th = layout.theta(np.ascontiguousarray(mu, dtype=float), fb, meta)
    if status != layout.OK:
        return None
    nq = plan["n_hat"].shape[0]
    w, gap = np.empty(nq), np.empty(nq)
    mphi, seg = np.zeros((nq, plan["k"])), np.zeros(nq, dtype=np.int64)
    status, s = pairing.pair_points(th, fb, ib, meta, w, gap, mphi, seg)
    if status != layout.OK:
        return None
    d, b = np.empty(m), np.empty(n_c)
    contact_jumps(s, w, gap, mphi, seg, plan["sphi"], plan["n_hat"], plan["sdofs"],
                  plan["mdofs"], plan["rows"], uz, lam, d, b)
    return d, b


def _dual_matvec(loc: np.ndarray, n: int, x_solve: Callable) -> Callable:
    """``x -> P^T X^{-1} P x``, ``P`` the free dofs ``loc`` among ``n``."""
    def mv(x: np.ndarray) -> np.ndarray:
        v = np.zeros(n)
        v[loc] = x
        return np.asarray(x_solve(v)).ravel()[loc]

    return mv


def _projected(matvec: Callable, size: int, Q: np.ndarray | None = None
               ) -> spla.LinearOperator:
    """``(I - Q Q^T) M (I - Q Q^T)`` for the symmetric ``M`` of ``matvec`` and an
    l2-orthonormal ``Q`` (``M`` itself without ``Q``)."""
    def mv(x: np.ndarray) -> np.ndarray:
        x = np.ravel(x)
        if Q is not None:
            x = x - Q @ (Q.T @ x)
        y = matvec(x)
        return y - Q @ (Q.T @ y) if Q is not None else y

    return spla.LinearOperator((size, size), matvec=mv, dtype=float)


def _local_dual_max(loc: np.ndarray, n: int, x_solve: Callable,
                    U: np.ndarray | None = None) -> float:
    """``lambda_c``: the largest eigenvalue of ``P^T X^{-1} P`` on the l2-complement of the
    orthonormal ``U`` (all of it without ``U``): ``(I - U U^T) P^T X^{-1} P (I - U U^T)``,
    Lanczos, relative margin :data:`~rbbench.rb.algorithms.bounds.EIG_MARGIN` upwards. The
    remainder ``e = b_M - U U^T b_M`` lies in that complement, so ``||P e||_X'^2 <=
    lambda_c ||e||_2^2``."""
    op = _projected(_dual_matvec(loc, n, x_solve), loc.size, U)
    top = float(spla.eigsh(op, k=1, which="LA", tol=1e-12, v0=lanczos_start(loc.size),
                           return_eigenvectors=False)[0])
    return top * (1.0 + EIG_MARGIN)


def _dual_eigenvectors(loc: np.ndarray, n: int, x_solve: Callable, k: int) -> np.ndarray:
    """The ``k`` leading eigenvectors of ``P^T X^{-1} P`` (Lanczos; fewer on a small
    chain), largest first, l2-orthonormal."""
    k = int(min(k, loc.size - 2))
    if k < 1:
        return np.zeros((loc.size, 0))
    w, V = spla.eigsh(_projected(_dual_matvec(loc, n, x_solve), loc.size), k=k, which="LA",
                      tol=1e-10, v0=lanczos_start(loc.size))
    return np.ascontiguousarray(V[:, np.argsort(w)[::-1]])


def master_modes(S: np.ndarray, E: np.ndarray, k_max: int, share: float = EIG_SHARE
                 ) -> np.ndarray:
    """The modes ``U`` of the master half (at most ``k_max``, l2-orthonormal), one at a
    time: at every position ``i`` where ``floor((i + 1) share)`` steps up the next leading
    eigenvector of ``P_M^T X^{-1} P_M`` (``E``), elsewhere the next POD mode of the
    training vectors ``S``, taken from the leading left singular vectors of ``S`` projected
    off the modes so far (:data:`POD_BLOCK` at a time, Lanczos on the projected Gram
    matrix; while above :data:`POD_RTOL` of the first singular value); each new mode is
    orthonormalised against the ones before (twice). The POD shrinks ``||e||_2`` on the
    data; each eigenvector lowers ``lambda_c``, the largest eigenvalue left on the
    complement of ``U``. The modes do not depend on the cap: a smaller cap keeps the first
    columns."""
    n = E.shape[0] if E.size else S.shape[0]
    G = S @ S.T if S.size else np.zeros((n, n))
    Q = np.zeros((n, 0))
    s0, ie, buf, pod_left = None, 0, [], bool(S.size)
    for i in range(min(k_max, n)):
        eig = ie < E.shape[1] and (np.floor((i + 1) * share) > np.floor(i * share)
                                   or not pod_left)
        if not eig and pod_left and not buf:
            top, V = _leading_projected(G, Q, min(POD_BLOCK, n - Q.shape[1] - 2))
            s0 = top[0] if s0 is None else s0
            buf = [V[:, j] for j in range(V.shape[1]) if top[j] > POD_RTOL ** 2 * s0]
            pod_left = len(buf) == V.shape[1] > 0
        if not eig and buf:
            v = buf.pop(0)
        elif ie < E.shape[1]:
            v = E[:, ie].copy()
            ie += 1
        else:
            break
        for _ in range(2):
            v = v - Q @ (Q.T @ v)
        nv = float(np.linalg.norm(v))
        if nv > 1e-8:
            Q = np.hstack([Q, (v / nv)[:, None]])
    return np.ascontiguousarray(Q)


def _leading_projected(G: np.ndarray, Q: np.ndarray, k: int) -> tuple[np.ndarray,
                                                                      np.ndarray]:
    """The ``k`` largest eigenvalues (descending) and eigenvectors of ``(I - Q Q^T) G (I -
    Q Q^T)``."""
    if k < 1:
        return np.zeros(0), np.zeros((G.shape[0], 0))
    w, V = spla.eigsh(_projected(lambda x: G @ x, G.shape[0], Q), k=k, which="LA",
                      tol=1e-10, v0=lanczos_start(G.shape[0]))
    order = np.argsort(w)[::-1]
    return w[order], V[:, order]


def _slave_lifting(problem_at: Callable, layout: Any, free: np.ndarray, X: Any,
                   bounds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(L^{-1}, s_terms)``: ``B(mu)`` on the free dofs off the master chain is ``s(mu) M``
    (``s = theta . s_terms``, checked by probing), ``L L^T = M X_SS^{-1} M^T``."""
    master = np.unique(np.asarray(layout.master.dofs).ravel())
    S = np.flatnonzero(~np.isin(free, master))
    mu0 = bounds.mean(axis=1)
    M = sp.csr_matrix(problem_at(mu0).B)[:, S]
    V = np.random.default_rng(0).standard_normal((S.size, 3))
    MV = np.asarray(M @ V)
    try:
        terms = affine_decomposition(lambda mu: sp.csr_matrix(problem_at(mu).B)[:, S] @ V,
                                     bounds)
    except NotAffineError:
        raise BoundUnsupported("B(mu) off the master chain is not affine in mu") from None
    scale = float(np.abs(MV).max())
    s_terms = np.array([float(np.vdot(t, MV) / np.vdot(MV, MV)) for t in terms])
    if max(float(np.abs(t - s * MV).max()) for t, s in zip(terms, s_terms, strict=True))\
            > 1e-10 * scale:
        raise BoundUnsupported("B(mu) off the master chain is not a multiple s(mu) M of one "
                               "matrix: no online lifting of the constraint residual")
    th = [np.concatenate([[1.0], bounds[:, k]]) for k in range(2)]
    if np.prod([t @ s_terms for t in th]) <= 0:
        raise BoundUnsupported("s(mu) changes sign over D")
    XS = sp.csc_matrix(sp.csr_matrix(X)[S][:, S])
    lu = spla.splu(XS)
    Mt = M.T.toarray()
    D = M @ lu.solve(np.asfortranarray(Mt))
    D = 0.5 * (np.asarray(D) + np.asarray(D).T)
    try:
        L = np.linalg.cholesky(D)
    except np.linalg.LinAlgError:
        raise BoundUnsupported("M X_SS^-1 M^T is not positive definite (a contact row with no "
                               "slave support)") from None
    return sla.solve_triangular(L, np.eye(L.shape[0]), lower=True), s_terms

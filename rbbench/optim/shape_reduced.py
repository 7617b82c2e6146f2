"""Reduced-basis state solver for ``shape_coulomb``: contact dofs exact, interior in span V.

**Exact affine decomposition of the moving-mesh stiffness.** In the coordinates
``(x1, eta)`` of the fixed rectangle, ``x2 = alpha(x1) (1 - eta) + gamma eta`` with
``alpha`` linear on each element column ``[x_c, x_{c+1}]``: the Q1 isoparametric element of
``shape_mesh`` is the pull-back of Q1 on the rectangle cell, and at a Gauss point of
abscissa ``t_g`` in column ``c`` the physical gradients are ``G0 + (s / d) G1 + (1 / d) G2``
with ``d = gamma - alpha(t_g)``, ``s = alpha'`` (slope of the column), ``G_m`` fixed.
Times the Jacobian ``det ~ d`` this gives, per column and Gauss line ``g``, six fixed
matrices with the coefficients ``theta = (d, s, 1, s^2 / d, s / d, 1 / d)``::

    A(alpha) = sum_c sum_g sum_k theta_k(d_cg, s_c) T_gk   (T_gk the same for every column)

exactly (``tests/optim/test_shape_reduced.py`` checks it against ``assemble_stiffness``), and
``d theta / d alpha`` is analytic. So a Galerkin projection costs no assembly online.

**Reduced model.** The contact nonlinearity lives on the ``2 I - 1`` contact dofs ``u_c``;
what costs in the high-fidelity (HF) solve is the Schur complement on them (a sparse LU
per design). The trial space is ``{(u_c, V a)}``: ``u_c`` exact, the interior in ``span V``
(orthonormal in l2). Galerkin gives ``S_N = G_cc - G_cV K^-1 G_Vc``, ``K = V^T A_ii V``,
``f_N`` likewise, with ``G = W^T A W`` from the projected templates (the interior block
reduced to ``1 + I + 6 nx`` distinct coefficient functions, :func:`term_map`), then the
same semismooth Newton (``shape_state.solve_condensed`` on a :class:`ReducedCondensed`)
and the same adjoint, ``p = (p_c, -K^-1 G_Vc p_c)``, ``xi_i = p . dG/dalpha_i x + c
[contact] p_lam`` (the Lagrangian of the Galerkin system). ``S_N >= S`` (energy).

**Which V.** If the HF state and adjoint interiors at ``alpha`` lie in ``span V`` the
reduced ``J`` and ``xi`` equal the HF ones there (first-order consistency, Keil et al.
2021, ESAIM M2AN 55:1239). That alone is not enough here: with V = {state, adjoint} at
``alpha_0`` (full scene) the reduced ``xi`` is off by 6x (relative 2-norm) after a step of
1e-3 along ``-xi``, because the contact displacements move in directions whose interior
response V lacks (the spectrum of ``A_cc^-1 (A_cc - S)`` decays slowly: no short POD).
:func:`interior_space` gives the harmonic extensions of all ``2 I - 1`` contact unit
vectors and the load response at one design from the HF factors (two triangular block
solves): with them the model is exact at that design for every contact state, and the
relative errors of ``J`` / ``xi`` after steps of 1e-3 / 1e-2 / 3e-2 along ``-xi`` were
3e-6 / 5e-4 / 5e-3 and 5e-4 / 2e-3 / 1.4e-2 (full scene, ``N = 162``).
With ``V`` = every interior unit vector the model is the HF model (tested).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from rbbench.interfaces import HFVectors, ReducedSolution
from rbbench.optim.shape_adjoint import Evaluation, objective_gradient_lam, partition
from rbbench.optim.shape_mesh import _GAUSS, _shape_gradients, element_dofs, top_load
from rbbench.optim.shape_scene import ShapeScene, design_space
from rbbench.optim.shape_state import (
    ShapeState,
    dof_sets,
    objective,
    solve_condensed,
    solve_jacobian,
)
from rbbench.scene.parameters import ParameterSpace

#: coefficient functions ``theta_k(d, s)`` and their partial derivatives (d, s)
_THETA = (lambda d, s: d, lambda d, s: s, lambda d, s: np.ones_like(d),
          lambda d, s: s * s / d, lambda d, s: s / d, lambda d, s: 1.0 / d)
_DTHETA = (lambda d, s: (np.ones_like(d), 0 * d), lambda d, s: (0 * d, np.ones_like(d)),
           lambda d, s: (0 * d, 0 * d), lambda d, s: (-s * s / d ** 2, 2 * s / d),
           lambda d, s: (-s / d ** 2, 1.0 / d), lambda d, s: (-1.0 / d ** 2, 0 * d))
#: the pairs (m, n) of gradient parts whose products ``B_m^T D B_n`` (+ sym) make term k
_PAIRS = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def _strain(gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """Voigt strain matrix ``(3, 8)`` of the four nodal gradients ``(gx, gy)``."""
    B = np.zeros((3, 8))
    B[0, 0::2], B[1, 1::2] = gx, gy
    B[2, 0::2], B[2, 1::2] = gy, gx
    return B


@dataclass(frozen=True)
class ColumnTemplates:
    """``T[g * 6 + k]`` on the ``4 (ny + 1)`` dofs of one element column; ``dofs[c]`` maps
    them to global dofs for column ``c``; ``t[g]`` the Gauss abscissae in ``[0, 1]``."""

    T: np.ndarray          # (12, ld, ld)
    dofs: np.ndarray       # (nx, ld)
    t: np.ndarray          # (2,)
    h: float
    gamma: float


@lru_cache(maxsize=8)
def column_templates(sc: ShapeScene) -> ColumnTemplates:
    """The fixed matrices ``T_gk`` of the affine decomposition (module docstring)."""
    g, D = sc.grid, sc.D
    de = 1.0 / g.ny
    ld = 4 * (g.ny + 1)
    T = np.zeros((12, ld, ld))
    loc = element_dofs(np.array([[0, 1, 3, 2]]) + 2 * np.arange(g.ny)[:, None])
    for q in _GAUSS:
        dN = _shape_gradients(q)
        line = int(q[0] > 0)
        for j in range(g.ny):
            e = (j + 0.5 * (1.0 + q[1])) * de
            B = (_strain(dN[:, 0] * 2 / g.h, 0 * dN[:, 0]),
                 _strain(-dN[:, 1] * (1 - e) * 2 / de, 0 * dN[:, 0]),
                 _strain(0 * dN[:, 0], dN[:, 1] * 2 / de))
            for k, (m, n) in enumerate(_PAIRS):
                K = B[m].T @ D @ B[n]
                K = K if m == n else K + K.T
                T[line * 6 + k][np.ix_(loc[j], loc[j])] += 0.25 * g.h * de * K
    # local node 2 j + side is global node j (nx + 1) + c + side
    nodes = (np.arange(g.ny + 1)[:, None] * (g.nx + 1) + np.arange(2)[None, :]).ravel()
    base = np.stack([2 * nodes, 2 * nodes + 1], axis=1).ravel()
    dofs = base[None, :] + 2 * np.arange(g.nx)[:, None]
    t = 0.5 * (1.0 + np.array([-1.0, 1.0]) / np.sqrt(3.0))
    return ColumnTemplates(T, dofs, t, g.h, g.gamma)


def theta(tpl: ColumnTemplates, alpha: np.ndarray, derivative: bool = False):
    """``theta (nx, 12)``; with ``derivative`` also ``d theta / d alpha_c`` and
    ``d theta / d alpha_{c+1}`` (each ``(nx, 12)``)."""
    a0, a1 = alpha[:-1, None], alpha[1:, None]
    d = tpl.gamma - ((1 - tpl.t[None, :]) * a0 + tpl.t[None, :] * a1)     # (nx, 2)
    s = np.broadcast_to((a1 - a0) / tpl.h, d.shape)
    th = np.stack([f(d, s) for f in _THETA], axis=2).reshape(len(d), 12)
    if not derivative:
        return th
    parts = [f(d, s) for f in _DTHETA]
    dd = np.stack([p[0] for p in parts], axis=2)                      # (nx, 2, 6)
    ds = np.stack([p[1] for p in parts], axis=2)
    w0 = -(1 - tpl.t)[None, :, None]
    w1 = -tpl.t[None, :, None]
    d0 = (dd * w0 - ds / tpl.h).reshape(len(d), 12)
    d1 = (dd * w1 + ds / tpl.h).reshape(len(d), 12)
    return th, d0, d1


_NONLINEAR = np.array([3, 4, 5, 9, 10, 11])   # columns of theta with k = 3, 4, 5


@lru_cache(maxsize=8)
def term_map(sc: ShapeScene) -> sp.csr_matrix:
    """``R`` with ``theta(alpha).ravel() = R @ phi(alpha)``, ``phi = (1, alpha,
    theta_k for k = 3, 4, 5 per column and line)``: ``d`` and ``s`` are affine in the
    design and ``theta_2 = 1``, so the interior block needs ``n_phi = 1 + I + 6 nx``
    matrices instead of ``12 nx``."""
    tpl, nx = column_templates(sc), sc.grid.nx
    n = nx + 1
    rows, cols, vals = [], [], []

    def put(r, c, v):
        rows.append(r)
        cols.append(c)
        vals.append(v)

    for c in range(nx):
        for g in range(2):
            r = 12 * c + 6 * g
            put(r, 0, tpl.gamma)
            put(r, 1 + c, -(1 - tpl.t[g]))
            put(r, 2 + c, -tpl.t[g])
            put(r + 1, 1 + c, -1.0 / tpl.h)
            put(r + 1, 2 + c, 1.0 / tpl.h)
            put(r + 2, 0, 1.0)
            for k in range(3):
                put(r + 3 + k, 1 + n + 6 * c + 3 * g + k, 1.0)
    return sp.csr_matrix((vals, (rows, cols)), shape=(12 * nx, 1 + n + 6 * nx))


def coefficients(alpha: np.ndarray, th: np.ndarray) -> np.ndarray:
    """``phi(alpha)`` of :func:`term_map` from ``theta(alpha)`` ``(nx, 12)``."""
    return np.concatenate([[1.0], alpha, th[:, _NONLINEAR].ravel()])


def assemble_affine(sc: ShapeScene, alpha: np.ndarray):
    """``A(alpha)`` from the templates (sparse, all dofs): the check of the decomposition."""
    tpl = column_templates(sc)
    K = np.einsum("cq,qab->cab", theta(tpl, np.asarray(alpha, float)), tpl.T)
    rows = np.repeat(tpl.dofs, tpl.dofs.shape[1], axis=1).ravel()
    cols = np.tile(tpl.dofs, (1, tpl.dofs.shape[1])).ravel()
    n = 2 * sc.grid.n_nodes
    return sp.csr_matrix((K.ravel(), (rows, cols)), shape=(n, n))


@dataclass
class ReducedCondensed:
    """Duck type of :class:`~rbbench.optim.shape_state.Condensed` in reduced coordinates
    ``x = (u_c, a)``: ``free = contact + interior = range(m + N)``, ``A = G`` dense."""

    S: np.ndarray
    f: np.ndarray
    free: np.ndarray
    contact: np.ndarray
    interior: np.ndarray
    A: np.ndarray
    L: np.ndarray
    chol: tuple

    def solve_interior(self, b: np.ndarray) -> np.ndarray:
        """``K^-1 b`` with ``K = V^T A_ii V``."""
        return sla.cho_solve(self.chol, b) if len(self.interior) else np.zeros_like(b)

    def extend(self, v_c: np.ndarray) -> np.ndarray:
        """Reduced coordinates ``(v_c, -K^-1 G_Vc v_c)`` (the Galerkin harmonic extension)."""
        return np.concatenate([v_c, -self.solve_interior(self.A[self.interior][:, self.contact]
                                                         @ v_c)])


class ReducedModel:
    """Galerkin reduced state model with contact dofs exact and an interior basis ``V``
    (:meth:`enrich` adds vectors and re-projects the templates)."""

    def __init__(self, sc: ShapeScene) -> None:
        self.sc, self.tpl = sc, column_templates(sc)
        free, self.contact_dofs = dof_sets(sc)
        self.free = free
        n = 2 * sc.grid.n_nodes
        self.m = len(self.contact_dofs)
        mask = np.zeros(n, dtype=bool)
        mask[free] = True
        mask[self.contact_dofs] = False
        self.interior_mask = mask
        self.load = top_load(sc.grid, sc.pressure, sc.traction)
        self.V = np.zeros((n, 0))
        self._local_contact()
        self._project()

    @property
    def N(self) -> int:
        return self.V.shape[1]

    def _local_contact(self) -> None:
        """Per column the reduced indices of ``u_t(c), u_t(c+1), u_nu(c), u_nu(c+1)`` and
        their local dofs (``u_t(0)`` is the roller: a zero column, index 0)."""
        nx = self.sc.grid.nx
        c = np.arange(nx)
        self.cidx = np.stack([np.maximum(c - 1, 0), c, nx + c, nx + c + 1], axis=1)
        self.cloc = np.array([0, 2, 1, 3])
        self.cmask = np.ones((nx, 4))
        self.cmask[0, 0] = 0.0

    def enrich(self, vectors, tol: float = 1e-10, reset: bool = False) -> int:
        """Add the interior parts of ``vectors`` (full dofs, one per row or a list), each
        scaled to unit norm, orthogonalised against ``V`` (twice) and orthonormalised by an
        SVD that drops directions below ``tol``; ``reset`` replaces ``V``. The projected
        operators get the new rows and columns only (:meth:`_append`). Returns the count
        of new basis vectors."""
        if reset:
            self.V = np.zeros((len(self.interior_mask), 0))
            self._project()
        V = self.V
        R = np.array([np.where(self.interior_mask, np.asarray(v, float), 0.0)
                      for v in vectors]).T
        norms = np.linalg.norm(R, axis=0)
        R = R[:, norms > 0] / norms[norms > 0]
        for _ in range(2):
            R = R - V @ (V.T @ R)
        U, s, _ = np.linalg.svd(R, full_matrices=False)
        keep = s > tol * max(1.0, float(s[0]) if s.size else 1.0)
        self._append(U[:, keep])
        return int(np.sum(keep))

    def _project(self) -> None:
        """The projected operators from scratch: the contact block, then every column of
        ``V`` appended (:meth:`_append`)."""
        V, nx = self.V, self.sc.grid.nx
        self.V = V[:, :0]
        self.Mc = np.einsum("qal,clb->cqab", self.tpl.T[:, self.cloc][:, :, self.cloc],
                            np.broadcast_to(np.eye(4) * self.cmask[:, None, :], (nx, 4, 4)))
        self.Mc *= self.cmask[:, None, :, None]
        self.Mv = np.zeros((term_map(self.sc).shape[1], 0))
        self.iu = (np.zeros(0, dtype=int), np.zeros(0, dtype=int))
        self.L_red = self.load[self.contact_dofs].copy()
        self._append(V)

    def _append(self, Vn: np.ndarray, chunk: int = 4) -> None:
        """Append the orthonormal columns ``Vn`` to ``V`` and the new rows / columns of the
        projected templates: per column ``c`` (local trial matrix ``W_c``: 4 contact unit
        columns, then ``V``) the contact rows ``Mc (nx, 12, 4, 4 + N)``, and for the interior
        block per coefficient function of :func:`term_map` (9 combinations of the templates
        per column) the entries ``(i, j)``, ``i <= j``, of ``V^T T V`` packed column by
        column, ``Mv (n_phi, N (N + 1) / 2)``: one GEMV assembles ``K``. The entries of the
        old columns are kept: the cost is that of the new columns only."""
        tpl, nx = self.tpl, self.sc.grid.nx
        N0, k = self.N, Vn.shape[1]
        self.V = np.column_stack([self.V, Vn])
        if k == 0:
            return
        ld = tpl.dofs.shape[1]
        R = term_map(self.sc).tocsr()
        cols0 = np.array([0, 1, 2, *range(nx + 2, nx + 8)])     # phi columns of column 0
        # (column c: 0, 1 + c, 2 + c, nx + 2 + 6 c ...)
        T9 = sp.csr_matrix(np.einsum("pq,qab->pab", R[:12][:, cols0].toarray().T,
                                     tpl.T).reshape(-1, ld))
        # new packed entries: column j = N0 + jj, rows i = 0 .. j
        jj = np.repeat(np.arange(k), N0 + 1 + np.arange(k))
        ii = np.concatenate([np.arange(N0 + 1 + t) for t in range(k)])
        Mc = np.empty((nx, 12, 4, k))
        Mv = np.zeros((R.shape[1], len(ii)))
        for c0 in range(0, nx, chunk):
            c = np.arange(c0, min(c0 + chunk, nx))
            Vc = self.V[tpl.dofs[c]]                               # (len(c), ld, N)
            Vnew = Vc[:, :, N0:]
            Mc[c] = np.einsum("qal,clb->cqab", tpl.T[:, self.cloc, :], Vnew) \
                * self.cmask[c][:, None, :, None]
            TV = (T9 @ np.moveaxis(Vnew, 0, 1).reshape(ld, -1)).reshape(9, ld, len(c), k)
            M9 = np.matmul(np.swapaxes(Vc, 1, 2)[:, None], np.moveaxis(TV, 2, 0))
            P = M9[..., ii, jj]                                    # (len(c), 9, new packed)
            Mv[0] += P[:, 0].sum(axis=0)
            Mv[1 + c] += P[:, 1]
            Mv[2 + c] += P[:, 2]
            Mv[(cols0[3:][None, :] + 6 * c[:, None]).ravel()] += P[:, 3:].reshape(
                6 * len(c), P.shape[2])
        self.Mc = np.concatenate([self.Mc, Mc], axis=3)
        self.Mv = np.concatenate([self.Mv, Mv], axis=1)
        self.iu = (np.concatenate([self.iu[0], ii]), np.concatenate([self.iu[1], N0 + jj]))
        self.L_red = np.concatenate([self.L_red, Vn.T @ self.load])

    def galerkin(self, alpha: np.ndarray) -> np.ndarray:
        """``G = W^T A(alpha) W`` (dense, ``m + N``), assembled from the projected templates."""
        m, N = self.m, self.N
        th = theta(self.tpl, alpha)
        G = np.zeros((m + N, m + N))
        K = np.zeros((N, N))
        K[self.iu] = coefficients(alpha, th) @ self.Mv
        G[m:, m:] = K + np.triu(K, 1).T
        nx = len(th)
        Cx = np.matmul(th[:, None, :], self.Mc.reshape(nx, 12, -1)).reshape(nx, 4, 4 + N)
        cV = self._scatter @ Cx[:, :, 4:].reshape(4 * nx, N)
        G[:m, m:], G[m:, :m] = cV, cV.T
        np.add.at(G, (self.cidx[:, :, None], self.cidx[:, None, :]), Cx[:, :, :4])
        return G

    @property
    def _scatter(self) -> sp.csr_matrix:
        """``P`` (``m x 4 nx``): row ``cidx[c, a]`` of the contact unknowns gets entry
        ``4 c + a`` of the per-column contact rows."""
        if getattr(self, "_scatter_matrix", None) is None:
            nx = len(self.cidx)
            self._scatter_matrix = sp.csr_matrix(
                (np.ones(4 * nx), (self.cidx.ravel(), np.arange(4 * nx))), shape=(self.m, 4 * nx))
        return self._scatter_matrix

    def design_products(self, alpha: np.ndarray, q: np.ndarray, x: np.ndarray) -> np.ndarray:
        """``q . dG/dalpha_i x`` for every design node (reduced vectors ``q, x``)."""
        m, n, N = self.m, len(alpha), self.N
        _, d0, d1 = theta(self.tpl, alpha, derivative=True)
        qc, xc = q[self.cidx] * self.cmask, x[self.cidx] * self.cmask
        qv, xv = q[m:], x[m:]
        nx = len(qc)
        Mc = self.Mc.reshape(nx * 48, 4 + N)
        b = np.einsum("ca,cqab,cb->cq", qc, self.Mc[..., :4], xc)
        Y = (Mc[:, 4:] @ np.column_stack([xv, qv])).reshape(nx, 12, 4, 2)
        b += np.einsum("ca,cqa->cq", qc, Y[..., 0]) + np.einsum("ca,cqa->cq", xc, Y[..., 1])
        i0, i1 = self.iu
        z = qv[i0] * xv[i1] + xv[i0] * qv[i1]
        z[i0 == i1] *= 0.5
        bv = self.Mv @ z                                     # (n_phi,)
        xi = bv[1:1 + n].copy()
        bnl = bv[1 + n:].reshape(len(b), 6)
        xi[:-1] += np.sum(b * d0, axis=1) + np.sum(bnl * d0[:, _NONLINEAR], axis=1)
        xi[1:] += np.sum(b * d1, axis=1) + np.sum(bnl * d1[:, _NONLINEAR], axis=1)
        return xi

    def condense(self, alpha: np.ndarray) -> ReducedCondensed:
        """Galerkin Schur complement ``S_N`` and load ``f_N`` on the contact dofs."""
        m = self.m
        G = self.galerkin(np.asarray(alpha, float))
        contact, interior = np.arange(m), m + np.arange(self.N)
        L = self.L_red
        if self.N:
            chol = sla.cho_factor(G[m:, m:])
            X = sla.cho_solve(chol, np.column_stack([G[m:, :m], L[m:]]))
            S = G[:m, :m] - G[:m, m:] @ X[:, :m]
            f = L[:m] - G[:m, m:] @ X[:, m]
        else:
            chol, S, f = (np.zeros((0, 0)), False), G.copy(), L.copy()
        return ReducedCondensed(0.5 * (S + S.T), f, np.arange(m + self.N), contact, interior,
                                G, L, chol)

    def full(self, x: np.ndarray) -> np.ndarray:
        """Full displacement (all dofs) of the reduced coordinates ``x = (u_c, a)``."""
        u = self.V @ x[self.m:]
        u[self.contact_dofs] = x[:self.m]
        return u

    @property
    def parameters(self) -> ParameterSpace:
        """The design box ``lb <= alpha <= ub`` (:func:`rbbench.optim.shape_scene.design_space`;
        the linear constraints of the admissible set are the optimiser's)."""
        return design_space(self.sc)

    def solve(self, mu: np.ndarray) -> ReducedSolution:
        """The model interface: the reduced state at the design ``mu`` (checked against the
        design box), ``u`` its reduced coordinates ``(u_c, a)``, ``lam`` the nodal normal
        forces, ``detail`` the :class:`~rbbench.optim.shape_state.ShapeState` (a
        :class:`~rbbench.optim.shape_state.StateSolveError` when Newton fails)."""
        t0 = time.perf_counter()
        alpha = self.parameters.check(mu)
        st = self.state(alpha)
        return ReducedSolution(mu=alpha, u=self.coordinates(st), lam=st.lam,
                               iterations=int(st.iterations), stop_reason="converged",
                               time_s=time.perf_counter() - t0, detail=st)

    def reconstruct(self, solution: ReducedSolution) -> HFVectors:
        """The displacement ``W x`` on the free dofs and the nodal normal forces."""
        return HFVectors(u=self.full(solution.u)[self.free], lam=np.asarray(solution.lam))

    def state(self, alpha: np.ndarray, tol: float = 1e-11, max_iter: int = 100,
              y0: np.ndarray | None = None, reconstruct: bool = True) -> ShapeState:
        """Reduced state: the semismooth Newton of ``shape_state`` on ``(S_N, f_N)``.

        ``state.u`` is the full displacement ``W x`` (``None`` without ``reconstruct``: an
        ``O(dofs N)`` product the optimiser does not need); ``state.cond.A`` the Galerkin
        matrix.
        """
        alpha = np.asarray(alpha, dtype=float)
        cond = self.condense(alpha)
        st = solve_condensed(self.sc, alpha, cond, tol=tol, max_iter=max_iter, y0=y0)
        st.u = self.full(st.u[:self.m + self.N]) if reconstruct else None
        return st

    def coordinates(self, st: ShapeState) -> np.ndarray:
        """Reduced coordinates ``x = (u_c, a)`` of a reduced state."""
        m = self.m
        u_c = np.concatenate([st.u_t, st.u_n])
        cond = st.cond
        a = cond.solve_interior(cond.L[m:] - cond.A[m:, :m] @ u_c) if self.N else np.zeros(0)
        return np.concatenate([u_c, a])

    def subgradient(self, st: ShapeState) -> np.ndarray:
        """``xi = q . dG/dalpha x + c [contact] p_lam`` (module docstring), all reduced."""
        n, m = len(st.alpha), self.m
        p = adjoint(self.sc, st)
        q = st.cond.extend(p[:m])
        xi = self.design_products(st.alpha, q, self.coordinates(st))
        return xi + st.c * st.contact * p[m:m + n]

    def evaluate(self, alpha: np.ndarray, y0: np.ndarray | None = None,
                 tol: float = 1e-11, reconstruct: bool = True) -> Evaluation:
        """Reduced ``Theta_N(alpha)``, its subgradient and the reduced state
        (``reconstruct``: :meth:`state`)."""
        st = self.state(alpha, tol=tol, y0=y0, reconstruct=reconstruct)
        return Evaluation(np.asarray(alpha, float).copy(), objective(self.sc, st.lam),
                          self.subgradient(st), st, partition(self.sc, st))


def adjoint(sc: ShapeScene, st: ShapeState) -> np.ndarray:
    """Adjoint ``p`` of the semismooth system: ``Jac^T p = -grad_y J`` (``shape_adjoint``)."""
    n = len(st.alpha)
    m = 2 * n - 1
    rhs = np.zeros(st.jacobian.shape[0])
    rhs[m:m + n] = -objective_gradient_lam(sc, st.lam)
    return solve_jacobian(st.jacobian, rhs, m, transpose=True)


def hf_snapshots(sc: ShapeScene, st: ShapeState) -> list[np.ndarray]:
    """HF state ``u`` and adjoint ``p_full`` (full dofs) at an HF state: the enrichment."""
    n = len(st.alpha)
    p = adjoint(sc, st)
    p_full = np.zeros(2 * sc.grid.n_nodes)
    p_full[st.cond.free] = st.cond.extend(p[:2 * n - 1])
    return [st.u, p_full]


def interior_space(sc: ShapeScene, st: ShapeState) -> np.ndarray:
    """Rows: the discrete harmonic extensions ``-A_ii^-1 A_ic e_j`` of the contact unit
    vectors and ``A_ii^-1 L_i`` at the HF state's design (full dofs), by the HF factors.

    With them in ``span V`` every reduced state at that design is the HF state (the
    interior is an affine function of ``u_c``): the model is exact there.
    """
    cond = st.cond
    rhs = np.column_stack([-cond.A[cond.interior][:, cond.contact].toarray(),
                           cond.L[cond.interior]])
    y = spla.spsolve_triangular(cond.L_ii, rhs, lower=True, unit_diagonal=True)
    X = spla.spsolve_triangular(cond.U_ii, y, lower=False)
    out = np.zeros((X.shape[1], 2 * sc.grid.n_nodes))
    out[:, cond.free[cond.interior]] = X.T
    return out


def state_vector(st: ShapeState) -> np.ndarray:
    """``y = (u_t, u_nu, lam, tau)``: the warm start of the semismooth Newton."""
    return np.concatenate([st.u_t, st.u_n, st.lam, st.tau])

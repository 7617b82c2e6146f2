"""Model-B Coulomb contact state by a semismooth Newton method on the contact dofs.

Model B of the talk "On coupling of complementarity with friction in contact shape
optimization", eq. (2) with ``Q~_i = F(|u_t^i|) lam^i d|u_t^i|``: the body rests on the rigid
line ``x2 = 0``; at design node ``i`` the gap is ``u_nu^i + alpha_i >= 0`` (``u_nu = u_2``,
``u_t = u_1``, the talk's kinematics), ``lam^i >= 0`` the nodal normal force and ``tau^i``
the tangential force on the body, ``tau^i in -F(|u_t^i|) lam^i d|u_t^i|``.

The stiffness is condensed onto the contact dofs (Schur complement, one factorisation of
the interior block), and the state ``y = (u_t, u_nu, lam, tau)`` solves the semismooth
system (Alart-Curnier / Hueber-Stadler-Wohlmuth form, constant ``c > 0``)::

    R1 = S u_c - f_c - (tau, lam)                     (equilibrium on the contact dofs)
    R2 = lam - max(0, lam - c (u_nu + alpha))         (Signorini)
    R3 = tau - P_[-s, s](tau - c u_t),  s = F(|u_t|) lam+   (Coulomb, model B)

Branches of the generalised Jacobian at a kink: ``lam - c g = 0`` counts as no contact,
``|tau - c u_t| = s`` as sticking; the same choice gives the adjoint (``shape_adjoint``).
Node 0 lies on the roller ``u_1 = 0`` of the left side: it has no friction unknown.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from rbbench.optim.shape_mesh import assemble_stiffness, top_load
from rbbench.optim.shape_scene import ShapeScene


class StateSolveError(RuntimeError):
    """The state solve did not converge; the message says after what and why."""


@dataclass
class Condensed:
    """Contact-condensed operators at one design: ``S u_c = f_c + (tau, lam)``.

    One sparse LU of the free stiffness in the order (interior by minimum degree, contact
    last): its trailing block gives the Schur complement ``S = L_cc U_cc`` without
    ``A_ii^-1 A_ic`` column by column; the same LU solves full systems.
    """

    S: np.ndarray          # (m, m), m = 2 I - 1; u_c = (u_t at nodes 1.., u_nu at nodes 0..)
    f: np.ndarray
    free: np.ndarray       # free dofs (roller removed)
    contact: np.ndarray    # positions of u_c in the free dofs
    interior: np.ndarray   # positions of the other free dofs, in factorisation order
    L_ii: object           # unit lower factor of A_ii (CSR), that order
    U_ii: object           # upper factor of A_ii (CSR)
    A: object              # free-free stiffness (CSC); singular: the vertical translation
    L: np.ndarray          # free load

    def solve_interior(self, b: np.ndarray) -> np.ndarray:
        """``A_ii^-1 b`` (``b`` in the order of ``interior``), by the two triangular factors."""
        y = spla.spsolve_triangular(self.L_ii, b, lower=True, unit_diagonal=True)
        return spla.spsolve_triangular(self.U_ii, y, lower=False)

    def extend(self, v_c: np.ndarray) -> np.ndarray:
        """Free vector ``(-A_ii^-1 A_ic v_c, v_c)``: the discrete harmonic extension."""
        v = np.zeros(len(self.free))
        v[self.contact] = v_c
        v[self.interior] = -self.solve_interior(self.A[self.interior][:, self.contact] @ v_c)
        return v


@dataclass
class ShapeState:
    """Solution of the state problem at ``alpha`` and what the adjoint needs."""

    alpha: np.ndarray
    u: np.ndarray | None   # full displacement (all dofs, roller dofs 0); None: not formed
    u_t: np.ndarray        # (I - 1,)
    u_n: np.ndarray        # (I,)
    lam: np.ndarray        # (I,) nodal normal forces (raw, not clipped)
    tau: np.ndarray        # (I - 1,) nodal tangential forces on the body
    contact: np.ndarray    # bool (I,): Signorini branch active
    stick: np.ndarray      # bool (I - 1,): stick branch
    jacobian: np.ndarray   # generalised Jacobian of (R1, R2, R3) at the solution
    c: float
    iterations: int
    residual: float
    cond: Condensed


def dof_sets(sc: ShapeScene) -> tuple[np.ndarray, np.ndarray]:
    """Free dofs (left side ``u_1 = 0`` removed) and the contact dofs ``u_c`` (global)."""
    g = sc.grid
    n = 2 * g.n_nodes
    free = np.setdiff1d(np.arange(n), 2 * g.left())
    bottom = g.bottom()
    return free, np.concatenate([2 * bottom[1:], 2 * bottom + 1])


@lru_cache(maxsize=8)
def _interior_order(sc: ShapeScene) -> np.ndarray:
    """Minimum-degree order of the interior block (its pattern does not depend on alpha)."""
    A, _, free, contact = _free_system(sc, sc.initial_design())
    interior = np.setdiff1d(np.arange(len(free)), contact)
    lu = spla.splu(A[interior][:, interior].tocsc(), permc_spec="MMD_AT_PLUS_A",
                   diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    return interior[np.argsort(lu.perm_c)]


def _free_system(sc: ShapeScene, alpha: np.ndarray):
    A_all = assemble_stiffness(sc.grid, alpha, sc.D)
    L_all = top_load(sc.grid, sc.pressure, sc.traction)
    free, contact_g = dof_sets(sc)
    pos = np.full(A_all.shape[0], -1)
    pos[free] = np.arange(len(free))
    return A_all[free][:, free].tocsc(), L_all[free], free, pos[contact_g]


def condense(sc: ShapeScene, alpha: np.ndarray) -> Condensed:
    """Schur complement on the contact dofs from one bordered sparse LU.

    The free stiffness is factorised in the order (interior by minimum degree, contact
    last) without pivoting (it is symmetric positive semi-definite, its kernel the vertical
    translation, which only the contact dofs see; ``shift I`` is added to the contact block
    so that the last pivots stay regular and subtracted again): the trailing block of
    ``L U`` is ``S = A_cc - A_ci A_ii^-1 A_ic`` and the leading blocks factor ``A_ii``; no
    ``A_ii^-1 A_ic`` is formed column by column.
    """
    A, L, free, contact = _free_system(sc, alpha)
    interior = _interior_order(sc)
    perm = np.concatenate([interior, contact])
    k, m = len(interior), len(contact)
    # + shift I on the contact block: the factor stays regular, S + shift I comes out
    shift = float(np.mean(A.diagonal()[contact]))
    Ap = A[perm][:, perm] + sp.diags(np.r_[np.zeros(k), np.full(m, shift)])
    lu = spla.splu(Ap.tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0,
                   options={"SymmetricMode": True, "Equil": False})
    S = (lu.L[k:, k:] @ lu.U[k:, k:]).toarray() - shift * np.eye(m)
    cond = Condensed(0.5 * (S + S.T), np.empty(len(contact)), free, contact, interior,
                     lu.L[:k, :k].tocsr(), lu.U[:k, :k].tocsr(), A, L)
    w = cond.solve_interior(L[interior])
    cond.f = L[contact] - A[contact][:, interior] @ w
    return cond


def _residual_and_jacobian(sc: ShapeScene, S: np.ndarray, f: np.ndarray, alpha: np.ndarray,
                           y: np.ndarray, c: float):
    """``R(y)`` and one element of its generalised Jacobian (the branches documented above)."""
    n = len(alpha)
    m = 2 * n - 1
    u_c, lam, tau = y[:m], y[m:m + n], y[m + n:]
    u_t, u_n = u_c[:n - 1], u_c[n - 1:]
    jac = np.zeros((len(y), len(y)))
    r1 = S @ u_c - f
    r1[:n - 1] -= tau
    r1[n - 1:] -= lam
    jac[:m, :m] = S
    jac[np.arange(n - 1), m + n + np.arange(n - 1)] = -1.0
    jac[n - 1 + np.arange(n), m + np.arange(n)] = -1.0
    active = lam - c * (u_n + alpha) > 0
    r2 = np.where(active, c * (u_n + alpha), lam)
    i2 = m + np.arange(n)
    jac[i2[active], n - 1 + np.flatnonzero(active)] = c
    jac[i2[~active], m + np.flatnonzero(~active)] = 1.0
    lam_t = lam[1:]
    lam_p = np.maximum(lam_t, 0.0)
    F, dF = sc.friction(np.abs(u_t))
    s = F * lam_p
    z = tau - c * u_t
    stick = np.abs(z) <= s
    sgn = np.sign(z)
    r3 = np.where(stick, c * u_t, tau - sgn * s)
    i3 = m + n + np.arange(n - 1)
    k = np.arange(n - 1)
    jac[i3[stick], k[stick]] = c
    sl = ~stick
    jac[i3[sl], m + n + k[sl]] = 1.0
    jac[i3[sl], m + 1 + k[sl]] = -sgn[sl] * F[sl] * (lam_t[sl] > 0)
    jac[i3[sl], k[sl]] = -sgn[sl] * lam_p[sl] * dF[sl] * np.sign(u_t[sl])
    return np.concatenate([r1, r2, r3]), jac, active, stick


def solve_jacobian(jac: np.ndarray, rhs: np.ndarray, m: int,
                   transpose: bool = False) -> np.ndarray:
    """``jac^-1 rhs`` (or ``jac^-T rhs``) by eliminating the forces.

    The equilibrium rows of the generalised Jacobian are ``[S, -P]`` with ``P`` the
    permutation pairing ``(tau, lam)`` with ``(u_t, u_nu)`` (module docstring), so the force
    increments are explicit, ``dz = P^T (S du - r1)``, and the complementarity rows
    ``[B, C]`` leave ``(B + C P^T S) du = r23 + C P^T r1`` of the size ``m`` of ``u_c``
    instead of ``2 m`` (a dense LU of 1 / 8 of the cost); the transpose likewise. Both
    matrices are singular together (``det`` equal up to sign): a floating body (no node in
    contact: the vertical translation) makes them so, and then the dense LU of ``jac``
    gives the step as before the elimination.
    """
    S, B, C = jac[:m, :m], jac[m:, :m], jac[m:, m:]
    row = np.argmin(jac[:m, m:], axis=0)          # P[row[j], j] = 1 (the entry -1)
    M = B + C @ S[row]
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", sla.LinAlgWarning)
            if transpose:            # [S, B^T; -P^T, C^T] (p1, p2) = (g1, g2)
                g1, g2 = rhs[:m], rhs[m:]
                q = np.zeros(m)
                q[row] = g2
                p2 = sla.solve(M.T, g1 + S @ q, check_finite=True)
                p1 = np.zeros(m)
                p1[row] = C.T @ p2 - g2
                return np.concatenate([p1, p2])
            r1, r23 = rhs[:m], rhs[m:]
            du = sla.solve(M, r23 + C @ r1[row], check_finite=True)
            return np.concatenate([du, (S @ du - r1)[row]])
    except sla.LinAlgWarning:
        return sla.solve(jac.T if transpose else jac, rhs, check_finite=True)


def solve_state(sc: ShapeScene, alpha: np.ndarray, tol: float = 1e-11, max_iter: int = 100,
                y0: np.ndarray | None = None) -> ShapeState:
    """Solve the model-B state at ``alpha`` (semismooth Newton with Armijo backtracking)."""
    alpha = np.asarray(alpha, dtype=float)
    cond = condense(sc, alpha)
    return solve_condensed(sc, alpha, cond, tol=tol, max_iter=max_iter, y0=y0)


def solve_condensed(sc: ShapeScene, alpha: np.ndarray, cond: Condensed, tol: float = 1e-11,
                    max_iter: int = 100, y0: np.ndarray | None = None) -> ShapeState:
    """Semismooth Newton on ``(R1, R2, R3)`` for given condensed operators."""
    n = len(alpha)
    S, f = cond.S, cond.f
    c = float(np.mean(np.diag(S)))
    if y0 is None:
        total = max(abs(float(np.sum(f[n - 1:]))), 1e-30)
        y0 = np.concatenate([np.zeros(n - 1), -alpha, np.full(n, total / n), np.zeros(n - 1)])
    y = y0.copy()
    scale = max(float(np.linalg.norm(f)), 1e-300)
    for it in range(1, max_iter + 1):
        r, jac, _, _ = _residual_and_jacobian(sc, S, f, alpha, y, c)
        nr = float(np.linalg.norm(r))
        try:
            dy = solve_jacobian(jac, -r, 2 * n - 1)
        except (sla.LinAlgError, ValueError) as exc:
            raise StateSolveError(f"singular Newton matrix at iteration {it} ({exc})") from None
        t = 1.0
        while t > 1e-8:
            r_new = _residual_and_jacobian(sc, S, f, alpha, y + t * dy, c)[0]
            if np.linalg.norm(r_new) <= (1.0 - 1e-4 * t) * nr:
                break
            t *= 0.5
        y = y + t * dy
        r, jac, active, stick = _residual_and_jacobian(sc, S, f, alpha, y, c)
        res = float(np.linalg.norm(r)) / scale
        if res <= tol:
            return _state(sc, alpha, cond, y, jac, active, stick, c, it, res)
    raise StateSolveError(f"semismooth Newton: no convergence in {max_iter} iterations "
                          f"(relative residual {res:.3g} > tol {tol:g})")


def _state(sc, alpha, cond, y, jac, active, stick, c, it, res) -> ShapeState:
    n = len(alpha)
    m = 2 * n - 1
    u_c = y[:m]
    u_free = np.zeros(len(cond.free))
    u_free[cond.contact] = u_c
    rhs = cond.L[cond.interior] - cond.A[cond.interior][:, cond.contact] @ u_c
    u_free[cond.interior] = cond.solve_interior(rhs)
    u = np.zeros(2 * sc.grid.n_nodes)
    u[cond.free] = u_free
    return ShapeState(alpha=alpha, u=u, u_t=u_c[:n - 1], u_n=u_c[n - 1:], lam=y[m:m + n],
                      tau=y[m + n:], contact=active, stick=stick, jacobian=jac, c=c,
                      iterations=it, residual=res, cond=cond)


def objective(sc: ShapeScene, lam: np.ndarray) -> float:
    """The shape-optimisation talk's ``J = ||lam||_p^p`` (p = 6) of the nodal normal forces."""
    return float(np.sum(np.abs(lam) ** sc.power))

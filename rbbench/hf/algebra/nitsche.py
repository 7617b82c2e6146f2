"""Algebra of the Nitsche contact formulation (frictionless), shared by the HF solver,
the metrics and the reduced model.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slides "Nitsche's method (1/2)" and "(2/2)"; Chouly & Hild
(2013), Chouly, Hild & Renard (2015). With ``[x]_- = min(x, 0)`` (non-positive part), the
Signorini conditions ``u_n <= d^n``, ``sigma_nn(u) <= 0``,
``sigma_nn(u) (u_n - d^n) = 0`` are equivalent to the Alart-Curnier equation::

    sigma_nn(u) = [P_gamma(u)]_-,   P_gamma(u) = sigma_nn(u) - gamma (u_n - d^n),

for any ``gamma > 0``. Nitsche's method imposes it weakly: for all ``v``::

    a(u, v) - theta int 1/gamma sigma_nn(u) sigma_nn(v)
            + int 1/gamma [P_gamma(u)]_- P_theta(v) = f(v),
    P_theta(v) = theta sigma_nn(v) - gamma v_n.

``theta = 1`` is Benaceur et al.'s variant: the optimality condition of the Nitsche energy
``J(v) = 1/2 a(v, v) - f(v) - 1/2 int sigma_nn(v)^2 / gamma
+ 1/2 int [P_gamma(v)]_-^2 / gamma``; ``theta = 0`` and ``theta = -1`` (skew-symmetric)
are the usual variants. ``gamma = gamma0 E / h`` (Pa/m) with ``E`` the slave's
Young's modulus and ``h`` the slave facet length at the point.

Discrete form (points ``q`` with weights ``w_q``, ``D = diag(w / gamma)``,
``S`` = :attr:`~rbbench.interfaces.NitscheProblem.Snn`, ``U`` = ``Un``, ``G = diag(gamma)``)::

    s = S u + s_lift,  P = s - G (U u - gap)
    R(u) = A u - F - theta S^T D s + (theta S - G U)^T D [P]_-
    K(u) = A - theta S^T D S + (theta S - G U)^T D H (S - G U),   H = diag(P < 0)

``K`` is the generalised (Heaviside) Jacobian of ``R`` (Benaceur et al.: ``A_gamma + B_gamma(u_k)``
with the tangent ``H(-P_gamma(u_k))``). The contact pressure is ``p = -[P]_- >= 0``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from rbbench.hf.geometry.facets import gauss_legendre_01
from rbbench.hf.geometry.operators import normal_stress
from rbbench.hf.geometry.pairing import pair
from rbbench.interfaces import NitscheProblem

__all__ = ["NitscheState", "ac_residual", "ac_residual_nodal", "ac_residual_variants",
           "energy", "gamma_scaling", "pressure", "project_pressure", "residual", "state",
           "tangent"]


def gamma_scaling(gamma0: float, E: float, h: np.ndarray) -> np.ndarray:
    """Nitsche parameter per point, ``gamma = gamma0 E / h`` (Pa/m).

    Chouly & Hild (2013) take ``gamma = gamma0 / h`` with a dimensionless
    ``gamma0``; the Young's modulus ``E`` makes ``gamma0`` independent of the
    material (``sigma_nn`` scales with ``E``).
    """
    return float(gamma0) * float(E) / np.asarray(h, dtype=float)


@dataclass
class NitscheState:
    """Point values at a displacement: stress ``s``, ``P_gamma``, active set ``H``."""

    s: np.ndarray  # sigma_nn(u) at the points (Pa)
    P: np.ndarray  # P_gamma(u) = s - gamma (u_n - d^n)
    active: np.ndarray  # H(-P): P < 0

    @property
    def neg(self) -> np.ndarray:
        """``[P]_- = min(P, 0)``."""
        return np.minimum(self.P, 0.0)


def state(prob: NitscheProblem, u_free: np.ndarray) -> NitscheState:
    """Point values of ``sigma_nn``, ``P_gamma`` and the active set at ``u`` (free dofs)."""
    s = prob.Snn @ u_free + prob.snn_lift
    P = s - prob.gamma * (prob.Un @ u_free - prob.gap)
    return NitscheState(s, P, P < 0.0)


def residual(prob: NitscheProblem, u_free: np.ndarray, st: NitscheState | None = None
             ) -> np.ndarray:
    """``R(u)`` (module docstring; Benaceur et al.'s "Residual vector R_gamma^n")."""
    st = state(prob, u_free) if st is None else st
    dw = prob.weights / prob.gamma
    th = float(prob.theta)
    f = dw * st.neg
    r = prob.A @ u_free - prob.F + prob.Snn.T @ (th * (f - dw * st.s)) \
        - prob.Un.T @ (prob.gamma * f)
    return np.asarray(r).ravel()


def tangent(prob: NitscheProblem, u_free: np.ndarray, st: NitscheState | None = None
            ) -> sp.csr_matrix:
    """``K(u)`` (module docstring; Benaceur et al.'s "Tangent matrix B_gamma^n(mu, w)"), sparse."""
    st = state(prob, u_free) if st is None else st
    dw = prob.weights / prob.gamma
    th = float(prob.theta)
    G = sp.diags(prob.gamma)
    left = th * prob.Snn - G @ prob.Un  # P_theta
    right = prob.Snn - G @ prob.Un  # dP / du
    K = prob.A - th * (prob.Snn.T @ sp.diags(dw) @ prob.Snn) \
        + left.T @ sp.diags(dw * st.active) @ right
    return sp.csr_matrix(K)


def energy(prob: NitscheProblem, u_free: np.ndarray, st: NitscheState | None = None) -> float:
    """Nitsche energy ``J(u)`` (Benaceur et al.'s "Nitsche's energy"); ``R`` is its gradient
    for theta = 1."""
    st = state(prob, u_free) if st is None else st
    dw = prob.weights / prob.gamma
    return float(0.5 * u_free @ (prob.A @ u_free) - prob.F @ u_free
                 - 0.5 * np.sum(dw * st.s**2) + 0.5 * np.sum(dw * st.neg**2))


def pressure(prob: NitscheProblem, u_free: np.ndarray) -> np.ndarray:
    """Contact pressure at the points, ``p = -[P_gamma(u)]_- >= 0`` (Pa)."""
    return -state(prob, u_free).neg


def project_pressure(prob: NitscheProblem, p: np.ndarray) -> np.ndarray:
    """L2(Gamma_c) projection of point pressures on the multiplier space (``lam`` of Nitsche).

    ``lam = W^{-1} Mlam^T diag(w) p``: with the P0 / LAC spaces the mean pressure
    over each support (non-negative), so the mixed formulation's metrics (force,
    half-width, contact.csv) apply to it unchanged.
    """
    rhs = np.asarray(prob.Mlam.T @ (prob.weights * p)).ravel()
    if rhs.size == 0:
        return rhs
    W = prob.W.tocsc()
    return np.asarray(spla.spsolve(W, rhs)).ravel() if W.shape[0] > 1 else rhs / W[0, 0]


def ac_residual(prob: NitscheProblem, u_free: np.ndarray) -> float:
    """Benaceur et al.'s relative Alart-Curnier residual ``e_AC^n`` (slide "Relative error on the
    Alart-Curnier reformulation"), a fraction::

        e_AC = || sigma_nn(u) - [P_gamma(u)]_- || / || sigma_nn(u) ||

    in the L2(Gamma_c) norm of the contact quadrature (``sum_q w_q x_q^2``). Zero
    for the exact solution; O(h) for the discrete one.
    """
    st = state(prob, u_free)
    den = float(np.sqrt(np.sum(prob.weights * st.s**2)))
    num = float(np.sqrt(np.sum(prob.weights * (st.s - st.neg) ** 2)))
    return num / den if den > 0 else 0.0


# ---------------------------------------------------------------------------
# e_AC variants (Benaceur et al.'s "l2(Gamma_c)" norm is not specified; README "Nitsche")
# ---------------------------------------------------------------------------
def _facet_operators(layout, mu: np.ndarray, s_local: np.ndarray):
    """``(Un, gap, Snn, fq)`` at local coordinates ``s_local`` of every slave facet.

    Same pairing as the contact operators (ray cast along the slave normal,
    :func:`rbbench.hf.geometry.operators.pair`), evaluated at arbitrary points of the facets
    instead of the contact quadrature; ``Snn`` is the stress of the slave element
    adjacent to each facet. Also returns the physical facet lengths ``L``.
    """
    s_local = np.asarray(s_local, dtype=float)
    p = pair(layout, mu, local=(s_local, np.ones(s_local.size)))
    return (p.jump(p.nrm, layout.n_dofs), p.gap, normal_stress(layout, p, mu), p.fq,
            np.linalg.norm(p.b - p.a, axis=1))


def ac_residual_nodal(s: np.ndarray, pen: np.ndarray, gamma: np.ndarray) -> float:
    """``|| s - [s - gamma pen]_- ||_2 / || s ||_2`` of nodal vectors (plain l2 norms).

    ``s``: sigma_nn at the slave contact nodes, ``pen = u_n - d^n`` there, ``gamma``
    the Nitsche parameter there. Zero iff the Alart-Curnier equation holds at every node.
    """
    s, pen, gamma = (np.asarray(v, dtype=float) for v in (s, pen, gamma))
    den = float(np.linalg.norm(s))
    return float(np.linalg.norm(s - np.minimum(s - gamma * pen, 0.0))) / den if den > 0 else 0.0


def ac_residual_variants(layout, prob: NitscheProblem, u: np.ndarray, mu,
                         n_points: int = 6) -> dict[str, float]:
    """Benaceur et al.'s relative Alart-Curnier residual under three readings of its norm.

    ``u``: all dofs (``result.u``); ``layout``: the backend's
    :class:`~rbbench.hf.geometry.operators.ContactLayout`. Returns fractions:

    ``quad``
        :func:`ac_residual`: L2(Gamma_c) by the contact quadrature of the solve
        (the points where the Nitsche equation is imposed).
    ``nodal``
        plain l2 over the slave contact nodes (:func:`ac_residual_nodal`): at each
        node, ``sigma_nn`` and ``u_n - d^n`` are the means of the values at that
        node of its (one or two) slave facets (``sigma_nn``: stress of each facet's
        adjacent element along the slave normal there; ``u_n``: jump along that
        normal, master ray cast from the node; with smooth normals the two facets
        share it); ``gamma = gamma0 E / h`` with ``h``
        the mean of the adjacent facet lengths.
    ``l2``
        L2(Gamma_c) of the finite-element functions ``sigma_nn(u_h) - [P_gamma(u_h)]_-``
        over ``sigma_nn(u_h)``, ``n_points`` Gauss points per slave facet (independent
        of the quadrature of the solve; sees the variation of ``u_n`` inside a facet).
    """
    mu = np.atleast_1d(np.asarray(mu, dtype=float))
    u = np.asarray(u, dtype=float)
    g0E = float(prob.gamma0) * float(prob.E)
    out = {"quad": ac_residual(prob, u[prob.free])}
    # L2 of the FE functions
    sg, wg = gauss_legendre_01(n_points)
    Un, gap, Snn, fq, L = _facet_operators(layout, mu, sg)
    s = Snn @ u
    r = s - np.minimum(s - g0E / L[fq] * (Un @ u - gap), 0.0)
    w = np.tile(wg, L.size) * L[fq]
    den = float(np.sum(w * s**2))
    out["l2"] = float(np.sqrt(np.sum(w * r**2) / den)) if den > 0 else 0.0
    # nodal: facet-end values averaged at the shared slave nodes (the chain is ordered:
    # node j is the end of facet j - 1 and the start of facet j)
    Un, gap, Snn, fq, L = _facet_operators(layout, mu, np.array([0.0, 1.0]))
    nf = L.size
    ends = np.stack([Snn @ u, Un @ u - gap, np.repeat(L, 2)], axis=1).reshape(nf, 2, 3)
    chained = np.r_[False, np.all(np.isclose(layout.slave.b[:-1], layout.slave.a[1:]),
                                  axis=1)]
    start = np.arange(nf) + np.cumsum(~chained) - 1  # a break in the chain: new node
    acc, cnt = np.zeros((start[-1] + 2, 3)), np.zeros(start[-1] + 2)
    for k, nodes in enumerate((start, start + 1)):
        np.add.at(acc, nodes, ends[:, k])
        np.add.at(cnt, nodes, 1.0)
    keep = cnt > 0
    nodal = acc[keep] / cnt[keep, None]
    out["nodal"] = ac_residual_nodal(nodal[:, 0], nodal[:, 1], g0E / nodal[:, 2])
    return out

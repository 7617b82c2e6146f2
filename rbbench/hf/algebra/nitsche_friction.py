"""Algebra of Nitsche contact with Tresca or Coulomb friction (2D), plain functions on arrays.

Chouly (2014), "An adaptation of Nitsche's method to the Tresca friction problem";
Chouly, Hild & Renard (2015), "Symmetric and non-symmetric variants of Nitsche's method
for contact problems in elasticity"; Renard (2013), "Generalized Newton's methods for the
approximation and resolution of frictional contact problems in elasticity". Same signs as
:mod:`rbbench.hf.algebra.nitsche` (``n`` the slave's outward normal, ``u_n`` the normal
jump, ``[x]_- = min(x, 0)``); ``t = (-n_y, n_x)`` and ``u_t`` the tangential jump of
:attr:`~rbbench.interfaces.ContactOperators.Ut`, ``sigma_nt = t . sigma(u) n`` (``Snt``).

With the slip of the load step ``v = u_t - ut_prev`` (quasi-static, ``ut_prev`` the jump at
the end of the previous step), the Coulomb / Tresca conditions are equivalent to::

    sigma_nn = [P_n(u)]_-,           P_n(u) = sigma_nn(u) - gamma (u_n - d^n)
    sigma_nt = [P_t(u)]_S,           P_t(u) = sigma_nt(u) - gamma v(u)

``[x]_S`` the projection on ``[-S, S]``; ``S = s`` (Tresca) or ``S = -F [P_n(u)]_-``
(Coulomb; model B: ``F = F(|u_t|)`` of the full jump, as the mixed solver's model B).
Nitsche's method: for all ``v``, with ``P_theta,t(v) = theta sigma_nt(v) - gamma v_t``::

    (frictionless Nitsche terms) - theta int 1/gamma sigma_nt(u) sigma_nt(v)
                                 + int 1/gamma [P_t(u)]_S P_theta,t(v) = f(v)

**Sign against the mixed formulation.** The weak form of equilibrium holds
``- int sigma_nn v_n - int sigma_nt v_t``, the mixed one ``+ Bn^T lam_n + Bt^T lam_t``: the
mixed multipliers are ``lam_n = -sigma_nn`` and ``lam_t = -sigma_nt``. The Nitsche
tractions comparable with them are ``lam_n = -[P_n]_-`` and ``lam_t = -[P_t]_S``
(:func:`tractions`); a sliding point has ``[P_t]_S = -S sign(v)``, i.e. ``lam_t = +S
sign(v)``, the mixed slip law (:mod:`rbbench.hf.algebra.friction`).

Discrete form (points ``q``, ``D = diag(w / gamma)``, ``G = diag(gamma)``; ``T = Snt``,
``U = Ut``; the normal part ``R_n``, ``K_n`` of :mod:`rbbench.hf.algebra.nitsche`)::

    st = T u + snt_lift,  v = U u + ut_lift - ut_prev,  Pt = st - G v,  z = [Pt]_S
    R(u) = R_n(u) - theta T^T D st + (theta T - G U)^T D z
    K(u) = K_n(u) - theta T^T D T + (theta T - G U)^T D (X (T - G U) + Y dS/du)

with ``X = diag(|Pt| < S)`` (stick), ``Y = diag(sign(Pt) (|Pt| >= S))`` (slip); Tresca:
``dS/du = 0``; Coulomb, with ``p = -[P_n]_-`` and ``H = diag(P_n < 0)``::

    dS/du = -F H (S_n - G U_n) + p F'(|u_t|) sign(u_t) U     (F' = 0 for a constant nu_F)

The slip term makes ``K`` non-symmetric for Coulomb (Renard 2013); ``K`` is an element of
the generalised (Newton) Jacobian of the piecewise smooth ``R``.

With ``S = 0`` (``nu_F = 0`` or ``s = 0``) the tangential term is ``-theta T^T D st``: the
condition ``sigma_nt = 0`` imposed by Nitsche, not naturally; it vanishes for ``theta = 0``
only, so ``nu_F = 0`` reproduces the frictionless Nitsche solve exactly for ``theta = 0``
and within the discretisation error otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from rbbench.hf.algebra import friction as fa
from rbbench.hf.algebra import nitsche as nt
from rbbench.interfaces import NitscheFrictionProblem

__all__ = ["FrictionState", "condition_residuals", "point_states", "residual", "state",
           "tangent", "tractions"]


@dataclass
class FrictionState:
    """Point values at a displacement: the normal :class:`~rbbench.hf.algebra.nitsche.
    NitscheState` and the tangential quantities."""

    normal: nt.NitscheState
    st: np.ndarray  # sigma_nt(u) (Pa)
    ut: np.ndarray  # full tangential jump u_t (m)
    slip: np.ndarray  # v = u_t - ut_prev (m)
    Pt: np.ndarray  # P_t(u) = sigma_nt - gamma v
    S: np.ndarray  # the radius of the projection (Pa)
    coefficient: np.ndarray | None  # Coulomb F per point (None: Tresca)

    @property
    def z(self) -> np.ndarray:
        """``[P_t]_S``, the Nitsche shear stress."""
        return np.clip(self.Pt, -self.S, self.S)

    @property
    def stick(self) -> np.ndarray:
        """``|P_t| < S``: the projection is the identity."""
        return np.abs(self.Pt) < self.S


def _law(name: str) -> fa.CoefficientLaw:
    if name not in fa.COEFFICIENT_LAWS:
        raise ValueError(f"coefficient law {name!r} is not known; known: "
                         + ", ".join(map(repr, fa.COEFFICIENT_LAWS)))
    return fa.COEFFICIENT_LAWS[name]


def coefficient(prob: NitscheFrictionProblem, ut: np.ndarray) -> np.ndarray | None:
    """Coulomb ``F`` per point (``None`` for Tresca): ``nu_F``, or the slip law of ``|u_t|``."""
    if prob.law == "tresca":
        return None
    if prob.coefficient_law is not None:
        return np.asarray(_law(prob.coefficient_law).f(np.abs(ut)), float)
    return np.asarray(prob.coefficient, float)


def state(prob: NitscheFrictionProblem, u_free: np.ndarray) -> FrictionState:
    """Point values of the normal and the tangential Nitsche quantities at ``u`` (free dofs)."""
    ns = nt.state(prob, u_free)
    st = prob.Snt @ u_free + prob.snt_lift
    ut = prob.Ut @ u_free + prob.ut_lift
    slip = ut - prob.ut_prev
    F = coefficient(prob, ut)
    S = np.asarray(prob.threshold, float) if F is None else -F * ns.neg
    return FrictionState(ns, st, ut, slip, st - prob.gamma * slip, S, F)


def residual(prob: NitscheFrictionProblem, u_free: np.ndarray,
             fs: FrictionState | None = None) -> np.ndarray:
    """``R(u)`` (module docstring)."""
    fs = state(prob, u_free) if fs is None else fs
    dw = prob.weights / prob.gamma
    th = float(prob.theta)
    tz = dw * fs.z
    r = nt.residual(prob, u_free, fs.normal) + prob.Snt.T @ (th * (tz - dw * fs.st)) \
        - prob.Ut.T @ (prob.gamma * tz)
    return np.asarray(r).ravel()


def tangent(prob: NitscheFrictionProblem, u_free: np.ndarray,
            fs: FrictionState | None = None) -> sp.csr_matrix:
    """``K(u)`` (module docstring): an element of the generalised Jacobian, sparse."""
    fs = state(prob, u_free) if fs is None else fs
    dw = prob.weights / prob.gamma
    th = float(prob.theta)
    G = sp.diags(prob.gamma)
    left = th * prob.Snt - G @ prob.Ut  # P_theta,t
    dPt = prob.Snt - G @ prob.Ut
    K = nt.tangent(prob, u_free, fs.normal) - th * (prob.Snt.T @ sp.diags(dw) @ prob.Snt)
    dz = sp.diags(fs.stick.astype(float)) @ dPt
    if fs.coefficient is not None:
        ys = np.sign(fs.Pt) * ~fs.stick  # d[x]_S / dS on the slip set
        dPn = prob.Snn - G @ prob.Un
        dz = dz + sp.diags(-ys * fs.coefficient * fs.normal.active) @ dPn
        if prob.coefficient_law is not None:
            law = _law(prob.coefficient_law)
            if law.df is not None:
                dF = np.asarray(law.df(np.abs(fs.ut)), float) * np.sign(fs.ut)
                dz = dz + sp.diags(ys * -fs.normal.neg * dF) @ prob.Ut
    return sp.csr_matrix(K + left.T @ sp.diags(dw) @ dz)


def tractions(fs: FrictionState) -> tuple[np.ndarray, np.ndarray]:
    """``(lam_n, lam_t) = (-[P_n]_-, -[P_t]_S)``: the Nitsche tractions with the signs of the
    mixed multipliers (module docstring)."""
    return -fs.normal.neg, -fs.z


def point_states(fs: FrictionState) -> np.ndarray:
    """Per point: ``"open"`` (``P_n >= 0``), ``"stick"`` (``|P_t| < S``), else ``"slip"``:
    the sets of the generalised Newton (no tolerance)."""
    states = np.where(fs.stick, "stick", "slip").astype(object)
    states[~fs.normal.active] = "open"
    return states


def condition_residuals(prob: NitscheFrictionProblem, fs: FrictionState) -> dict[str, float]:
    """Relative residuals of the contact conditions at the points, the definitions of
    :func:`rbbench.hf.algebra.friction.friction_residuals` (same keys) with the gap
    ``d^n - u_n``, the slip ``v`` and the Nitsche tractions (:func:`tractions`) given directly
    (``D = 0``: displacements divided by ``max(|gap|, |v|)``, forces by the largest traction).

    Not zero at the discrete solution: Nitsche imposes the conditions weakly, so they measure
    its consistency error (``O(h)``), like the ``e_AC`` of Benaceur, Drouet, Ehrlacher, Ern &
    Niakh, "Model order reduction methods: parametric variational inequalities" (talk); the
    Newton residual measures the algebraic convergence.
    """
    lam_n, lam_t = tractions(fs)
    g = (fs.normal.P - fs.normal.s) / prob.gamma  # d^n - u_n, from P_n = s - gamma (u_n - d^n)
    m = lam_n.size
    return fa.friction_residuals(np.zeros((2 * m, 2 * m)), np.concatenate([g, -fs.slip]),
                                 lam_n, lam_t, fs.S)

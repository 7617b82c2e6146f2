"""Reduced Nitsche model: POD primal space, DEIM of the contact term at quadrature points.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slides "RB model" (Nitsche): ``u_N = Z c``, a reduced Newton
method
``(A_N + B_N(mu, c_k)) dc = -R_N(mu, c_k)``, and an affine approximation of the
parameter- and iteration-dependent contact arrays so that the online stage does
not depend on the HF size.

**Reduced residual.** With the point quantities of :mod:`rbbench.hf.algebra.nitsche` projected on
``Z`` (``SZ = Snn Z``, ``UZ = Un Z``, ``s = SZ c + s_lift``,
``P = s - gamma (UZ c + u_lift,n - d^n)``, ``dw = w / gamma``)::

    R_N(c) = A_N c - F_N + sum_q y_q(c),
    y_q(c) = dw_q ( [P_q]_- (theta SZ_q - gamma_q UZ_q) - theta s_q SZ_q )   (an N-vector)

``A_N``, ``F_N`` are affine in mu (verified by probing,
:func:`rbbench.rb.algorithms.affine.affine_decomposition`). The sum over all contact quadrature
points is the HF-size-dependent part.

**Hyper-reduction at contact quadrature points.** Online only some points are
evaluated: their rows of ``Un``, ``Snn``, the gap, weights and facet lengths at
mu come from the backend's contact layout restricted to the slave facets of
those points and a window of master facets (:class:`PointEvaluator`, the
machinery of :class:`rbbench.rb.hyper.contact_eim.RowEvaluator`), so nothing scales with the
mesh. Two ways to replace the sum over all points (``ReduceConfig.hyper``):

* ``"auto"`` -> **empirical cubature** (``"ecsw"``, Farhat et al.'s energy-conserving
  sampling and weighting; Hernandez et al. 2017): ``sum_q y_q ~ sum_{q in I} omega_q
  y_q`` with weights ``omega >= 0`` from a sparse non-negative least-squares fit of the
  training sums (:func:`sparse_nnls`, Lawson-Hanson stopped at the tolerance). Each
  selected point contributes its exact (nonlinear) value and tangent, so a moving
  contact edge is integrated, not interpolated; for ``theta = 1`` the reduced
  problem stays the minimisation of a reduced energy (symmetric tangent).
* ``"eim"`` -> **DEIM** of the point contributions (``"deim"``): ``Y(mu, c) =
  [y_q(c)]_q`` (n_q x N, flattened) interpolated by the greedy EIM of
  :func:`rbbench.rb.algorithms.eim.deim`, ``Y ~ Q Q_I^{-1} Y_I`` at ``M`` magic entries
  ``(q_i, n_i)``, so ``sum_q y_q ~ T Q_I^{-1} Y_I`` with ``T = sum_q Q_q``; the
  tangent is the exact derivative of the interpolant. Measured on
  ``hertz_halfdisks`` (level 0, N = 20): validation ``e_EIM`` 16-37 % and 3 of 10
  online Newton solves not converging: ``[P_gamma]_-`` has a kink at the contact
  edge, which moves with mu and c, and an interpolation from a few point values
  generalises badly (as the entrywise EIM of ``B(mu)`` in :mod:`rbbench.rb.hyper.contact_eim`).
  Kept for comparison with Benaceur et al.'s EIM.
* ``"none"`` -> plain: the exact sum over all points online (HF-size dependent).

Why not Benaceur et al.'s entrywise EIM of the HF tangent ``B_gamma(mu, u_k)``: its
entries move with the pairing, and an entry gathers the points of a master dof,
which change with mu; the point contributions are local (one point's pairing
and stress give all its entries).

**Training.** Snapshots of the point contributions are taken at the states the
online solver visits: the iterates of the plain reduced Newton method (exact
sums) from the online start, at the training parameters and at a denser grid of
D (no HF solve is needed there, only the contact operators), plus the projected
HF solutions. The online Newton method starts from the reduced solution at the
nearest training parameter (small arrays stored in the model); the training
iterates use the nearest *other* training parameter, a wider jump. Cold starts
(``c = 0``: no contact, then a deep penetration) are left out: their huge
pressures would set the scale of the relative tolerance. Reported (Benaceur et
al.'s "EIM errors", ratios of maxima over the validation set): ``e_EIM`` of the reduced
contact residual ``r_c = sum_q y_q`` and of its tangent, at every online Newton
iterate and at convergence.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rbbench.hf.algebra.nitsche import gamma_scaling
from rbbench.hf.geometry.chains import normal_stress_terms
from rbbench.hf.geometry.operators import contact_operators
from rbbench.hf.geometry.pairing import ContactLayout
from rbbench.interfaces import HFVectors
from rbbench.rb.algorithms.affine import AffineOperator, LinearInMu
from rbbench.rb.hyper.contact_eim import pair_in_windows, restrict_layout
from rbbench.rb.online import ReducedBasis, require_basis
from rbbench.scene.parameters import ParameterSpace

__all__ = ["NitscheOnlineResult", "NitscheReducedModel", "PointEvaluator", "ReducedPoints",
           "sparse_nnls", "build_point_evaluator", "full_points", "reduced_newton"]


# ---------------------------------------------------------------------------
# point data projected on the primal basis
# ---------------------------------------------------------------------------
@dataclass
class ReducedPoints:
    """Contact data at some quadrature points, projected on ``Z`` (all arrays small).

    ``UZ``, ``SZ`` (n_p, N): ``Un Z``, ``Snn Z``; ``u0``, ``s0`` (n_p,): ``Un u_lift``,
    ``Snn u_lift``; ``gap``, ``w``, ``gamma`` (n_p,).
    """

    UZ: np.ndarray
    SZ: np.ndarray
    u0: np.ndarray
    s0: np.ndarray
    gap: np.ndarray
    w: np.ndarray
    gamma: np.ndarray

    def take(self, idx: np.ndarray) -> ReducedPoints:
        return ReducedPoints(*(getattr(self, f)[idx] for f in
                               ("UZ", "SZ", "u0", "s0", "gap", "w", "gamma")))

    def P(self, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(s, P)`` at the points for ``u = Z c + u_lift``."""
        s = self.SZ @ c + self.s0
        return s, s - self.gamma * (self.UZ @ c + self.u0 - self.gap)

    def contributions(self, c: np.ndarray, theta: float) -> np.ndarray:
        """``Y`` (n_p, N): ``y_q(c)`` of the module docstring."""
        s, P = self.P(c)
        dw = self.w / self.gamma
        a = theta * self.SZ - self.gamma[:, None] * self.UZ
        return dw[:, None] * (np.minimum(P, 0.0)[:, None] * a - theta * s[:, None] * self.SZ)

    def tangent(self, c: np.ndarray, theta: float, weights: np.ndarray | None = None
                ) -> np.ndarray:
        """``sum_q omega_q dy_q / dc`` (N x N), the Heaviside tangent of the point sum
        (``weights = omega``; all ones by default)."""
        _, P = self.P(c)
        dw = self.w / self.gamma if weights is None else weights * self.w / self.gamma
        a = theta * self.SZ - self.gamma[:, None] * self.UZ
        b = self.SZ - self.gamma[:, None] * self.UZ
        return (a * (dw * (P < 0.0))[:, None]).T @ b - theta * (self.SZ * dw[:, None]).T @ self.SZ

    def entries(self, c: np.ndarray, theta: float, pt: np.ndarray, col: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray]:
        """Entries ``Y[pt_i, col_i]`` (M,) and their derivatives ``dY[pt_i, col_i]/dc`` (M, N)."""
        s, P = self.P(c)
        dw = (self.w / self.gamma)[pt]
        g = self.gamma[pt]
        SZ, UZ = self.SZ[pt], self.UZ[pt]
        rows = np.arange(pt.size)
        a_n = theta * SZ[rows, col] - g * UZ[rows, col]
        s_n = SZ[rows, col]
        y = dw * (np.minimum(P[pt], 0.0) * a_n - theta * s[pt] * s_n)
        dy = dw[:, None] * ((P[pt] < 0.0)[:, None] * a_n[:, None] * (SZ - g[:, None] * UZ)
                            - theta * s_n[:, None] * SZ)
        return y, dy


def full_points(layout: ContactLayout, mu: np.ndarray, Zfull: np.ndarray, u_lift: np.ndarray,
                gamma0: float) -> ReducedPoints:
    """All contact points at mu (offline): :func:`~rbbench.hf.geometry.operators.contact_operators`
    with the stress, projected on ``Zfull`` (n_dofs x N, zero rows at Dirichlet dofs)."""
    c = contact_operators(layout, mu, stress=True)
    E = layout.stress.material(mu)[0]
    return ReducedPoints(UZ=np.asarray(c.Un @ Zfull), SZ=np.asarray(c.Snn @ Zfull),
                         u0=np.asarray(c.Un @ u_lift), s0=np.asarray(c.Snn @ u_lift),
                         gap=c.gap, w=c.weights, gamma=gamma_scaling(gamma0, E, c.facet_length))


# ---------------------------------------------------------------------------
# restricted evaluation at the magic points (HF-size independent)
# ---------------------------------------------------------------------------
@dataclass
class PointEvaluator:
    """Rows of ``Un``, ``Snn``, gap, weights, facet lengths at some quadrature points,
    projected on a local basis by :meth:`project`.

    Attributes
    ----------
    layout : ContactLayout
        Restricted: the slave facets of the points (with their :class:`SlaveStress`),
        the master facets of their windows, dofs renumbered ``0 .. n_local - 1``.
    windows : (lo, hi) or None
        Master-facet window of each point of the restricted facets (as in
        :func:`rbbench.rb.hyper.contact_eim.build_row_evaluator`).
    select : (n_p,)
        The requested points among the points of the restricted facets.
    points : (n_p,)
        Their global quadrature indices.
    local_dofs : (n_local,)
        Global dofs behind the local numbering.
    """

    layout: ContactLayout
    windows: tuple[np.ndarray, ...] | None
    select: np.ndarray
    points: np.ndarray
    local_dofs: np.ndarray

    def project(self, mu: np.ndarray, Z_loc: np.ndarray, lift_loc: np.ndarray, gamma0: float
                ) -> ReducedPoints:
        """The points at mu projected on ``Z_loc`` (n_local, N), without forming matrices:
        each row is gathered from its few dofs (O(n_p x dofs per point x N))."""
        p = pair_in_windows(self.layout, mu, self.windows, "a magic point")
        sel = self.select
        terms = [(c[sel], d[sel]) for c, d in p.jump_terms(p.nrm)]
        cs, ds = normal_stress_terms(self.layout.stress, self.layout.slave, self.layout.degree,
                                     p.fq[sel], p.sq[sel], p.nrm[sel], mu)
        UZ = sum(np.einsum("qj,qjn->qn", c, Z_loc[d]) for c, d in terms)
        u0 = sum(np.einsum("qj,qj->q", c, lift_loc[d]) for c, d in terms)
        SZ = np.einsum("qj,qjn->qn", cs, Z_loc[ds])
        s0 = np.einsum("qj,qj->q", cs, lift_loc[ds])
        h = np.linalg.norm(p.b - p.a, axis=1)[p.fq[sel]]
        E = self.layout.stress.material(mu)[0]
        return ReducedPoints(UZ=UZ, SZ=SZ, u0=u0, s0=s0, gap=p.gap[sel], w=p.w[sel],
                             gamma=gamma_scaling(gamma0, E, h))


def build_point_evaluator(layout: ContactLayout, points: np.ndarray, mus: np.ndarray,
                          margin: int = 2) -> PointEvaluator:
    """Restrict ``layout`` to the quadrature ``points`` (global indices, facet-major:
    point ``q`` is Gauss point ``q % n_gauss`` of slave facet ``q // n_gauss``).

    Master windows: the range of master facets each point hits over ``mus`` (a
    dense sample of D), widened by ``margin``; online, a point leaving its window
    raises :class:`~rbbench.rb.hyper.contact_eim.HyperReductionError`.
    """
    points = np.asarray(points, dtype=np.int64)
    ng = layout.n_gauss
    facets = np.unique(points // ng)
    small, windows, local = restrict_layout(layout, facets, mus, margin, with_stress=True)
    select = np.searchsorted(facets, points // ng) * ng + points % ng
    return PointEvaluator(small, windows, select, points, local)


# ---------------------------------------------------------------------------
# reduced Newton
# ---------------------------------------------------------------------------
@dataclass
class NitscheOnlineResult:
    """One reduced solve (a :class:`rbbench.interfaces.Solution`: ``u`` the coordinates
    ``c`` (N,), ``lam`` empty: no multiplier space), iterates, stop reason, time (s)."""

    c: np.ndarray
    iterations: int
    stop_reason: str
    time_s: float
    residuals: list[float] = field(default_factory=list)
    iterates: list[np.ndarray] = field(default_factory=list)
    reason: str = ""
    mu: np.ndarray | None = None

    @property
    def u(self) -> np.ndarray:
        return self.c

    @property
    def lam(self) -> np.ndarray:
        return np.zeros(0)


def reduced_newton(system: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, float]],
                   c0: np.ndarray, max_iter: int = 50, tol: float = 1e-10,
                   keep_iterates: bool = False) -> NitscheOnlineResult:
    """Dense generalised Newton with Armijo backtracking on ``||R||`` (never hangs).

    ``system(c) -> (R, K, scale)``: residual, tangent, and the scale of the relative
    residual ``||R|| / scale``. Stops: ``converged`` (``<= tol``; or ``<= 1e-7`` once
    the residual stops decreasing under full steps: the rounding floor),
    ``max_iterations``, ``stagnation`` (no decrease in 3 successive line searches),
    ``diverged`` (singular tangent), ``nan``.
    """
    t0 = time.perf_counter()
    c = np.array(c0, dtype=float)
    res: list[float] = []
    its: list[np.ndarray] = [c.copy()] if keep_iterates else []
    R, K, scale = system(c)
    fails, flat = 0, 0

    def out(it, reason, why):
        return NitscheOnlineResult(c, it, reason, time.perf_counter() - t0, res, its, why)

    for it in range(max_iter + 1):
        rel = float(np.linalg.norm(R) / max(scale, np.finfo(float).tiny))
        res.append(rel)
        if not np.isfinite(rel):
            return out(it, "nan", "non-finite residual")
        if rel <= tol:
            return out(it, "converged", f"relative residual {rel:.2e}")
        flat = flat + 1 if len(res) > 1 and rel >= 0.1 * res[-2] else 0
        if flat >= 2 and rel <= 1e-7:
            return out(it, "converged", f"relative residual {rel:.2e} at the rounding floor")
        if it == max_iter:
            return out(it, "max_iterations", f"relative residual {rel:.2e}")
        try:
            d = np.linalg.solve(K, -R)
        except np.linalg.LinAlgError:
            return out(it, "diverged", "singular reduced tangent")
        if not np.all(np.isfinite(d)):
            return out(it, "diverged", "singular reduced tangent")
        r0, t = np.linalg.norm(R), 1.0
        for _ in range(31):
            Rn, Kn, sn = system(c + t * d)
            if np.all(np.isfinite(Rn)) and np.linalg.norm(Rn) <= (1.0 - 1e-4 * t) * r0:
                fails = 0
                break
            t *= 0.5
        else:
            fails += 1
            if fails >= 3:
                return out(it, "stagnation", f"no decrease in 3 line searches ({rel:.2e})")
            t = 1.0
            Rn, Kn, sn = system(c + d)
        c = c + t * d
        R, K, scale = Rn, Kn, sn
        if keep_iterates:
            its.append(c.copy())
    return out(max_iter, "max_iterations", "")  # pragma: no cover - the loop returns


def _scale(A: np.ndarray, F: np.ndarray, c: np.ndarray, rc: np.ndarray) -> float:
    return max(np.linalg.norm(F), np.linalg.norm(A @ c), np.linalg.norm(rc))


def _plain_system(A: np.ndarray, F: np.ndarray, rp: ReducedPoints, theta: float,
                  weights: np.ndarray | None = None):
    """``c -> (R, K, scale)`` with the (weighted) sums over the points of ``rp``."""

    def system(c):
        Y = rp.contributions(c, theta)
        rc = Y.sum(axis=0) if weights is None else weights @ Y
        return A @ c - F + rc, A + rp.tangent(c, theta, weights), _scale(A, F, c, rc)

    return system


def sparse_nnls(H: np.ndarray, g: np.ndarray, bb: float, tol: float,
                max_terms: int | None = None) -> tuple[np.ndarray, list[float]]:
    """Sparse non-negative least squares ``min ||G x - b||, x >= 0`` from its Gram data.

    Lawson-Hanson active set, one index added per outer step (the largest
    component of the negative gradient ``G^T (b - G x)``), stopped as soon as
    ``||G x - b|| <= tol ||b||`` or ``max_terms`` indices are used: the empirical
    cubature (ECSW) selection. ``H = G^T G``, ``g = G^T b``, ``bb = b^T b``.
    Returns ``(x, errors)``, ``errors[k]`` the relative residual after step ``k``.
    """
    n = H.shape[0]
    x = np.zeros(n)
    passive = np.zeros(n, dtype=bool)
    max_terms = n if max_terms is None else int(max_terms)
    errors: list[float] = []

    def err(v):
        return float(np.sqrt(max(bb - 2.0 * v @ g + v @ (H @ v), 0.0) / bb))

    gscale = float(np.abs(g).max()) if g.size else 0.0
    for _ in range(3 * n):
        if (errors and errors[-1] <= tol) or passive.sum() >= max_terms:
            break
        w = g - H @ x
        w[passive] = -np.inf
        j = int(np.argmax(w))
        if not w[j] > 1e-14 * gscale:
            break
        passive[j] = True
        for _ in range(3 * n):
            idx = np.flatnonzero(passive)
            z = np.linalg.lstsq(H[np.ix_(idx, idx)], g[idx], rcond=None)[0]
            if np.all(z > 0):
                x[:] = 0.0
                x[idx] = z
                break
            xi = x[idx]
            neg = z <= 0
            alpha = float(np.min(xi[neg] / (xi[neg] - z[neg])))
            x[idx] = xi + alpha * (z - xi)
            drop = idx[x[idx] <= 1e-14 * max(float(x.max()), np.finfo(float).tiny)]
            x[drop] = 0.0
            passive[drop] = False
        errors.append(err(x))
    return x, errors


# ---------------------------------------------------------------------------
# the model
# ---------------------------------------------------------------------------
@dataclass
class NitscheReducedModel:
    """Small dense arrays and picklable maps: :meth:`solve` never touches HF data.

    Attributes
    ----------
    A, F : AffineOperator
        ``A_N``, ``F_N`` on :class:`~rbbench.rb.algorithms.affine.LinearInMu` coefficients.
    coefficients : LinearInMu
    evaluator : PointEvaluator
        The points evaluated online (all contact points for the plain model).
    Z_loc : (n_local, N)
        The primal basis on the evaluator's local dofs (zero at Dirichlet dofs).
    lift_loc : (n_local,)
        The Dirichlet lifting there.
    theta, gamma0 : float
        The Nitsche formulation's parameters.
    mode : {"ecsw", "deim", "none"}
        Hyper-reduction (module docstring).
    omega : (n_p,) or None
        ECSW weights of the evaluator's points (``None``: all ones, plain).
    entry_pt, entry_col, TQinv
        DEIM: magic entries ``(point of the evaluator, column of Z)`` and ``T Q_I^{-1}``
        (N x M).
    start_mus, start_c : (P, p), (P, N)
        Reduced solutions at the training parameters (the online initial guess).
    info : dict
    parameters : ParameterSpace or None
        The domain D that :meth:`solve` checks mu against (set by the offline skeleton).
    basis : ReducedBasis or None
        The primal basis on the free dofs (HF size), for :meth:`reconstruct` only.
    """

    A: AffineOperator
    F: AffineOperator
    coefficients: LinearInMu
    evaluator: PointEvaluator
    Z_loc: np.ndarray
    lift_loc: np.ndarray
    theta: float
    gamma0: float
    mode: str
    start_mus: np.ndarray
    start_c: np.ndarray
    omega: np.ndarray | None = None
    entry_pt: np.ndarray | None = None
    entry_col: np.ndarray | None = None
    TQinv: np.ndarray | None = None
    info: dict = field(default_factory=dict)
    parameters: ParameterSpace | None = None
    basis: ReducedBasis | None = None

    @property
    def N(self) -> int:
        return int(self.Z_loc.shape[1])

    @property
    def R(self) -> int:  # no dual space
        return 0

    def points(self, mu: np.ndarray) -> ReducedPoints:
        """The evaluator's points at mu, projected on the local basis."""
        return self.evaluator.project(mu, self.Z_loc, self.lift_loc, self.gamma0)

    def system(self, mu: np.ndarray):
        """``(A_N, F_N, c -> (R, K, scale))`` at mu (the online arrays)."""
        th = self.coefficients(mu)
        A, F = self.A(th), self.F(th)
        rp = self.points(mu)
        if self.mode != "deim":
            return A, F, _plain_system(A, F, rp, self.theta, self.omega)
        pt, col, TQ, theta = self.entry_pt, self.entry_col, self.TQinv, self.theta

        def system(c):
            y, dy = rp.entries(c, theta, pt, col)
            rc = TQ @ y
            return A @ c - F + rc, A + TQ @ dy, _scale(A, F, c, rc)

        return A, F, system

    def initial_guess(self, mu: np.ndarray) -> np.ndarray:
        """The reduced solution at the nearest training parameter."""
        d = np.linalg.norm(self.start_mus - np.atleast_1d(mu)[None, :], axis=1)
        return self.start_c[int(np.argmin(d))].copy()

    def solve(self, mu: np.ndarray, c0: np.ndarray | None = None, max_iter: int = 50,
              tol: float = 1e-10, keep_iterates: bool = False) -> NitscheOnlineResult:
        """Online solve: check mu against D (:attr:`parameters`; a
        :class:`~rbbench.scene.parameters.SceneError` outside it, as the HF solve), evaluate
        the points at mu, then :func:`reduced_newton`."""
        t0 = time.perf_counter()
        mu = (np.atleast_1d(np.asarray(mu, dtype=float)) if self.parameters is None
              else self.parameters.check(mu))
        _, _, system = self.system(mu)
        res = reduced_newton(system, self.initial_guess(mu) if c0 is None else c0,
                             max_iter=max_iter, tol=tol, keep_iterates=keep_iterates)
        res.time_s = time.perf_counter() - t0
        res.mu = mu
        return res

    def reconstruct(self, solution: NitscheOnlineResult) -> HFVectors:
        """``Z c`` on the free dofs; no multipliers (the contact pressure follows from u)."""
        return require_basis(self).vectors(solution.c)

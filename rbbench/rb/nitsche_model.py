"""Reduced Nitsche model: POD primal space, DEIM of the contact term at quadrature points.

Seed 000, slides "RB model" (Nitsche): ``u_N = Z c``, a reduced Newton method
``(A_N + B_N(mu, c_k)) dc = -R_N(mu, c_k)``, and an affine approximation of the
parameter- and iteration-dependent contact arrays so that the online stage does
not depend on the HF size.

**Reduced residual.** With the point quantities of :mod:`rbbench.hf.nitsche_algebra` projected on
``Z`` (``SZ = Snn Z``, ``UZ = Un Z``, ``s = SZ c + s_lift``,
``P = s - gamma (UZ c + u_lift,n - d^n)``, ``dw = w / gamma``)::

    R_N(c) = A_N c - F_N + sum_q y_q(c),
    y_q(c) = dw_q ( [P_q]_- (theta SZ_q - gamma_q UZ_q) - theta s_q SZ_q )   (an N-vector)

``A_N``, ``F_N`` are affine in mu (verified by probing,
:func:`rbbench.rb.mixed_model.affine_decomposition`). The sum over all contact quadrature
points is the HF-size-dependent part.

**Hyper-reduction at contact quadrature points.** Online only some points are
evaluated: their rows of ``Un``, ``Snn``, the gap, weights and facet lengths at
mu come from the backend's contact layout restricted to the slave facets of
those points and a window of master facets (:class:`PointEvaluator`, the
machinery of :class:`rbbench.rb.contact_eim.RowEvaluator`), so nothing scales with the
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
  :func:`rbbench.rb.eim.deim`, ``Y ~ Q Q_I^{-1} Y_I`` at ``M`` magic entries
  ``(q_i, n_i)``, so ``sum_q y_q ~ T Q_I^{-1} Y_I`` with ``T = sum_q Q_q``; the
  tangent is the exact derivative of the interpolant. Measured on
  ``hertz_halfdisks`` (level 0, N = 20): validation ``e_EIM`` 16-37 % and 3 of 10
  online Newton solves not converging: ``[P_gamma]_-`` has a kink at the contact
  edge, which moves with mu and c, and an interpolation from a few point values
  generalises badly (as the entrywise EIM of ``B(mu)`` in :mod:`rbbench.rb.contact_eim`).
  Kept for comparison with the seed's EIM.
* ``"none"`` -> plain: the exact sum over all points online (HF-size dependent).

Why not the seed's entrywise EIM of the HF tangent ``B_gamma(mu, u_k)``: its
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
pressures would set the scale of the relative tolerance. Reported (the seed's
"EIM errors", ratios of maxima over the validation set): ``e_EIM`` of the reduced
contact residual ``r_c = sum_q y_q`` and of its tangent, at every online Newton
iterate and at convergence.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from rbbench.hf.contact_geometry import ContactLayout, contact_operators, normal_stress_terms
from rbbench.hf.nitsche_algebra import gamma_scaling, pressure, state
from rbbench.rb.contact_eim import HyperReductionError, pair_in_windows, restrict_layout
from rbbench.rb.eim import deim
from rbbench.rb.mixed_model import AffineOperator, LinearInMu, NotAffineError, affine_decomposition

__all__ = ["NitscheOnlineResult", "NitscheReducedModel", "PointEvaluator", "ReducedPoints",
           "sparse_nnls",
           "build_point_evaluator", "full_points", "reduce_nitsche", "reduced_newton"]


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
    """All contact points at mu (offline): :func:`~rbbench.hf.contact_geometry.contact_operators`
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
        :func:`rbbench.rb.contact_eim.build_row_evaluator`).
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
    raises :class:`~rbbench.rb.contact_eim.HyperReductionError`.
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
    """One reduced solve: coordinates ``c`` (N,), iterates, stop reason, time (s)."""

    c: np.ndarray
    iterations: int
    stop_reason: str
    time_s: float
    residuals: list[float] = field(default_factory=list)
    iterates: list[np.ndarray] = field(default_factory=list)
    reason: str = ""


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
        ``A_N``, ``F_N`` on :class:`~rbbench.rb.mixed_model.LinearInMu` coefficients.
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
        """Online solve: evaluate the points at mu, then :func:`reduced_newton`."""
        t0 = time.perf_counter()
        mu = np.atleast_1d(np.asarray(mu, dtype=float))
        _, _, system = self.system(mu)
        res = reduced_newton(system, self.initial_guess(mu) if c0 is None else c0,
                             max_iter=max_iter, tol=tol, keep_iterates=keep_iterates)
        res.time_s = time.perf_counter() - t0
        return res


# ---------------------------------------------------------------------------
# offline stage
# ---------------------------------------------------------------------------
DEFINITIONS = {
    "err_u": "relative error ||u - u_N||_X / ||u||_X per validation mu (X: the scene's V inner "
             "product on free dofs; u: the HF Nitsche solution); *_max / *_mean over the "
             "validation set (the seed's e_N^u)",
    "err_lam": "Nitsche: relative L2(Gamma_c) error of the contact pressure -[P_gamma]_- at the "
               "quadrature points, ||p(u) - p(u_N)|| / ||p(u)|| (the Nitsche multiplier)",
    "err_snn": "the seed's e_N^nn: ||sigma_nn(u) - sigma_nn(u_N)|| / ||sigma_nn(u)|| in "
               "L2(Gamma_c) (contact quadrature), per validation mu",
    "penetration": "largest pointwise penetration max_q (Un u_N - gap)_+ (m) per validation mu",
    "energy_err": "|J(u_N) - J(u)| / |J(u)|, J = 1/2 a(u, u) - f(u) (the seed's HF energy)",
    "t_online": "wall time of one online solve: evaluate the hyper-reduction points at mu "
                "(pairing restricted to their facets), reduced Newton from the nearest "
                "training solution; median and IQR over validation mus x repeats (s)",
    "speedup": "median HF Nitsche Newton solve time (discretise + formulate + solve) / median "
               "online time",
    "eim_error": "training error of the hyper-reduction after each added term: ECSW: relative "
                 "l2 residual of the weighted training sums; DEIM: greedy EIM relative max-norm "
                 "error of the point contributions (ratio of maxima)",
    "eim": "rows: points evaluated online; e_eim_valid: the seed's e_EIM of the reduced "
           "contact residual r_c = sum_q y_q over the validation set and every online Newton "
           "iterate (max over mu and k of ||r_c - r_c^hyper||_inf / max of ||r_c||_inf); "
           "e_eim_cv_valid: at convergence only; *_by_iteration: per iteration index; "
           "e_eim_tangent_*: the same for the reduced contact tangent dr_c/dc (N x N)",
    "err_u_plain": "err_u of the plain reduced model (exact sums over all contact points, "
                   "no hyper-reduction), per validation mu: the floor for this V_N",
}


#: Default cap on the empirical cubature points, per primal mode (``m_eim`` overrides).
#: With a tolerance only, the NNLS keeps adding points as the mesh is refined (hertz,
#: N = 20, tol 1e-4: 221 points at level 0, 435 at level 1) while err_u is already at the
#: plain model's floor; with 6 N = 120 points err_u_max is 1.0e-4 / 1.4e-4 at levels 0 / 1
#: (plain: 8.9e-5 / 5.6e-5) and the online time stays flat (measured, README "Nitsche").
ECSW_POINTS_PER_MODE = 6


def _nearest_other(mus: np.ndarray) -> np.ndarray:
    d = np.linalg.norm(mus[:, None, :] - mus[None, :, :], axis=2)
    np.fill_diagonal(d, np.inf)
    return np.argmin(d, axis=1)


def reduce_nitsche(scene: Any, config: Any, progress: Callable[[str], None] = lambda m: None,
                   snapshot_progress: bool = False, registry: Any = None) -> Any:
    """Offline stage of the reduced Nitsche model and its online validation.

    ``config`` is a :class:`rbbench.rb.offline.ReduceConfig` (``primal``, ``N``,
    ``tol_pod``, ``hyper``, ``tol_eim``, ``m_eim``, ``n_eim_train``, sizes, cache,
    ``online_repeats``); the dual / stabiliser fields do not apply. ``hyper``:
    ``"auto"``: empirical cubature at the contact points (``"ecsw"``, tolerance
    ``tol_eim`` on the relative residual of the training sums, at most ``m_eim``
    points, default :data:`ECSW_POINTS_PER_MODE` ``* N``); ``"eim"``: DEIM of the
    point contributions (``"deim"``); ``"none"``:
    plain. A solver that does not solve Nitsche (e.g. the default ``ssn``) is
    replaced by the formulation's (``newton``). Returns a
    :class:`rbbench.rb.offline.ReduceResult`.
    """
    from rbbench.hf.model import ProblemCache, default_solver, make_components
    from rbbench.rb.offline import (
        DivergedError,
        ReduceResult,
        _check_finite,
        _xn,
        eim_grid,
        fixed_contact_points,
        primal_basis,
        training_snapshots,
    )
    from rbbench.registry import default_registry

    reg = registry or default_registry()
    if config.hyper == "affine":
        raise ValueError("hyper 'affine': the Nitsche contact term is nonlinear; use 'auto' "
                         "(empirical cubature), 'eim' (DEIM) or 'none' (plain)")
    fixed_contact_points(scene, config.hyper, plain_ok=False)
    solver = config.solver
    if "nitsche" not in reg.get("solver", solver).capabilities.get("formulations", ()):
        solver = default_solver("nitsche", reg)
        config = replace(config, solver=solver)
    reg.get("primal", config.primal)
    t0 = time.perf_counter()
    timings: dict[str, float] = {}
    mus_train, train, valid = training_snapshots(scene, config, "nitsche", solver, progress,
                                                 snapshot_progress, reg)
    mus_valid = valid.mus
    timings["snapshots_s"] = time.perf_counter() - t0

    b, f, _ = make_components(scene, config.backend, "nitsche", solver, registry=reg,
                              component_options=config.component_options)
    if not hasattr(b, "contact_layout"):
        raise ValueError(f"backend {config.backend!r} provides no contact layout: the reduced "
                         "Nitsche model evaluates the contact points from it")
    layout = b.contact_layout()
    problem_at = ProblemCache(b, f)
    p0 = problem_at(scene.default_mu)
    X = problem_at.X_free(scene.default_mu)
    theta, gamma0 = float(f.theta), float(f.gamma0)

    t1 = time.perf_counter()
    primal = primal_basis(reg, config, train.U, X, progress)
    Z = primal.Z
    N = Z.shape[1]
    Zfull = np.zeros((p0.u_lift.size, N))
    Zfull[p0.free] = Z
    u_lift = p0.u_lift
    timings["primal_s"] = time.perf_counter() - t1

    t1 = time.perf_counter()
    progress("affine decomposition of A_N, F_N (verified by probing)")
    try:  # problem_at caches the HF problem at each probe
        A_op = AffineOperator(affine_decomposition(lambda mu: Z.T @ (problem_at(mu).A @ Z),
                                                   scene.bounds))
        F_op = AffineOperator(affine_decomposition(lambda mu: Z.T @ problem_at(mu).F,
                                                   scene.bounds))
    except NotAffineError as exc:
        raise ValueError(f"reduced Nitsche model: A_N or F_N is {exc}") from None
    coef = LinearInMu(np.asarray(scene.bounds).shape[0])
    timings["affine_s"] = time.perf_counter() - t1

    # ---- plain reduced Newton iterates: the hyper-reduction's training data ----
    t1 = time.perf_counter()
    grid = eim_grid(scene, config, len(mus_train), per_interval=2)
    c_hf_train = (Z.T @ (X @ train.U)).T  # projections (X-orthonormal Z), (P, N)
    plain_c = np.zeros_like(c_hf_train)
    progress(f"plain reduced Newton on {len(mus_train)} training + {len(grid)} grid parameters")
    Ysnap: list[np.ndarray] = []  # point contributions (n_q, N) per training state
    plain_stops: dict[str, int] = {}

    def plain_solve(mu, c0):
        th = coef(mu)
        rp = full_points(layout, mu, Zfull, u_lift, gamma0)
        res = reduced_newton(_plain_system(A_op(th), F_op(th), rp, theta), c0,
                             keep_iterates=True)
        plain_stops[res.stop_reason] = plain_stops.get(res.stop_reason, 0) + 1
        return res, rp

    near = _nearest_other(mus_train) if len(mus_train) > 1 else np.zeros(1, dtype=int)
    for j, mu in enumerate(mus_train):
        res, rp = plain_solve(mu, c_hf_train[near[j]])
        plain_c[j] = res.c
        Ysnap.extend(rp.contributions(c, theta) for c in res.iterates)
        Ysnap.append(rp.contributions(c_hf_train[j], theta))
    for mu in grid:
        k = int(np.argmin(np.linalg.norm(mus_train - mu, axis=1)))
        res, rp = plain_solve(mu, plain_c[k])
        Ysnap.extend(rp.contributions(c, theta) for c in res.iterates)
    for Y in Ysnap:
        _check_finite("Nitsche hyper-reduction snapshots", Y)
    timings["plain_training_s"] = time.perf_counter() - t1

    t1 = time.perf_counter()
    hyper = {"none": "none", "eim": "deim"}.get(config.hyper, "ecsw")
    nq = layout.slave.n * layout.n_gauss
    histories: dict[str, Any] = {
        "pod_singular_values": primal.history.get("singular_values", []),
        "primal": {k: v for k, v in primal.history.items() if k != "singular_values"},
        "plain_training_stops": plain_stops}
    sample = np.vstack([mus_train, grid, mus_valid])
    extra: dict[str, Any] = {}
    if hyper == "ecsw":
        progress("empirical cubature (ECSW) at the contact points")
        H = np.zeros((nq, nq))
        g = np.zeros(nq)
        n_sums = 0  # b^T b: each non-zero training sum is scaled to norm 1
        for Y in Ysnap:  # rows of G: the N entries of one training sum, scaled to norm 1
            bj = Y.sum(axis=0)
            nb = float(np.linalg.norm(bj))
            n_sums += nb > 0
            sc = nb or 1.0
            H += (Y @ Y.T) / sc**2
            g += (Y @ bj) / sc**2
        bb = float(n_sums) or 1.0
        cap = config.m_eim or ECSW_POINTS_PER_MODE * N
        omega, errors = sparse_nnls(H, g, bb, tol=config.tol_eim, max_terms=cap)
        pts = np.flatnonzero(omega > 0)
        if pts.size == 0:
            raise HyperReductionError("ECSW selected no point: the contact sums are zero")
        ev = build_point_evaluator(layout, pts, sample)
        extra["omega"] = omega[pts]
        histories["eim_error"] = errors
        histories["eim"] = {"method": "ecsw", "rows": int(pts.size), "M": int(pts.size),
                            "tol": config.tol_eim, "max_points": int(cap),
                            "e_train": float(errors[-1]),
                            "weights_sum_over_all": float(omega.sum() / nq)}
    elif hyper == "deim":
        progress("DEIM of the contact point contributions")
        eim = deim(np.stack([Y.ravel() for Y in Ysnap], axis=1), tol=config.tol_eim,
                   m_max=config.m_eim)
        if eim.m == 0:
            raise HyperReductionError("DEIM found no term: the contact contributions are zero")
        e_pt, e_col = np.divmod(eim.magic, N)
        pts = np.unique(e_pt)
        ev = build_point_evaluator(layout, pts, sample)
        T = eim.Q.reshape(nq, N, eim.m).sum(axis=0)  # (N, M)
        extra.update(entry_pt=np.searchsorted(pts, e_pt), entry_col=e_col,
                     TQinv=T @ np.linalg.inv(eim.Q[eim.magic]))
        histories["eim_error"] = eim.errors.tolist()
        histories["eim"] = {"method": "deim", "rows": int(pts.size), "M": int(eim.m),
                            "tol": config.tol_eim, "e_train": float(eim.errors[-1])}
    else:
        ev = build_point_evaluator(layout, np.arange(nq), sample)
        histories["eim"] = {"method": "none", "rows": int(nq), "M": None}
    histories["eim"].update({"n_train_states": len(Ysnap),
                             "n_train_mus": int(len(grid) + len(mus_train)),
                             "n_local_dofs": int(ev.local_dofs.size),
                             "master_facets": 0 if ev.layout.master is None
                             else int(ev.layout.master.n)})
    del Ysnap
    model = NitscheReducedModel(A=A_op, F=F_op, coefficients=coef, evaluator=ev,
                                Z_loc=np.ascontiguousarray(Zfull[ev.local_dofs]),
                                lift_loc=u_lift[ev.local_dofs].copy(), theta=theta,
                                gamma0=gamma0, mode=hyper,
                                start_mus=np.asarray(mus_train, dtype=float),
                                start_c=plain_c.copy(),
                                info={"N": N, "hyper": hyper, "theta": theta,
                                      "gamma0": gamma0}, **extra)
    timings["hyper_s"] = time.perf_counter() - t1
    timings["offline_s"] = time.perf_counter() - t0

    # ---- online validation ----
    progress("online validation")
    err_u, err_p, err_s, pen, e_en, t_on, err_plain = [], [], [], [], [], [], []
    stops: dict[str, int] = {}
    iters: list[int] = []
    num_k: dict[int, float] = {}
    acc = {"den": 0.0, "num_cv": 0.0, "den_cv": 0.0, "num_t": 0.0, "den_t": 0.0,
           "num_tcv": 0.0, "den_tcv": 0.0}
    for j, mu in enumerate(valid.mus):
        p = problem_at(mu)
        u = valid.U[:, j]
        runs = []
        for _ in range(max(1, config.online_repeats)):
            res = model.solve(mu)
            runs.append(res.time_s)
        t_on.extend(runs)
        stops[res.stop_reason] = stops.get(res.stop_reason, 0) + 1
        iters.append(res.iterations)
        if not np.all(np.isfinite(res.c)):
            raise DivergedError(f"online Nitsche solve at mu = {mu.tolist()}: non-finite "
                                f"({res.stop_reason})")
        uN = Z @ res.c
        err_u.append(float(np.sqrt(_xn(X, u - uN) / _xn(X, u))))
        w = p.weights
        pu, pN = pressure(p, u), pressure(p, uN)
        err_p.append(_l2rel(w, pu - pN, pu))
        su, sN = state(p, u).s, state(p, uN).s
        err_s.append(_l2rel(w, su - sN, su))
        pen.append(float(max(0.0, np.max(p.Un @ uN - p.gap))))
        J = 0.5 * u @ (p.A @ u) - p.F @ u
        JN = 0.5 * uN @ (p.A @ uN) - p.F @ uN
        e_en.append(float(abs(JN - J) / abs(J)) if J != 0 else float("nan"))
        # the plain model and the seed's e_EIM along the online iterates
        rp = full_points(layout, mu, Zfull, u_lift, gamma0)
        th = coef(mu)
        exact = _plain_system(A_op(th), F_op(th), rp, theta)
        plain = reduced_newton(exact, model.initial_guess(mu))
        err_plain.append(float(np.sqrt(_xn(X, u - Z @ plain.c) / _xn(X, u))))
        walk = model.solve(mu, keep_iterates=True).iterates
        A_mu, F_mu, system = model.system(mu)
        for k, c in enumerate(walk):
            Rx, Kx, _ = exact(c)
            Rh, Kh, _ = system(c)
            e_r, m_r = float(np.abs(Rx - Rh).max()), float(np.abs(Rx - A_mu @ c + F_mu).max())
            e_t, m_t = float(np.abs(Kx - Kh).max()), float(np.abs(Kx - A_mu).max())
            num_k[k] = max(num_k.get(k, 0.0), e_r)
            acc["den"] = max(acc["den"], m_r)
            acc["num_t"], acc["den_t"] = max(acc["num_t"], e_t), max(acc["den_t"], m_t)
            if k == len(walk) - 1:
                acc["num_cv"], acc["den_cv"] = max(acc["num_cv"], e_r), max(acc["den_cv"], m_r)
                acc["num_tcv"] = max(acc["num_tcv"], e_t)
                acc["den_tcv"] = max(acc["den_tcv"], m_t)

    def ratio(a, b_):
        return float(a / b_) if b_ > 0 else 0.0

    histories["eim"].update({
        "e_eim_valid": ratio(max(num_k.values(), default=0.0), acc["den"]),
        "e_eim_cv_valid": ratio(acc["num_cv"], acc["den_cv"]),
        "e_eim_valid_by_iteration": [ratio(num_k[k], acc["den"]) for k in sorted(num_k)],
        "e_eim_tangent_valid": ratio(acc["num_t"], acc["den_t"]),
        "e_eim_tangent_cv_valid": ratio(acc["num_tcv"], acc["den_tcv"])})
    histories["online_stops"] = stops
    histories["online_iterations"] = iters
    histories["err_u_plain"] = err_plain
    histories["err_snn"] = err_s
    histories["formulation"] = {"name": "nitsche", "theta": theta, "gamma0": gamma0}
    timings["total_s"] = time.perf_counter() - t0
    cfg = asdict(config)
    cfg.update(formulation="nitsche", solver=solver, dual=None, stabilizer=None)
    return ReduceResult(
        scene=scene.name, config=cfg, N=N, R=0, K_pga=0, hyper=hyper,
        n_train=len(mus_train), n_valid=len(mus_valid), n_hf_dofs=int(train.n_dofs),
        n_contact=int(nq), err_u=err_u, err_lam=err_p, penetration=pen, complementarity=[],
        energy_err=e_en, beta={}, t_online=t_on,
        t_hf=[float(t) for t in np.concatenate([train.times, valid.times])],
        timings=timings, histories=histories, definitions=DEFINITIONS, model=model,
        valid_mus=np.asarray(valid.mus))


def _l2rel(w: np.ndarray, diff: np.ndarray, ref: np.ndarray) -> float:
    d = float(np.sqrt(np.sum(w * ref**2)))
    return float(np.sqrt(np.sum(w * diff**2)) / d) if d > 0 else 0.0

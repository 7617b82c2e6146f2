"""The subproblem of the bundle trust-region method in a variable metric, and the metric.

:func:`solve_subproblem` solves ``min v + d'Md/(2t)`` s.t. ``v >= g_j.d - alpha_j`` and
``x + d`` in the polyhedron by daqp; ``M = I`` (``metric="identity"``) is Schramm-Zowe's
BT subproblem, a positive definite ``M`` the variable metric bundle subproblem of
Lemarechal and Sagastizabal (1997, Math. Prog. 76:393-410) and Vlcek and Luksan (2001,
JOTA 111:407-430). :class:`VariableMetric` keeps ``M``: a damped BFGS matrix updated at
serious steps (Powell 1978 damping), its eigenvalues kept in ``[m_min, m_max]``.
``M`` is dimensionless: it is the Hessian approximation of the normalised ``f`` times the
unit of ``t`` (``|g_0|^-2``, see :mod:`rbbench.optim.bundle`), so ``M = I`` is the identity
metric and, with the Hessian ``B`` of ``f`` learnt, ``t = 1`` gives the quasi-Newton step.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rbbench.optim.polyhedron import Polyhedron

_INF = 1e30  # daqp's infinity


@dataclass
class Subproblem:
    """Solution of the BT subproblem at trust parameter ``t`` (normalised units)."""

    d: np.ndarray
    v: float
    lam: np.ndarray  # multipliers of the cuts (sum 1)
    t: float
    kkt: float = math.nan
    ok: bool = True
    message: str = ""
    Md: np.ndarray | None = None  # M d (None: M = I)

    @property
    def pred(self) -> float:  # predicted decrease -v >= 0
        return -self.v

    @property
    def agg_norm(self) -> float:
        """``|s| = |M d| / t``: the aggregate subgradient plus its normal-cone part."""
        return float(np.linalg.norm(self.d if self.Md is None else self.Md)) / self.t


def _subproblem_data(x: np.ndarray, t: float, G: np.ndarray, alpha: np.ndarray,
                     poly: Polyhedron, sigma: float,
                     M: np.ndarray | None = None) -> tuple[np.ndarray, ...]:
    """daqp's ``(H, f, A, bupper, blower)`` of the BT subproblem in the scaled variables
    ``z = (d / a, v / sigma)``, ``a = sqrt(sigma t)``: ``min z_v + z_d'M z_d / 2`` s.t.
    ``(a / sigma) g_j.z_d - z_v <= alpha_j / sigma`` and the polyhedron, so that a model
    decrease of order ``sigma`` gives an O(1) problem for daqp's absolute tolerances.
    The first ``n + 1`` bounds are simple bounds on ``z``, then the rows of C, then the
    cuts; general rows scaled to unit norm. Also returns the row norms and ``a``."""
    n, m, mc = x.size, G.shape[0], poly.C.shape[0]
    a = math.sqrt(sigma * t)
    H, f = np.diag(np.r_[np.ones(n), 0.0]), np.r_[np.zeros(n), 1.0]
    if M is not None:
        H[:n, :n] = M
    A = np.vstack([np.hstack([poly.C, np.zeros((mc, 1))]),
                   np.hstack([(a / sigma) * G, -np.ones((m, 1))])])
    rows = np.linalg.norm(A, axis=1)
    rows[rows == 0.0] = 1.0
    Cx = poly.C @ x
    scale = np.r_[np.full(n, a), 1.0, rows[:mc] * a, rows[mc:] * sigma]
    up = np.concatenate([poly.ub - x, [math.inf], poly.cu - Cx, alpha]) / scale
    lo = np.concatenate([poly.lb - x, [-math.inf], poly.cl - Cx, np.full(m, -math.inf)]) / scale
    return (H, f, np.ascontiguousarray(A / rows[:, None]), np.minimum(up, _INF),
            np.maximum(lo, -_INF), rows, a)


def kkt_residual(H: np.ndarray, f: np.ndarray, A: np.ndarray, up: np.ndarray,
                 lo: np.ndarray, z: np.ndarray, lam: np.ndarray) -> float:
    """Largest violation of the KKT conditions of ``min z'Hz/2 + f'z``,
    ``lo <= [I; A] z <= up`` at ``(z, lam)`` (lam > 0 on upper, < 0 on lower bounds):
    stationarity, primal feasibility and complementarity: an optimality certificate
    that does not trust the solver's exit flag."""
    Af = np.vstack([np.eye(z.size), A])
    Az = Af @ z
    stat = np.abs(H @ z + f + Af.T @ lam).max()
    feas = max(float(np.max(Az - up)), float(np.max(lo - Az)), 0.0)
    slack = np.where(lam > 0, up - Az, np.where(lam < 0, Az - lo, 0.0))
    comp = float(np.max(np.abs(lam * slack)))
    return float(max(stat, feas, comp))


#: daqp settings tried in turn: its proximal-point iterations (eps_prox > 0) for the zero
#: Hessian block of v, tolerances loosened only if a tighter try fails. Measured on 4117
#: subproblems of the test problems: eps_prox = 1e-6 cycled (exit -2) 13 times, eps_prox = 1
#: never, KKT residuals <= 2e-12; near-parallel cuts at 1e-10 of the optimum need 1e-10.
_DAQP_TRIES = tuple({"eps_prox": e, "eta_prox": eta, "primal_tol": tol, "dual_tol": tol}
                    for e, eta, tol in ((1.0, 1e-12, 1e-12), (1.0, 1e-12, 1e-10),
                                        (0.1, 1e-9, 1e-9), (-1e-6, -1.0, 1e-9)))
#: largest violation of the polyhedron accepted at a trial point
FEAS_TOL = 1e-9


def solve_subproblem(x: np.ndarray, t: float, G: np.ndarray, alpha: np.ndarray,
                     poly: Polyhedron, sigma: float = 1.0,
                     M: np.ndarray | None = None) -> Subproblem:
    """``min v + d'Md/(2t)`` s.t. ``G d - v <= alpha``, ``x + d`` in ``poly``, by daqp.

    ``M`` symmetric positive definite (None: the identity). ``sigma`` is the expected size
    of ``-v`` (the problem is scaled by it, see :func:`_subproblem_data`). The Hessian is
    singular in ``v``: daqp's proximal option (``eps_prox > 0``) handles it; the next
    setting of :data:`_DAQP_TRIES` is tried if daqp fails or ``x + d`` violates ``poly``
    by more than :data:`FEAS_TOL`. The cut multipliers sum to one at an exact solution;
    ``kkt`` is :func:`kkt_residual` of the scaled problem (in units of ``sigma``).
    """
    import daqp

    n, mc = x.size, poly.C.shape[0]
    H, f, A, up, lo, rows, a = _subproblem_data(x, t, G, alpha, poly, sigma, M)
    sense = np.zeros(up.size, dtype=np.int32)
    flags = []
    for settings in _DAQP_TRIES:
        z, _, flag, info = daqp.solve(H, f, A, up, lo, sense, **settings)
        z, lam = np.asarray(z, dtype=float), np.asarray(info["lam"], dtype=float)
        ok = int(flag) == 1 and np.isfinite(z).all() and np.isfinite(lam).all()
        d = a * z[:n]
        flags.append(int(flag) if not ok or poly.is_feasible(x + d, FEAS_TOL) else "infeasible")
        if flags[-1] == 1:
            return Subproblem(d=d, v=sigma * float(z[n]), lam=lam[n + 1 + mc:] / rows[mc:],
                              t=t, kkt=kkt_residual(H, f, A, up, lo, z, lam),
                              Md=None if M is None else M @ d)
    return Subproblem(d=np.zeros(n), v=0.0, lam=np.zeros(G.shape[0]), t=t, ok=False,
                      message=f"daqp exit flags {flags}")


class VariableMetric:
    """The metric ``M`` of the subproblem: ``None`` (identity) or damped BFGS.

    :meth:`update` after a serious step ``s = x_{k+1} - x_k`` with the subgradient
    difference ``y = g_{k+1} - g_k`` at the two centres (Vlcek-Luksan 2001, serious-step
    BFGS update), in the units of ``M`` (``y`` times the unit of ``t``):

    * first update: ``M = (y'y / s'y) I`` (Shanno-Phua scaling, Nocedal-Wright eq. 6.20)
      if ``s'y > 0``;
    * Powell's damping: if ``s'y < 0.2 s'Ms``, ``y <- theta y + (1 - theta) M s`` with
      ``theta = 0.8 s'Ms / (s'Ms - s'y)``, so that ``s'y >= 0.2 s'Ms > 0`` and ``M`` stays
      positive definite (Nocedal-Wright, procedure 18.2);
    * BFGS: ``M <- M - Ms s'M / s'Ms + y y' / s'y``;
    * safeguard: eigenvalues clipped to ``[m_min, m_max]`` (counted in ``clips``), the
      bounded-metric assumption of Lemarechal-Sagastizabal (1997) and Vlcek-Luksan (2001)
      under which the stopping test and the convergence theory of BT carry over.
    """

    def __init__(self, n: int, kind: str = "identity", m_min: float = 1e-4,
                 m_max: float = 1e8) -> None:
        if kind not in ("identity", "bfgs"):
            raise ValueError(f"metric {kind!r}: valid are 'identity', 'bfgs'")
        self.kind, self.m_min, self.m_max = kind, m_min, m_max
        self.M = None if kind == "identity" else np.eye(n)
        self.updates = self.skips = self.clips = 0

    def update(self, s: np.ndarray, y: np.ndarray) -> None:
        """Damped BFGS update with the step ``s`` and subgradient change ``y`` (M's units);
        skipped (counted in ``skips``) if ``s`` is negligible or the data non-finite."""
        if self.M is None:
            return
        if not (np.isfinite(s).all() and np.isfinite(y).all()) or not s @ s > 0:
            self.skips += 1
            return
        sy = float(s @ y)
        if self.updates == 0 and sy > 0:
            self.M = np.eye(s.size) * float(np.clip(y @ y / sy, self.m_min, self.m_max))
        Ms = self.M @ s
        sMs = float(s @ Ms)
        if sy < 0.2 * sMs:
            theta = 0.8 * sMs / (sMs - sy)
            y = theta * y + (1 - theta) * Ms
            sy = float(s @ y)
        M = self.M - np.outer(Ms, Ms) / sMs + np.outer(y, y) / sy
        w, V = np.linalg.eigh(0.5 * (M + M.T))
        if w.min() < self.m_min or w.max() > self.m_max:
            self.clips += 1
            w = np.clip(w, self.m_min, self.m_max)
        self.M = (V * w) @ V.T
        self.updates += 1

"""Bundle trust-region method (BT) for a nonsmooth, nonconvex f over a polyhedron.

The method of Schramm and Zowe (1992, SIAM J. Optim. 2:121-152), the "BT" algorithm of
Outrata, Kocvara, Zowe (1998, *Nonsmooth approach to optimization problems with
equilibrium constraints*), on plain arrays. The oracle returns ``(f(x), g)``, ``g`` one
(Clarke) subgradient. What is implemented (deviations from the papers marked *):

* **Model.** Each evaluated ``y_j`` gives the cut ``f(x_k) - alpha_j + g_j.d`` at the centre
  ``x_k`` with the distance-measure error (Schramm-Zowe; Lemarechal-Strodiot-Bihain)
  ``alpha_j = max(|f(x_k) - f_j - g_j.(x_k - y_j)|, gamma s_j^2)``, ``s_j = |x_k - y_j|``
  exactly (an aggregated cut: the convex combination of its members' ``s_j`` plus the
  length of every later serious step, an upper bound). *Optional lower bound: the cut
  ``v >= f_lower - f(x_k)`` (``J >= 0``: ``f_lower = 0``).
* **Subproblem.** ``min v + |d|^2/(2t)`` s.t. ``v >= g_j.d - alpha_j``, ``x_k + d`` in the
  polyhedron, by daqp (Arnstrom, Bemporad, Axehill 2022) in ``(d, v)``, scaled so that it
  is O(1) (:func:`_subproblem_data`). Its Hessian is singular in ``v``: daqp's proximal
  option (``eps_prox > 0``, proximal-point iterations converging to the exact solution of
  the semidefinite QP), checked against active-set enumeration and trust-constr in the
  tests. Cut multipliers ``lambda_j`` (sum 1) give ``p = sum lambda_j g_j``,
  ``alpha_p = sum lambda_j alpha_j`` and ``d = -t (p + nu)``, ``nu`` in the normal cone.
* **Trust-parameter loop** (BT's inner iteration). Trial ``y = x_k + d``, model decrease
  ``v < 0``. Descent, ``f(y) - f(x_k) <= m_L v``: if ``g(y).d < m_R v`` (still steep at
  ``y``) keep ``y`` as candidate, ``t *= t_increase`` and retry (*no new trial when the
  step no longer changes, within 1e-3), else a serious step to the best candidate. No
  descent: a pending candidate becomes the serious step; else a null step (the cut of
  ``y`` changes the model, ``g(y).d - alpha_y >= m_R v``, or ``t = t_min``) or
  ``t *= t_decrease`` and retry. *Every evaluated cut enters the bundle.
* **Stopping rule.** ``-v = |d|^2/t + nu.d + alpha_p <= eps`` (nonnegative terms), tested
  at ``max(t, t0)``: the model decrease grows with ``t``, so a ``t`` shrunk by failures
  cannot fake convergence.
* **Scale.** ``f``, ``g`` are divided by ``f_scale = |f(x0)|`` (else ``|g(x0)|``, else 1);
  ``t`` and ``gamma`` are dimensionless: internally ``t |g_0|^-2`` and ``gamma |g_0|^2``
  with ``g_0`` the normalised first subgradient, so ``t = 1`` means the first model step
  predicts a decrease of ``|f(x0)| / 2``. The run is invariant under ``f -> c f`` and
  ``x -> c x`` (``c > 0``); ``eps`` is relative to ``|f(x0)|``. History ``f``, ``pred``,
  ``agg_norm`` are in the oracle's units, ``t`` in the options' units.
* **Bundle size.** Above ``max_bundle`` cuts with zero multiplier go (oldest first), then
  the active ones except the centre's are aggregated (Kiwiel 1985). *If
  daqp fails (nearly parallel cuts), the bundle is reset once to the centre, the newer
  cuts and the last aggregate.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

Oracle = Callable[[np.ndarray], tuple[float, np.ndarray]]
_INF = 1e30  # daqp's infinity
_GROUPS = {"lb": "x >= lb", "ub": "x <= ub", "cl": "C x >= cl", "cu": "C x <= cu"}


@dataclass
class Polyhedron:
    """The set ``{x : lb <= x <= ub, cl <= C x <= cu}`` (infinite bounds allowed)."""

    lb: np.ndarray
    ub: np.ndarray
    C: np.ndarray
    cl: np.ndarray
    cu: np.ndarray

    def __post_init__(self) -> None:
        for key in ("lb", "ub", "cl", "cu"):
            setattr(self, key, np.asarray(getattr(self, key), dtype=float).ravel())
        n = self.lb.size
        self.C = np.asarray(self.C, dtype=float).reshape(-1, n)
        sizes = {"ub": n, "cl": self.C.shape[0], "cu": self.C.shape[0]}
        for key, size in sizes.items():
            if (got := getattr(self, key).size) != size:
                raise ValueError(f"Polyhedron.{key}: {got} entries, need {size}")
        for lo, hi in (("lb", "ub"), ("cl", "cu")):
            bad = np.flatnonzero(getattr(self, lo) > getattr(self, hi))
            if bad.size:
                raise ValueError(f"Polyhedron: {lo} > {hi} at index {int(bad[0])}")
        if not np.isfinite(self.C).all():
            raise ValueError("Polyhedron.C: non-finite entries")

    @classmethod
    def box(cls, lb: np.ndarray, ub: np.ndarray) -> Polyhedron:
        """A box ``lb <= x <= ub`` without general constraints."""
        lb = np.asarray(lb, dtype=float).ravel()
        return cls(lb, ub, np.zeros((0, lb.size)), np.zeros(0), np.zeros(0))

    @property
    def n(self) -> int:
        return self.lb.size

    def residuals(self, x: np.ndarray) -> dict[str, float]:
        """Largest violation per group ``lb, ub, cl, cu`` (raw: > 0 violated, -inf if the
        group has no finite bound)."""
        x = np.asarray(x, dtype=float).ravel()
        Cx = self.C @ x
        parts = {"lb": self.lb - x, "ub": x - self.ub, "cl": self.cl - Cx, "cu": Cx - self.cu}
        return {k: float(np.max(v, initial=-math.inf)) for k, v in parts.items()}

    def is_feasible(self, x: np.ndarray, tol: float = 1e-8) -> bool:
        return all(r <= tol for r in self.residuals(x).values())

    def check(self, x: np.ndarray, name: str = "x0", tol: float = 1e-8) -> None:
        """Raise ValueError naming every violated group and by how much."""
        x = np.asarray(x, dtype=float).ravel()
        if x.size != self.n:
            raise ValueError(f"{name}: {x.size} entries, the polyhedron has {self.n}")
        if not np.isfinite(x).all():
            raise ValueError(f"{name}: non-finite entries")
        res = self.residuals(x)
        bad = [f"{k} ({_GROUPS[k]}) violated by {v:.3g}" for k, v in res.items() if v > tol]
        if bad:
            raise ValueError(f"{name} is infeasible: " + "; ".join(bad))


@dataclass
class BundleOptions:
    """Parameters of :func:`bundle_trust` (``0 < m_L < m_R < 1``; ``eps`` relative to
    ``|f(x0)|``, ``t`` and ``gamma`` dimensionless: see the module docstring)."""

    t0: float = 1.0
    t_min: float = 1e-10
    t_max: float = 1e3
    m_L: float = 0.1
    m_R: float = 0.5
    eps: float = 1e-6
    max_iter: int = 200
    max_evals: int = 400
    max_bundle: int = 40
    gamma: float = 0.01
    f_lower: float = -math.inf
    t_increase: float = 4.0
    t_decrease: float = 0.25

    def __post_init__(self) -> None:
        checks = [("m_L, m_R", 0 < self.m_L < self.m_R < 1, "need 0 < m_L < m_R < 1"),
                  ("t0", 0 < self.t_min <= self.t0 <= self.t_max, "need 0 < t_min <= t0 <= t_max"),
                  ("eps", self.eps >= 0, "need eps >= 0"),
                  ("gamma", self.gamma >= 0, "need gamma >= 0"),
                  ("f_lower", not math.isnan(self.f_lower), "need a number (-inf: none)"),
                  ("max_iter", self.max_iter >= 1, "need max_iter >= 1"),
                  ("max_evals", self.max_evals >= 1, "need max_evals >= 1"),
                  ("max_bundle", self.max_bundle >= 4, "need max_bundle >= 4"),
                  ("t_increase", self.t_increase > 1, "need t_increase > 1"),
                  ("t_decrease", 0 < self.t_decrease < 1, "need 0 < t_decrease < 1")]
        for key, ok, why in checks:
            if not ok:
                raise ValueError(f"BundleOptions.{key}: {why}")


@dataclass
class BundleResult:
    """Outcome: the last stability centre ``x`` with ``f``, ``g`` (as the oracle returned
    them), counts, why the run stopped and the history rows (one per oracle evaluation,
    plus one for a serious step to a pending candidate taken without a new evaluation)."""

    x: np.ndarray
    f: float
    g: np.ndarray
    iterations: int
    evaluations: int
    stop_reason: str
    history: list[dict] = field(default_factory=list)


class OracleFailure(RuntimeError):
    """The oracle raised or returned non-finite values."""


def call_oracle(oracle: Oracle, x: np.ndarray, n: int) -> tuple[float, np.ndarray]:
    """``oracle(x)`` checked: finite ``f``, a finite subgradient of length ``n``; any
    exception becomes :class:`OracleFailure` carrying its message."""
    try:
        f, g = oracle(x.copy())
        f = float(f)
        g = np.asarray(g, dtype=float).ravel()
    except Exception as exc:  # noqa: BLE001 - any oracle failure ends the run cleanly
        raise OracleFailure(f"{type(exc).__name__}: {exc}") from exc
    if g.size != n:
        raise OracleFailure(f"subgradient has {g.size} entries, need {n}")
    if not (math.isfinite(f) and np.isfinite(g).all()):
        raise OracleFailure(f"non-finite value (f = {f}, finite g: {bool(np.isfinite(g).all())})")
    return f, g


def objective_scale(f0: float, g0: np.ndarray) -> float:
    """``|f(x0)|``, else ``|g(x0)|``, else 1: the unit of f inside the optimisers."""
    for s in (abs(f0), float(np.linalg.norm(g0))):
        if s > 0 and math.isfinite(s):
            return s
    return 1.0


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

    @property
    def pred(self) -> float:  # predicted decrease -v >= 0
        return -self.v

    @property
    def agg_norm(self) -> float:
        """``|s| = |d| / t``: the aggregate subgradient plus its normal-cone part."""
        return float(np.linalg.norm(self.d)) / self.t


def _subproblem_data(x: np.ndarray, t: float, G: np.ndarray, alpha: np.ndarray,
                     poly: Polyhedron, sigma: float) -> tuple[np.ndarray, ...]:
    """daqp's ``(H, f, A, bupper, blower)`` of the BT subproblem in the scaled variables
    ``z = (d / a, v / sigma)``, ``a = sqrt(sigma t)``: ``min z_v + |z_d|^2 / 2`` s.t.
    ``(a / sigma) g_j.z_d - z_v <= alpha_j / sigma`` and the polyhedron, so that a model
    decrease of order ``sigma`` gives an O(1) problem for daqp's absolute tolerances.
    The first ``n + 1`` bounds are simple bounds on ``z``, then the rows of C, then the
    cuts; general rows scaled to unit norm. Also returns the row norms and ``a``."""
    n, m, mc = x.size, G.shape[0], poly.C.shape[0]
    a = math.sqrt(sigma * t)
    H, f = np.diag(np.r_[np.ones(n), 0.0]), np.r_[np.zeros(n), 1.0]
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
                     poly: Polyhedron, sigma: float = 1.0) -> Subproblem:
    """``min v + |d|^2/(2t)`` s.t. ``G d - v <= alpha``, ``x + d`` in ``poly``, by daqp.

    ``sigma`` is the expected size of ``-v`` (the problem is scaled by it, see
    :func:`_subproblem_data`). The Hessian is singular in ``v``: daqp's proximal option
    (``eps_prox > 0``) handles it; the next setting of :data:`_DAQP_TRIES` is tried if
    daqp fails or ``x + d`` violates ``poly`` by more than :data:`FEAS_TOL`. The cut
    multipliers sum to one at an exact solution; ``kkt`` is :func:`kkt_residual` of the
    scaled problem (in units of ``sigma``).
    """
    import daqp

    n, mc = x.size, poly.C.shape[0]
    H, f, A, up, lo, rows, a = _subproblem_data(x, t, G, alpha, poly, sigma)
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
                              t=t, kkt=kkt_residual(H, f, A, up, lo, z, lam))
    return Subproblem(d=np.zeros(n), v=0.0, lam=np.zeros(G.shape[0]), t=t, ok=False,
                      message=f"daqp exit flags {flags}")


class _Bundle:
    """Cuts stored as (subgradient, value of the linearisation at the centre, distance),
    each with a permanent id; the aggregate of the last subproblem kept aside for a reset."""

    def __init__(self, n: int) -> None:
        self.G = np.zeros((0, n))
        self.c = np.zeros(0)
        self.s = np.zeros(0)
        self.Y = np.zeros((0, n))  # the evaluated points; NaN rows for aggregates
        self.ids = np.zeros(0, dtype=int)
        self.next_id = 0
        self.centre_id = -1
        self.agg: tuple[np.ndarray, float, float, int] | None = None

    def __len__(self) -> int:
        return self.c.size

    def add(self, x: np.ndarray, y: np.ndarray, f: float, g: np.ndarray) -> int:
        """Append the cut of ``(y, f, g)``; returns its id."""
        return self._append(g, f + g @ (x - y), float(np.linalg.norm(x - y)), y)

    def _append(self, g: np.ndarray, c: float, s: float, y: np.ndarray) -> int:
        self.G = np.vstack([self.G, g])
        self.c = np.append(self.c, c)
        self.s = np.append(self.s, s)
        self.Y = np.vstack([self.Y, y])
        self.ids = np.append(self.ids, self.next_id)
        self.next_id += 1
        return self.next_id - 1

    def move(self, x_old: np.ndarray, x_new: np.ndarray, centre_id: int) -> None:
        """New stability centre: the point of cut ``centre_id``."""
        step = x_new - x_old
        self.c = self.c + self.G @ step
        point = ~np.isnan(self.Y[:, 0])
        self.s = np.where(point, np.linalg.norm(x_new - np.nan_to_num(self.Y), axis=1),
                          self.s + np.linalg.norm(step))
        self.centre_id = centre_id
        if self.agg is not None:
            g, c, s, last = self.agg
            self.agg = (g, c + float(g @ step), s + float(np.linalg.norm(step)), last)

    def alpha(self, fx: float, gamma: float) -> np.ndarray:
        """Schramm-Zowe's nonnegative errors ``max(|f(x) - c_j|, gamma s_j^2)``."""
        a = np.maximum(np.abs(fx - self.c), gamma * self.s**2)
        a[self.ids == self.centre_id] = 0.0
        return a

    def remember(self, lam: np.ndarray) -> None:
        """Keep the aggregate cut ``sum lam_j (g_j, c_j, s_j)`` of a solved subproblem."""
        w = np.maximum(lam, 0.0)
        w = w / w.sum() if w.sum() > 0 else np.full(w.size, 1.0 / w.size)
        self.agg = (w @ self.G, float(w @ self.c), float(w @ self.s), int(self.ids.max()))

    def reset(self, protect: set[int]) -> None:
        """Kiwiel's minimal bundle: the centre, the cuts added after the last aggregate,
        ``protect`` (ids) and the aggregate (whose subproblem solution it preserves)."""
        if self.agg is None:
            return
        g, c, s, last = self.agg
        keep = (self.ids > last) | np.isin(self.ids, [self.centre_id, *protect])
        self._select(keep)
        self._append(g, c, s, np.full(self.G.shape[1], np.nan))
        self.agg = None

    def make_room(self, lam: np.ndarray, cap: int, protect: set[int]) -> None:
        """Keep at most ``cap - 1`` cuts (room for one more; ``cap >= 4``): drop inactive
        ones (oldest first), then aggregate the active ones except the centre's and the
        ids in ``protect`` (the aggregate keeps the last subproblem's solution)."""
        if len(self) < cap:
            return
        keep = np.ones(len(self), dtype=bool)
        fixed = np.isin(self.ids, [self.centre_id, *protect])
        for j in range(len(self)):
            if keep.sum() < cap:
                break
            if not fixed[j] and lam[j] <= 1e-12 * max(lam.max(), 1.0):
                keep[j] = False
        if keep.sum() < cap:
            self._select(keep)
            return
        mix = keep & ~fixed
        w = np.maximum(lam, 0.0) * mix
        w = w / w.sum() if w.sum() > 0 else mix / mix.sum()
        g, c, s = w @ self.G, float(w @ self.c), float(w @ self.s)
        self._select(~mix)
        self._append(g, c, s, np.full(self.G.shape[1], np.nan))

    def _select(self, keep: np.ndarray) -> None:
        self.G, self.c, self.s, self.Y = self.G[keep], self.c[keep], self.s[keep], self.Y[keep]
        self.ids = self.ids[keep]


def _same_step(d: np.ndarray, d_ref: np.ndarray, rtol: float = 1e-3) -> bool:
    return bool(np.linalg.norm(d - d_ref) <= rtol * np.linalg.norm(d_ref))


@dataclass
class _Trial:
    """An evaluated trial point (normalised ``f``, ``g``) and the subproblem that gave it."""

    y: np.ndarray
    f: float
    g: np.ndarray
    qp: Subproblem
    cut_id: int
    raw: tuple[float, np.ndarray]  # f, g in the oracle's units


class _Run:
    """State of one BT run: centre, bundle, trust parameter, counters, history."""

    def __init__(self, oracle: Oracle, x0: np.ndarray, poly: Polyhedron,
                 opts: BundleOptions, callback: Callable[[dict], None] | None) -> None:
        self.oracle, self.poly, self.o, self.callback = oracle, poly, opts, callback
        self.x, self.n = x0, x0.size
        self.fx, self.gx = math.nan, np.full(x0.size, math.nan)
        self.raw: tuple[float, np.ndarray] = (math.nan, self.gx)
        self.t, self.scale, self.sigma = opts.t0, 1.0, 1.0
        self.tunit, self.gamma, self.f_low = 1.0, opts.gamma, -math.inf
        self.iters = self.evals = self.resets = 0
        self.history: list[dict] = []
        self.bundle = _Bundle(x0.size)

    def evaluate(self, y: np.ndarray) -> tuple[float, np.ndarray]:
        self.evals += 1
        return call_oracle(self.oracle, y, self.n)

    def start(self) -> str | None:
        """Evaluate ``x0``, fix the scale, seed the bundle with the centre's cut."""
        try:
            f, g = self.evaluate(self.x)
        except OracleFailure as exc:
            return f"oracle failed: {exc}"
        self.scale = objective_scale(f, g)
        self.fx, self.gx, self.raw = f / self.scale, g / self.scale, (f, g)
        g2 = float(self.gx @ self.gx)
        self.tunit = 1.0 / g2 if g2 > 0 else 1.0
        self.gamma = self.o.gamma / self.tunit
        self.f_low = self.o.f_lower / self.scale
        self.bundle.centre_id = self.bundle.add(self.x, self.x, self.fx, self.gx)
        self.record("start", f, None)
        return None

    def direction(self, t: float, protect: set[int] | None = None) -> Subproblem:
        """The subproblem, scaled by the last predicted decrease (floor 1e-14); if daqp
        fails (degenerate, nearly parallel cuts), once more after a bundle reset."""
        for attempt in range(2):
            qp = self.solve(t)
            if qp.ok or attempt or self.bundle.agg is None:
                break
            self.bundle.reset(protect or set())
            self.resets += 1
        if qp.ok:
            self.sigma = min(max(qp.pred, 1e-14), 1e6)
            self.bundle.remember(qp.lam)
        return qp

    def converged(self, qp: Subproblem) -> bool:
        """``-v <= eps`` at ``t`` and, if ``t < t0``, also at ``t0``."""
        if qp.pred > self.o.eps:
            return False
        if qp.t >= self.o.t0 * self.tunit:
            return True
        ref = self.solve(self.o.t0)
        return ref.ok and ref.pred <= self.o.eps

    def solve(self, t: float) -> Subproblem:
        """The subproblem at ``t`` (options' units), with the cut ``v >= f_lower - f(x)``
        if a lower bound is given; ``lam`` of the bundle's cuts only."""
        G, alpha = self.bundle.G, self.bundle.alpha(self.fx, self.gamma)
        low = math.isfinite(self.f_low)
        if low:
            G, alpha = np.vstack([G, np.zeros(self.n)]), np.r_[alpha, max(self.fx - self.f_low, 0)]
        qp = solve_subproblem(self.x, t * self.tunit, G, alpha, self.poly, self.sigma)
        if low:
            qp.lam = qp.lam[:-1]
        return qp

    def record(self, kind: str, f_trial: float, qp: Subproblem | None) -> None:
        row = {"iteration": self.iters + (kind in ("t_up", "t_down")), "kind": kind,
               "serious": kind in ("serious", "start"), "f": self.raw[0],
               "f_trial": f_trial,
               "step_norm": float(np.linalg.norm(qp.d)) if qp else 0.0,
               "t": qp.t / self.tunit if qp else self.t,
               "agg_norm": qp.agg_norm * self.scale if qp else math.nan,
               "pred": qp.pred * self.scale if qp else math.nan,
               "evaluations": self.evals, "bundle_size": len(self.bundle)}
        self.history.append(row)
        if self.callback is not None:
            self.callback(row)

    def serious(self, trial: _Trial) -> None:
        self.bundle.move(self.x, trial.y, trial.cut_id)
        self.x, self.fx, self.gx = trial.y, trial.f, trial.g
        self.t = trial.qp.t / self.tunit
        self.raw = trial.raw

    def finish(self, cand: _Trial | None, reason: str) -> str:
        """Stop; a pending descent candidate becomes the last serious step first."""
        if cand is not None:
            self.serious(cand)
            self.iters += 1
            self.record("serious", cand.raw[0], cand.qp)
        return reason

    def iterate(self) -> str | None:
        """One BT iteration (a serious or a null step after the trust-parameter loop);
        returns a stop reason or None."""
        cand: _Trial | None = None
        while True:
            keep = set() if cand is None else {cand.cut_id}
            qp = self.direction(self.t, keep)
            if not qp.ok:
                return self.finish(cand, f"qp failed: {qp.message}")
            if cand is None and self.converged(qp):
                return f"converged: predicted decrease {qp.pred:.3g} <= eps (normalised)"
            if cand is not None and _same_step(qp.d, cand.qp.d):
                self.finish(cand, "")  # a larger t no longer moves the step
                return None
            if self.evals >= self.o.max_evals:
                return self.finish(cand, "max_evals")
            self.bundle.make_room(qp.lam, self.o.max_bundle, keep)
            y = self.x + qp.d
            try:
                f, g = self.evaluate(y)
            except OracleFailure as exc:
                return self.finish(cand, f"oracle failed: {exc}")
            fn, gn = f / self.scale, g / self.scale
            trial = _Trial(y, fn, gn, qp, self.bundle.add(self.x, y, fn, gn), (f, g))
            kind, cand = self.decide(trial, cand)
            if kind in ("serious", "null"):
                self.iters += 1
            self.record(kind, f, qp)
            if kind in ("serious", "null"):
                return None

    def decide(self, trial: _Trial, cand: _Trial | None) -> tuple[str, _Trial | None]:
        """BT's tests on a trial: ``(kind, candidate)`` with kind serious / null / t_up /
        t_down (Schramm-Zowe 1992, sec. 3; ``m_L`` descent, ``m_R`` model change)."""
        o, v, d = self.o, trial.qp.v, trial.qp.d
        slope = float(trial.g @ d)
        if trial.f - self.fx <= o.m_L * v:
            best = trial if cand is None or trial.f <= cand.f else cand
            if best is trial and slope < o.m_R * v and self.t < o.t_max:
                self.t = min(self.t * o.t_increase, o.t_max)
                return "t_up", trial
            self.serious(best)
            return "serious", None
        if cand is not None:
            self.serious(cand)
            return "serious", None
        alpha_y = max(abs(self.fx - (trial.f - slope)), self.gamma * float(d @ d))
        if slope - alpha_y >= o.m_R * v or self.t <= o.t_min:
            return "null", None
        self.t = max(self.t * o.t_decrease, o.t_min)
        return "t_down", None

    def result(self, reason: str) -> BundleResult:
        return BundleResult(x=self.x.copy(), f=self.raw[0], g=self.raw[1].copy(),
                            iterations=self.iters, evaluations=self.evals,
                            stop_reason=reason, history=self.history)


def bundle_trust(oracle: Oracle, x0: np.ndarray, polyhedron: Polyhedron,
                 options: BundleOptions | None = None,
                 callback: Callable[[dict], None] | None = None) -> BundleResult:
    """Minimise a locally Lipschitz ``f`` over ``polyhedron`` by the bundle trust-region
    method (Schramm-Zowe 1992; see the module docstring for the model, the tests, the
    stopping rule and the scaling).

    Parameters
    ----------
    oracle : ``x -> (f(x), g)`` with ``g`` one subgradient; an exception or a non-finite
        value ends the run with ``stop_reason = "oracle failed: <message>"``.
    x0 : a feasible start (ValueError naming the violated groups otherwise).
    polyhedron, options, callback : the admissible set; :class:`BundleOptions`;
        called with each history row.

    Returns
    -------
    BundleResult
        The last stability centre; one history row per oracle evaluation with ``kind``
        start / serious / null / t_up / t_down (``iteration`` counts serious + null steps).
    """
    opts = options if options is not None else BundleOptions()
    x0 = np.array(x0, dtype=float).ravel()
    polyhedron.check(x0, "x0")
    run = _Run(oracle, x0, polyhedron, opts, callback)
    reason = run.start()
    while reason is None:
        if run.iters >= opts.max_iter:
            reason = "max_iter"
            break
        reason = run.iterate()
    return run.result(reason)

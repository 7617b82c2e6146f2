"""Bundle trust-region method (BT) for a nonsmooth, nonconvex f over a polyhedron.

The method of Schramm and Zowe (1992, SIAM J. Optim. 2:121-152), the "BT" algorithm of
Outrata, Kocvara, Zowe (1998, *Nonsmooth approach to optimization problems with
equilibrium constraints*), on plain arrays. The oracle returns ``(f(x), g)``, ``g`` one
(Clarke) subgradient. What is implemented (deviations from the papers marked [dev]):

* **Model.** Each evaluated ``y_j`` gives the cut ``f(x_k) - alpha_j + g_j.d`` at the centre
  ``x_k`` with the distance-measure error (Schramm-Zowe; Lemarechal-Strodiot-Bihain)
  ``alpha_j = max(|f(x_k) - f_j - g_j.(x_k - y_j)|, gamma s_j^2)``, ``s_j = |x_k - y_j|``
  exactly (an aggregated cut: the convex combination of its members' ``s_j`` plus the
  length of every later serious step, an upper bound). [dev] Optional lower bound: the cut
  ``v >= f_lower - f(x_k)`` (``J >= 0``: ``f_lower = 0``).
* **Subproblem.** ``min v + d'Md/(2t)`` s.t. ``v >= g_j.d - alpha_j``, ``x_k + d`` in the
  polyhedron (``M = I``: ``metric="identity"``, BT itself; ``metric="bfgs"``: ``M`` a damped
  BFGS matrix updated at serious steps, eigenvalues in ``metric_bounds``: the variable
  metric bundle method of Lemarechal-Sagastizabal 1997 / Vlcek-Luksan 2001 inside BT's
  safeguards, :mod:`rbbench.optim.bundle_metric`), by daqp (Arnstrom, Bemporad, Axehill
  2022) in ``(d, v)``, scaled so that it is O(1) (:func:`_subproblem_data`). Its Hessian is
  singular in ``v``: daqp's proximal option (``eps_prox > 0``, proximal-point iterations
  converging to the exact solution of the semidefinite QP), checked against active-set
  enumeration and trust-constr in the tests. Cut multipliers ``lambda_j`` (sum 1) give ``p =
  sum lambda_j g_j``, ``alpha_p = sum lambda_j alpha_j`` and ``d = -t M^-1 (p + nu)``,
  ``nu`` in the normal cone.
* **Trust-parameter loop** (BT's inner iteration). Trial ``y = x_k + d``, model decrease
  ``v < 0``. Descent, ``f(y) - f(x_k) <= m_L v``: if ``g(y).d < m_R v`` (still steep at
  ``y``) keep ``y`` as candidate, ``t *= t_increase`` and retry ([dev] no new trial when the
  step no longer changes, within 1e-3), else a serious step to the best candidate. No
  descent: a pending candidate becomes the serious step; else a null step (the cut of
  ``y`` changes the model, ``g(y).d - alpha_y >= m_R v``, or ``t = t_min``) or
  ``t *= t_decrease`` and retry. [dev] Every evaluated cut enters the bundle.
* **Stopping rule.** ``-v = d'Md/t + nu.d + alpha_p <= eps`` (nonnegative terms), tested
  at ``max(t, t0)``: the model decrease grows with ``t``, so a ``t`` shrunk by failures
  cannot fake convergence. In a metric, ``d'Md/t = t |p + nu|^2_{M^-1}`` is the predicted
  decrease of the quasi-Newton model; the eigenvalue bounds ``m_min <= M <= m_max`` give
  ``t0 |p + nu|^2 <= m_max eps`` and ``alpha_p <= eps`` at a stop: still an
  ``eps``-stationarity certificate, relative to ``|f(x0)|``.
* **Scale.** ``f``, ``g`` are divided by ``f_scale = |f(x0)|`` (else ``|g(x0)|``, else 1);
  ``t`` and ``gamma`` are dimensionless: internally ``t |g_0|^-2`` and ``gamma |g_0|^2``
  with ``g_0`` the normalised first subgradient, so ``t = 1`` means the first model step
  predicts a decrease of ``|f(x0)| / 2``. The run is invariant under ``f -> c f`` and
  ``x -> c x`` (``c > 0``); ``eps`` is relative to ``|f(x0)|``. History ``f``, ``pred``,
  ``agg_norm`` are in the oracle's units, ``t`` in the options' units.
* **Bundle size.** Above ``max_bundle`` cuts with zero multiplier go (oldest first), then
  the active ones except the centre's are aggregated (Kiwiel 1985). [dev] If
  daqp fails (nearly parallel cuts), the bundle is reset once to the centre, the newer
  cuts and the last aggregate.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rbbench.optim.bundle_metric import (  # noqa: F401 - re-exported
    FEAS_TOL,
    Subproblem,
    VariableMetric,
    _subproblem_data,
    kkt_residual,
    solve_subproblem,
)
from rbbench.optim.polyhedron import Polyhedron  # noqa: F401 - re-exported

Oracle = Callable[[np.ndarray], tuple[float, np.ndarray]]


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
    metric: str = "identity"
    metric_bounds: tuple[float, float] = (1e-4, 1e8)

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
                  ("t_decrease", 0 < self.t_decrease < 1, "need 0 < t_decrease < 1"),
                  ("metric", self.metric in ("identity", "bfgs"), "'identity' or 'bfgs'"),
                  ("metric_bounds", 0 < self.metric_bounds[0] <= 1 <= self.metric_bounds[1],
                   "need 0 < m_min <= 1 <= m_max")]
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
        self.metric = VariableMetric(x0.size, opts.metric, *opts.metric_bounds)

    def evaluate(self, y: np.ndarray) -> tuple[float, np.ndarray]:
        self.evals += 1
        return call_oracle(self.oracle, y, self.n)

    def start(self) -> str | None:
        """Evaluate ``x0``, fix the scale, start the bundle with the centre's cut."""
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
        qp = solve_subproblem(self.x, t * self.tunit, G, alpha, self.poly, self.sigma,
                              self.metric.M)
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
        """Move the centre to ``trial``; update the metric (M's units: ``g`` times the unit
        of ``t``)."""
        self.metric.update(trial.y - self.x, (trial.g - self.gx) * self.tunit)
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

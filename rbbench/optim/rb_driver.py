"""Reduced-basis-driven shape optimisation: a trust region of local reduced models.

After Qian, Grepl, Veroy, Willcox (2017, SIAM J. Sci. Comput. 39:S434) and Keil, Mechelli,
Ohlberger, Schindler, Volkwein (2021, ESAIM M2AN 55:1239), adapted to the nonsmooth ``Theta`` of
model B of the talk "On coupling of complementarity with friction in contact shape optimization"
and the bundle method:

1. At the start the reduced model of ``shape_reduced`` gets the interior space of the HF
   factors there (``interior_space``: the harmonic extensions of the contact unit vectors
   and the load response); it is then exact at ``alpha_0`` (same ``J``, same subgradient)
   and accurate to second order nearby. At each new centre ``alpha_k`` the HF state and
   adjoint there are added to the basis (``centre_update = "incremental"``: the reduced
   operators get the new rows and columns only; the model is exact at ``alpha_k`` by the
   first-order consistency of Keil et al.), or the basis is replaced by the interior space
   of ``alpha_k`` (``"rebuild"``).
2. The bundle trust-region method minimises the reduced ``Theta_N`` over the admissible
   polyhedron intersected with the box ``|alpha - alpha_k|_inf <= Delta_k``.
3. The candidate is HF-evaluated: ``rho = (J_k - J(alpha~)) / (Theta_N(alpha_k) -
   Theta_N(alpha~))``. ``rho >= eta_accept`` accepts it (new centre, basis updated as in 1.);
   ``rho >= eta_expand`` with the step on the box boundary doubles ``Delta``; a rejection
   sets ``Delta = shrink * |step|_inf`` and adds the HF state and adjoint of the rejected
   candidate to the basis (the model becomes exact there too).
4. Stop when the reduced run at the centre predicts no decrease (the bundle's own stopping
   rule on a model exact at the centre: an HF stationarity certificate of the bundle's
   kind) or below ``ftol J_k``; when an accepted step ends inside the trust region
   (``|step|_inf < Delta / 2``: the region did not limit it) and the reduced run converged
   there, or its HF relative decrease is below ``stall_rtol`` (the reduced bundle run
   stalled, as the HF-driven one does in the same valleys of ``J ~ lam^6``: null steps
   until ``max_iter``); when ``Delta < delta_min``; after ``max_outer`` iterations.

Every accepted iterate is HF-evaluated, so the reported ``J_hf`` is the HF value at the
returned design and the history's ``J`` is monotone on accepted steps.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rbbench.optim.bundle import BundleOptions, BundleResult, Polyhedron, bundle_trust
from rbbench.optim.shape_adjoint import Evaluation, evaluate
from rbbench.optim.shape_reduced import ReducedModel, hf_snapshots, interior_space, state_vector
from rbbench.optim.shape_scene import ShapeScene
from rbbench.optim.shape_state import StateSolveError


def _inner_default() -> BundleOptions:
    return BundleOptions(max_iter=100, max_evals=200)


#: how the reduced model follows an accepted centre: ``incremental`` adds the HF state and
#: adjoint there to the basis (new rows / columns of the reduced operators only),
#: ``rebuild`` replaces the basis by the interior space of the new centre
CENTRE_UPDATES = ("incremental", "rebuild")


@dataclass
class RBOptions:
    """Trust region (``Delta`` in the units of ``alpha``, inf-norm) and inner bundle runs."""

    delta0: float = 0.01
    delta_min: float = 1e-6
    delta_max: float = 0.2
    eta_accept: float = 0.1
    eta_expand: float = 0.75
    expand: float = 2.0
    shrink: float = 0.5
    max_outer: int = 30
    ftol: float = 1e-8
    stall_rtol: float = 0.05
    centre_update: str = "incremental"
    inner: BundleOptions = field(default_factory=_inner_default)

    def __post_init__(self) -> None:
        checks = [("delta0", 0 < self.delta_min <= self.delta0 <= self.delta_max,
                   "need 0 < delta_min <= delta0 <= delta_max"),
                  ("eta_accept", 0 < self.eta_accept <= self.eta_expand < 1,
                   "need 0 < eta_accept <= eta_expand < 1"),
                  ("expand", self.expand > 1, "need expand > 1"),
                  ("shrink", 0 < self.shrink < 1, "need 0 < shrink < 1"),
                  ("max_outer", self.max_outer >= 1, "need max_outer >= 1"),
                  ("centre_update", self.centre_update in CENTRE_UPDATES,
                   f"{self.centre_update!r}: valid are {', '.join(CENTRE_UPDATES)}")]
        for key, ok, why in checks:
            if not ok:
                raise ValueError(f"RBOptions.{key}: {why}")


@dataclass
class RBResult(BundleResult):
    """:class:`BundleResult` fields (``f``: the reduced ``Theta_N`` at ``x``; ``g``: the HF
    subgradient there) plus the costs and the HF-verified ``J_hf`` at ``x``."""

    hf_solves: int = 0
    rb_solves: int = 0
    basis_size: int = 0
    wall_s: float = 0.0
    J_hf: float = math.nan


def trust_polyhedron(poly: Polyhedron, x: np.ndarray, delta: float) -> Polyhedron:
    """``poly`` intersected with the box ``|y - x|_inf <= delta``."""
    return Polyhedron(np.maximum(poly.lb, x - delta), np.minimum(poly.ub, x + delta),
                      poly.C, poly.cl, poly.cu)


class ReducedOracle:
    """``alpha -> (Theta_N, xi_N)`` warm-started from the last reduced state; counts calls."""

    def __init__(self, model: ReducedModel, y0: np.ndarray) -> None:
        self.model, self.y0, self.calls = model, y0, 0

    def __call__(self, alpha: np.ndarray) -> tuple[float, np.ndarray]:
        self.calls += 1
        try:
            ev = self.model.evaluate(alpha, y0=self.y0, reconstruct=False)
        except StateSolveError:
            ev = self.model.evaluate(alpha, reconstruct=False)      # cold start
        self.y0 = state_vector(ev.state)
        return ev.J, ev.xi


@dataclass
class _Outer:
    """State of the outer loop."""

    x: np.ndarray
    ev: Evaluation
    delta: float
    hf: int = 1
    rb: int = 0
    rho: float = math.nan
    err: tuple = (math.nan, math.nan)
    history: list = field(default_factory=list)


def optimize_rb(sc: ShapeScene, alpha0: np.ndarray, options: RBOptions | None = None,
                callback: Callable[[dict], None] | None = None) -> RBResult:
    """Minimise ``Theta`` over the admissible set by trust-region reduced models.

    Parameters
    ----------
    sc, alpha0 : scene and a feasible start (ValueError naming the violated groups else).
    options : :class:`RBOptions`.
    callback : called with each history row (``start``, then one per outer iteration:
        ``accepted`` / ``rejected`` / ``stationary``).

    Returns
    -------
    RBResult
        ``x`` the last accepted (HF-verified) design, ``J_hf`` its HF objective, ``f`` the
        reduced objective there, ``g`` its HF subgradient, ``hf_solves`` (HF state solves,
        the start included), ``rb_solves`` (reduced state solves), ``basis_size`` (the
        last ``N``), ``wall_s``; ``iterations`` outer iterations, ``evaluations`` the
        HF + reduced solves; a failing HF solve ends the run with its reason.
    """
    o = options if options is not None else RBOptions()
    t0 = time.perf_counter()
    poly = Polyhedron(**sc.admissible())
    x0 = np.array(alpha0, dtype=float).ravel()
    poly.check(x0, "alpha0")
    run = _Outer(x0, evaluate(sc, x0), o.delta0)
    model = ReducedModel(sc)
    model.enrich(interior_space(sc, run.ev.state), reset=True)
    f_red, reason = run.ev.J, "max_outer"
    _record(run, 0, "start", run.ev.J, math.nan, 0.0, model, t0, callback)
    for k in range(1, o.max_outer + 1):
        run.rho, run.err = math.nan, (math.nan, math.nan)
        res, oracle = _inner(model, run, poly, o)
        run.rb += oracle.calls
        f_red = res.history[0]["f"]       # the reduced J at the centre
        pred = f_red - res.f
        step = float(np.max(np.abs(res.x - run.x)))
        if pred <= o.ftol * abs(run.ev.J) or step == 0.0:
            reason = (f"converged: {res.stop_reason}" if res.stop_reason.startswith("conv")
                      else f"no reduced decrease at the centre (inner: {res.stop_reason})")
            _record(run, k, "stationary", run.ev.J, pred, step, model, t0, callback)
            break
        try:
            ev = _hf_evaluate(sc, res.x, state_vector(run.ev.state))
        except StateSolveError as exc:
            reason = f"HF state solve failed: {exc}"
            break
        run.hf += 1
        run.err = (abs(res.f - ev.J) / abs(ev.J),
                   float(np.linalg.norm(res.g - ev.xi) / max(np.linalg.norm(ev.xi), 1e-300)))
        J_old, interior = run.ev.J, step < 0.5 * run.delta
        kind = _update(run, ev, res, pred, step, model, sc, o)
        _record(run, k, kind, ev.J, pred, step, model, t0, callback)
        f_red = res.f if kind == "accepted" else f_red
        if kind == "accepted" and interior:
            gain = (J_old - ev.J) / abs(J_old)
            if res.stop_reason.startswith("converged"):
                reason = f"converged: reduced optimum inside the trust region ({res.stop_reason})"
                break
            if gain < o.stall_rtol:
                reason = (f"stalled: step inside the trust region gained {gain:.3g} < "
                          f"stall_rtol (inner: {res.stop_reason})")
                break
        if run.delta < o.delta_min:
            reason = f"trust radius {run.delta:.3g} < delta_min"
            break
    return RBResult(x=run.x.copy(), f=f_red, g=run.ev.xi.copy(),
                    iterations=len(run.history) - 1, evaluations=run.hf + run.rb,
                    stop_reason=reason, history=run.history,
                    hf_solves=run.hf, rb_solves=run.rb, basis_size=model.N,
                    wall_s=time.perf_counter() - t0, J_hf=run.ev.J)


def _hf_evaluate(sc: ShapeScene, alpha: np.ndarray, y0: np.ndarray) -> Evaluation:
    """HF evaluation warm-started from the centre's state, cold-started if that fails
    (the semismooth Newton can stall from a far warm start where a cold one converges)."""
    try:
        return evaluate(sc, alpha, y0=y0)
    except StateSolveError:
        return evaluate(sc, alpha)


def _inner(model: ReducedModel, run: _Outer, poly: Polyhedron,
           o: RBOptions) -> tuple[BundleResult, ReducedOracle]:
    """One bundle run on the reduced model in the trust box around the centre."""
    oracle = ReducedOracle(model, state_vector(run.ev.state))
    box = trust_polyhedron(poly, run.x, run.delta)
    return bundle_trust(oracle, run.x, box, o.inner), oracle


def _update(run: _Outer, ev: Evaluation, res: BundleResult, pred: float, step: float,
            model: ReducedModel, sc: ShapeScene, o: RBOptions) -> str:
    """Accept / reject the HF-evaluated candidate, update ``Delta`` and the basis."""
    rho = (run.ev.J - ev.J) / pred
    run.rho = rho
    if rho >= o.eta_accept and ev.J < run.ev.J:
        if rho >= o.eta_expand and step >= 0.99 * run.delta:
            run.delta = min(o.expand * run.delta, o.delta_max)
        run.x, run.ev = res.x.copy(), ev
        if o.centre_update == "rebuild":
            model.enrich(interior_space(sc, ev.state), reset=True)
        else:
            model.enrich(hf_snapshots(sc, ev.state))
        return "accepted"
    run.delta = o.shrink * step
    model.enrich(hf_snapshots(sc, ev.state))
    return "rejected"


def _record(run: _Outer, k: int, kind: str, J_trial: float, pred: float, step: float,
            model: ReducedModel, t0: float, callback) -> None:
    row = {"iteration": k, "kind": kind, "J": run.ev.J, "J_trial": J_trial,
           "pred": pred, "rho": run.rho, "err_J_trial": run.err[0],
           "err_xi_trial": run.err[1], "step_inf": step,
           "delta": run.delta, "hf_solves": run.hf, "rb_solves": run.rb,
           "basis_size": model.N, "grad_norm": float(np.linalg.norm(run.ev.xi)),
           "wall_s": time.perf_counter() - t0}
    run.history.append(row)
    if callback is not None:
        callback(row)


def side_by_side(sc: ShapeScene, rb_options: RBOptions | None = None,
                 hf_options: BundleOptions | None = None, repeats: int = 3) -> dict:
    """HF-driven bundle and RB-driven runs from ``sc.initial_design()`` in this process
    with one BLAS thread, then the per-evaluation times (median of ``repeats`` cold
    solves + subgradients) of the HF and of the final reduced model at the RB optimum."""
    from statistics import median

    from rbbench.runtime.threads import one_blas_thread

    poly = Polyhedron(**sc.admissible())
    out: dict = {"J0": None}
    with one_blas_thread():
        t = time.perf_counter()
        hf = bundle_trust(_hf_oracle(sc), sc.initial_design(), poly, hf_options)
        hf_wall = time.perf_counter() - t
        rb = optimize_rb(sc, sc.initial_design(), rb_options)
        model = ReducedModel(sc)
        model.enrich(interior_space(sc, evaluate(sc, rb.x).state))
        times = {}
        for name, fun in (("hf", lambda: evaluate(sc, rb.x)), ("rb", lambda: model.evaluate(rb.x))):
            samples = []
            for _ in range(repeats):
                t = time.perf_counter()
                fun()
                samples.append(time.perf_counter() - t)
            times[name] = median(samples)
    out.update(J0=hf.history[0]["f"], hf_J=hf.f, hf_evaluations=hf.evaluations,
               hf_iterations=hf.iterations, hf_stop=hf.stop_reason, hf_wall_s=hf_wall,
               rb_J=rb.f, rb_J_hf=rb.J_hf, rb_hf_solves=rb.hf_solves, rb_solves=rb.rb_solves,
               rb_outer=rb.iterations, rb_basis=rb.basis_size, rb_stop=rb.stop_reason,
               rb_wall_s=rb.wall_s, wall_ratio=hf_wall / rb.wall_s,
               J_rel_diff=(rb.J_hf - hf.f) / hf.f, eval_hf_s=times["hf"],
               eval_rb_s=times["rb"], eval_speedup=times["hf"] / times["rb"],
               rb_history=rb.history, rb_residuals=sc.residuals(rb.x),
               hf_x=np.asarray(hf.x).tolist(), rb_x=np.asarray(rb.x).tolist(),
               hf_J_history=[h["f"] for h in hf.history],
               hf_residuals=sc.residuals(hf.x))
    return out


def _hf_oracle(sc: ShapeScene):
    def oracle(alpha: np.ndarray) -> tuple[float, np.ndarray]:
        ev = evaluate(sc, alpha)
        return ev.J, ev.xi
    return oracle


class RBHistory:
    """``history.csv`` appended row by row (flushed) and the progress line of an RB run;
    ``rows`` carry ``f`` (the HF ``J`` at the centre) and ``serious`` (start / accepted)
    as the HF driver's rows do."""

    FIELDS = ("iteration", "kind", "serious", "f", "J_trial", "pred", "rho", "step_inf",
              "delta", "grad_norm", "hf_solves", "rb_solves", "basis_size", "err_J_trial",
              "err_xi_trial", "wall_s", "stage", "relax", "force_mismatch", "contact_nodes")

    def __init__(self, path, quiet: bool = False) -> None:
        import csv

        self.path, self.quiet, self.rows, self._csv = path, quiet, [], csv
        with open(path, "w", newline="") as fh:
            csv.writer(fh).writerow(self.FIELDS)

    def __call__(self, row: dict) -> None:
        row = {**row, "f": row["J"],
               "serious": row.get("serious", row["kind"] in ("start", "accepted"))}
        self.rows.append(row)
        with open(self.path, "a", newline="") as fh:
            self._csv.writer(fh).writerow([row.get(k, "") for k in self.FIELDS])
        if not self.quiet:
            print(f"  it {row['iteration']:>3} {row['kind']:<10} J {row['J']:.6e}  "
                  f"trial {row['J_trial']:.4e}  step {row['step_inf']:.2e}  "
                  f"Delta {row['delta']:.2e}  |xi| {row['grad_norm']:.2e}  "
                  f"HF solves {row['hf_solves']}  RB solves {row['rb_solves']}  "
                  f"N {row['basis_size']}  {row['wall_s']:.1f} s", flush=True)


def rb_options(cfg) -> RBOptions:
    """The :class:`RBOptions` of ``rbbench optimize --driver rb``: ``max_outer =
    cfg.max_iter``, the inner bundle's ``eps = cfg.eps`` and metric."""
    if cfg.method != "bundle":
        raise ValueError(f"--method {cfg.method!r}: the rb driver runs the bundle method only")
    return RBOptions(max_outer=cfg.max_iter,
                     inner=BundleOptions(max_iter=100, max_evals=200, eps=cfg.eps,
                                         metric=cfg.metric))


def optimize_rb_run(sc: ShapeScene, cfg, out) -> tuple[RBResult, dict, RBHistory]:
    """``rbbench optimize --driver rb --strategy none``: :func:`optimize_rb` from the initial
    design with :func:`rb_options`; ``history.csv`` in ``out``."""
    opts = rb_options(cfg)
    hist = RBHistory(out / "history.csv", cfg.quiet)
    res = optimize_rb(sc, sc.initial_design(), opts, hist)
    counts = {"hf_solves": res.hf_solves, "rb_solves": res.rb_solves,
              "basis_size": res.basis_size, "J_opt_hf": res.J_hf, "J_opt_reduced": res.f}
    return res, counts, hist

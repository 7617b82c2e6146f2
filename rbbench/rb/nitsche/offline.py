"""The Nitsche formulation's offline steps: affine A_N, F_N; training states of the plain
reduced Newton method; empirical cubature (ECSW) or DEIM at the contact points.

The model and the online solve are in :mod:`rbbench.rb.nitsche.model` (its docstring
describes the reduced residual, the hyper-reduction and its training); the skeleton
(snapshots, primal space) is :mod:`rbbench.rb.offline`; validation adds the pressure and
sigma_nn errors, the plain model's error (the floor for this V_N) and the e_EIM of Benaceur,
Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric variational
inequalities" (talk), slide "EIM errors", along the online iterates.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

import numpy as np

from rbbench.hf.algebra.nitsche import pressure, residual, state
from rbbench.hf.components import default_solver
from rbbench.rb.algorithms.affine import (
    AffineOperator,
    LinearInMu,
    NotAffineError,
    affine_decomposition,
)
from rbbench.rb.algorithms.eim import deim
from rbbench.rb.config import ReduceConfig, config_dict
from rbbench.rb.hyper.contact_eim import HyperReductionError
from rbbench.rb.nitsche.model import (
    NitscheReducedModel,
    _plain_system,
    build_point_evaluator,
    full_points,
    reduced_newton,
    sparse_nnls,
)
from rbbench.rb.nitsche.options import NitscheOptions
from rbbench.rb.offline import (
    DivergedError,
    check_finite,
    eim_grid,
    fixed_contact_points,
    primal_histories,
)
from rbbench.rb.online import ReducedBasis
from rbbench.rb.validation import ReducedStage, xnorm2
from rbbench.registry import Registry
from rbbench.scene.loading import Scene

DEFINITIONS = {
    "err_indicator_u": "residual indicator of the reduced solution (not a bound): "
                       "||R(u_N)||_X' / ||u||_X per validation mu, R the HF Nitsche residual "
                       "at mu (rbbench.hf.algebra.nitsche.residual) in the dual norm of X, "
                       "evaluated with the HF operators (HF cost); err_indicator_u_max / "
                       "_mean over the validation set",
    "indicator_effectivity": "||R(u_N)||_X' / ||u - u_N||_X per validation mu; "
                             "indicator_effectivity_min / _median / _max over the "
                             "validation set (below 1: the indicator underestimates)",
    "err_u": "relative error ||u - u_N||_X / ||u||_X per validation mu (X: the scene's V inner "
             "product on free dofs; u: the HF Nitsche solution); *_max / *_mean over the "
             "validation set (Benaceur et al.'s e_N^u)",
    "err_lam": "Nitsche: relative L2(Gamma_c) error of the contact pressure -[P_gamma]_- at the "
               "quadrature points, ||p(u) - p(u_N)|| / ||p(u)|| (the Nitsche multiplier)",
    "err_snn": "Benaceur et al.'s e_N^nn: ||sigma_nn(u) - sigma_nn(u_N)|| / ||sigma_nn(u)|| in "
               "L2(Gamma_c) (contact quadrature), per validation mu",
    "penetration": "largest pointwise penetration max_q (Un u_N - gap)_+ (m) per validation mu",
    "energy_err": "|J(u_N) - J(u)| / |J(u)|, J = 1/2 a(u, u) - f(u) (Benaceur et al.'s HF energy)",
    "t_online": "wall time of one online solve: evaluate the hyper-reduction points at mu "
                "(pairing restricted to their facets), reduced Newton from the nearest "
                "training solution; median and IQR over validation mus x repeats (s)",
    "speedup": "speed-up against the timed HF solve: median HF Nitsche Newton solve time "
               "(discretise + formulate + solve) / median online time (against the HF floor: "
               "speedup_floor)",
    "eim_error": "training error of the hyper-reduction after each added term: ECSW: relative "
                 "l2 residual of the weighted training sums; DEIM: greedy EIM relative max-norm "
                 "error of the point contributions (ratio of maxima)",
    "eim": "rows: points evaluated online; e_eim_valid: Benaceur et al.'s e_EIM of the reduced "
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


class NitscheReduction:
    """The Nitsche formulation's steps in the offline skeleton (``Formulation.reduction()``).

    Shared fields used: ``primal``, ``N``, ``tol_pod``, ``hyper``, sizes, cache,
    ``online_repeats``; its own options: :class:`NitscheOptions` (no dual space, no
    stabiliser). ``hyper``: ``"auto"``: empirical cubature at the contact points
    (``"ecsw"``, tolerance ``tol_eim`` on the relative residual of the training sums, at
    most ``m_eim`` points, default :data:`ECSW_POINTS_PER_MODE` ``* N``); ``"eim"``: DEIM of
    the point contributions (``"deim"``); ``"none"``: plain.
    """

    name = "nitsche"
    label = "the nitsche formulation"
    #: the hyper-reducers these steps carry out (besides "auto")
    hypers = ("eim", "ecsw", "deim", "none")
    Options = NitscheOptions

    def prepare(self, scene: Scene, config: ReduceConfig, registry: Registry) -> ReduceConfig:
        """Checks before any HF work. A solver that does not solve Nitsche (e.g. the
        default ``ssn``) is replaced by the formulation's (``newton``)."""
        if config.hyper == "affine":
            raise ValueError("hyper 'affine': the Nitsche contact term is nonlinear; use "
                             "'auto' (empirical cubature), 'eim' (DEIM) or 'none' (plain)")
        fixed_contact_points(scene, config.hyper, plain_ok=False)
        solver = config.solver
        if "nitsche" not in registry.get("solver", solver).capabilities.get("formulations",
                                                                              ()):
            config = replace(config, solver=default_solver("nitsche", registry))
        registry.get("primal", config.primal)
        return config

    def reduce(self, ctx: Any) -> NitscheStage:
        return NitscheStage(ctx)


class NitscheStage(ReducedStage):
    """Offline: affine A_N, F_N, plain training iterates, ECSW / DEIM point selection.
    Validation: pressure and sigma_nn errors, the plain model's error, e_EIM."""

    definitions = DEFINITIONS
    beta: dict = {}

    def __init__(self, ctx: Any) -> None:
        self.ctx, config, b, f = ctx, ctx.config, ctx.backend, ctx.formulation
        if not hasattr(b, "contact_layout"):
            raise ValueError(f"backend {config.backend!r} provides no contact layout: the "
                             "reduced Nitsche model evaluates the contact points from it")
        self.layout = b.contact_layout()
        p0 = ctx.problem_at(ctx.scene.default_mu)
        self.theta, self.gamma0 = float(f.theta), float(f.gamma0)
        self.Z = Z = ctx.Z
        self.N = N = int(Z.shape[1])
        self.Zfull = np.zeros((p0.u_lift.size, N))
        self.Zfull[p0.free] = Z
        self.u_lift = p0.u_lift
        self.n_contact = int(self.layout.slave.n * self.layout.n_gauss)
        self.config = config_dict(config)
        self._affine_step(ctx)
        Ysnap, plain_c = self._training_states(ctx)
        self._hyper_step(ctx, Ysnap, plain_c)
        self.err_s: list[float] = []
        self.indicator_eff: list[float] = []
        self.err_plain: list[float] = []
        self.iters: list[int] = []
        self.num_k: dict[int, float] = {}
        self.acc = {"den": 0.0, "num_cv": 0.0, "den_cv": 0.0, "num_t": 0.0, "den_t": 0.0,
                    "num_tcv": 0.0, "den_tcv": 0.0}

    # -- offline -----------------------------------------------------------------------
    def _affine_step(self, ctx: Any) -> None:
        t1 = time.perf_counter()
        ctx.progress("affine decomposition of A_N, F_N (verified by probing)")
        Z, problem_at, bounds = self.Z, ctx.problem_at, ctx.scene.bounds
        try:  # problem_at caches the HF problem at each probe
            self.A_op = AffineOperator(affine_decomposition(
                lambda mu: Z.T @ (problem_at(mu).A @ Z), bounds))
            self.F_op = AffineOperator(affine_decomposition(
                lambda mu: Z.T @ problem_at(mu).F, bounds))
        except NotAffineError as exc:
            raise ValueError(f"reduced Nitsche model: A_N or F_N is {exc}") from None
        self.coef = LinearInMu(np.asarray(bounds).shape[0])
        ctx.timings["affine_s"] = time.perf_counter() - t1

    def _plain_solve(self, mu: np.ndarray, c0: np.ndarray, stops: dict) -> tuple:
        th = self.coef(mu)
        rp = full_points(self.layout, mu, self.Zfull, self.u_lift, self.gamma0)
        res = reduced_newton(_plain_system(self.A_op(th), self.F_op(th), rp, self.theta), c0,
                             keep_iterates=True)
        stops[res.stop_reason] = stops.get(res.stop_reason, 0) + 1
        return res, rp

    def _training_states(self, ctx: Any) -> tuple[list[np.ndarray], np.ndarray]:
        """Point contributions at the plain reduced Newton iterates (the hyper-reduction's
        training data) and the plain reduced solutions at the training parameters."""
        t1 = time.perf_counter()
        mus_train, theta = ctx.mus_train, self.theta
        self.grid = grid = eim_grid(ctx.scene, ctx.options, len(mus_train), per_interval=2)
        c_hf_train = (self.Z.T @ (ctx.X @ ctx.train.U)).T  # projections (X-orthonormal Z)
        plain_c = np.zeros_like(c_hf_train)
        ctx.progress(f"plain reduced Newton on {len(mus_train)} training + {len(grid)} grid "
                     "parameters")
        Ysnap: list[np.ndarray] = []  # point contributions (n_q, N) per training state
        self.plain_stops: dict[str, int] = {}
        near = (_nearest_other(mus_train) if len(mus_train) > 1
                else np.zeros(1, dtype=int))
        for j, mu in enumerate(mus_train):
            res, rp = self._plain_solve(mu, c_hf_train[near[j]], self.plain_stops)
            plain_c[j] = res.c
            Ysnap.extend(rp.contributions(c, theta) for c in res.iterates)
            Ysnap.append(rp.contributions(c_hf_train[j], theta))
        for mu in grid:
            k = int(np.argmin(np.linalg.norm(mus_train - mu, axis=1)))
            res, rp = self._plain_solve(mu, plain_c[k], self.plain_stops)
            Ysnap.extend(rp.contributions(c, theta) for c in res.iterates)
        for Y in Ysnap:
            check_finite("Nitsche hyper-reduction snapshots", Y)
        ctx.timings["plain_training_s"] = time.perf_counter() - t1
        return Ysnap, plain_c

    def _hyper_step(self, ctx: Any, Ysnap: list[np.ndarray], plain_c: np.ndarray) -> None:
        t1 = time.perf_counter()
        config, options, primal, nq = ctx.config, ctx.options, ctx.primal, self.n_contact
        hyper = {"none": "none", "eim": "deim", "deim": "deim"}.get(config.hyper, "ecsw")
        self.histories = {**primal_histories(primal), "plain_training_stops": self.plain_stops}
        sample = np.vstack([ctx.mus_train, self.grid, ctx.mus_valid])
        if hyper == "ecsw":
            ctx.progress("empirical cubature (ECSW) at the contact points")
            ev, extra, info = _ecsw(self.layout, Ysnap, sample, nq, self.N, options,
                                    self.histories)
        elif hyper == "deim":
            ctx.progress("DEIM of the contact point contributions")
            ev, extra, info = _deim(self.layout, Ysnap, sample, nq, self.N, options,
                                    self.histories)
        else:
            ev, extra = build_point_evaluator(self.layout, np.arange(nq), sample), {}
            info = {"method": "none", "rows": int(nq), "M": None}
        info.update({"n_train_states": len(Ysnap),
                     "n_train_mus": int(len(self.grid) + len(ctx.mus_train)),
                     "n_local_dofs": int(ev.local_dofs.size),
                     "master_facets": 0 if ev.layout.master is None
                     else int(ev.layout.master.n)})
        self.histories["eim"] = info
        self.hyper = hyper
        self.model = NitscheReducedModel(
            A=self.A_op, F=self.F_op, coefficients=self.coef, evaluator=ev,
            Z_loc=np.ascontiguousarray(self.Zfull[ev.local_dofs]),
            lift_loc=self.u_lift[ev.local_dofs].copy(), theta=self.theta, gamma0=self.gamma0,
            mode=hyper, start_mus=np.asarray(ctx.mus_train, dtype=float),
            start_c=plain_c.copy(),
            info={"N": self.N, "hyper": hyper, "theta": self.theta, "gamma0": self.gamma0},
            basis=ReducedBasis(self.Z), **extra)
        ctx.timings["hyper_s"] = time.perf_counter() - t1

    # -- validation --------------------------------------------------------------------
    def record_online(self, mu: np.ndarray, solutions: list) -> None:
        res = solutions[-1]
        self.iters.append(res.iterations)
        if not np.all(np.isfinite(res.c)):
            raise DivergedError(f"online Nitsche solve at mu = {mu.tolist()}: non-finite "
                                f"({res.stop_reason})")

    def metrics(self, mu: np.ndarray, p: Any, u: np.ndarray, lam: np.ndarray, res: Any,
                hf: Any) -> dict[str, float]:
        w, u_n = p.weights, hf.u
        pu, pN = pressure(p, u), pressure(p, u_n)
        su, sN = state(p, u).s, state(p, u_n).s
        self.err_s.append(_l2rel(w, su - sN, su))
        pen = float(max(0.0, np.max(p.Un @ u_n - p.gap)))
        self._eim_along_iterates(mu, u)
        return {"err_lam": _l2rel(w, pu - pN, pu), "penetration": pen,
                **self._indicator(p, u, u_n)}

    def _indicator(self, p: Any, u: np.ndarray, u_n: np.ndarray) -> dict[str, float]:
        """The residual indicator ``||R(u_N)||_X'`` at one validation mu (HF operators),
        beside the true error in X (:data:`DEFINITIONS`)."""
        if getattr(self, "_x_solve", None) is None:
            from rbbench.rb.algorithms.infsup import make_solver

            self._x_solve = make_solver(self.ctx.X)
        X = self.ctx.X
        r = residual(p, u_n)
        eta = float(np.sqrt(max(float(r @ np.asarray(self._x_solve(r)).ravel()), 0.0)))
        e = u - u_n
        err = float(np.sqrt(max(float(e @ (X @ e)), 0.0)))
        eff = eta / err if err > 0 else float("inf")
        self.indicator_eff.append(eff)
        return {"err_indicator_u": eta / float(np.sqrt(u @ (X @ u))),
                "indicator_effectivity": eff}

    def summary(self) -> dict[str, Any]:
        """The indicator's effectivity over the validation set (:data:`DEFINITIONS`)."""
        eff = [x for x in self.indicator_eff if np.isfinite(x)]
        return {"indicator_effectivity_min": min(eff) if eff else None,
                "indicator_effectivity_median": float(np.median(eff)) if eff else None,
                "indicator_effectivity_max": max(eff) if eff else None}

    def _eim_along_iterates(self, mu: np.ndarray, u: np.ndarray) -> None:
        """The plain model's error and Benaceur et al.'s e_EIM along the online iterates at mu."""
        X, model, acc, num_k = self.ctx.X, self.model, self.acc, self.num_k
        rp = full_points(self.layout, mu, self.Zfull, self.u_lift, self.gamma0)
        th = self.coef(mu)
        exact = _plain_system(self.A_op(th), self.F_op(th), rp, self.theta)
        plain = reduced_newton(exact, model.initial_guess(mu))
        self.err_plain.append(float(np.sqrt(xnorm2(X, u - self.Z @ plain.c) / xnorm2(X, u))))
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

    def finish(self, histories: dict, timings: dict) -> None:
        acc, num_k = self.acc, self.num_k
        histories["eim"].update({
            "e_eim_valid": _ratio(max(num_k.values(), default=0.0), acc["den"]),
            "e_eim_cv_valid": _ratio(acc["num_cv"], acc["den_cv"]),
            "e_eim_valid_by_iteration": [_ratio(num_k[k], acc["den"]) for k in sorted(num_k)],
            "e_eim_tangent_valid": _ratio(acc["num_t"], acc["den_t"]),
            "e_eim_tangent_cv_valid": _ratio(acc["num_tcv"], acc["den_tcv"])})
        histories["online_iterations"] = self.iters
        histories["err_u_plain"] = self.err_plain
        histories["err_snn"] = self.err_s
        histories["formulation"] = {"name": "nitsche", "theta": self.theta,
                                    "gamma0": self.gamma0}


def _ratio(a: float, b: float) -> float:
    return float(a / b) if b > 0 else 0.0


def _ecsw(layout: Any, Ysnap: list[np.ndarray], sample: np.ndarray, nq: int, N: int,
          options: NitscheOptions, histories: dict) -> tuple[Any, dict, dict]:
    """Empirical cubature: NNLS weights on the training sums (rows of G scaled to norm 1)."""
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
    cap = options.m_eim or ECSW_POINTS_PER_MODE * N
    omega, errors = sparse_nnls(H, g, bb, tol=options.tol_eim, max_terms=cap)
    pts = np.flatnonzero(omega > 0)
    if pts.size == 0:
        raise HyperReductionError("ECSW selected no point: the contact sums are zero")
    ev = build_point_evaluator(layout, pts, sample)
    histories["eim_error"] = errors
    info = {"method": "ecsw", "rows": int(pts.size), "M": int(pts.size),
            "tol": options.tol_eim, "max_points": int(cap), "e_train": float(errors[-1]),
            "weights_sum_over_all": float(omega.sum() / nq)}
    return ev, {"omega": omega[pts]}, info


def _deim(layout: Any, Ysnap: list[np.ndarray], sample: np.ndarray, nq: int, N: int,
          options: NitscheOptions, histories: dict) -> tuple[Any, dict, dict]:
    """DEIM of the point contributions (magic entries ``(point, column)``)."""
    eim = deim(np.stack([Y.ravel() for Y in Ysnap], axis=1), tol=options.tol_eim,
               m_max=options.m_eim)
    if eim.m == 0:
        raise HyperReductionError("DEIM found no term: the contact contributions are zero")
    e_pt, e_col = np.divmod(eim.magic, N)
    pts = np.unique(e_pt)
    ev = build_point_evaluator(layout, pts, sample)
    T = eim.Q.reshape(nq, N, eim.m).sum(axis=0)  # (N, M)
    extra = dict(entry_pt=np.searchsorted(pts, e_pt), entry_col=e_col,
                 TQinv=T @ np.linalg.inv(eim.Q[eim.magic]))
    histories["eim_error"] = eim.errors.tolist()
    info = {"method": "deim", "rows": int(pts.size), "M": int(eim.m),
            "tol": options.tol_eim, "e_train": float(eim.errors[-1])}
    return ev, extra, info


def _nearest_other(mus: np.ndarray) -> np.ndarray:
    d = np.linalg.norm(mus[:, None, :] - mus[None, :, :], axis=2)
    np.fill_diagonal(d, np.inf)
    return np.argmin(d, axis=1)


def _l2rel(w: np.ndarray, diff: np.ndarray, ref: np.ndarray) -> float:
    d = float(np.sqrt(np.sum(w * ref**2)))
    return float(np.sqrt(np.sum(w * diff**2)) / d) if d > 0 else 0.0

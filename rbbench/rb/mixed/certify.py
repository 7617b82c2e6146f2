"""The error bound in the mixed reduction: built offline, measured on the validation set.

:class:`Certifier` builds the online bound (:func:`rbbench.rb.mixed.bounds.build_mixed_bound`)
where the model allows it (``certified = "rigorous"``: online, HF-size independent apart from
the contact rows; with the contact EIM on a two-body scene
:func:`rbbench.rb.mixed.contact_bound.build_contact_bound`), else evaluates the same
theorem with the HF operators at each validation mu (``certified = "rigorous
(HF-evaluated)"``: no online bound), else reports why there is none. Per validation mu it
records the bound beside the true error in the same norm and their ratio (the
effectivity), and the bound's online time side by side with the online solve's (one
interleaved loop of solve, bound, solve, bound ... under the online-time protocol).
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from rbbench.rb.algorithms.bounds import coercivity_constants
from rbbench.rb.mixed.bounds import (
    BoundUnsupported,
    build_mixed_bound,
    constant_in_mu,
    hf_bound,
)
from rbbench.runtime.threads import one_blas_thread
from rbbench.runtime.timing import gc_paused

__all__ = ["BOUND_DEFINITIONS", "Certifier"]

BOUND_DEFINITIONS = {
    "err_bound_u": "certified bound Delta_u(mu) of ||u - u_N||_X (Haasdonk, Salomon & "
                   "Wohlmuth 2012, rbbench.rb.algorithms.bounds) divided by the HF ||u||_X, "
                   "the same normalisation and norm as err_u, per validation mu; "
                   "err_bound_u_max / _mean over the validation set",
    "effectivity": "Delta_u / ||u - u_N||_X per validation mu (>= 1: the bound holds); "
                   "effectivity_min / _median / _max over the validation set",
    "err_bound_lam": "Delta_lam / ||lam||_*: bound of the multiplier error in the natural "
                     "norm ||eta||_* = ||B^T eta||_X' (not the W norm of err_lam), per "
                     "validation mu; err_lam_nat the true error in that norm",
    "certified": "'rigorous': the online bound (affine operators, mu-independent A and B; "
                 "or, on a two-body scene with the contact EIM, the contact rows of B(mu) "
                 "and G(mu) evaluated exactly online and B(mu)^T lam_N compressed with its "
                 "remainder bounded, rbbench.rb.mixed.contact_bound: nothing left out); "
                 "'rigorous (HF-evaluated)': the same theorem with the HF operators at mu (no "
                 "online bound for this model, e.g. an EIM constraint); 'none': no bound, "
                 "the reason in histories.bound. A parameter where B^T is not injective (no "
                 "natural multiplier norm) gets NaN rows, listed in histories.bound.no_bound_at",
    "bound_rho": "the bound's terms per validation mu, divided by the HF ||u||_X: bound_rho "
                 "= ||r_u||_X' (primal residual), bound_sigma = ||[B u_N - G]_+||_*' (the "
                 "violated constraint in the dual natural norm)",
    "bound_eim_residual": "two-body online bound only: the part of rho from the compression "
                          "of the master half b_M of B(mu)^T lam_N, lambda_c^(1/2) ||b_M - "
                          "U U^T b_M||_2 (an upper bound of its X' norm; the slave half is "
                          "exact), per validation mu, divided by the HF ||u||_X; it is "
                          "INCLUDED in bound_rho and err_bound_u",
    "t_bound": "the bound's online time, measured side by side with the reduced solve: at "
               "each validation mu, online_repeats rounds of one reduced solve (its own "
               "time_s, as t_online) then one bound evaluation at its (c, a) (wall time of "
               "the call), under the online-time protocol (one untimed warm-up round, one "
               "BLAS thread, garbage collector paused); t_bound_median_s and "
               "t_bound_solve_median_s: the medians of the bound's and of the solve's times "
               "of that one interleaved loop over validation mus x repeats; t_bound_ratio: "
               "their quotient (not t_bound_median_s over t_online_median_s, which comes "
               "from the separate consecutive solves); t_bound_hf_median_s: certified = "
               "'rigorous (HF-evaluated)': median time of one HF evaluation of the bound "
               "(m solves with X for D = B X^-1 B^T, then the terms)",
}


class Certifier:
    """The bound of a mixed stage: offline build, per-mu numbers, summary."""

    def __init__(self, ctx: Any, stage: Any) -> None:
        t0 = time.perf_counter()
        self.ctx, self.x_solve = ctx, stage.x_solve
        self.info: dict[str, Any] = {}
        self.rows: dict[str, list[float]] = {"t_bound": [], "t_bound_solve": [],
                                             "effectivity": []}
        self.online, self.certified = None, "none"
        self.model, self._warm = stage.model, False
        self.alpha: float | None = None
        self.gamma: float | None = None
        model = stage.model
        cone = bool(stage.dual.is_cone) and float(np.min(stage.Vg, initial=0.0)) >= 0.0
        if stage.hyper == "affine" and cone and ctx.options.bound in ("auto", "online"):
            try:
                self.online = build_mixed_bound(ctx.problem_at, stage.Z_off, stage.Vg, ctx.X,
                                                self.x_solve, ctx.scene.bounds)
                self.alpha, self.gamma = self.online.alpha, self.online.gamma
                self.certified = "rigorous"
                model.bound = self.online
                self.online(ctx.scene.default_mu, np.zeros(stage.Z_off.shape[1]),
                            np.zeros(stage.R))  # compile / load the kernel, untimed
            except BoundUnsupported as exc:
                self.info["online_refused"] = str(exc)
        if stage.hyper == "eim" and cone and ctx.options.bound == "online":
            self._contact_bound(ctx, stage)
        if self.online is None and cone:
            if constant_in_mu(lambda mu: ctx.problem_at(mu).A, ctx.scene.bounds):
                A0 = ctx.problem_at(ctx.scene.default_mu).A
                self.alpha, self.gamma = coercivity_constants(A0, ctx.X)
                self.certified = "rigorous (HF-evaluated)"
            else:
                self.info["refused"] = "a(.,.; mu) depends on mu: no coercivity lower bound"
        elif not cone:
            self.info["refused"] = ("the dual space is not a cone of non-negative generators: "
                                    "lam_N may leave M = {lam >= 0}, which the bound needs")
        self.info.update({"certified": self.certified, "alpha_lb": self.alpha,
                          "gamma_ub": self.gamma,
                          "build_s": time.perf_counter() - t0})

    def _contact_bound(self, ctx: Any, stage: Any) -> None:
        """The online bound with the contact rows evaluated online
        (:mod:`rbbench.rb.mixed.contact_bound`), where the scene allows it."""
        from rbbench.rb.mixed.contact_bound import build_contact_bound
        from rbbench.rb.offline import eim_training_set

        try:
            self.online = build_contact_bound(
                ctx.backend.contact_layout(), ctx.problem_at, stage.Z_off, stage.Vg, ctx.X,
                self.x_solve, ctx.scene.bounds,
                eim_training_set(ctx.scene, ctx.options, ctx.mus_train), ctx.progress,
                pod_max=ctx.options.bound_pod_max)
        except (ValueError, RuntimeError, np.linalg.LinAlgError) as exc:
            # BoundUnsupported, a pairing outside the sampled windows, no Lanczos convergence
            self.online = None
            self.info["online_refused"] = f"{type(exc).__name__}: {exc}"
            return
        self.alpha, self.gamma = self.online.alpha, self.online.gamma
        self.certified = "rigorous"
        stage.model.bound = self.online
        self.info["pod_modes_BtVg"] = int(self.online.U.shape[1])
        self.info["lambda_c"] = float(self.online.lam_c)
        self.online(ctx.scene.default_mu, np.zeros(stage.Z_off.shape[1]), np.zeros(stage.R))

    def metrics(self, mu: np.ndarray, p: Any, u: np.ndarray, lam: np.ndarray, res: Any,
                hf: Any) -> dict[str, float]:
        """Bound, true error (X norm; multipliers in the natural norm), effectivity at mu."""
        if self.certified == "none":
            return {}
        X = self.ctx.X
        e = u - hf.u
        err = float(np.sqrt(max(e @ (X @ e), 0.0)))
        norm = float(np.sqrt(u @ (X @ u)))
        if self.online is not None:
            b = self._side_by_side(mu)
            extra = {"bound_eim_residual": float(getattr(self.online, "last_remainder",
                                                         0.0))}
        else:
            extra = {}
            t0 = time.perf_counter()
            try:
                b = hf_bound(p, X, self.x_solve, hf.u, hf.lam, self.alpha, self.gamma)
            except ValueError as exc:  # B^T not injective at this mu: no natural norm
                self.info.setdefault("no_bound_at", []).append(
                    {"mu": np.asarray(mu, float).tolist(), "reason": str(exc)})
                return dict.fromkeys(_KEYS, float("nan"))  # the per-mu lists stay aligned
            self.rows.setdefault("t_bound_hf", []).append(time.perf_counter() - t0)
        eff = b.delta_u / err if err > 0 else float("inf")
        self.rows["effectivity"].append(eff)
        lam_nat = _xdual(p.B.T @ lam, self.x_solve)
        err_lam = _xdual(p.B.T @ (lam - hf.lam), self.x_solve)
        rel = 1.0 / lam_nat if lam_nat > 0 else float("nan")
        return {"err_bound_u": b.delta_u / norm, "effectivity": eff,
                "err_bound_lam": b.delta_lam * rel, "err_lam_nat": err_lam * rel,
                "bound_rho": b.terms.rho / norm, "bound_sigma": b.terms.sigma / norm,
                **{k: v / norm for k, v in extra.items()}}

    def _side_by_side(self, mu: np.ndarray) -> Any:
        """``online_repeats`` rounds of one reduced solve then one bound at its coefficients
        (the online-time protocol: one untimed round first, one BLAS thread, the garbage
        collector paused); records both times, returns the last bound."""
        reps = max(1, int(self.ctx.config.online_repeats))
        model, bound = self.model, self.online
        t_solve, t_bound = self.rows["t_bound_solve"], self.rows["t_bound"]
        with one_blas_thread(), gc_paused():
            if not self._warm:
                sol = model.solve(mu)
                bound(mu, sol.c, sol.alpha)
                self._warm = True
            for _ in range(reps):
                sol = model.solve(mu)
                t0 = time.perf_counter()
                b = bound(mu, sol.c, sol.alpha)
                t_bound.append(time.perf_counter() - t0)
                t_solve.append(float(sol.time_s))
        return b

    def summary(self) -> dict[str, Any]:
        eff = [x for x in self.rows["effectivity"] if np.isfinite(x)]
        tb, ts = self.rows["t_bound"], self.rows["t_bound_solve"]
        t_bound = float(np.median(tb)) if tb else None
        t_solve = float(np.median(ts)) if ts else None
        return {"certified": self.certified,
                "effectivity_min": min(eff) if eff else None,
                "effectivity_median": float(np.median(eff)) if eff else None,
                "effectivity_max": max(eff) if eff else None,
                "t_bound_median_s": t_bound,
                "t_bound_solve_median_s": t_solve,
                "t_bound_ratio": t_bound / t_solve if t_bound and t_solve else None,
                "t_bound_hf_median_s": (float(np.median(self.rows["t_bound_hf"]))
                                        if self.rows.get("t_bound_hf") else None)}


_KEYS = ("err_bound_u", "effectivity", "err_bound_lam", "err_lam_nat", "bound_rho",
         "bound_sigma")


def _xdual(r: np.ndarray, x_solve: Any) -> float:
    return float(np.sqrt(max(float(r @ np.asarray(x_solve(r)).ravel()), 0.0)))

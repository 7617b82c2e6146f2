"""The mixed formulation's offline steps: dual cone, stabiliser, hyper-reduction.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slide "Decorrelated model reduction": after the primal space
V_N (shared skeleton, :mod:`rbbench.rb.offline`) the multiplier snapshots are compressed to a
cone
``W_R^+ = Span+(Vg)`` (a registered dual compressor: CPG, mCPG, ENG, ...), the saddle point
is stabilised (none / online supremizers / PGA, a registered stabiliser), and the reduced
constraint ``(B_N(mu), G_N(mu))`` is made HF-size independent by the exact affine
decomposition or the contact EIM (hyper ``"affine"`` / ``"eim"``; ``"none"`` projects the
HF operators online). Validation adds the multiplier error, penetration, complementarity
and the inf-sup constants beta_HF, beta_dec, beta_on, beta_off per validation mu.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Any

import numpy as np

from rbbench.rb.algorithms import infsup as inf
from rbbench.rb.algorithms.affine import NotAffineError
from rbbench.rb.compressors import is_online, make_stabilizer, pga_delta, takes_delta
from rbbench.rb.config import ReduceConfig, config_dict
from rbbench.rb.mixed.certify import BOUND_DEFINITIONS, Certifier
from rbbench.rb.mixed.model import build_affine_model, projector
from rbbench.rb.mixed.options import MixedOptions
from rbbench.rb.mixed.plain import PlainProjection, PlainReducedModel
from rbbench.rb.offline import (
    check_finite,
    eim_training_set,
    fixed_contact_points,
    primal_histories,
)
from rbbench.rb.online import PlainArrays, ReducedBasis
from rbbench.rb.validation import ReducedStage, xnorm2
from rbbench.registry import Registry
from rbbench.scene.loading import Scene, SceneError

DEFINITIONS = {
    "err_u": "relative error ||u - u_N||_X / ||u||_X per validation mu (X: the scene's V inner "
             "product on free dofs); *_max / *_mean: max / mean over the validation set",
    "err_lam": "relative error ||lam - lam_R||_W / ||lam||_W per validation mu (W: multiplier "
               "Gram matrix at that mu)",
    "penetration": "largest mean penetration over one HF multiplier's support, "
                   "max_i (B u_N - G)_i / int phi_i clipped at 0 (m), at each validation mu, "
                   "for the reconstructed displacement",
    "complementarity": "|lam_R . (G - B u_N)| / (||lam_R||_2 ||G||_2) at the HF rows, per "
                       "validation mu (0: the reconstruction is complementary)",
    "lam_best_valid": "per validation mu: ||lam - Pi lam||_W / ||lam||_W, Pi the W-projection "
                      "onto the reduced cone (span for a non-cone dual): the best err_lam any "
                      "reduced model on this dual space can reach; lam_best_max: its max",
    "online_stops": "stop reasons of the online solves of the last repeat per validation "
                    "mu, counted",
    "energy_err": "|J(u_N) - J(u)| / |J(u)|, J = 1/2 a(u,u) - f(u) on free dofs (lifted)",
    "beta": "inf-sup constants per validation mu: 'value' is the cone value (kind "
            "'cone-exact': face enumeration; 'cone-upper': best local minimum, an UPPER "
            "estimate), 'span' the inf-sup over span(generators), a LOWER bound of the cone "
            "value; 'is_zero' the exact test for beta = 0 (an SVD bound, else an LP: "
            "rbbench.rb.algorithms.infsup_zero), null when no LP method decided, the reason in "
            "'zero_note'. hf: whole V against the HF "
            "cone W+ (kind 'span-lower-bound': the span value over all multipliers, a lower "
            "bound; 'c': c_HF(mu), the continuity constant of b(mu) on V x W, "
            "sup b(v, eta) / (||v||_X ||eta||_W)); dec: V_N; on: V_N + S_R(mu) (online "
            "supremizers, equal to whole V against the reduced cone); off: V_N + S_PGA. "
            "The raw values carry units (X is the energy inner product: beta ~ 1 / sqrt(E)); "
            "'value_rel' = value / c_HF(mu) and 'span_rel' = span / c_HF(mu) are "
            "dimensionless (invariant under rescaling X or W; Benaceur et al.'s ratio delta_PGA = "
            "sup beta_HF / c_HF), every row divided by the same c_HF(mu) so rows compare",
    "beta_rel": "beta_<name>_rel_min / beta_<name>_span_rel_min: min over the validation "
                "set of the rows' value_rel / span_rel (beta / c_HF(mu), see 'beta'); "
                "beta_<name>_min / beta_<name>_span_min: the same of the raw values",
    "t_online": "wall time of one online solve (assemble the reduced arrays + solve the "
                "reduced saddle point), seconds; median and inter-quartile range over "
                "validation mus x repeats. With hyper = 'none' (e.g. online supremizers) it "
                "INCLUDES the HF assembly at mu, the online supremizers and the projection "
                "(their part alone: t_online_hf_assembly_s): that model's online cost grows "
                "with the HF size",
    "speedup": "speed-up against the timed HF solve: t_hf_median_s (median over the training "
               "and validation snapshots of the stored HF solve time: discretise + formulate "
               "+ solve) / t_online_median_s (against the HF floor: speedup_floor)",
    "e_proj": "dual compressor: relative max projection error of the multiplier snapshots on "
              "the cone after r generators (Benaceur et al., mCPG algorithm (4/4))",
    "e_orth": "normalised distance of each new generator from the previous cone",
    "sigma_max": "PGA: max over the training set of sigma_S(mu) before each addition",
    "pga_delta": "PGA tolerance on sigma_max; default: Benaceur et al.'s rule "
                 "delta = sup_mu beta/c "
                 "over a training subset, beta the inf-sup over span(generators) in whole V "
                 "(a lower bound of beta_on), c the boundedness constant",
    "eim_error": "hyper 'eim': relative max-norm EIM training error of the contact rows "
                 "B(mu) Z_off after each magic row (Benaceur et al.'s 'EIM errors' definition, "
                 "ratio of "
                 "maxima over the training set); eim_error_G the same for G(mu); "
                 "eim.e_eim_valid_BN / _GN: the resulting error of B_N, G_N over the validation "
                 "set; eim_entrywise: Benaceur et al.'s entrywise EIM of B(mu) for comparison",
    **BOUND_DEFINITIONS,
}


def scene_defaults(scene: Scene, config: ReduceConfig) -> ReduceConfig:
    """``config`` with the scene's ``[reduce]`` defaults where the reduction gives none: the
    PGA cap ``k_pga_max`` (stabilizer ``pga`` only; a ``--k-max`` given wins)."""
    cap = scene.data.get("reduce", {}).get("k_pga_max")
    options = config.options
    if cap is None or options.k_pga_max is not None or options.stabilizer != "pga":
        return config
    return replace(config, options=replace(options, k_pga_max=int(cap)))


class MixedReduction:
    """The mixed formulation's steps in the offline skeleton (``Formulation.reduction()``)."""

    name = "mixed"
    label = "the mixed formulation (frictionless scenes)"
    #: the hyper-reducers these steps carry out (besides "auto")
    hypers = ("affine", "eim", "none")
    Options = MixedOptions

    def prepare(self, scene: Scene, config: ReduceConfig, registry: Registry) -> ReduceConfig:
        """Checks before any HF work: the named components exist, an online stabiliser goes
        with the plain model, and the contact points are fixed when hyper ``"eim"`` needs
        them (kept for :meth:`reduce`)."""
        options = config.options
        registry.get("primal", config.primal)  # unknown names fail before HF work
        registry.get("dual", options.dual)
        registry.get("stabilizer", options.stabilizer)
        if is_online(registry, options.stabilizer) and config.hyper in ("affine", "eim"):
            raise SceneError(f"stabilizer {options.stabilizer!r} builds its space online from "
                             f"the HF B(mu): use hyper 'none' or 'auto', not {config.hyper!r}")
        if config.hyper == "eim" and scene.data["geometry"]["kind"] not in ("halfdisks",
                                                                            "hemispheres"):
            raise SceneError(f"{scene.path}: hyper 'eim' (the contact EIM of B(mu) and "
                             "g(mu)) needs a two-body scene (geometry kind 'halfdisks' or "
                             "'hemispheres'); here: "
                             "hyper 'auto', 'affine' or 'none'")
        self.fixed_points = fixed_contact_points(scene, config.hyper)
        return scene_defaults(scene, config)

    def reduce(self, ctx: Any) -> MixedStage:
        return MixedStage(ctx, self.fixed_points)


class MixedStage(ReducedStage):
    """Dual cone, stabiliser and hyper-reduction of the mixed model (offline), then its
    online solve and per-mu metrics (validation)."""

    definitions = DEFINITIONS

    def __init__(self, ctx: Any, fixed_points: bool) -> None:
        self.ctx = ctx
        self.x_solve = inf.make_solver(ctx.X)
        self.Z = ctx.Z
        self.N = int(self.Z.shape[1])
        self.n_contact = int(ctx.train.LAM.shape[0])
        self.config = config_dict(ctx.config)
        self._dual_step(ctx)
        self._stabilizer_step(ctx)
        self._hyper_step(ctx, fixed_points)
        ctx.progress("error bound (offline stage)")
        self.certifier = Certifier(ctx, self)
        self.beta: dict[str, list] = {"hf": [], "dec": [], "on": [], "off": []}
        self.lam_floor: list[float] = []
        self.t_asm: list[float] = []

    # -- offline -----------------------------------------------------------------------
    def _dual_step(self, ctx: Any) -> None:
        options = ctx.options
        t1 = time.perf_counter()
        ctx.progress(f"dual compressor {options.dual}")
        W_ref = ctx.problem_at(ctx.scene.default_mu).W
        self.dual = ctx.registry.create("dual", options.dual)(ctx.train.LAM, W_ref,
                                                              tol=options.tol_dual,
                                                              r_max=options.R)
        self.Vg = self.dual.generators
        check_finite(f"dual compressor {options.dual!r}: the generators", self.Vg)
        self.R = int(self.Vg.shape[1])
        ctx.timings["dual_s"] = time.perf_counter() - t1

    def _stabilizer_step(self, ctx: Any) -> None:
        options, primal = ctx.options, ctx.primal
        t1 = time.perf_counter()
        self.stabilizer = stabilizer = make_stabilizer(ctx.registry, options)
        hyper = ctx.config.hyper
        if stabilizer.online and hyper in ("affine", "eim"):
            raise ValueError(f"stabilizer {options.stabilizer!r} builds its space online from "
                             f"the HF B(mu): use hyper 'none' or 'auto', not {hyper!r}")
        self.histories = {**primal_histories(primal), "e_proj": list(self.dual.e_proj),
                          "e_orth": list(self.dual.e_orth)}
        delta = None
        if takes_delta(ctx.registry, options.stabilizer):
            ctx.progress(f"{options.stabilizer.upper()} (supremizers on the training set)")
            delta = pga_delta(options, [ctx.problem_at(mu) for mu in ctx.mus_train],
                              self.x_solve, self.Vg, ctx.registry)
        self.Z_off, stab_hist = stabilizer.offline(
            self.Z, self.Vg, ctx.X, self.x_solve,
            (ctx.problem_at(mu).B for mu in ctx.mus_train), delta)
        check_finite(f"stabilizer {options.stabilizer!r}: the offline basis", self.Z_off)
        self.K = int(self.Z_off.shape[1] - self.Z.shape[1])
        # beta_off applies to an offline stabiliser only
        self.offline_stab = not stabilizer.online and options.stabilizer != "none"
        self.histories.update({k: v for k, v in stab_hist.items() if k != "K"})
        ctx.timings["stabilizer_s"] = time.perf_counter() - t1

    def _hyper_step(self, ctx: Any, fixed_points: bool) -> None:
        """Exact affine, else (``"auto"``) EIM when the contact points are fixed
        (``fixed_points``), else the plain model."""
        config, options, scene = ctx.config, ctx.options, ctx.scene
        t1 = time.perf_counter()
        hyper, model = config.hyper, None
        surface = scene.data["geometry"]["kind"] == "hemispheres"  # 3D: a cubic map in mu
        if not self.stabilizer.online and hyper in ("auto", "affine", "eim"):
            reduced_ops = projector(ctx.problem_at, self.Z_off, self.Vg)
            if hyper in ("auto", "affine"):
                ctx.progress("exact affine decomposition (verified by probing)")
                try:
                    model = build_affine_model(reduced_ops, scene.bounds,
                                               is_cone=self.dual.is_cone,
                                               max_degree=3 if surface else 1)
                    hyper = "affine"
                except NotAffineError as exc:
                    if hyper == "affine":
                        raise
                    self.histories["affine_refused"] = str(exc)
                    hyper = ("eim" if hasattr(ctx.backend, "contact_layout") and fixed_points
                             else "none")
            if hyper == "eim":
                ctx.progress("EIM on the contact rows (B(mu) Z, G(mu))")
                constraint = _contact_eim(ctx.backend, scene, config.backend, options,
                                          ctx.problem_at,
                                          ctx.mus_train, ctx.mus_valid, self.Z_off, self.Vg,
                                          self.histories)
                model = build_affine_model(reduced_ops, scene.bounds,
                                           is_cone=self.dual.is_cone, constraint=constraint)
        elif hyper == "auto":
            hyper = "none"
        if model is None:  # plain: the HF operators at mu projected online
            stab = self.stabilizer if self.stabilizer.online else None
            model = PlainReducedModel(PlainArrays(ctx.problem_source(), PlainProjection(
                self.Z_off, self.Vg, stab, ctx.X, self.x_solve)))
        model.online_method = options.online_method
        model.basis = ReducedBasis(self.Z_off, self.Vg)
        self.hyper, self.model = hyper, model
        ctx.timings["hyper_s"] = time.perf_counter() - t1

    # -- validation --------------------------------------------------------------------
    def record_online(self, mu: np.ndarray, solutions: list) -> None:
        """The plain model: its HF assembly and projection at mu (``t_online_hf_assembly_s``)."""
        if solutions[-1].assembly_s:
            self.t_asm.append(solutions[-1].assembly_s)

    def metrics(self, mu: np.ndarray, p: Any, u: np.ndarray, lam: np.ndarray, res: Any,
                hf: Any) -> dict[str, float]:
        lam_r, u_n = hf.lam, hf.u
        lam_w2 = xnorm2(p.W, lam)
        err_lam = float(np.sqrt(xnorm2(p.W, lam - lam_r) / lam_w2))
        # the floor: best approximation of lam in the reduced cone (W-projection)
        self.lam_floor.append(float(self.dual.project(lam, p.W)[2]) / np.sqrt(lam_w2))
        disc_gap = p.G - p.B @ u_n  # weighted, per multiplier
        pen = float(max(0.0, -(disc_gap / np.asarray(p.W.sum(axis=1)).ravel()).min()))
        den = np.linalg.norm(lam_r) * np.linalg.norm(p.G)
        compl = float(abs(lam_r @ disc_gap) / den) if den > 0 else 0.0
        self._infsup(p)
        return {"err_lam": err_lam, "penetration": pen, "complementarity": compl,
                **self.certifier.metrics(mu, p, u, lam, res, hf)}

    def summary(self) -> dict[str, Any]:
        """The bound's entries of the row (:data:`BOUND_DEFINITIONS`)."""
        return self.certifier.summary()

    def _infsup(self, p: Any) -> None:
        """beta_HF, beta_dec, beta_on (and beta_off) at one validation mu; H H^T =
        B X^{-1} B^T (m solves), computed once per mu."""
        exact_max_r, X, Vg, Z = self.ctx.options.exact_max_r, self.ctx.X, self.Vg, self.Z
        B, Wm = p.B, p.W
        H = inf.supremizer_operator(B, self.x_solve)
        # beta_HF: whole V against the HF cone W+ (all m multipliers): only the span
        # value (a lower bound of the cone value) is computable at this size
        Wd = Wm.toarray() if hasattr(Wm, "toarray") else np.asarray(Wm)
        b_hf, c_hf = inf.span_constants(H @ H.T, Wd)
        zero = inf.zero_test(H.T)
        self.beta["hf"].append(_normalised({"value": b_hf, "kind": "span-lower-bound",
                                            "span": b_hf, "c": c_hf, "is_zero": zero.is_zero,
                                            "zero_note": zero.note}, c_hf))
        S, M = inf.quotient_matrices(B, X, Vg, Wm, Z=Z)
        self.beta["dec"].append(_labelled(inf.infsup_cone(
            S, M, C=(Z.T @ (B.T @ Vg)), exact_max_r=exact_max_r), c_hf))
        # beta_on: V_N + S_R(mu) contains the supremizer of every cone element, so it
        # equals the whole-V value over the reduced cone, computed from H
        C_on = inf.cone_coupling(H, Vg)
        self.beta["on"].append(_labelled(inf.infsup_cone(
            C_on.T @ C_on, Vg.T @ (Wm @ Vg), C=C_on, exact_max_r=exact_max_r), c_hf))
        if self.offline_stab:
            S, M = inf.quotient_matrices(B, X, Vg, Wm, Z=self.Z_off)
            self.beta["off"].append(_labelled(inf.infsup_cone(
                S, M, C=(self.Z_off.T @ (B.T @ Vg)), exact_max_r=exact_max_r), c_hf))

    def finish(self, histories: dict, timings: dict) -> None:
        if not self.offline_stab:
            self.beta.pop("off")
        histories["lam_best_valid"] = self.lam_floor
        histories["bound"] = self.certifier.info
        if self.t_asm:
            timings["t_online_hf_assembly_s"] = float(np.median(self.t_asm))


def _contact_eim(backend, scene: Scene, backend_name: str, options: MixedOptions, problem_at,
                 mus_train, mus_valid, Z: np.ndarray, Vg: np.ndarray, histories: dict):
    """hyper = "eim": :func:`rbbench.rb.hyper.contact_eim.contact_eim`, its error curves and
    validation."""
    from rbbench.hf.geometry.operators import contact_operators
    from rbbench.hf.geometry.surface import SurfaceLayout, contact_operators_3d
    from rbbench.rb.hyper.contact_eim import contact_eim, entrywise_eim_error
    from rbbench.rb.hyper.surface_eim import ROW_THRESHOLD, build_surface_row_evaluator

    if not hasattr(backend, "contact_layout"):
        raise ValueError(f"hyper 'eim': backend {backend_name!r} provides no contact layout "
                         "(Backend.contact_layout); use hyper 'none'")
    layout = backend.contact_layout()
    p0 = problem_at(mus_train[0])
    mus_eim = eim_training_set(scene, options, mus_train)
    dirichlet = np.setdiff1d(np.arange(layout.n_dofs), p0.free)
    # the lifting at the ends of the training set (cached problems)
    lifts = np.stack([p0.u_lift, problem_at(mus_train[-1]).u_lift])
    B_eim, G_eim = [], []
    for mu in mus_eim:
        c = (contact_operators_3d(layout, mu) if isinstance(layout, SurfaceLayout)
             else contact_operators(layout, mu))
        Bfull = c.B()
        touched = dirichlet[np.asarray(abs(Bfull[:, dirichlet]).sum(axis=0)).ravel() > 0]
        if touched.size and np.any(lifts[:, touched] != 0):  # symmetry planes: zero, allowed
            raise ValueError("hyper 'eim': the contact rows touch Dirichlet dofs of nonzero "
                             "imposed value; the contact EIM assumes the contact zone is away "
                             "from a nonhomogeneous Dirichlet boundary")
        B_eim.append(Bfull[:, p0.free])
        G_eim.append(c.G())
    surface = isinstance(layout, SurfaceLayout)  # 3D: row-aware magic entries
    ceim = contact_eim(layout, B_eim, np.stack(G_eim, axis=1), Z, Vg, p0.free, mus_eim,
                       tol=options.tol_eim, m_max=options.m_eim,
                       row_evaluator=build_surface_row_evaluator if surface else None,
                       row_threshold=ROW_THRESHOLD if surface else 1.0)
    ceim.info["n_eim_train"] = len(mus_eim)
    # validation e_EIM of the reduced constraint (Benaceur et al.'s ratio of maxima over the set)
    num_b = den_b = num_g = den_g = 0.0
    for mu in mus_valid:
        p = problem_at(mu)
        Bn, Gn = Vg.T @ (p.B @ Z), Vg.T @ p.G
        Be, Ge = ceim(mu)
        num_b, den_b = max(num_b, np.abs(Bn - Be).max()), max(den_b, np.abs(Bn).max())
        num_g, den_g = max(num_g, np.abs(Gn - Ge).max()), max(den_g, np.abs(Gn).max())
    histories["eim_error"] = ceim.info["errors_B"]
    histories["eim_error_G"] = ceim.info["errors_G"]
    histories["eim"] = {k: v for k, v in ceim.info.items() if not k.startswith("errors")}
    histories["eim"]["e_eim_valid_BN"] = float(num_b / den_b)
    histories["eim"]["e_eim_valid_GN"] = float(num_g / den_g)
    histories["eim_entrywise"] = entrywise_eim_error(
        [problem_at(mu).B for mu in mus_train], [problem_at(mu).B for mu in mus_valid],
        tol=options.tol_eim)
    return ceim


def _labelled(r: inf.InfSup, c_hf: float) -> dict[str, Any]:
    """One beta row of an :class:`~rbbench.rb.algorithms.infsup.InfSup` (DEFINITIONS["beta"])."""
    return _normalised({"value": float(r.value), "kind": r.kind, "span": float(r.span),
                        "is_zero": r.is_zero, "zero_note": r.zero_note}, c_hf)


def _normalised(row: dict[str, Any], c_hf: float) -> dict[str, Any]:
    """``row`` with ``value_rel = value / c_HF(mu)``, ``span_rel = span / c_HF(mu)`` (NaN
    when ``c_HF = 0``), ``is_zero`` as a bool (None: undecided) and ``zero_note`` (why
    undecided) only when there is one."""
    rel = 1.0 / c_hf if c_hf > 0 else float("nan")
    zero, note = row["is_zero"], row.pop("zero_note", "")
    return {**row, "value_rel": float(row["value"]) * rel, "span_rel": float(row["span"]) * rel,
            "is_zero": None if zero is None else bool(zero), **({"zero_note": note} if note
                                                                else {})}

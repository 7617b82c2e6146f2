"""The offline / online RB pipeline for the mixed formulation (``rbbench reduce``).

scene -> training / validation sets -> HF snapshots (cached) -> primal POD ->
dual compressor (cone) -> stabiliser (none / online supremizers / PGA) ->
reduced model (exact-affine, or "plain": HF assembly projected online) ->
validation metrics and inf-sup constants, each labelled with what it is.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rbbench.hf.model import ProblemCache, discretize_for, make_components
from rbbench.hf.snapshots import compute_snapshots
from rbbench.rb import infsup as inf
from rbbench.rb.compressors import pga_default_delta
from rbbench.rb.mixed_model import (
    ONLINE_METHODS,
    NotAffineError,
    build_affine_model,
    projector,
    solve_reduced,
)
from rbbench.registry import Registry, default_registry
from rbbench.scene.loading import Scene, SceneError
from rbbench.scene.sampling import parameter_set

HYPER = ("auto", "affine", "eim", "none")


class DivergedError(RuntimeError):
    """A stage produced non-finite numbers (the runner's ``diverged`` status)."""


def _check_finite(what: str, a: np.ndarray) -> None:
    if not np.all(np.isfinite(a)):
        raise DivergedError(f"{what} has {int(np.sum(~np.isfinite(a)))} non-finite entries")


@dataclass
class ReduceConfig:
    """Choices of one reduction (CLI ``rbbench reduce``)."""

    primal: str = "pod"
    dual: str = "mcpg"
    stabilizer: str = "pga"
    hyper: str = "auto"
    N: int | None = None
    R: int | None = None
    tol_pod: float = 1e-4
    tol_dual: float = 1e-3
    delta_pga: float | None = None  # default: max beta / c over a training subset (seed rule)
    k_pga_max: int | None = None  # cap on dim S_PGA (the online size is N + K)
    n_train: int | None = None
    n_valid: int | None = None
    backend: str = "skfem"
    formulation: str = "mixed"
    solver: str = "ssn"
    n_jobs: int | None = None
    cache_dir: str = ".rbbench_cache"
    online_repeats: int = 20
    online_method: str = "daqp"  # reduced saddle-point solver: daqp (QP) or pdas (LCP)
    backend_options: dict = field(default_factory=dict)  # e.g. NGSolve {"mesh": "skfem"}
    formulation_options: dict = field(default_factory=dict)  # e.g. Nitsche {"gamma0": 1.0}
    exact_max_r: int = 10
    tol_eim: float = 1e-4
    m_eim: int | None = None
    n_eim_train: int | None = None  # default: 4 (n_train - 1) + 1 grid points (+ training);
    # Nitsche: 2 (n_train - 1) + 1 (rbbench.rb.nitsche_model)

    @property
    def component_options(self) -> dict:
        """``{"backend": ..., "formulation": ...}`` for :func:`rbbench.hf.model.make_components`."""
        return {"backend": dict(self.backend_options),
                "formulation": dict(self.formulation_options)}

    def __post_init__(self) -> None:
        # component names are checked against the registry in reduce(); here only what
        # does not depend on which plugins are installed
        if self.hyper not in HYPER:
            raise ValueError(f"hyper {self.hyper!r}: valid: {', '.join(HYPER)}")
        if self.online_method not in ONLINE_METHODS:
            raise ValueError(f"online method {self.online_method!r}: valid: "
                             f"{', '.join(ONLINE_METHODS)}")
        if self.stabilizer == "supremizer" and self.hyper in ("affine", "eim"):
            raise ValueError("stabilizer 'supremizer' builds V_N + S_R(mu) online from the HF "
                             f"B(mu): use hyper 'none' or 'auto', not {self.hyper!r}")


@dataclass
class ReduceResult:
    """Everything ``rbbench reduce`` reports (``result.json``)."""

    scene: str
    config: dict
    N: int
    R: int
    K_pga: int
    hyper: str
    n_train: int
    n_valid: int
    n_hf_dofs: int
    n_contact: int
    err_u: list[float]
    err_lam: list[float]
    penetration: list[float]
    complementarity: list[float]
    energy_err: list[float]
    beta: dict[str, list]
    t_online: list[float]
    t_hf: list[float]
    timings: dict[str, float]
    histories: dict[str, Any] = field(default_factory=dict)
    definitions: dict[str, str] = field(default_factory=dict)
    model: Any = field(default=None, repr=False)  # ReducedModel (None for hyper 'none')
    valid_mus: Any = field(default=None, repr=False)

    def summary(self) -> dict[str, Any]:
        def finite(reduce_):
            def f(v):
                v = [x for x in v if x is not None and np.isfinite(x)]
                return float(reduce_(v)) if v else None
            return f

        mx, mean, mn = finite(np.max), finite(np.mean), finite(np.min)

        t_on = float(np.median(self.t_online))
        t_hf = float(np.median(self.t_hf))
        out = {
            "scene": self.scene, "N": self.N, "R": self.R, "K_pga": self.K_pga,
            "dim_primal_online": self.N + (self.K_pga if self.config["stabilizer"] == "pga"
                                           else 0),
            "hyper": self.hyper, "M_eim": self.histories.get("eim", {}).get("rows"),
            "n_train": self.n_train, "n_valid": self.n_valid,
            "n_hf_dofs": self.n_hf_dofs, "n_contact": self.n_contact,
            "err_u_max": mx(self.err_u), "err_u_mean": mean(self.err_u),
            "err_lam_max": mx(self.err_lam), "err_lam_mean": mean(self.err_lam),
            "penetration_max": mx(self.penetration), "energy_err_max": mx(self.energy_err),
            "complementarity_max": mx(self.complementarity),
            "lam_best_max": mx(self.histories.get("lam_best_valid", [])),
            "online_stops": self.histories.get("online_stops", {}),
            "beta_kind": {k: _kind_at_min(v) for k, v in self.beta.items()},
            "t_offline_s": self.timings.get("offline_s"),
            "t_online_median_s": t_on,
            "t_online_iqr_s": float(np.subtract(*np.percentile(self.t_online, [75, 25]))),
            "t_hf_median_s": t_hf, "speedup": t_hf / t_on if t_on > 0 else None,
        }
        for name, rows in self.beta.items():
            out[f"beta_{name}_min"] = mn([r["value"] for r in rows])
            out[f"beta_{name}_span_min"] = mn([r["span"] for r in rows])
            out[f"beta_{name}_zero_any"] = bool(any(r["is_zero"] for r in rows))
        out["config"] = self.config
        out["timings"] = self.timings
        out["histories"] = self.histories
        out["per_mu"] = {"err_u": self.err_u, "err_lam": self.err_lam,
                         "penetration": self.penetration,
                         "complementarity": self.complementarity, "beta": self.beta}
        out["definitions"] = self.definitions
        return out


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
            "value; 'is_zero' the exact LP test for beta = 0. hf: whole V against the HF "
            "cone W+ (kind 'span-lower-bound': the span value over all multipliers, a lower "
            "bound); dec: V_N; on: V_N + S_R(mu) (online supremizers, equal to whole V "
            "against the reduced cone); off: V_N + S_PGA",
    "t_online": "wall time of one online solve (assemble the reduced arrays + solve the "
                "reduced saddle point), seconds; median and inter-quartile range over "
                "validation mus x repeats. With hyper = 'none' (e.g. online supremizers) it "
                "INCLUDES the HF assembly at mu, the online supremizers and the projection "
                "(their part alone: t_online_hf_assembly_s): that model's online cost grows "
                "with the HF size",
    "speedup": "median HF solve time / median online time",
    "e_proj": "dual compressor: relative max projection error of the multiplier snapshots on "
              "the cone after r generators (seed 000, mCPG (4/4))",
    "e_orth": "normalised distance of each new generator from the previous cone",
    "sigma_max": "PGA: max over the training set of sigma_S(mu) before each addition",
    "pga_delta": "PGA tolerance on sigma_max; default: the seed's rule delta = sup_mu beta/c "
                 "over a training subset, beta the inf-sup over span(generators) in whole V "
                 "(a lower bound of beta_on), c the boundedness constant",
    "eim_error": "hyper 'eim': relative max-norm EIM training error of the contact rows "
                 "B(mu) Z_off after each magic row (seed 'EIM errors' definition, ratio of "
                 "maxima over the training set); eim_error_G the same for G(mu); "
                 "eim.e_eim_valid_BN / _GN: the resulting error of B_N, G_N over the validation "
                 "set; eim_entrywise: the seed's entrywise EIM of B(mu) for comparison",
}


def _progress(msg: str) -> None:
    return None


def reduce(scene: Scene, config: ReduceConfig, progress: Callable[[str], None] = _progress,
           snapshot_progress: bool = False, registry: Registry | None = None) -> ReduceResult:
    """Run the offline stage on the training set and validate online.

    The primal and dual compressors and the stabiliser are the registered plugins named in
    ``config`` (``registry``: default, the discovered plugins). ``config.formulation ==
    "nitsche"``: the reduced Nitsche model (:func:`rbbench.rb.nitsche_model.reduce_nitsche`).
    """
    if config.formulation == "nitsche":
        from rbbench.rb.nitsche_model import reduce_nitsche

        return reduce_nitsche(scene, config, progress=progress,
                              snapshot_progress=snapshot_progress, registry=registry)
    reg = registry or default_registry()
    for role in ("primal", "dual", "stabilizer"):
        reg.get(role, getattr(config, role))  # unknown names fail before any HF work
    fixed_points = fixed_contact_points(scene, config.hyper)
    t0 = time.perf_counter()
    timings: dict[str, float] = {}
    mus_train, train, valid = training_snapshots(scene, config, config.formulation,
                                                 config.solver, progress, snapshot_progress,
                                                 reg)
    timings["snapshots_s"] = time.perf_counter() - t0

    b, f, _ = make_components(scene, config.backend, config.formulation, config.solver,
                              component_options=config.component_options,
                              registry=reg)
    problem_at = ProblemCache(b, f)
    X = problem_at.X_free(scene.default_mu)
    x_solve = inf.make_solver(X)
    W_ref = problem_at(scene.default_mu).W

    t1 = time.perf_counter()
    primal = primal_basis(reg, config, train.U, X, progress)
    Z = primal.Z
    timings["primal_s"] = time.perf_counter() - t1

    t1 = time.perf_counter()
    progress(f"dual compressor {config.dual}")
    dual = reg.create("dual", config.dual)(train.LAM, W_ref, tol=config.tol_dual, r_max=config.R)
    Vg = dual.generators
    _check_finite(f"dual compressor {config.dual!r}: the generators", Vg)
    timings["dual_s"] = time.perf_counter() - t1

    # stabiliser
    t1 = time.perf_counter()
    stabilizer = make_stabilizer(reg, config)
    if stabilizer.online and config.hyper in ("affine", "eim"):
        raise ValueError(f"stabilizer {config.stabilizer!r} builds its space online from the HF "
                         f"B(mu): use hyper 'none' or 'auto', not {config.hyper!r}")
    histories: dict[str, Any] = {
        "pod_singular_values": primal.history.get("singular_values", []),
        "primal": {k: v for k, v in primal.history.items() if k != "singular_values"},
        "e_proj": list(dual.e_proj), "e_orth": list(dual.e_orth)}
    delta = None
    if config.stabilizer == "pga":
        progress("PGA (supremizers on the training set)")
        delta = pga_delta(config, [problem_at(mu) for mu in mus_train], x_solve, Vg)
    Z_off, stab_hist = stabilizer.offline(Z, Vg, X, x_solve,
                                          (problem_at(mu).B for mu in mus_train), delta)
    _check_finite(f"stabilizer {config.stabilizer!r}: the offline basis", Z_off)
    K = int(Z_off.shape[1] - Z.shape[1])
    offline_stab = not stabilizer.online and config.stabilizer != "none"  # beta_off applies
    histories.update({k: v for k, v in stab_hist.items() if k != "K"})
    timings["stabilizer_s"] = time.perf_counter() - t1

    # hyper-reduction / reduced model
    t1 = time.perf_counter()
    hyper = config.hyper
    model = None
    if not stabilizer.online and hyper in ("auto", "affine", "eim"):
        reduced_ops = projector(problem_at, Z_off, Vg)
        if hyper in ("auto", "affine"):
            progress("exact affine decomposition (verified by probing)")
            try:
                model = build_affine_model(reduced_ops, scene.bounds, is_cone=dual.is_cone)
                hyper = "affine"
            except NotAffineError as exc:
                if hyper == "affine":
                    raise
                histories["affine_refused"] = str(exc)
                hyper = "eim" if hasattr(b, "contact_layout") and fixed_points else "none"
        if hyper == "eim":
            progress("EIM on the contact rows (B(mu) Z, G(mu))")
            constraint = _contact_eim(b, scene, config, problem_at, mus_train, valid.mus,
                                       Z_off, Vg, histories)
            model = build_affine_model(reduced_ops, scene.bounds, is_cone=dual.is_cone,
                                       constraint=constraint)
    elif hyper == "auto":
        hyper = "none"
    timings["hyper_s"] = time.perf_counter() - t1
    timings["offline_s"] = time.perf_counter() - t0

    # online validation
    progress("online validation")
    err_u, err_lam, pen, e_en, t_on, t_asm = [], [], [], [], [], []
    compl: list[float] = []
    lam_floor: list[float] = []
    stops: dict[str, int] = {}
    beta: dict[str, list] = {"hf": [], "dec": [], "on": [], "off": []}
    for j, mu in enumerate(valid.mus):
        p = problem_at(mu)
        u = valid.U[:, j]
        lam = valid.LAM[:, j]
        if model is not None:
            Zu = Z_off
            runs = []
            for _ in range(config.online_repeats):
                res = model.solve(mu, method=config.online_method)
                runs.append(res.time_s)
        else:
            # the plain model's online step starts from the HF operators at mu: time a
            # fresh assembly (the cached problem serves the error evaluation)
            ta = time.perf_counter()
            p_fresh = f.build(discretize_for(b, f, mu))
            Zu = Z_off
            if stabilizer.online:
                Zu = stabilizer.online_basis(Z_off, Vg, X, x_solve, p_fresh.B)
            arrays = projector(lambda _mu, p=p_fresh: p, Zu, Vg)(mu)
            t_asm.append(time.perf_counter() - ta)
            runs = []
            for _ in range(config.online_repeats):
                res = solve_reduced(*arrays, method=config.online_method)
                runs.append(res.time_s + t_asm[-1])
        t_on.extend(runs)
        u_n = Zu @ res.c
        lam_r = Vg @ res.alpha
        err_u.append(float(np.sqrt(_xn(X, u - u_n) / _xn(X, u))))
        err_lam.append(float(np.sqrt(_xn(p.W, lam - lam_r) / _xn(p.W, lam))))
        # the floor: best approximation of lam in the reduced cone (W-projection)
        lam_floor.append(float(dual.project(lam, p.W)[2]) / np.sqrt(_xn(p.W, lam)))
        disc_gap = p.G - p.B @ u_n  # weighted, per multiplier
        pen.append(float(max(0.0, -(disc_gap / np.asarray(p.W.sum(axis=1)).ravel()).min())))
        den = np.linalg.norm(lam_r) * np.linalg.norm(p.G)
        compl.append(float(abs(lam_r @ disc_gap) / den) if den > 0 else 0.0)
        stops[res.stop_reason] = stops.get(res.stop_reason, 0) + 1
        J = _energy(p, u)
        e_en.append(abs(_energy(p, u_n) - J) / abs(J) if J != 0 else float("nan"))
        # inf-sup constants; H H^T = B X^{-1} B^T (m solves), computed once per mu
        B, Wm = p.B, p.W
        H = inf.supremizer_operator(B, x_solve)
        # beta_HF: whole V against the HF cone W+ (all m multipliers): only the span
        # value (a lower bound of the cone value) is computable at this size
        Wd = Wm.toarray() if hasattr(Wm, "toarray") else np.asarray(Wm)
        b_hf = inf.infsup_span(H @ H.T, Wd)
        beta["hf"].append({"value": b_hf, "kind": "span-lower-bound", "span": b_hf,
                           "is_zero": bool(inf.beta_zero_test(H.T))})
        S, M = inf.quotient_matrices(B, X, Vg, Wm, Z=Z)
        beta["dec"].append(_labelled(inf.infsup_cone(
            S, M, C=(Z.T @ (B.T @ Vg)), exact_max_r=config.exact_max_r)))
        # beta_on: V_N + S_R(mu) contains the supremizer of every cone element, so it
        # equals the whole-V value over the reduced cone, computed from H
        C_on = inf.cone_coupling(H, Vg)
        beta["on"].append(_labelled(inf.infsup_cone(
            C_on.T @ C_on, Vg.T @ (Wm @ Vg), C=C_on, exact_max_r=config.exact_max_r)))
        if offline_stab:
            S, M = inf.quotient_matrices(B, X, Vg, Wm, Z=Z_off)
            beta["off"].append(_labelled(inf.infsup_cone(
                S, M, C=(Z_off.T @ (B.T @ Vg)), exact_max_r=config.exact_max_r)))
    if not offline_stab:
        beta.pop("off")
    histories["online_stops"] = stops
    histories["lam_best_valid"] = lam_floor
    if t_asm:
        timings["t_online_hf_assembly_s"] = float(np.median(t_asm))
    timings["total_s"] = time.perf_counter() - t0
    return ReduceResult(
        scene=scene.name, config=asdict(config), N=int(Z.shape[1]), R=int(Vg.shape[1]),
        K_pga=K, hyper=hyper, n_train=len(mus_train), n_valid=len(valid.mus),
        n_hf_dofs=int(train.n_dofs), n_contact=int(train.LAM.shape[0]),
        err_u=err_u, err_lam=err_lam, penetration=pen, complementarity=compl,
        energy_err=e_en, beta=beta,
        t_online=t_on, t_hf=[float(t) for t in np.concatenate([train.times, valid.times])],
        timings=timings, histories=histories, definitions=DEFINITIONS, model=model,
        valid_mus=np.asarray(valid.mus))


def make_stabilizer(reg: Registry, config: ReduceConfig) -> Any:
    """The registered stabiliser ``config.stabilizer`` (PGA capped at ``k_pga_max``)."""
    opts = {"max_dim": config.k_pga_max} if config.stabilizer == "pga" else {}
    return reg.create("stabilizer", config.stabilizer, **opts)


def pga_delta(config: ReduceConfig, problems: list, x_solve: Any,
              Vg: np.ndarray) -> float | None:
    """The PGA tolerance: ``config.delta_pga``, else the seed's rule (friction example:
    ``delta_PGA = sup beta_HF / c_HF = 0.072``) with beta the span value over the reduced
    cone (a lower bound), over every fifth training problem. ``None`` unless PGA."""
    if config.stabilizer != "pga":
        return None
    if config.delta_pga is not None:
        return config.delta_pga
    probe = problems[:: max(1, len(problems) // 5)]
    return pga_default_delta([p.B for p in probe], [p.W for p in probe], x_solve, Vg,
                             fraction=1.0, over="max")


def fixed_contact_points(scene: Scene, hyper: str, plain_ok: bool = True) -> bool:
    """Whether the contact quadrature points are the same at every mu (hyper-reduction by
    rows or points needs them).

    ``[discretization] contact_integration = "segmented"`` moves them with mu: an explicit
    ``hyper = "eim"`` (or any reduced model when ``plain_ok`` is false: the reduced
    Nitsche model evaluates its contact points at fixed positions) raises a
    :class:`~rbbench.scene.loading.SceneError`; ``"auto"`` falls back to the plain model.
    """
    disc = scene.data.get("discretization", {})
    rule = disc.get("contact_integration", "gauss")
    geo = scene.data.get("geometry", {})
    two_bodies = geo.get("kind") == "halfdisks" and geo.get("lower", "half_disk") == "half_disk"
    if rule == "gauss" or not two_bodies:
        return True  # segmentation needs a master mesh: rigid / obstacle points are fixed
    if hyper == "eim" or not plain_ok:
        what = "the reduced Nitsche model" if not plain_ok else "hyper 'eim'"
        alt = "" if not plain_ok else "use hyper 'auto' or 'none' (plain reduced model), or "
        raise SceneError(f"{scene.path}: [discretization] contact_integration = {rule!r} "
                         f"moves the contact points with mu, so {what} (points fixed "
                         f"offline) cannot be built; {alt}set contact_integration = 'gauss'")
    return False


def eim_grid(scene: Scene, config: ReduceConfig, n_train: int, per_interval: int = 4
             ) -> np.ndarray:
    """``config.n_eim_train`` parameters (default ``per_interval (n_train - 1) + 1``): a
    uniform grid of D for one parameter, else the scene's training sampling."""
    lo, hi = scene.bounds[:, 0], scene.bounds[:, 1]
    n_grid = config.n_eim_train or per_interval * (n_train - 1) + 1
    if len(lo) == 1:
        return lo + np.linspace(0.0, 1.0, n_grid)[:, None] * (hi - lo)
    return parameter_set(scene, "train", n_grid)


def eim_training_set(scene: Scene, config: ReduceConfig, mus_train: np.ndarray) -> np.ndarray:
    """The EIM training set: the snapshot parameters plus :func:`eim_grid` (default
    4 (n_train - 1) + 1 points). Only the contact operators are evaluated there (no HF
    solve), so it can be much denser (seed: 61, 150)."""
    return np.vstack([np.asarray(mus_train), eim_grid(scene, config, len(mus_train))])


def primal_basis(reg: Registry, config: ReduceConfig, U: np.ndarray, X: Any,
                 progress: Callable[[str], None] = _progress) -> Any:
    """The registered primal compressor ``config.primal`` on the displacement snapshots
    ``U`` in the X inner product (size ``config.N``, else tolerance ``config.tol_pod``);
    a non-finite basis raises :class:`DivergedError`."""
    progress(f"primal {config.primal}")
    primal = reg.create("primal", config.primal)(
        U, X, tol=None if config.N else config.tol_pod, n=config.N)
    _check_finite(f"primal compressor {config.primal!r}: the basis", primal.Z)
    return primal


def training_snapshots(scene: Scene, config: ReduceConfig, formulation: str, solver: str,
                       progress: Callable[[str], None] = _progress,
                       snapshot_progress: bool = False,
                       registry: Registry | None = None) -> tuple[np.ndarray, Any, Any]:
    """``(mus_train, train, valid)``: the training / validation sets of ``config`` and their
    HF snapshots (:func:`rbbench.hf.snapshots.compute_snapshots`, cached on disk)."""
    mus_train = parameter_set(scene, "train", config.n_train)
    mus_valid = parameter_set(scene, "valid", config.n_valid)
    snap_kw = dict(backend=config.backend, formulation=formulation, solver=solver,
                   cache_dir=Path(config.cache_dir), n_jobs=config.n_jobs,
                   progress=snapshot_progress, component_options=config.component_options,
                   registry=registry)
    progress(f"HF snapshots ({formulation}): {len(mus_train)} training, {len(mus_valid)} "
             "validation")
    return (mus_train, compute_snapshots(scene, mus_train, **snap_kw),
            compute_snapshots(scene, mus_valid, **snap_kw))


def _contact_eim(backend, scene: Scene, config: ReduceConfig, problem_at, mus_train,
                  mus_valid, Z: np.ndarray, Vg: np.ndarray, histories: dict):
    """hyper = "eim": :func:`rbbench.rb.contact_eim.contact_eim`, its error curves and
    validation."""
    from rbbench.hf.contact_geometry import contact_operators
    from rbbench.rb.contact_eim import contact_eim, entrywise_eim_error

    if not hasattr(backend, "contact_layout"):
        raise ValueError(f"hyper 'eim': backend {config.backend!r} provides no contact layout "
                         "(Backend.contact_layout); use hyper 'none'")
    layout = backend.contact_layout()
    p0 = problem_at(mus_train[0])
    mus_eim = eim_training_set(scene, config, mus_train)
    dirichlet = np.setdiff1d(np.arange(layout.n_dofs), p0.free)
    B_eim, G_eim = [], []
    for mu in mus_eim:
        c = contact_operators(layout, mu)
        Bfull = c.B()
        if Bfull[:, dirichlet].nnz:
            raise ValueError("hyper 'eim': the contact rows touch Dirichlet dofs; the contact "
                             "EIM assumes the contact zone is away from the Dirichlet boundary")
        B_eim.append(Bfull[:, p0.free])
        G_eim.append(c.G())
    ceim = contact_eim(layout, B_eim, np.stack(G_eim, axis=1), Z, Vg, p0.free, mus_eim,
                       tol=config.tol_eim, m_max=config.m_eim)
    ceim.info["n_eim_train"] = len(mus_eim)
    # validation e_EIM of the reduced constraint (seed's ratio of maxima over the set)
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
        tol=config.tol_eim)
    return ceim


def _kind_at_min(rows: list[dict]) -> str | None:
    """Kind of the beta value at which the minimum over the validation set is reached."""
    ok = [r for r in rows if r["value"] is not None and np.isfinite(r["value"])]
    return min(ok, key=lambda r: r["value"])["kind"] if ok else None


def _xn(X, v: np.ndarray) -> float:
    return float(v @ (X @ v))


def _energy(p, u_free: np.ndarray) -> float:
    return float(0.5 * u_free @ (p.A @ u_free) - p.F @ u_free)


def _labelled(r: inf.InfSup) -> dict[str, Any]:
    return {"value": float(r.value), "kind": r.kind, "span": float(r.span),
            "is_zero": bool(r.is_zero)}

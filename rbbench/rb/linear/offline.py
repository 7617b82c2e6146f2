"""The offline skeleton for the linear scenes: no dual, no stabiliser, no contact.

The same steps and objects as :func:`rbbench.rb.offline.offline` (training / validation
sets, cached HF snapshots, a primal space, the formulation's ``reduction()`` steps building
a :class:`~rbbench.rb.validation.ReducedStage`, then the shared
:func:`~rbbench.rb.validation.validate`), with the HF solves of :mod:`rbbench.hf.linear.model`
instead of a contact solver: nothing of the contact pipeline is built.

* ``thermal`` (elliptic): primal = the registered compressor (``pod``: Benaceur, Drouet,
  Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric variational inequalities"
  (talk), slide "Method 1: Proper Orthogonal Decomposition").
* ``heat`` (implicit Euler): primal ``pod`` is POD-greedy (Haasdonk & Ohlberger 2008): POD
  in time of the projection error of the trajectory the estimator ranks worst over the
  training set, one mode per iteration, up to ``N`` (else tolerance ``tol_pod`` on the
  relative estimator). Errors are in the discrete ``L2(0, T; X)`` norm: validation sees
  flattened trajectories and ``X = kron(dt I_K, X)``.

The reduced model and its estimator: :mod:`rbbench.rb.linear.model`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from types import SimpleNamespace
from typing import Any

import numpy as np
import scipy.sparse as sp

from rbbench.hf.linear.model import NO_CONTACT, LinearHF, linear_snapshots, space_time_norm
from rbbench.rb.algorithms.infsup import make_solver
from rbbench.rb.compressors import PrimalBasis
from rbbench.rb.config import ReduceConfig, config_dict
from rbbench.rb.linear.model import ReducedLinear, build_reduced, coercivity_reference
from rbbench.rb.offline import (
    OfflineContext,
    check_finite,
    clipped_size,
    prepare_config,
    primal_basis,
    primal_histories,
)
from rbbench.rb.online import ReducedBasis
from rbbench.rb.validation import ReducedStage, ReduceResult, validate, xnorm2
from rbbench.registry import Registry, default_registry
from rbbench.runtime.threads import one_blas_thread
from rbbench.scene.linear import check_physics, is_parabolic
from rbbench.scene.loading import Scene, SceneError
from rbbench.scene.sampling import parameter_set

__all__ = ["DEFINITIONS", "LinearReduction", "LinearStage", "pod_greedy", "reduce_linear"]

DEFINITIONS = {
    "err_u": "relative error ||u - u_N|| / ||u|| per validation mu: X norm (thermal: the "
             "H1_0 seminorm |.|_1, h1_semi; h1: the full H1 norm); heat: the discrete "
             "L2(0, T; X) norm (dt sum_k ||.||_X^2)^(1/2) over the implicit Euler steps",
    "err_est": "the a posteriori error bound divided by ||u||: elliptic ||r||_X' / alpha_LB; "
               "heat ((||e0||_M^2 + dt / alpha_LB sum_k ||r^k||_X'^2) / alpha_LB)^(1/2) "
               "(rbbench.rb.linear.model); per validation mu",
    "effectivity": "bound / true error, ||.|| as err_u (>= 1: the bound is rigorous), per "
                   "validation mu; effectivity_min / _max over the validation set",
    "alpha_lb": "min-theta coercivity lower bound alpha(mu_ref) min_q theta_q(mu) / "
                "theta_q(mu_ref), mu_ref the upper corner of D (thermal: min_i mu_i)",
    "t_online": "wall time of one reduced solve (assemble the affine sums + dense solve; "
                "heat: one LU, K triangular solves), without the estimator (t_estimate), "
                "one BLAS thread; median over validation mus x repeats",
    "pod_greedy": "heat: estimator (relative to ||u_N||) of the worst training mu before "
                  "each POD-greedy addition, and the training index picked",
}


@dataclass
class LinearOptions:
    """The linear formulation takes no option of its own: no dual space, no stabiliser, no
    solver (its reduction uses the shared fields only)."""


class LinearReduction:
    """The linear formulation's steps in the offline skeleton (``Formulation.reduction()``)."""

    name = "linear"
    label = "the linear formulation"
    Options = LinearOptions
    takes_solver = False

    def prepare(self, scene: Scene, config: ReduceConfig, registry: Registry) -> ReduceConfig:
        """Checks before any HF work: a linear scene, no solver, a registered primal
        compressor (``pod`` for heat: POD-greedy), hyper ``auto`` / ``affine`` (exact
        affine)."""
        check_physics(scene)
        if config.solver is not None:
            raise SceneError(f"{scene.path}: a linear scene (no contact) has one direct "
                             f"solve: no solver option (got {config.solver!r})")
        registry.get("primal", config.primal)
        if is_parabolic(scene) and config.primal != "pod":
            raise SceneError(f"{scene.path}: physics 'heat' is reduced by POD-greedy (primal "
                             f"'pod'), not {config.primal!r}")
        if config.hyper not in ("auto", "affine"):
            raise SceneError(f"{scene.path}: a linear scene is exactly affine in mu: hyper "
                             f"'auto' or 'affine', not {config.hyper!r}")
        return config

    def reduce(self, ctx: OfflineContext) -> LinearStage:
        return LinearStage(ctx)

    def run(self, scene: Scene, config: ReduceConfig, progress: Callable[[str], None],
            registry: Registry) -> ReduceResult:
        """The linear scenes' own skeleton (their HF snapshots need no contact components):
        :func:`run_linear`."""
        return run_linear(scene, config, progress, registry)


class LinearStage(ReducedStage):
    """The reduced model of ``ctx.Z`` (probed affine terms + estimator), its online solve
    and per-mu numbers (error bound, effectivity)."""

    definitions = DEFINITIONS
    hyper = "affine"

    def __init__(self, ctx: OfflineContext) -> None:
        t0 = time.perf_counter()
        self.ctx, self.Z = ctx, ctx.Z
        self.N, self.R, self.K, self.n_contact = int(self.Z.shape[1]), None, None, None
        lin = ctx.linear
        self.model = lin.build(self.Z)
        check_finite("reduced operators", self.model.A)
        ctx.timings["hyper_s"] = time.perf_counter() - t0
        self.config = {**config_dict(ctx.config), "hyper": "affine"}
        self.histories = {**primal_histories(ctx.primal), "alpha_ref": lin.alpha_ref,
                          "mu_ref": lin.mu_ref.tolist()}
        self.beta: dict[str, list] = {}
        self.t_estimate: list[float] = []
        self.effectivity: list[float] = []

    def metrics(self, mu: np.ndarray, problem: Any, u: np.ndarray, lam: np.ndarray,
                result: Any, hf: Any) -> dict[str, float]:
        t0 = time.perf_counter()
        bound = self.model.estimate(mu, result.u)
        self.t_estimate.append(time.perf_counter() - t0)
        err = np.sqrt(xnorm2(self.ctx.X, u - hf.u))
        norm = np.sqrt(xnorm2(self.ctx.X, u))
        self.effectivity.append(bound / err if err > 0 else np.nan)
        return {"err_est": bound / norm, "effectivity": self.effectivity[-1],
                "alpha_lb": self.model.alpha_lb(mu)}

    def finish(self, histories: dict, timings: dict) -> None:
        timings["t_estimate_median_s"] = float(np.median(self.t_estimate))

    def summary(self) -> dict[str, Any]:
        eff = [e for e in self.effectivity if np.isfinite(e)]
        return {"reason": NO_CONTACT, "effectivity_min": min(eff) if eff else None,
                "online_method": "dense LU (numpy / scipy)"}


class LinearData:
    """The spatial problems at mu (cached), ``X``, the min-theta reference and the builder
    of reduced models (:func:`rbbench.rb.linear.model.build_reduced`)."""

    def __init__(self, hf: LinearHF, scene: Scene) -> None:
        self.hf, self.scene = hf, scene
        self._cache: dict[bytes, Any] = {}
        self.bounds = scene.bounds
        self.mu_ref = self.bounds[:, 1].copy()
        p = self(self.mu_ref)
        self.X = p.X[p.free][:, p.free].tocsr()
        self.x_solve = make_solver(self.X)
        self.alpha_ref = coercivity_reference(p.A, self.X)

    def __call__(self, mu: Any) -> Any:
        key = np.asarray(mu, float).tobytes()
        if key not in self._cache:
            self._cache[key] = self.hf.problem(mu)
        return self._cache[key]

    def build(self, Z: np.ndarray) -> ReducedLinear:
        model = build_reduced(self, Z, self.bounds, self.x_solve, self.mu_ref, self.alpha_ref)
        model.parameters = self.scene.parameter_space
        model.basis = ReducedBasis(Z)
        return model


#: POD-greedy stops (``"rank"``) when the projection error of the trajectory it picks has
#: an X-norm below this fraction of that trajectory's: nothing new is left in the training set
RANK_TOL = 1e-10


def pod_greedy(lin: LinearData, U: np.ndarray, mus: np.ndarray, n_max: int,
               tol: float | None) -> PrimalBasis:
    """POD-greedy (Haasdonk & Ohlberger 2008) on the training trajectories ``U`` (flattened
    ``(K, n)`` columns): start from the largest trajectory, then add the first X-POD mode of
    the projection error of the trajectory with the largest relative estimator.

    At most ``n_max`` modes, and never more than the training set spans (``n_train K`` and
    ``n``). ``history["pod_greedy"]["stop_reason"]``: ``"size"`` (``n_max`` modes),
    ``"tolerance"`` (the worst relative estimator ``<= tol``), ``"rank"`` (the picked
    trajectory's projection error is below :data:`RANK_TOL` of its norm: the training set
    is exhausted), ``"estimator not finite"``.
    """
    n = lin.X.shape[0]
    trajs = [U[:, j].reshape(-1, n) for j in range(U.shape[1])]
    cap = min(n_max, sum(t.shape[0] for t in trajs), n)
    Z = np.zeros((n, 0))
    picks, sigma, reason = [], [], "size"
    while Z.shape[1] < cap:
        if Z.shape[1] == 0:
            j = int(np.argmax([np.linalg.norm(t) for t in trajs]))
        else:
            model = lin.build(Z)
            est = []
            for mu in mus:
                c = model.coefficients(mu)
                est.append(model.estimate(mu, c) / max(np.linalg.norm(c), 1e-300))
            if not np.all(np.isfinite(est)):
                reason = "estimator not finite"
                break
            j = int(np.argmax(est))
            sigma.append(float(est[j]))
            if tol is not None and est[j] <= tol:
                reason = "tolerance"
                break
        E = trajs[j].T - Z @ (Z.T @ (lin.X @ trajs[j].T))
        w, V = np.linalg.eigh(E.T @ (lin.X @ E))  # first X-POD mode of E (K x K)
        T = trajs[j].T
        if w[-1] <= RANK_TOL**2 * float(np.sum(T * (lin.X @ T))):
            reason = "rank"
            break
        mode = E @ V[:, -1:]
        mode = mode - Z @ (Z.T @ (lin.X @ mode))  # re-orthogonalise
        Z = np.hstack([Z, mode / np.sqrt(xnorm2(lin.X, mode[:, 0]))])
        picks.append(j)
    if reason == "size" and Z.shape[1] < n_max:
        reason = "rank"  # the cap was the training set's span
    return PrimalBasis(Z=Z, name="pod-greedy",
                       history={"pod_greedy": {"sigma": sigma, "picks": picks,
                                               "stop_reason": reason}})


def _space_time(lin: LinearData) -> tuple[Any, Callable[[Any], Any]]:
    """``(X_st, problem_at)`` of the validation in L2(0, T; X): the space-time norm and a
    problem view without energy (``A = 0``, ``F = 0``: energy_err is NaN)."""
    p = lin(lin.mu_ref)
    X_st = space_time_norm(lin.X, p.dt, p.steps)
    n = X_st.shape[0]
    view = SimpleNamespace(A=sp.csr_matrix((n, n)), F=np.zeros(n))
    return X_st, lambda mu: view


def reduce_linear(scene: Scene, config: ReduceConfig,
                  progress: Callable[[str], None] = lambda m: None,
                  registry: Registry | None = None) -> ReduceResult:
    """Offline (snapshots, primal / POD-greedy, the formulation's stage) then the shared
    validation, for a linear scene (module docstring); :func:`rbbench.rb.offline.reduce`
    dispatches a linear formulation here."""
    reg = registry or default_registry()
    steps, config = prepare_config(scene, config, reg)
    return steps.run(scene, config, progress, reg)


def run_linear(scene: Scene, config: ReduceConfig, progress: Callable[[str], None],
               reg: Registry) -> ReduceResult:
    """The linear skeleton on a prepared configuration (``LinearReduction.run``)."""
    steps = LinearReduction()
    t0 = time.perf_counter()
    mus_train = parameter_set(scene, "train", config.n_train)
    mus_valid = parameter_set(scene, "valid", config.n_valid)
    hf = LinearHF(scene, config.backend, reg, config.backend_options)
    progress(f"HF snapshots (linear): {len(mus_train)} training, {len(mus_valid)} validation")
    train = linear_snapshots(scene, mus_train, hf, config.backend, config.cache_dir, reg)
    valid = linear_snapshots(scene, mus_valid, hf, config.backend, config.cache_dir, reg)
    timings = {"snapshots_s": time.perf_counter() - t0}
    with one_blas_thread():  # small dense algebra: one thread (2 shared cores)
        t1 = time.perf_counter()
        lin = LinearData(hf, scene)
        clipped = None
        if is_parabolic(scene):
            progress(f"primal POD-greedy (N = {config.N})")
            primal = pod_greedy(lin, train.U, mus_train, config.N or len(mus_train),
                                None if config.N else config.tol_pod)
            if config.N is not None and primal.Z.shape[1] < config.N:
                why = primal.history["pod_greedy"]["stop_reason"]
                clipped = (f"-N {config.N}: POD-greedy built {primal.Z.shape[1]} modes only "
                           f"(stop reason {why!r}: the {len(mus_train)} training "
                           "trajectories span no more; clipped)")
            X_ctx, problem_at = _space_time(lin)
        else:
            primal = primal_basis(reg, config, train.U, lin.X, progress)
            if config.N is not None and primal.Z.shape[1] < config.N:
                clipped = clipped_size("-N", config.N, int(primal.Z.shape[1]), len(mus_train))
            X_ctx, problem_at = lin.X, lin
        timings["primal_s"] = time.perf_counter() - t1
        form = reg.create("formulation", config.formulation)
        ctx = OfflineContext(scene, config, reg, progress, hf.backend, form, problem_at, X_ctx,
                             mus_train, train, np.asarray(mus_valid), valid, primal, t0,
                             timings)
        ctx.linear = lin
        if clipped:
            ctx.warn(clipped)
        stage = steps.reduce(ctx)
    timings["offline_s"] = time.perf_counter() - t0
    return validate(ctx, stage)

"""The collocation reduced friction model as a stage of the offline skeleton.

The model of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods:
parametric variational inequalities" (talk), slides "Plain RBM", "Preliminaries", "Greedy
Collocation Node Selection (GCNS)"; the steps are listed in :mod:`rbbench.rb.friction.offline`
(which selects this stage or the wedge one, :mod:`rbbench.rb.friction.wedge.stage`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from functools import partial
from types import SimpleNamespace
from typing import Any

import numpy as np
import scipy.linalg as sla

from rbbench.hf.algebra.friction import law_residuals
from rbbench.hf.components import discretize_for
from rbbench.rb.algorithms import infsup as inf
from rbbench.rb.algorithms.cones.metric import span_projection
from rbbench.rb.algorithms.gcns import gcns, tangential_violation
from rbbench.rb.algorithms.pod import pod
from rbbench.rb.compressors import make_stabilizer, pga_delta, takes_delta
from rbbench.rb.config import config_dict
from rbbench.rb.friction.collocation.model import (
    FrictionReducedModel,
    condense_reduced,
    project_friction,
    solve_coulomb,
)
from rbbench.rb.friction.infsup import validation_constants
from rbbench.rb.friction.profiles import PROFILE_DEFINITION, lam_t_profiles
from rbbench.rb.offline import check_finite, primal_histories
from rbbench.rb.online import PlainArrays, ReducedBasis
from rbbench.rb.validation import ReducedStage, xnorm2

__all__ = ["DEFINITIONS", "FrictionStage", "TangentialBasis", "TangentialPOD", "tangential_pod"]

DEFINITIONS = {
    "err_u": "relative error ||u - u_N||_X / ||u||_X per validation mu (X: the scene's V inner "
             "product on free dofs); *_max / *_mean: max / mean over the validation set",
    "err_lam": "normal multipliers: ||lam_n - Vn c_n||_W / ||lam_n||_W per validation mu, W "
               "the L2(Gamma_c(mu)) Gram matrix of the nodal (P1) multipliers (Wt)",
    "err_lam_t": "tangential multipliers: ||lam_t - Vt theta||_W / ||lam_t||_W, same W",
    "lam_t_best": "per validation mu: ||lam_t - Pi lam_t||_W / ||lam_t||_W, Pi the W-projection "
                  "onto X_S = span(Vt): the floor of err_lam_t on this space",
    "lam_best_valid": "per validation mu: the same floor of err_lam on the normal cone",
    "friction_residual": "max over ALL HF nodes of [|lam_t| - nu_F lam_n]_+ (Tresca: "
                         "[|lam_t| - s]_+) of the reconstructed multipliers, relative to the "
                         "largest reconstructed lam_n (Tresca: s)",
    "collocation_violation": "the same at the GCNS nodes only (the reduced constraint; ~0)",
    "friction_law_residual": "max over ALL HF contact nodes of the friction law residual of "
                             "the reconstruction (u_N, lam_n,R, lam_t,R): max(min(|v|, |lam_t "
                             "- s sign(v)|), |lam_t| - s, -lam_n, 0) with the slip v = Bt u_N "
                             "+ ut_lift (mean jump per node) over the HF solution's max |v| "
                             "and forces over the HF solution's max lam_n; s = nu_F lam_n,R "
                             "(Tresca: the threshold); 0 iff every node sticks or slips "
                             "against the bound, inside the cone",
    "slip_law_residual": "max over the HF nodes where the reconstruction slips (|v| > 1e-3 of "
                         "the HF solution's max |v|) of |lam_t - s sign(v)| over the HF "
                         "solution's max lam_n: how far a slipping node is from the bound "
                         "that must oppose its slip",
    "penetration": "max_i (Bn u_N - Gn)_i / int phi_i clipped at 0 (m), nodal rows",
    "complementarity": "|lam_n,R . (Gn - Bn u_N)| / (||lam_n,R||_2 ||Gn||_2) at the HF rows",
    "gcns_history": "per GCNS set C(q), q = 0, 1, ...: S_q, e_nt = e_GCNS^{n tau}(q) = max over "
                    "training mu and HF nodes of [|lam_t,S| - nu_F lam_n,R]_+ (Pa; e_nt_rel: "
                    "over max |lam_t| of the snapshots), e_gcns = max over training mu of "
                    "||lam_t - lam_t,S||_W / ||lam_t||_W, mu_index (training column mu_q)",
    "gcns_iterations": "q of the kept collocation set (published: 20); S_q its size "
                       "(published: 40)",
    "t_online": "wall time of one online solve: HF assembly at mu + projection on the bases "
                "(t_online_hf_assembly_s, the plain model: grows with the HF size) + the "
                "reduced Coulomb fixed point (t_online_solve_median_s); median over "
                "validation mus x repeats",
    "speedup": "median HF solve time / median online time",
    "u_best": "per validation mu: ||u - Pi u||_X / ||u||_X, Pi the X-projection onto the "
              "online primal space span(Z_off): the floor of err_u",
    "dim_v_off": "N + K: the primal space after the stabiliser (PGA on the combined form "
                 "b^n + b^tau: [Bn; Bt] against blockdiag(Vn, Vt); published: 70)",
    "delta_pga": "PGA tolerance: Benaceur et al.'s rule sup_mu beta / c of the combined form over "
                 "every fifth training mu (beta over span(blockdiag(Vn, Vt)) in whole V, a "
                 "lower bound; published: 0.072); null without PGA",
    "beta": "inf-sup constants of the combined form b^n + b^tau per validation mu "
            "(rbbench.rb.friction.infsup.validation_constants): hf = whole V against the HF "
            "set R^m_+ x R^m (span value: a LOWER BOUND), dec = whole V against the reduced "
            "dual set, off = span(Z_off) (the online primal space) against the reduced dual "
            "set; 'value' of kind cone-exact / cone-upper (an upper estimate) / "
            "span-lower-bound, 'span' the span lower bound, 'is_zero' the exact LP test, 'c' "
            "the continuity constant on the same spaces; value_rel / span_rel = value / c_HF(mu) "
            "(dimensionless; Benaceur et al.'s delta_PGA ratio). Raw values are in the units of "
            "X and W (X: energy inner product, so beta ~ 1 / sqrt(E))",
    "lam_t_profiles": PROFILE_DEFINITION,
}


@dataclass
class TangentialBasis:
    """The tangential space ``X_S = span(generators)`` (W-orthonormal POD modes of lam_t)."""

    generators: np.ndarray
    name: str = "pod"
    history: dict[str, Any] = field(default_factory=dict)

    @property
    def S(self) -> int:
        return int(self.generators.shape[1])


def tangential_pod(LAM_T: np.ndarray, W: Any, tol: float | None = None,
                   s_max: int | None = None) -> TangentialBasis:
    """The tangential compressor: POD of the lam_t snapshots in the W inner product
    (Benaceur et al., "Preliminaries" 1: ``X_S^tau = Span{v_s^tau}``), ``S`` = ``s_max`` modes or
    the energy tolerance ``tol`` (:func:`rbbench.rb.algorithms.pod.pod`)."""
    res = pod(LAM_T, W, tol=tol, n=s_max)
    return TangentialBasis(res.Z, "pod", {"singular_values": res.s.tolist(),
                                          "tail": res.tail.tolist()})


class TangentialPOD:
    """The tangential compressor as a registry component (role ``"tangential"``, to be
    declared): ``(LAM_T, W, *, tol=None, s_max=None) -> TangentialBasis``
    (:func:`tangential_pod`)."""

    name = "pod"

    def __call__(self, LAM_T: np.ndarray, W: Any, *, tol: float | None = None,
                 s_max: int | None = None) -> TangentialBasis:
        return tangential_pod(LAM_T, W, tol=tol, s_max=s_max)


class FrictionStage(ReducedStage):
    """Spaces, stabiliser, GCNS and the plain online stage of the reduced friction model."""

    definitions = DEFINITIONS
    hyper = "none"
    online_method = "daqp (Coulomb fixed point)"

    def __init__(self, ctx: Any) -> None:
        self.ctx, config = ctx, ctx.config
        if ctx.train.LAM_T is None:
            raise ValueError("friction snapshots without lam_t: the solver "
                             f"{config.solver!r} returns no tangential multipliers")
        self.x_solve = inf.make_solver(ctx.X)
        self.Z = ctx.Z
        self.N = int(self.Z.shape[1])
        self.n_contact = int(2 * ctx.train.LAM.shape[0])
        self.config = {**config_dict(config), "online_method": self.online_method}
        self.beta: dict[str, list] = {}
        self._spaces(ctx)
        self._stabilizer(ctx)
        self._gcns(ctx)
        self.model = self.reduced  # plain: the HF problem at mu projected online
        self.floors: dict[str, list[float]] = {"lam_best_valid": []}
        self.t_asm: list[float] = []
        self.t_solve: list[float] = []

    # -- offline -----------------------------------------------------------------------
    def _spaces(self, ctx: Any) -> None:
        """The normal cone (registered dual compressor) and X_S (:func:`tangential_pod`)."""
        options = ctx.options
        t1 = time.perf_counter()
        self.W_ref = ctx.problem_at(ctx.scene.default_mu).W
        ctx.progress(f"normal cone: dual compressor {options.dual}")
        self.dual = ctx.registry.create("dual", options.dual)(
            ctx.train.LAM, self.W_ref, tol=options.tol_dual, r_max=options.R)
        self.Vn = self.dual.generators
        check_finite(f"dual compressor {options.dual!r}: the generators", self.Vn)
        self.R = int(self.Vn.shape[1])
        ctx.progress("tangential space: POD of lam_t")
        self.tangential = TangentialPOD()(ctx.train.LAM_T, self.W_ref,
                                          s_max=options.S if options.S else self.R)
        self.Vt = self.tangential.generators
        check_finite("tangential POD: the modes", self.Vt)
        self.S = self.tangential.S
        self.histories = {**primal_histories(ctx.primal), "e_proj": list(self.dual.e_proj),
                          "e_orth": list(self.dual.e_orth),
                          "tangential_singular_values":
                              self.tangential.history["singular_values"]}
        ctx.timings["dual_s"] = time.perf_counter() - t1

    def _stabilizer(self, ctx: Any) -> None:
        """``none`` or PGA on the combined form (``B = [Bn; Bt]``, ``blockdiag(Vn, Vt)``)."""
        options = ctx.options
        t1 = time.perf_counter()
        Vg = self._generators()
        combined = [SimpleNamespace(B=_stack_b(ctx.problem_at(mu)),
                                    W=sla.block_diag(*(2 * [ctx.problem_at(mu).W.toarray()])))
                    for mu in ctx.mus_train]
        delta = None
        if takes_delta(ctx.registry, options.stabilizer):
            ctx.progress(f"{options.stabilizer.upper()} on b^n + b^tau (supremizers on the "
                         "training set)")
            delta = pga_delta(options, combined, self.x_solve, Vg, ctx.registry)
        self.Z_off, hist = make_stabilizer(ctx.registry, options).offline(
            self.Z, Vg, ctx.X, self.x_solve, (c.B for c in combined), delta)
        check_finite(f"stabilizer {options.stabilizer!r}: the offline basis", self.Z_off)
        self.K = int(self.Z_off.shape[1] - self.N)
        self.histories.update({k: v for k, v in hist.items() if k != "K"})
        ctx.timings["stabilizer_s"] = time.perf_counter() - t1

    def _generators(self) -> np.ndarray:
        """The combined dual generators ``blockdiag(Vn, Vt)`` (2m x (R + S))."""
        return sla.block_diag(self.Vn, self.Vt)

    def _gcns(self, ctx: Any) -> None:
        """GCNS on the training set, then the model with the training solutions."""
        options = ctx.options
        t1 = time.perf_counter()
        ctx.progress("GCNS (collocation nodes of the tangential constraint)")
        problems = [ctx.problem_at(mu) for mu in ctx.mus_train]
        self.law = problems[0].law
        self.train_arrays = [project_friction(p, self.Z_off, self.Vn, self.Vt)
                             for p in problems]
        self.train_cond = [condense_reduced(a) for a in self.train_arrays]
        self._x_last: dict[int, np.ndarray] = {}
        res = gcns(self._solve_training, ctx.train.LAM_T, [p.W for p in problems],
                   per_iteration=options.gcns_per_iteration, max_iterations=options.gcns_max,
                   patience=options.gcns_patience)
        self.gcns = res
        x_train = self._training_solutions(res.nodes)
        self.reduced = FrictionReducedModel(
            Qn=self.Vn[res.nodes], Qt=self.Vt[res.nodes], nodes=res.nodes, law=self.law,
            mus_train=np.asarray(ctx.mus_train, float), x_train=x_train,
            parameters=ctx.scene.parameter_space,
            info={"N": self.Z_off.shape[1], "R": self.R, "S": self.S, "S_q": res.S_q},
            arrays_at=PlainArrays(ctx.problem_source(), partial(
                project_friction, Z=self.Z_off, Vn=self.Vn, Vt=self.Vt)),
            basis=ReducedBasis(self.Z_off, self.Vn, self.Vt))
        self.histories["gcns_history"] = res.history
        ctx.timings["gcns_s"] = time.perf_counter() - t1

    def _training_solutions(self, nodes: np.ndarray) -> np.ndarray:
        """``(c_n, theta)`` per training mu at the collocation set ``nodes``."""
        xs = []
        for j, cond in enumerate(self.train_cond):
            vals = self.train_arrays[j].law_values[nodes]
            xs.append(solve_coulomb(cond, self.Vn[nodes], self.Vt[nodes], vals, self.law,
                                    self._x_last.get(j)).x)
        return np.array(xs)

    def _solve_training(self, nodes: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """GCNS's ``solve_all``: reduced lam_t and its bound at every HF node, per training
        mu (warm-started from the previous GCNS iteration)."""
        X = self._training_solutions(nodes)
        self._x_last = dict(enumerate(X))
        LT = self.Vt @ X[:, self.R:].T
        bounds = np.column_stack([self._bound(self.train_arrays[j].law_values, x[:self.R])
                                  for j, x in enumerate(X)])
        return LT, bounds

    def _bound(self, values: np.ndarray, c_n: np.ndarray) -> np.ndarray:
        """The tangential bound at every HF node: ``nu_F Vn c_n`` (Coulomb) or ``s``."""
        return values if self.law == "tresca" else values * (self.Vn @ c_n)

    def _floors(self, lam: np.ndarray, lam_t: np.ndarray, W: Any) -> dict[str, float]:
        """Best approximations (relative W errors): lam_n in the normal cone, lam_t in X_S."""
        self.floors["lam_best_valid"].append(
            float(self.dual.project(lam, W)[2]) / np.sqrt(xnorm2(W, lam)))
        t2 = xnorm2(W, lam_t)
        return {"lam_t_best": float(span_projection(lam_t, self.Vt, W)[2] / np.sqrt(t2))
                if t2 > 0 else 0.0}

    # -- validation --------------------------------------------------------------------
    def record_online(self, mu: np.ndarray, solutions: list) -> None:
        """The online time split: the reduced arrays at mu (the plain model: its HF assembly
        and projection, once per mu) and the reduced solves."""
        self.t_asm.append(solutions[-1].assembly_s)
        self.t_solve.extend(s.time_s - s.assembly_s for s in solutions)

    def metrics(self, mu: np.ndarray, p: Any, u: np.ndarray, lam: np.ndarray, res: Any,
                hf: Any) -> dict[str, float]:
        j = int(np.argmin(np.linalg.norm(self.ctx.valid.mus - np.asarray(mu)[None, :], axis=1)))
        lam_t = self.ctx.valid.LAM_T[:, j]
        ln, lt, u_n = hf.lam, hf.lam_t, hf.u
        W = p.W
        n2, t2 = xnorm2(W, lam), xnorm2(W, lam_t)
        floors = {**self._floors(lam, lam_t, W), "u_best": self._u_floor(u)}
        bound = np.asarray(p.threshold, float) if self.law == "tresca" else \
            np.asarray(p.coefficient, float) * ln
        viol = tangential_violation(lt[:, None], bound[:, None])[:, 0]
        nodes = self._collocation_nodes()
        scale = float(np.max(bound if self.law == "tresca" else ln, initial=0.0)) or 1.0
        gap = p.Gn - p.Bn @ u_n
        den = np.linalg.norm(ln) * np.linalg.norm(p.Gn)
        law, slipping = self._law_residuals(p, u, lam, u_n, ln, lt)
        return {
            "err_lam": float(np.sqrt(xnorm2(W, lam - ln) / n2)),
            "penetration": float(max(0.0, -(gap / p.node_weights).min())),
            "complementarity": float(abs(ln @ gap) / den) if den > 0 else 0.0,
            "err_lam_t": float(np.sqrt(xnorm2(W, lam_t - lt) / t2)) if t2 > 0 else 0.0,
            **floors,
            "friction_residual": float(viol.max(initial=0.0)) / scale,
            "collocation_violation": float(viol[nodes].max(initial=0.0)) / scale,
            "friction_law_residual": float(law.max(initial=0.0)),
            "slip_law_residual": float(slipping.max(initial=0.0)),
            "online_iterations": float(res.iterations),
        } | self._infsup(p)

    def _law_residuals(self, p: Any, u: np.ndarray, lam: np.ndarray, u_n: np.ndarray,
                       ln: np.ndarray, lt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """:func:`rbbench.hf.algebra.friction.law_residuals` of the reconstruction, slips
        and forces scaled by the HF solution ``(u, lam)`` at the same mu (one load step:
        ``ut_prev = 0``)."""
        lift = p.steps[-1].ut_lift
        v_red = (p.Bt @ u_n + lift) / p.node_weights
        v_hf = (p.Bt @ u + lift) / p.node_weights
        s = np.asarray(p.threshold, float) if self.law == "tresca" else \
            np.asarray(p.coefficient, float) * ln
        return law_residuals(v_red, ln, lt, s, float(np.abs(v_hf).max(initial=0.0)),
                             float(np.max(lam, initial=0.0)))

    def _n_signed(self) -> int:
        """Signed coefficients of the dual set ``{V y : y[:n] >= 0}`` (the normal cone's R)."""
        return self.R

    def _infsup(self, p: Any) -> dict[str, float]:
        """The combined inf-sup rows hf / dec / off of one validation mu (``self.beta``;
        DEFINITIONS["beta"]); returns no per-mu metric."""
        consts = validation_constants(p.Bn, p.Bt, p.W, self.x_solve, self.ctx.X,
                                      self._generators(), self._n_signed(), self.Z_off,
                                      self.ctx.options.exact_max_r)
        for name, r in consts.items():
            self.beta.setdefault(name, []).append(r.as_dict())
        return {}

    def _profiles(self) -> dict[str, Any]:
        """HF against reduced lam_t at the box's ends and centre
        (:func:`rbbench.rb.friction.profiles.lam_t_profiles`)."""
        ctx = self.ctx

        def solve(mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            hf = self.model.reconstruct(self.model.solve(mu))
            return hf.lam, hf.lam_t

        return lam_t_profiles(
            ctx.mus_train, ctx.scene.bounds, ctx.train.LAM, ctx.train.LAM_T, solve,
            lambda mu: discretize_for(ctx.backend, ctx.formulation, mu).contact
            .colloc_points[:, 0],
            lambda mu: ctx.problem_at(mu).coefficient)

    def _u_floor(self, u: np.ndarray) -> float:
        """``||u - Pi u||_X / ||u||_X``, ``Pi`` the X-projection onto span(Z_off)."""
        if not hasattr(self, "_XZ"):
            self._XZ = np.asarray(self.ctx.X @ self.Z_off)
            self._ZXZ = sla.cho_factor(self.Z_off.T @ self._XZ)
        d = u - self.Z_off @ sla.cho_solve(self._ZXZ, self._XZ.T @ u)
        return float(np.sqrt(max(xnorm2(self.ctx.X, d), 0.0) / xnorm2(self.ctx.X, u)))

    def _collocation_nodes(self) -> np.ndarray:
        """The HF nodes where the reduced model imposes the tangential constraint."""
        return self.gcns.nodes

    def finish(self, histories: dict, timings: dict) -> None:
        histories.update(self.floors)
        if self.t_asm:
            timings["t_online_hf_assembly_s"] = float(np.median(self.t_asm))
            timings["t_online_solve_median_s"] = float(np.median(self.t_solve))

    def summary(self) -> dict[str, Any]:
        g = self.gcns
        return {"S": self.S, "S_q": g.S_q, "gcns_iterations": g.iterations,
                "gcns_nodes": [int(i) for i in g.nodes], "gcns_stop": g.stop,
                "gcns_history": g.history, "dim_primal_online": int(self.Z_off.shape[1]),
                "dim_v_off": int(self.Z_off.shape[1]),
                "delta_pga": self.histories.get("pga_delta"),
                "lam_t_profiles": self._profiles()}


def _stack_b(p: Any) -> Any:
    """The combined constraint rows ``[Bn; Bt]`` of a friction problem (sparse)."""
    import scipy.sparse as sp

    return sp.vstack([p.Bn, p.Bt]).tocsr()

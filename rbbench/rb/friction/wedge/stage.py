"""The wedge dual model in the friction offline skeleton (``friction_dual = "wedge"``).

:class:`WedgeStage` replaces three steps of
:class:`rbbench.rb.friction.collocation.stage.FrictionStage` (the collocation model of Benaceur,
Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric variational
inequalities" (talk)): the dual spaces are the cones of ``w+ = F lam_n + lam_t`` and
``w- = F lam_n - lam_t`` (the registered dual compressor, ``R`` generators for ``w+`` and ``S``
for ``w-``: ``R + S`` dual unknowns, as the collocation model's ``R`` normal + ``S`` tangential),
the stabiliser acts on the combined generators ``[Ln; Lt]`` (PGA on ``b^n + b^tau``), and there is
no GCNS (the cone holds at every HF node by construction); the online solve is De Saxce's fixed
point (:mod:`rbbench.rb.friction.wedge.model`).

Measured on hertz_friction P1 (default mesh, 36910 dofs, 513 contact nodes, F = 0.2; 41
training, 20 validation mu; N = 30, PGA capped at K = 40, mCPG), max over validation:

=========================  ============  ============  ============  ==================
model                      colloc 20+20  wedge 20+20   wedge 10+10   wedge 20+20, no PGA
=========================  ============  ============  ============  ==================
err_u (floor 1.6e-4)       1.5e-2        2.4e-4        3.7e-4        2.2e-4
err_lam_n (floor 0.033)    0.147         0.063         0.074         0.58
err_lam_t                  6.35          0.187         0.221         1.73
lam_t floor (span)         0.090         0.091         0.120         0.091
friction residual          1.49          6e-17         8e-17         8e-17
online fixed-point its     13            6             6             94
reduced solve (s)          0.020         0.020         0.056         0.077
=========================  ============  ============  ============  ==================

(collocation with GCNS patience: S_q = 168, err_u 4.7e-3, err_lam_t 1.00.) Without PGA the
displacement stays good but the multipliers are not controlled (inf-sup).

``hyper = "eim"`` (:mod:`rbbench.rb.friction.wedge.hyper`): no HF work online. Same case,
wedge 20+20 with PGA, ``rbbench reduce``: err_u 2.6e-4 (plain 2.4e-4), err_lam_t 0.181
(0.187), online median 0.024 s (plain 0.32 s, HF 37 s): speed-up 1547 (plain 117).
"""

from __future__ import annotations

import time
from functools import partial
from typing import Any

import numpy as np

from rbbench.rb.algorithms.cones.metric import cone_projection, span_projection
from rbbench.rb.friction.collocation.stage import DEFINITIONS, FrictionStage
from rbbench.rb.friction.wedge.model import (
    WedgeReducedModel,
    condense_wedge,
    desaxce_coulomb,
    project_wedge,
    wedge_basis,
)
from rbbench.rb.offline import check_finite, primal_histories
from rbbench.rb.online import PlainArrays, ReducedBasis
from rbbench.rb.validation import xnorm2

__all__ = ["TABLE_ROWS", "WEDGE_DEFINITIONS", "WedgeStage", "comparison_table", "reduce_friction"]

WEDGE_DEFINITIONS = {
    **DEFINITIONS,
    "err_lam": "normal multipliers: ||lam_n - Ln c||_W / ||lam_n||_W per validation mu (wedge "
               "model: lam_n = (V+ c+ + V- c-) / 2F), W the L2(Gamma_c(mu)) Gram matrix",
    "err_lam_t": "tangential multipliers: ||lam_t - Lt c||_W / ||lam_t||_W (lam_t = "
                 "(V+ c+ - V- c-) / 2), same W",
    "lam_t_best": "per validation mu: ||lam_t - Pi lam_t||_W / ||lam_t||_W, Pi the W-projection "
                  "onto span(Lt) (the span of the wedge generators' tangential parts)",
    "lam_t_best_cone": "the same onto the cone Span+(Lt) (c >= 0)",
    "lam_best_valid": "per validation mu: the floor of err_lam on the cone Span+(Ln)",
    "collocation_violation": "0: the wedge model has no collocation nodes",
    "R": "generators of the w+ cone (R+); S: those of the w- cone (R-); R + S dual unknowns",
    "t_online": "wall time of one online solve: HF assembly at mu + projection (plain model; "
                "hyper 'eim': the affine A_N, F_N, the friction EIM and the slip rows, "
                "t_online_eim_s) + De Saxce's fixed point (t_online_solve_median_s); on the "
                "compiled path (online_path) one kernel call does both, and those two are "
                "the Python reference's split (t_online_python_median_s)",
    "online_path": "the path of the timed online solves: 'compiled (numba X)' (one numba "
                   "kernel per mu: EIM, condensation, De Saxce's fixed point) or 'python "
                   "(<why>)'; online_compile: the kernel's first call in this process (s, "
                   "whether from numba's disk cache), never part of t_online",
    "t_online_python_median_s": "compiled path: the median time of as many solves by the "
                                "Python reference at each validation mu, timed beside the "
                                "compiled ones (t_online_eim_s and t_online_solve_median_s "
                                "are its split); online_path_deviation_max: max over the "
                                "validation mu of max|x_compiled - x_python| / max|x_python| "
                                "for x = the primal coefficients a and the wedge coefficients c",
    "slip_deim": "hyper 'eim': M_s magic contact nodes of the DEIM of the slip |w_t| over the "
                 "De Saxce iterates of the training set (errors_slip: its relative max-norm "
                 "training error curve); M_n, M_t, M_G the friction EIM sizes of Ln^T Bn Z, "
                 "Lt^T Bt Z, Ln^T Gn",
}


class WedgeStage(FrictionStage):
    """Wedge cones, PGA on ``[Ln; Lt]``, De Saxce's fixed point (module docstring)."""

    definitions = WEDGE_DEFINITIONS
    online_method = "daqp (De Saxce fixed point on the wedge cones)"

    def __init__(self, ctx: Any) -> None:
        self.online: dict[str, Any] = {"online_path": "python (no hyper-reduction: HF "
                                                      "assembly at mu)"}
        self.t_python: list[float] = []
        self.path_deviation: list[float] = []
        super().__init__(ctx)  # builds the hyper model (self._hyper) when hyper is 'eim'

    def _hyper(self, ctx: Any) -> None:
        """hyper 'eim': :func:`rbbench.rb.friction.wedge.hyper.wedge_hyper_model` (the slip
        DEIM on the training iterates, the friction EIM on the EIM training set)."""
        from rbbench.rb.friction.eim import eim_histories
        from rbbench.rb.friction.wedge.hyper import wedge_hyper_model
        from rbbench.rb.offline import eim_training_set

        t1 = time.perf_counter()
        ctx.progress("hyper eim: slip DEIM, friction EIM, affine A_N, F_N")
        if not hasattr(ctx.backend, "contact_layout"):
            raise ValueError(f"hyper 'eim': backend {ctx.config.backend!r} provides no "
                             "contact layout; use hyper 'none'")
        p0 = ctx.problem_at(ctx.mus_train[0])
        self.model = wedge_hyper_model(
            self.reduced, self.wedge, self.Z_off, np.column_stack(self._slips),
            ctx.backend.contact_layout(), p0.free, ctx.problem_at, ctx.scene.bounds,
            eim_training_set(ctx.scene, ctx.options, ctx.mus_train), tol=ctx.options.tol_eim,
            m_max=ctx.options.m_eim)
        self.hyper = "eim"
        self.histories["eim"] = self.model.info
        self.histories.update(eim_histories(self.model.eim))
        ctx.timings["hyper_s"] = time.perf_counter() - t1
        self._prepare_online(ctx)

    def _prepare_online(self, ctx: Any) -> None:
        """The online path of the hyper model (compiled where it can:
        :mod:`rbbench.rb.friction.wedge.compiled`), prepared now so that the kernel's first
        call (compiling, or loading numba's disk cache; announced when it compiles) is never
        timed as an online solve."""
        from rbbench.rb.friction.wedge import compiled

        t1 = time.perf_counter()
        if compiled.path_reason(self.model) is None and not compiled.COMPILE \
                and not compiled.is_cached():
            ctx.progress("compiling the online kernels (first run after install, about "
                         f"{compiled.COMPILE_ESTIMATE_S} s)")
        self.online = {"online_path": self.model.online_path(),
                       "online_compile": dict(compiled.COMPILE) or None}
        ctx.timings["online_prepare_s"] = time.perf_counter() - t1

    def _spaces(self, ctx: Any) -> None:
        """The ``w+`` and ``w-`` cones (the registered dual compressor)."""
        options = ctx.options
        t1 = time.perf_counter()
        self.W_ref = ctx.problem_at(ctx.scene.default_mu).W
        F = np.asarray(ctx.problem_at(ctx.scene.default_mu).coefficient, float)
        ctx.progress(f"wedge cones of F lam_n +- lam_t: dual compressor {options.dual}")
        compress = ctx.registry.create("dual", options.dual)
        self.wedge = wedge_basis(compress, ctx.train.LAM, ctx.train.LAM_T, F, self.W_ref,
                                 tol=options.tol_dual, r_plus=options.R,
                                 r_minus=options.S if options.S else options.R)
        check_finite(f"dual compressor {options.dual!r}: the wedge generators",
                     self.wedge.generators)
        self.Vn, self.Vt = self.wedge.Ln, self.wedge.Lt
        self.R = int(self.wedge.Vp.shape[1])  # R + S dual unknowns, as the collocation model's
        self.S = int(self.wedge.Vm.shape[1])
        self.histories = {**primal_histories(ctx.primal), **self.wedge.history}
        ctx.timings["dual_s"] = time.perf_counter() - t1

    def _generators(self) -> np.ndarray:
        return self.wedge.generators

    def _gcns(self, ctx: Any) -> None:
        """No collocation: the training solutions (the online warm starts) and the model."""
        t1 = time.perf_counter()
        ctx.progress("training solutions (De Saxce fixed point)")
        problems = [ctx.problem_at(mu) for mu in ctx.mus_train]
        self.law = problems[0].law
        if any(not np.array_equal(np.asarray(p.coefficient, float), self.wedge.F)
               for p in problems):
            raise ValueError("wedge model: the friction coefficient depends on mu; the wedge "
                             "cones are built for one F per node")
        P = self.wedge.P
        self._slips: list[np.ndarray] = []  # |w_t| of every iterate: the slip DEIM's data
        runs = [desaxce_coulomb(condense_wedge(project_wedge(p, self.Z_off, self.wedge), P),
                                record=self._slips) for p in problems]
        self.histories["training_iterations"] = [r.iterations for r in runs]
        self.histories["training_stops"] = [r.stop_reason for r in runs]
        self.histories["training_rates"] = [r.rate for r in runs]
        self.reduced = WedgeReducedModel(
            P=P, mus_train=np.asarray(ctx.mus_train, float), x_train=np.array([r.c for r in runs]),
            parameters=ctx.scene.parameter_space,
            info={"N": self.Z_off.shape[1], "R+": int(self.wedge.Vp.shape[1]),
                  "R-": self.S},
            arrays_at=PlainArrays(ctx.problem_source(), partial(
                project_wedge, Z=self.Z_off, basis=self.wedge)),
            basis=ReducedBasis(self.Z_off, self.wedge.Ln, self.wedge.Lt))
        ctx.timings["gcns_s"] = time.perf_counter() - t1

    def record_online(self, mu: np.ndarray, solutions: list) -> None:
        """Where the compiled path ran (one kernel, no split of its time), as many solves by
        the Python reference beside it (their times, and the largest relative difference of
        ``a`` and ``c`` between the paths), whose EIM evaluation and fixed points the base
        class times apart."""
        if self.model is not self.reduced and solutions[-1].path == "compiled":
            fast = solutions[-1]
            solutions = [self.model.solve(mu, path="python") for _ in solutions]
            self.t_python.extend(s.time_s for s in solutions)
            ref = solutions[-1]
            self.path_deviation.append(max(_rel(fast.a, ref.a), _rel(fast.c, ref.c)))
        super().record_online(mu, solutions)

    def finish(self, histories: dict, timings: dict) -> None:
        super().finish(histories, timings)
        if self.t_python:
            timings["t_online_python_median_s"] = float(np.median(self.t_python))

    def _floors(self, lam: np.ndarray, lam_t: np.ndarray, W: Any) -> dict[str, float]:
        """Best approximations: lam_n in Span+(Ln); lam_t in span(Lt) and Span+(Lt)."""
        self.floors["lam_best_valid"].append(
            float(cone_projection(lam, self.wedge.Ln, W)[2]) / np.sqrt(xnorm2(W, lam)))
        t = float(np.sqrt(xnorm2(W, lam_t)))
        if t == 0:
            return {"lam_t_best": 0.0, "lam_t_best_cone": 0.0}
        return {"lam_t_best": float(span_projection(lam_t, self.wedge.Lt, W)[2]) / t,
                "lam_t_best_cone": float(cone_projection(lam_t, self.wedge.Lt, W)[2]) / t}

    def _collocation_nodes(self) -> np.ndarray:
        return np.zeros(0, dtype=int)

    def _n_signed(self) -> int:
        """Every wedge coefficient is signed (``c >= 0``: the cones of ``w+`` and ``w-``)."""
        return int(self.wedge.generators.shape[1])

    def summary(self) -> dict[str, Any]:
        return {"S": self.S, "R_plus": int(self.wedge.Vp.shape[1]), "R_minus": self.S,
                "S_q": 0, "gcns_iterations": 0, "gcns_nodes": [], "gcns_stop": "no GCNS (wedge)",
                "gcns_history": [], "dim_primal_online": int(self.Z_off.shape[1]),
                "dim_v_off": int(self.Z_off.shape[1]),
                "delta_pga": self.histories.get("pga_delta"),
                "training_iterations_max": max(self.histories["training_iterations"]),
                "friction_dual": "wedge", "lam_t_profiles": self._profiles(),
                **self.online, **self._python_side()}

    def _python_side(self) -> dict[str, Any]:
        """The Python reference beside the compiled path (:meth:`record_online`)."""
        if not self.t_python:
            return {}
        return {"t_online_python_median_s": float(np.median(self.t_python)),
                "online_path_deviation_max": max(self.path_deviation)}


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    """``max|a - b| / max|b|`` (0 for two zero vectors)."""
    top = float(np.abs(b).max(initial=0.0))
    return float(np.abs(a - b).max(initial=0.0)) / top if top > 0 else \
        float(np.abs(a).max(initial=0.0))


def reduce_friction(scene: Any, config: Any, friction_dual: str = "wedge",
                    progress: Any = None) -> Any:
    """:func:`rbbench.rb.offline.reduce` with the friction dual model ``friction_dual``
    (``"collocation"`` or ``"wedge"``) on a copy of ``config``."""
    from dataclasses import asdict, is_dataclass, replace

    from rbbench.rb.offline import reduce

    opts = config.options
    values = asdict(opts) if is_dataclass(opts) else dict(opts)
    config = replace(config, options={**values, "friction_dual": friction_dual})
    return reduce(scene, config) if progress is None else reduce(scene, config, progress)


#: rows of :func:`comparison_table`: (label, summary key, format)
TABLE_ROWS = (
    ("dual unknowns (R + S)", "dual_unknowns", "{:d}"), ("dim V_off", "dim_v_off", "{:d}"),
    ("S_q (collocation nodes)", "S_q", "{:d}"), ("err_u max", "err_u_max", "{:.2e}"),
    ("floor u (span Z_off)", "u_best_max", "{:.2e}"),
    ("err_u mean", "err_u_mean", "{:.2e}"), ("err_lam_n max", "err_lam_max", "{:.3g}"),
    ("floor lam_n", "lam_best_max", "{:.3g}"), ("err_lam_t max", "err_lam_t_max", "{:.3g}"),
    ("err_lam_t mean", "err_lam_t_mean", "{:.3g}"),
    ("floor lam_t (span)", "lam_t_best_max", "{:.3g}"),
    ("floor lam_t (cone)", "lam_t_best_cone_max", "{:.3g}"),
    ("friction residual max", "friction_residual_max", "{:.2e}"),
    ("friction law residual max", "friction_law_residual_max", "{:.2e}"),
    ("  at slipping nodes", "slip_law_residual_max", "{:.2e}"),
    ("online iterations max", "online_iterations_max", "{:.0f}"),
    ("t_online median (s)", "t_online_median_s", "{:.3f}"),
    ("  of which reduced solve (s)", "t_online_solve_median_s", "{:.4f}"),
    ("speed-up", "speedup", "{:.1f}"),
)


def comparison_table(summaries: dict[str, dict[str, Any]]) -> str:
    """A markdown table of ``rbbench reduce`` summaries side by side (one column each)."""
    names = list(summaries)
    lines = ["| | " + " | ".join(names) + " |", "|---" * (len(names) + 1) + "|"]
    for label, key, fmt in TABLE_ROWS:
        cells = []
        for s in summaries.values():
            v = s.get("timings", {}).get(key) if key.startswith("t_online_solve") else \
                (s.get("R", 0) + s.get("S", 0) if key == "dual_unknowns" else s.get(key))
            cells.append("-" if v is None else fmt.format(v))
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(lines)

"""The shared validation step: a reduced model against HF snapshots on the validation set.

Whatever the formulation, :func:`validate` solves the reduced model online at every
validation parameter (``config.online_repeats`` timed repetitions), and measures what every
reduced model has: the relative error of u in the X norm, the energy error, the online
time and stop reasons. The formulation's :class:`ReducedStage` adds its own per-mu
numbers (multiplier errors, penetration, inf-sup constants, hyper-reduction errors).
The result is a :class:`ReduceResult`; its :meth:`~ReduceResult.summary` is the row.
"""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rbbench.interfaces import HFVectors
from rbbench.rb.online import OnlineTimes, timed_online_solves
from rbbench.runtime.threads import BLAS_THREADS_DEFINITION, one_blas_thread
from rbbench.runtime.timing import ONLINE_PROTOCOL, ONLINE_PROTOCOL_DEFINITION


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
    model: Any = field(default=None, repr=False)  # the reduced model (rbbench.interfaces.Model)
    valid_mus: Any = field(default=None, repr=False)
    per_mu_extra: dict[str, list[float]] = field(default_factory=dict)  # a stage's own
    extra: dict[str, Any] = field(default_factory=dict)  # a stage's own summary entries
    warnings: list[str] = field(default_factory=list)  # e.g. -N larger than the rank
    #: the HF floor at each validation mu (s): one factorisation + one solve of A(mu)
    t_floor: list[float] = field(default_factory=list)
    floor_solver: str | None = None  # the direct solver of the floor
    online_path: str = ""  # the online paths that ran (compiled / python)
    online_method: str = ""  # the online methods that ran (auto resolved)

    def summary(self) -> dict[str, Any]:
        """The flat summary (``result.json``, one results row): max / mean / min over the
        validation set of the per-mu lists, each labelled in :attr:`definitions`."""
        mx, mean = _finite(np.max), _finite(np.mean)
        t_on = float(np.median(self.t_online))
        t_hf = float(np.median(self.t_hf))
        out = {
            "scene": self.scene, "N": self.N, "R": self.R, "K_pga": self.K_pga,
            # K: the offline enrichment (PGA's, or a plugin's offline stabiliser's; 0 otherwise)
            "dim_primal_online": self.N + (self.K_pga or 0),
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
            **_offline_times(self.timings),
            "t_online_median_s": t_on,
            "t_online_iqr_s": float(np.subtract(*np.percentile(self.t_online, [75, 25]))),
            "online_protocol": ONLINE_PROTOCOL, "online_path": self.online_path,
            "online_method": self.online_method,
            "t_hf_median_s": t_hf, "speedup": t_hf / t_on if t_on > 0 else None,
            **_floor_summary(self.t_floor, self.floor_solver, t_on),
        }
        out.update(beta_summary(self.beta))
        for name, values in self.per_mu_extra.items():  # e.g. friction: err_lam_t
            out[f"{name}_max"], out[f"{name}_mean"] = mx(values), mean(values)
        out.update(self.extra)
        out["warnings"] = list(self.warnings)
        out["config"] = self.config
        out["timings"] = self.timings
        out["histories"] = self.histories
        out["per_mu"] = {"err_u": self.err_u, "err_lam": self.err_lam,
                         "penetration": self.penetration,
                         "complementarity": self.complementarity, "beta": self.beta,
                         **self.per_mu_extra}
        out["definitions"] = self.definitions
        return out


def _finite(reduce_):
    """``reduce_`` over the finite, non-None values (None if there are none)."""

    def f(v):
        v = [x for x in v if x is not None and np.isfinite(x)]
        return float(reduce_(v)) if v else None

    return f


def _floor_summary(t_floor: list[float], solver: str | None, t_on: float) -> dict[str, Any]:
    """``floor_s`` (median over the validation mus of the HF floor), ``floor_solver`` and
    ``speedup_floor = floor_s / t_online_median_s`` (None without a floor)."""
    if not t_floor:
        return {"floor_s": None, "floor_solver": None, "speedup_floor": None}
    floor = float(np.median(t_floor))
    return {"floor_s": floor, "floor_solver": solver,
            "speedup_floor": floor / t_on if t_on > 0 else None}


def hf_floor(problem: Any) -> dict[str, Any] | None:
    """The HF floor of a validation problem (:func:`rbbench.hf.model.default_floor`: one
    factorisation + one solve of its stiffness with the direct solver of a default HF
    solve), or None for a problem that is not one stiffness solve away from its HF
    solution's floor (a parabolic scene's space-time view)."""
    from rbbench.hf.linear.model import LinearProblem
    from rbbench.hf.model import default_floor
    from rbbench.interfaces import ContactProblem, FrictionProblem, NitscheProblem

    if not isinstance(problem, (ContactProblem, FrictionProblem, NitscheProblem,
                                LinearProblem)):
        return None
    return default_floor(problem)


def _offline_times(timings: dict[str, float]) -> dict[str, Any]:
    """``t_offline_s`` (this run's wall time) beside the HF snapshot times from the cache
    (:data:`SHARED_DEFINITIONS`)."""
    t_off, t_snap = timings.get("offline_s"), timings.get("snapshots_s")
    t_hf = timings.get("snapshots_hf_train_s")
    both = t_off is not None and t_snap is not None and t_hf is not None
    return {"t_offline_s": t_off, "t_snapshots_hf_s": t_hf,
            "t_snapshots_hf_valid_s": timings.get("snapshots_hf_valid_s"),
            "t_offline_hf_s": t_off - t_snap + t_hf if both else None,
            "n_snapshots_cached": timings.get("snapshots_cached")}


def beta_summary(beta: dict[str, list[dict]]) -> dict[str, Any]:
    """Summary keys of the inf-sup rows per name: ``beta_<name>_min`` and ``_span_min``
    (raw), ``_rel_min`` and ``_span_rel_min`` (rows with ``value_rel``: beta / c_HF(mu)),
    ``_zero_any`` (some LP test found beta = 0) and ``_zero_undecided`` (how many LP tests
    were undecided: ``is_zero`` None)."""
    mn, out = _finite(np.min), {}
    for name, rows in beta.items():
        out[f"beta_{name}_min"] = mn([r["value"] for r in rows])
        out[f"beta_{name}_span_min"] = mn([r["span"] for r in rows])
        if rows and all("value_rel" in r for r in rows):
            out[f"beta_{name}_rel_min"] = mn([r["value_rel"] for r in rows])
            out[f"beta_{name}_span_rel_min"] = mn([r["span_rel"] for r in rows])
        out[f"beta_{name}_zero_any"] = bool(any(r["is_zero"] for r in rows))
        out[f"beta_{name}_zero_undecided"] = sum(r["is_zero"] is None for r in rows)
    return out


def _kind_at_min(rows: list[dict]) -> str | None:
    """Kind of the beta value at which the minimum over the validation set is reached."""
    ok = [r for r in rows if r["value"] is not None and np.isfinite(r["value"])]
    return min(ok, key=lambda r: r["value"])["kind"] if ok else None


def xnorm2(X: Any, v: np.ndarray) -> float:
    """``v^T X v`` (a squared norm)."""
    return float(v @ (X @ v))


def energy(p: Any, u_free: np.ndarray) -> float:
    """``J(u) = 1/2 u^T A u - F^T u`` on the free dofs (lifted problem)."""
    return float(0.5 * u_free @ (p.A @ u_free) - p.F @ u_free)


class ReducedStage(ABC):
    """A formulation's reduced model with what validating it needs (the offline steps'
    output, :meth:`rbbench.interfaces.Formulation.reduction`).

    Attributes
    ----------
    model : a :class:`rbbench.interfaces.Model`
        The reduced model, picklable; :func:`validate` calls only its ``solve(mu)`` and
        ``reconstruct(solution)``.
    hyper : str
        The hyper-reducer actually used.
    N, R, K : int
        Primal, dual and stabiliser sizes; ``n_contact`` the HF contact unknowns.
    config : dict
        The configuration as run (the ReduceConfig and the formulation's options, amended).
    histories : dict
        Offline histories (singular values, greedy errors, EIM errors, ...).
    definitions : dict
        What each reported number is.
    """

    model: Any = None
    hyper: str = "none"
    N: int = 0
    R: int = 0
    K: int = 0
    n_contact: int = 0
    config: dict
    histories: dict
    definitions: dict
    beta: dict

    @abstractmethod
    def metrics(self, mu: np.ndarray, problem: Any, u: np.ndarray, lam: np.ndarray,
                solution: Any, hf: HFVectors) -> dict[str, float]:
        """The formulation's per-mu numbers from the HF snapshot ``(u, lam)``, the HF problem
        at mu, the model's last ``solution`` and its HF vectors ``hf``: ``err_lam``,
        ``penetration`` and ``complementarity`` (when defined); any other key becomes a
        per-mu list of the result (``per_mu_extra``, summarised as ``<key>_max`` /
        ``<key>_mean``)."""

    def record_online(self, mu: np.ndarray, solutions: list) -> None:  # noqa: B027
        """The timed solutions at one validation mu (optional hook: e.g. the split of the
        online time into assembly and solve)."""

    def finish(self, histories: dict, timings: dict) -> None:  # noqa: B027 - optional hook
        """Add the stage's validation histories and timings (after the last mu)."""

    def summary(self) -> dict[str, Any]:
        """The stage's own entries of the flat summary (e.g. friction: ``S``, ``S_q``)."""
        return {}


def validate(ctx: Any, stage: ReducedStage) -> ReduceResult:
    """Validate ``stage.model`` on ``ctx.valid`` (the shared step of
    :func:`rbbench.rb.offline.reduce`) through the model interface only: ``solve(mu)``
    (``config.online_repeats`` timed repetitions under the online-time protocol,
    :func:`rbbench.rb.online.timed_online_solves`, the model warmed up once before its
    first) and ``reconstruct`` of the last one; the HF floor at every mu (:func:`hf_floor`).

    ``ctx`` is the :class:`rbbench.rb.offline.OfflineContext` the stage was built from.
    """
    model = stage.model
    n_valid = len(ctx.valid.mus)
    ctx.progress(f"online validation ({n_valid} mus: online solves, errors, inf-sup constants)")
    per_mu: dict[str, list[float]] = {"err_lam": [], "penetration": [], "complementarity": []}
    extra: dict[str, list[float]] = {}
    err_u, e_en, t_floor = [], [], []
    timed = OnlineTimes()
    floor_solver = None
    stops: dict[str, int] = {}
    X = ctx.X
    with one_blas_thread() as threads:  # every timed online solve: one BLAS thread
        for j, mu in enumerate(ctx.valid.mus):
            p = ctx.problem_at(mu)
            u, lam = ctx.valid.U[:, j], ctx.valid.LAM[:, j]
            run = timed_online_solves(model, [mu], ctx.config.online_repeats, warm_up=j == 0)
            timed.extend(run)
            sols = run.per_mu[0]
            res = sols[-1]
            stage.record_online(mu, sols)
            stops[res.stop_reason] = stops.get(res.stop_reason, 0) + 1
            hf = model.reconstruct(res)
            err_u.append(float(np.sqrt(xnorm2(X, u - hf.u) / xnorm2(X, u))))
            for key, value in stage.metrics(mu, p, u, lam, res, hf).items():
                (per_mu if key in per_mu else extra).setdefault(key, []).append(value)
            J = energy(p, u)
            e_en.append(float(abs(energy(p, hf.u) - J) / abs(J)) if J != 0 else float("nan"))
            floor = hf_floor(p)
            if floor is not None:
                t_floor.append(floor["floor_s"])
                floor_solver = floor["solver"]
            ctx.progress(f"online validation {j + 1}/{n_valid}: err_u {err_u[-1]:.3g}, "
                         f"online {np.median([s.time_s for s in sols]):.3g} s, "
                         f"{res.stop_reason}")
    histories = dict(stage.histories)
    histories["online_stops"] = stops
    timings = ctx.timings
    timings.update(snapshot_timings(ctx.train, ctx.valid))
    stage.finish(histories, timings)
    timings["total_s"] = time.perf_counter() - ctx.t0
    return ReduceResult(
        scene=ctx.scene.name, config=stage.config, N=stage.N, R=stage.R, K_pga=stage.K,
        hyper=stage.hyper, n_train=len(ctx.mus_train), n_valid=len(ctx.valid.mus),
        n_hf_dofs=int(ctx.train.n_dofs), n_contact=stage.n_contact, err_u=err_u,
        err_lam=per_mu["err_lam"], penetration=per_mu["penetration"],
        complementarity=per_mu["complementarity"], energy_err=e_en, beta=stage.beta,
        t_online=timed.times, online_path=timed.paths, online_method=timed.methods,
        t_hf=[float(t) for t in np.concatenate([ctx.train.times, ctx.valid.times])],
        timings=timings, histories=histories,
        definitions={**SHARED_DEFINITIONS, **stage.definitions},
        model=stage.model, valid_mus=np.asarray(ctx.valid.mus), per_mu_extra=extra,
        extra={**stage.summary(), "blas_threads": threads},
        warnings=list(getattr(ctx, "warnings", [])), t_floor=t_floor,
        floor_solver=floor_solver)


def snapshot_timings(train: Any, valid: Any) -> dict[str, float]:
    """The HF time of the snapshot sets as stored with each snapshot (the solve's own
    wall time, also when this run read it from the cache) and how many were cached."""
    sets = [x for x in (train, valid) if x is not None]
    return {"snapshots_hf_train_s": float(np.sum(train.times)),
            "snapshots_hf_valid_s": float(np.sum(valid.times)) if valid is not None else 0.0,
            "snapshots_cached": int(sum(x.P - x.n_computed for x in sets))}


SHARED_DEFINITIONS = {
    "t_offline_s": "wall time of this run's offline stage (s): the snapshot phase as it "
                   "happened (training AND validation snapshots; cache reads when cached, "
                   "else HF solves, in parallel with --jobs: timings.snapshots_s), then "
                   "primal, dual, stabiliser and hyper-reduction steps; it does NOT contain "
                   "the HF time of cached snapshots (t_snapshots_hf_s)",
    "t_snapshots_hf_s": "HF time of the training snapshots (s): sum over the training set of "
                        "each snapshot's stored solve time (discretise + formulate + solve, "
                        "meshing excluded), measured when it was computed, read from the "
                        "snapshot cache when cached; a serial sum (parallel workers: more "
                        "than their wall time)",
    "t_snapshots_hf_valid_s": "the same for the validation snapshots (not an offline cost: "
                              "they are the reference of the errors)",
    "t_offline_hf_s": "offline cost with the real HF snapshot time: t_offline_s - "
                      "timings.snapshots_s + t_snapshots_hf_s (the training snapshots at "
                      "their serial HF time, no validation snapshots)",
    "blas_threads": "the BLAS thread limit of the online validation loop (every timed online "
                    "solve and the per-mu error evaluation): " + BLAS_THREADS_DEFINITION,
    "n_snapshots_cached": "training + validation snapshots this run read from the cache",
    "floor_s": "the HF floor (s): one factorisation + one solve A(mu) x = F(mu) of the HF "
               "stiffness on the free dofs with the direct solver of a default HF solve "
               "(floor_solver names it), timed at each validation mu in the validation loop "
               "(one BLAS thread), median over the validation set; what no HF solve can beat "
               "(rbbench solve's floor_s, at one mu); null for a parabolic scene",
    "floor_solver": "the direct solver of floor_s",
    "online_protocol": ONLINE_PROTOCOL_DEFINITION,
    "online_path": "the online path(s) that ran in the timed solves: compiled (numba kernels) "
                   "or python ('/'-joined when both ran)",
    "online_method": "the online method(s) that ran in the timed solves (auto resolved, e.g. "
                     "nnls or daqp; empty for a model that names none)",
    "speedup": "speed-up against the timed HF solve: t_hf_median_s (median over the training "
               "and validation snapshots of the stored HF solve time) / t_online_median_s "
               "(against the HF floor: speedup_floor)",
    "speedup_floor": "speed-up against the HF floor: floor_s / t_online_median_s (speedup is "
                     "the one against the timed HF solve, t_hf_median_s / "
                     "t_online_median_s; their ratio speedup / speedup_floor = t_hf_median_s "
                     "/ floor_s is the HF solve's overhead over its floor)",
    "warnings": "what the reduction changed or doubts, in words (e.g. -N above the number or "
                "the numerical rank of the training snapshots: the basis built is smaller, "
                "N is the size built)",
}

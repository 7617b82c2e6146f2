"""Executing one case of a run matrix into a results row, in the calling process.

Shared by the runner (:mod:`rbbench.bench.runner`: the matrix loop, caching, manifest and
table) and the executors (``rbbench_plugins.executors``: where the cases run):
:func:`execute_case` turns a :class:`~rbbench.bench.matrix.Case` into its record
``{"row", "details"}`` and never raises for a failing case; :func:`decided_row` and
:func:`failed_row` give the rows of cases not run or lost by their executor;
:func:`alarm` raises :class:`CaseTimeout` at a case's time limit (in-process executors).
"""

from __future__ import annotations

import contextlib
import functools
import json
import os
import platform
import resource
import signal
import time
import traceback
from collections.abc import Callable
from datetime import datetime, timezone
from typing import Any

import numpy as np

from rbbench.bench import schema
from rbbench.bench.matrix import Case
from rbbench.provenance import _jsonable
from rbbench.registry import NotInstalledError, Registry, default_registry

__all__ = ["CaseTimeout", "alarm", "base_row", "decided_row", "execute_case", "failed_row",
           "run_provenance"]

#: Summary keys of :meth:`rbbench.rb.offline.ReduceResult.summary` copied as they are.
_COPIED = ("n_hf_dofs", "n_contact", "n_train", "n_valid", "N", "R", "M_eim", "err_u_max",
           "err_u_mean", "err_lam_max", "err_lam_mean", "lam_best_max", "penetration_max",
           "complementarity_max", "energy_err_max", "t_offline_s", "t_snapshots_hf_s",
           "t_offline_hf_s", "n_snapshots_cached", "t_online_median_s", "t_online_iqr_s",
           "t_hf_median_s", "speedup", "floor_s", "speedup_floor", "online_protocol",
           "online_path", "online_method")
#: Summary keys of a reduced friction model (rbbench.rb.friction.collocation.stage) copied as they
# are;  ``S_tau`` is its ``S`` (the row's ``S`` is the stabiliser size).
_FRICTION = ("err_lam_t_max", "err_lam_t_mean", "lam_t_best_max", "friction_residual_max",
             "friction_law_residual_max", "slip_law_residual_max",
             "online_iterations_max", "S_q", "gcns_iterations", "dim_v_off", "delta_pga")
#: Summary keys of a reduced model with an a posteriori error bound (linear scenes; mixed
#: contact scenes: err_bound_u_max, certified, the bound's online time).
_ESTIMATOR = ("err_est_max", "effectivity_min", "effectivity_max", "effectivity_median",
              "err_bound_u_max", "certified", "t_bound_median_s")
#: Summary entries of a friction reduction kept in the case details (report figures).
_FRICTION_DETAILS = ("gcns_history", "lam_t_profiles")
#: HF summary keys (rbbench.hf.metrics, rbbench.hf.metrics3d) copied into a mode-hf row as
#: they are when the summary has them: friction, the floor, the contact extent (2D
#: half-widths, 3D radii).
_HF_COPIED = ("tangential_force", "n_stick", "n_slip", "friction_residual", "floor_s",
              "solve_over_floor", "contact_half_width", "contact_half_width_gap",
              "contact_radius", "contact_radius_gap", "max_pressure")
#: The Hertz block's signed relative errors copied into a mode-hf row (``hertz_<key>``).
_HERTZ = ("a_rel_error", "a_gap_rel_error", "p0_rel_error")
#: Scene geometry kinds in 3D.
_GEOMETRIES_3D = ("hemispheres",)
_TIMINGS = {"t_snapshots_s": "snapshots_s", "t_primal_s": "primal_s", "t_dual_s": "dual_s",
            "t_stabilizer_s": "stabilizer_s", "t_hyper_s": "hyper_s"}


class CaseTimeout(Exception):
    """Raised inside a case when its time limit is reached (serial executor)."""



def _threads() -> str:
    keys = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
    return json.dumps({k: os.environ.get(k) for k in keys})


@functools.lru_cache(maxsize=1)
def run_provenance() -> dict[str, Any]:
    """Versions, git sha, machine and threads: the same for every row of a process (computed
    once; callers copy it into rows, never mutate it)."""
    import importlib.metadata as md

    from rbbench.provenance import provenance

    p = provenance()
    versions = {k: p[k] for k in ("numpy", "scipy", "python")}
    for mod in ("skfem", "daqp", "ngsolve", "petsc4py"):
        with contextlib.suppress(Exception):
            versions[mod] = md.version({"skfem": "scikit-fem"}.get(mod, mod))
    return {"rbbench_version": p["rbbench"], "git_sha": p["git_sha"] or "",
            "versions": json.dumps(versions, sort_keys=True),
            "machine": f"{p['machine']} ({platform.processor() or platform.machine()}, "
                       f"{p['cpus']} cpus)",
            "threads": _threads()}


def base_row(case: Case, run_id: str, executor: str) -> dict[str, Any]:
    """The identity, component and provenance columns of a case's row."""
    c = case.components
    return {"run_id": run_id, "case_id": case.case_id, "repetition": case.repetition,
            "seed": case.seed, "mode": case.mode, "scene": case.scene,
            "scene_overrides": json.dumps(list(case.overrides)),
            **{k: c[k] or None for k in ("backend", "formulation", "solver", "primal", "dual",
                                         "stabilizer", "hyper")},
            "executor": executor, "params": json.dumps(case.params, sort_keys=True),
            "N_req": case.N, "R_req": case.R,
            "started_at": datetime.now(timezone.utc).isoformat(timespec="seconds"),
            **run_provenance()}


def _peak_rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # KiB on Linux


def _fill(row: dict, s: dict, online_stabilizer: bool = False) -> None:
    """The row's columns from the summary ``s``; ``S``: the enrichment size, ``R`` for an
    online stabiliser (its ``capabilities["online_hf"]``), else the offline ``K``."""
    for k in _COPIED:
        row[k] = s.get(k)
    for col, key in _TIMINGS.items():
        row[col] = s["timings"].get(key)
    row["t_online_hf_assembly_s"] = s["timings"].get("t_online_hf_assembly_s")
    row["hyper_used"] = s["hyper"]
    row["S"] = s["R"] if online_stabilizer else s["K_pga"]
    for b in ("hf", "dec", "on", "off"):
        row[f"beta_{b}_min"] = s.get(f"beta_{b}_min")
        row[f"beta_{b}_kind"] = (s.get("beta_kind") or {}).get(b)
        row[f"beta_{b}_rel_min"] = s.get(f"beta_{b}_rel_min")  # beta / c_HF(mu), min
    row["beta_dec_zero_any"] = s.get("beta_dec_zero_any")
    row.update({k: s.get(k) for k in _ESTIMATOR})
    if _is_friction(s):
        row.update({k: s.get(k) for k in _FRICTION})
        row["S_tau"] = s.get("S")
        row["friction_dual"] = s.get("friction_dual") or s["config"].get("friction_dual")
        beta = (s.get("per_mu") or {}).get("beta") or {}
        for b in ("hf", "dec", "off"):  # from the per-mu rows where the summary has none
            rel = [float(v) for v in (e.get("value_rel") for e in beta.get(b) or [])
                   if isinstance(v, (int, float)) and np.isfinite(v)]
            if row[f"beta_{b}_rel_min"] is None:
                row[f"beta_{b}_rel_min"] = min(rel) if rel else None


def _is_friction(s: dict) -> bool:
    """Whether a reduction summary is that of a reduced friction model (it has S_q)."""
    return "S_q" in s


def _finite(s: dict) -> bool:
    keys = ("err_u_max", "t_online_median_s") + (("err_lam_max",) if s.get("n_contact")
                                                  is not None else ())
    return all(s.get(k) is not None and np.isfinite(s[k]) for k in keys)


def execute_case(case: Case, run_id: str, cache_dir: str, executor: str = "serial",
                 registry: Registry | None = None,
                 progress: Callable[[str], None] | None = None) -> dict[str, Any]:
    """Run one case in this process; never raises for a failing case.

    Returns ``{"row": <schema row>, "details": {...}}`` with the status set:
    ``ok``; ``diverged`` (an HF snapshot or an online solve did not converge, or
    the errors are not finite); ``not_installed`` (a component's extra is
    missing); ``timeout`` (:class:`CaseTimeout`); ``error`` (any other exception,
    with its traceback).
    """
    from rbbench.hf.snapshots.cache import SnapshotError
    from rbbench.rb.offline import DivergedError
    from rbbench.scene.loading import load_scene

    t0 = time.perf_counter()
    row = base_row(case, run_id, executor)
    details: dict[str, Any] = {}
    try:
        scene = load_scene(case.base_scene, case.overrides)
        if case.mode == "hf":
            _execute_hf(case, scene, row, registry)
        else:
            details = _execute_rb(case, scene, row, cache_dir, registry, progress)
    except CaseTimeout:
        row.update(status="timeout", reason=f"exceeded the case limit of {case.timeout_s:g} s")
    except NotInstalledError as exc:
        row.update(status="not_installed", reason=str(exc))
    except SnapshotError as exc:
        row.update(status="diverged", reason=f"HF snapshots: {exc}")
    except DivergedError as exc:
        row.update(status="diverged", reason=str(exc))
    except Exception as exc:  # noqa: BLE001 - a failing case is a row, never a lost run
        row.update(status="error", reason=f"{type(exc).__name__}: {exc}",
                   traceback=traceback.format_exc())
    row["t_case_s"] = time.perf_counter() - t0
    row["peak_rss_mb"] = _peak_rss_mb()
    return {"row": schema.normalise_row(row), "details": _jsonable(details)}


def _scene_dim(scene: Any) -> int:
    """The space dimension of a scene: 3 for the 3D geometry kinds (hemispheres), else 2."""
    return 3 if scene.data.get("geometry", {}).get("kind") in _GEOMETRIES_3D else 2


def _quiet(msg: str) -> None:
    return None


def _execute_rb(case: Case, scene: Any, row: dict, cache_dir: str, registry: Registry | None,
                progress: Callable[[str], None] | None) -> dict[str, Any]:
    """Mode rb: the reduction and its online validation; fills the row's columns and
    status and returns the case's details (per-mu values, histories, validation mus)."""
    from rbbench.rb.offline import reduce

    row["dim"] = _scene_dim(scene)  # also on a row whose reduction fails
    res = reduce(scene, case.reduce_config(cache_dir), progress=progress or _quiet,
                 registry=registry)
    s = res.summary()
    reg, stab = registry or default_registry(), s["config"].get("stabilizer")
    _fill(row, s, bool(stab in reg.names("stabilizer")
                       and reg.get("stabilizer", stab).capabilities.get("online_hf")))
    stops = s.get("online_stops", {})
    bad_stops = {k: v for k, v in stops.items() if not k.startswith("converged")}
    if not _finite(s):
        row.update(status="diverged", reason="non-finite reduced errors or online time")
    elif bad_stops:
        row.update(status="diverged", reason=f"online solves did not converge: {bad_stops}")
    else:
        row.update(status="ok", reason=s.get("reason", ""))  # linear: why no contact columns
    details = {"per_mu": s.get("per_mu", {}), "histories": s.get("histories", {}),
               "valid_mus": np.asarray(res.valid_mus).tolist(), "timings": s.get("timings", {})}
    if _is_friction(s):
        details.update({k: s.get(k) for k in _FRICTION_DETAILS})
    return details


def _execute_hf(case: Case, scene: Any, row: dict, registry: Registry | None) -> None:
    """Mode hf: ``hf_repeats`` HF solves at the scene's default mu (components built once,
    meshing not timed); fills the sizes, force, iterations and HF time columns."""
    from rbbench.hf.components import make_components
    from rbbench.hf.model import solve_hf
    from rbbench.scene.linear import is_linear

    c = case.components
    row["dim"] = _scene_dim(scene)
    if is_linear(scene):
        from rbbench.hf.linear.model import hf_row

        row.update(hf_row(scene, c["backend"], int(case.params.get("hf_repeats", 3)),
                          registry))
        return
    opts = case.solver_options
    comps = make_components(scene, c["backend"], c["formulation"], c["solver"], registry,
                            solver_options=opts)
    times, sol = [], None
    repeats = int(case.params.get("hf_repeats", 3))
    for k in range(repeats):  # the floor (factorise + solve of A) once, after the last solve
        sol = solve_hf(scene, None, c["backend"], c["formulation"], c["solver"],
                       registry=registry, solver_options=opts, components=comps,
                       floor=k == repeats - 1)
        times.append(sol.times["total_s"])
    m = sol.metrics
    row.update(n_hf_dofs=m["n_dofs"], n_contact=m["n_contact"],
               contact_force=m["contact_force"], hf_iterations=m["iterations"],
               t_hf_median_s=float(np.median(times)),
               hf_final_residual=m.get("final_residual"))
    row.update({k: m[k] for k in _HF_COPIED if k in m})
    hertz = m.get("hertz") or {}
    row.update({f"hertz_{k}": hertz.get(k) for k in _HERTZ})
    if not sol.result.converged:
        row.update(status="diverged", reason=f"HF solver stopped: {sol.result.stop_reason}")
    elif not np.isfinite(m["contact_force"]):
        row.update(status="diverged", reason="non-finite contact force")
    else:
        row.update(status="ok", reason="")


def decided_row(case: Case, run_id: str, executor: str) -> dict[str, Any]:
    """The row of a case decided without running it (skip / not_installed)."""
    row = base_row(case, run_id, executor)
    row.update(status=case.status, reason=case.reason, t_case_s=0.0,
               friction_dual=case.params.get("friction_dual"))
    return {"row": schema.normalise_row(row), "details": {}}


def failed_row(case: Case, run_id: str, executor: str, status: str, reason: str,
               tb: str = "") -> dict[str, Any]:
    """The row of a case that the executor itself lost (killed, crashed)."""
    row = base_row(case, run_id, executor)
    row.update(status=status, reason=reason, traceback=tb or None)
    return {"row": schema.normalise_row(row), "details": {}}


@contextlib.contextmanager
def alarm(seconds: float):
    """Raise :class:`CaseTimeout` in the main thread after ``seconds`` (SIGALRM).

    Python checks signals between bytecodes: a long compiled call (one sparse
    factorisation) finishes first. The process executors kill instead.
    """
    if seconds is None or seconds <= 0 or not hasattr(signal, "setitimer"):
        yield
        return

    def handler(signum, frame):
        raise CaseTimeout()

    old = signal.signal(signal.SIGALRM, handler)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)

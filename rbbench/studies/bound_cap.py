"""The speed / sharpness curve of the two-body online error bound in its number of POD modes.

The online bound of a moving contact (:mod:`rbbench.rb.mixed.contact_bound`) splits the
master half ``b_M`` of ``B(mu)^T lam_N`` into ``U g`` (``U``: at most ``bound_pod_max`` POD
modes) and a remainder bounded by ``lambda_c^(1/2) ||b_M - U g||_2``; fewer modes make the
evaluation cheaper and the remainder, hence the bound, larger (still rigorous). One reduced
model is built with the largest cap; every smaller cap is the same bound with its trailing
modes cut (:meth:`~rbbench.rb.mixed.contact_bound.ContactBound.with_modes`: the bound a
build with that cap gives, without rebuilding). All caps are then timed in one loop, each
bound right after a reduced solve at its parameter, as the reduction's row does.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from rbbench.hf.snapshots.compute import compute_snapshots
from rbbench.rb.config import ReduceConfig
from rbbench.rb.offline import offline
from rbbench.rb.validation import xnorm2
from rbbench.runtime.threads import one_blas_thread
from rbbench.runtime.timing import gc_paused
from rbbench.scene.loading import Scene, SceneError
from rbbench.studies.formatting import markdown_table

__all__ = ["bound_cap_study", "markdown"]


def bound_cap_study(scene: Scene, caps: tuple[int, ...] = (250, 150, 100, 60, 30),
                    N: int = 20, R: int = 20, n_valid: int = 20, repeats: int = 20,
                    cache_dir: str = ".rbbench_cache", progress=lambda m: None,
                    n_train: int | None = None) -> dict[str, Any]:
    """The curve (module docstring): per cap, over the validation set, the bound's and the
    solve's median times (``repeats`` interleaved rounds per parameter: solve, bound at cap
    1, solve, bound at cap 2, ...), their ratio, the effectivity min / median / max,
    ``err_bound_u_max`` and the remainder's share of ``rho`` (median); ``n_train``: the
    training set's size (default: the scene's)."""
    caps = tuple(sorted({int(k) for k in caps}, reverse=True))
    off = offline(scene, ReduceConfig(N=N, n_train=n_train, n_valid=n_valid,
                                      cache_dir=cache_dir, online_repeats=1,
                                      options={"R": R, "bound": "online",
                                               "bound_pod_max": caps[0]}), progress)
    ctx, stage = off.context, off.stage
    top = getattr(stage.model, "bound", None)
    if top is None or not hasattr(top, "with_modes"):
        info = getattr(getattr(stage, "certifier", None), "info", {})
        raise SceneError(f"{scene.name}: no two-body online bound to cut ("
                         f"{info.get('online_refused', 'no contact EIM')}): the study needs "
                         "a two-body scene with the contact EIM")
    bounds = [top.with_modes(k, stage.x_solve) for k in caps]
    mus = np.asarray(ctx.mus_valid)
    valid = compute_snapshots(scene, mus, cache_dir=cache_dir)
    X, Z, model = ctx.X, stage.Z_off, stage.model
    rows = [{"cap": k, "modes": int(b.U.shape[1]), "t_bound": [], "t_solve": [], "eff": [],
             "bound_rel": [], "rem_share": []} for k, b in zip(caps, bounds, strict=True)]
    progress(f"timing {len(caps)} caps x {len(mus)} parameters x {repeats} rounds")
    with one_blas_thread(), gc_paused():
        for j, mu in enumerate(mus):
            u = valid.U[:, j]
            for b in bounds:  # untimed round: compile, load
                sol = model.solve(mu)
                b(mu, sol.c, sol.alpha)
            for _ in range(repeats):
                for row, b in zip(rows, bounds, strict=True):
                    sol = model.solve(mu)
                    t0 = time.perf_counter()
                    res = b(mu, sol.c, sol.alpha)
                    row["t_bound"].append(time.perf_counter() - t0)
                    row["t_solve"].append(float(sol.time_s))
            for row, b in zip(rows, bounds, strict=True):
                sol = model.solve(mu)
                res = b(mu, sol.c, sol.alpha)
                e = u - Z @ sol.c
                err = float(np.sqrt(max(xnorm2(X, e), 0.0)))
                row["eff"].append(res.delta_u / err if err > 0 else float("inf"))
                row["bound_rel"].append(res.delta_u / float(np.sqrt(xnorm2(X, u))))
                row["rem_share"].append(b.last_remainder / res.terms.rho)
    out = [_summary(r) for r in rows]
    return {"scene": scene.name, "N": int(stage.N), "K_pga": int(stage.K), "R": int(stage.R),
            "n_valid": len(mus), "repeats": repeats,
            "bound_build_s": stage.certifier.info.get("build_s"), "rows": out}


def _summary(r: dict[str, Any]) -> dict[str, Any]:
    tb, ts = float(np.median(r["t_bound"])), float(np.median(r["t_solve"]))
    return {"cap": r["cap"], "modes": r["modes"], "t_bound_median_s": tb,
            "t_bound_solve_median_s": ts, "t_bound_ratio": tb / ts,
            "effectivity_min": float(np.min(r["eff"])),
            "effectivity_median": float(np.median(r["eff"])),
            "effectivity_max": float(np.max(r["eff"])),
            "err_bound_u_max": float(np.max(r["bound_rel"])),
            "remainder_share_median": float(np.median(r["rem_share"])),
            "remainder_share_max": float(np.max(r["rem_share"]))}


def markdown(out: dict[str, Any]) -> str:
    """The curve as a Markdown table."""
    head = (f"{out['scene']}: N = {out['N']} + {out['K_pga']} PGA, R = {out['R']}, "
            f"{out['n_valid']} validation parameters x {out['repeats']} rounds")
    table = markdown_table(
        ("cap", "modes", "t_bound (us)", "t_solve (us)", "ratio",
         "effectivity min / median / max", "err_bound_u_max", "remainder / rho median (max)"),
        ((r["cap"], r["modes"], f"{1e6 * r['t_bound_median_s']:.0f}",
          f"{1e6 * r['t_bound_solve_median_s']:.0f}", f"{r['t_bound_ratio']:.2f}",
          f"{r['effectivity_min']:.2f} / {r['effectivity_median']:.2f} / "
          f"{r['effectivity_max']:.2f}", f"{r['err_bound_u_max']:.3g}",
          f"{r['remainder_share_median']:.2f} ({r['remainder_share_max']:.2f})")
         for r in out["rows"]))
    return f"{head}\n\n{table}"

"""Small studies printed as Markdown tables (``rbbench hertz-table``, ``online-scaling``)."""

from __future__ import annotations

import time

import numpy as np

from rbbench.hf import solve_hf
from rbbench.scene import load_scene


def hertz_table(scene: str = "hertz_halfdisks", loads=(0.05, 0.01), levels=(0, 1, 2),
                mu: float = 1.0, overrides=(), progress=print) -> list[dict]:
    """2D Hertz errors against load and uniform mesh refinement (``discretization.level``).

    Errors are signed relative errors at the solver's own force:
    (computed - theory) / theory, for the half-width a and the peak pressure p0.
    """
    rows = []
    for d in loads:
        for level in levels:
            sc = load_scene(scene, [*overrides, f"load.displacement={d}",
                                    f"discretization.level={level}"])
            t0 = time.perf_counter()
            sol = solve_hf(sc, mu)
            m = sol.metrics
            rows.append({"d": d, "level": level, "n_dofs": m["n_dofs"],
                         "h_facet": float(sol.disc.contact.weights.reshape(-1, 2).sum(1).max())
                         if sol.disc.contact.n_quad % 2 == 0 else float("nan"),
                         "n_active": m["n_active"], "P": m["contact_force"],
                         "a": m["contact_half_width"], "a_hertz": m["hertz"]["a"],
                         "a_err": m["hertz"]["a_rel_error"], "p0": m["max_pressure"],
                         "p0_hertz": m["hertz"]["p0"], "p0_err": m["hertz"]["p0_rel_error"],
                         "stop": m["stop_reason"], "time_s": time.perf_counter() - t0})
            progress(f"d = {d:g}, level {level}: done in {rows[-1]['time_s']:.1f} s")
    return rows


def markdown(rows: list[dict]) -> str:
    head = ("| d (m) | level | dofs | active | P (N/m) | a (m) | a Hertz | a err | "
            "p0 (Pa) | p0 Hertz | p0 err | HF time (s) |")
    lines = [head, "|" + "---|" * 12]
    for r in rows:
        lines.append(
            f"| {r['d']:g} | {r['level']} | {r['n_dofs']} | {r['n_active']} | {r['P']:.4g} | "
            f"{r['a']:.4g} | {r['a_hertz']:.4g} | {100 * r['a_err']:+.2f} % | {r['p0']:.4g} | "
            f"{r['p0_hertz']:.4g} | {100 * r['p0_err']:+.2f} % | {r['time_s']:.2f} |")
    return "\n".join(lines)


def online_scaling(scene: str, config, levels=(0, 1), overrides=(), repeats: int = 30,
                   progress=print) -> list[dict]:
    """Online time of the same reduction at several mesh levels, timed side by side.

    One reduced model is built per ``discretization.level``; then every model
    solves every validation mu ``repeats`` times, the models interleaved in
    each round so that machine load hits them alike. Reports per level the
    HF size, the reduced sizes, the median and inter-quartile range of the
    online time (s) and its ratio to the first level.
    """
    from rbbench.rb_pipeline import reduce

    results = []
    for level in levels:
        sc = load_scene(scene, [*overrides, f"discretization.level={level}"])
        progress(f"level {level}: offline")
        res = reduce(sc, config)
        if res.model is None:
            raise ValueError(f"hyper {res.hyper!r} builds no HF-independent model; use 'eim' "
                             "or 'affine'")
        results.append(res)
    times: list[list[float]] = [[] for _ in results]
    for _ in range(repeats):
        for k, res in enumerate(results):
            for mu in res.valid_mus:
                times[k].append(res.model.solve(mu).time_s)
    rows = []
    base = float(np.median(times[0]))
    for level, res, t in zip(levels, results, times, strict=True):
        s = res.summary()
        med = float(np.median(t))
        rows.append({"level": level, "n_hf_dofs": s["n_hf_dofs"], "n_contact": s["n_contact"],
                     "N": s["N"], "K_pga": s["K_pga"], "R": s["R"], "M_eim": s["M_eim"],
                     "err_u_max": s["err_u_max"], "err_lam_max": s["err_lam_max"],
                     "t_online_median_s": med,
                     "t_online_iqr_s": float(np.subtract(*np.percentile(t, [75, 25]))),
                     "ratio_to_first": med / base, "t_hf_median_s": s["t_hf_median_s"]})
    return rows


def scaling_markdown(rows: list[dict]) -> str:
    lines = ["| level | HF dofs | contact rows | N + K | R | EIM rows | err u max | "
             "err lam max | online median (ms) | IQR (ms) | ratio | HF median (s) |",
             "|" + "---|" * 12]
    for r in rows:
        lines.append(
            f"| {r['level']} | {r['n_hf_dofs']} | {r['n_contact']} | {r['N']} + {r['K_pga']} | "
            f"{r['R']} | {r['M_eim']} | {r['err_u_max']:.2e} | {r['err_lam_max']:.2e} | "
            f"{1e3 * r['t_online_median_s']:.3f} | {1e3 * r['t_online_iqr_s']:.3f} | "
            f"{r['ratio_to_first']:.2f} | {r['t_hf_median_s']:.2f} |")
    return "\n".join(lines)

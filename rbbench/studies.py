"""Small studies printed as Markdown tables (``rbbench hertz-table``)."""

from __future__ import annotations

import time

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

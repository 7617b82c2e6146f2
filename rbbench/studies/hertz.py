"""2D Hertz errors against load and mesh level (``rbbench hertz-table``)."""

from __future__ import annotations

import time

import numpy as np

from rbbench.hf.model import solve_hf
from rbbench.scene.loading import load_scene
from rbbench.studies.formatting import markdown_table

__all__ = ["hertz_markdown", "hertz_table"]


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
            sol = solve_hf(sc, mu, floor=False)
            m = sol.metrics
            rows.append({"d": d, "level": level, "n_dofs": m["n_dofs"],
                         "h_facet": _largest_facet(sc, sol.disc),
                         "n_active": m["n_active"], "P": m["contact_force"],
                         "a": m["contact_half_width"], "a_hertz": m["hertz"]["a"],
                         "a_err": m["hertz"]["a_rel_error"], "p0": m["max_pressure"],
                         "p0_hertz": m["hertz"]["p0"], "p0_err": m["hertz"]["p0_rel_error"],
                         "stop": m["stop_reason"], "time_s": time.perf_counter() - t0})
            progress(f"d = {d:g}, level {level}: done in {rows[-1]['time_s']:.1f} s")
    return rows


def hertz_markdown(rows: list[dict]) -> str:
    """The rows of :func:`hertz_table` as a Markdown table (errors in %)."""
    head = ("d (m)", "level", "dofs", "active", "P (N/m)", "a (m)", "a Hertz", "a err",
            "p0 (Pa)", "p0 Hertz", "p0 err", "HF time (s)")
    return markdown_table(head, (
        (f"{r['d']:g}", r["level"], r["n_dofs"], r["n_active"], f"{r['P']:.4g}",
         f"{r['a']:.4g}", f"{r['a_hertz']:.4g}", f"{100 * r['a_err']:+.2f} %",
         f"{r['p0']:.4g}", f"{r['p0_hertz']:.4g}", f"{100 * r['p0_err']:+.2f} %",
         f"{r['time_s']:.2f}") for r in rows))


def _largest_facet(scene, disc) -> float:
    """Largest slave contact facet (m): ``facet_length`` when built, else the weights
    summed per facet (Gauss rule: the same points on every facet; NaN for segmented
    quadrature, whose pieces do not tell their facet)."""
    c, nf = disc.contact, int(disc.info.get("n_facets_slave", 0))
    if c.facet_length is not None:
        return float(np.max(c.facet_length))
    gauss = scene.data["discretization"].get("contact_integration", "gauss") == "gauss"
    if not gauss or nf <= 0 or c.n_quad % nf:
        return float("nan")
    return float(c.weights.reshape(nf, -1).sum(axis=1).max())

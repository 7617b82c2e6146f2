"""Online time of one reduction at several mesh levels (``rbbench online-scaling``)."""

from __future__ import annotations

import numpy as np

from rbbench._compat import deprecated_names
from rbbench.rb.online import OnlineTimes, timed_online_solves
from rbbench.runtime.threads import one_blas_thread
from rbbench.runtime.timing import ONLINE_PROTOCOL, gc_paused
from rbbench.scene.loading import load_scene
from rbbench.studies.formatting import markdown_table

__all__ = ["online_scaling", "scaling_markdown"]


def online_scaling(scene: str, config, levels=(0, 1), overrides=(), repeats: int = 30,
                   progress=print, baseline: str | None = None,
                   baseline_overrides=()) -> list[dict]:
    """Online time of the same reduction at several mesh levels, timed side by side.

    One reduced model is built per ``discretization.level`` (and, with ``baseline``, one
    more of that scene with ``baseline_overrides``, built with the same configuration: e.g.
    the 2D counterpart of a 3D scene, timed in the same loop); then every model
    solves every validation mu ``repeats`` times under the online-time protocol
    (:func:`rbbench.rb.online.timed_online_solves`: one untimed warm-up solve per model, one
    BLAS thread, garbage collector paused), the models interleaved in each round so that
    machine load hits them alike. Reports per level the HF size, the reduced sizes, the
    median and inter-quartile range of the online time (s), its ratio to the first level
    (``ratio_to_first``) and to the baseline's (``ratio_to_baseline``, with ``baseline``;
    the baseline's own row comes first, ``level`` None), the online path that ran
    (``compiled`` or ``python``), the online method that ran
    (``online_method``; ``auto`` resolved), the share of the 3D magic rows' slave points
    paired through the table of their hit triangle (``pairing_table_share``, None where
    there is no such pairing) and the protocol's name (``online_protocol``).
    """
    from rbbench.rb.offline import reduce

    cases = ([(None, load_scene(baseline, list(baseline_overrides)))] if baseline is not None
             else [])
    cases += [(level, load_scene(scene, [*overrides, f"discretization.level={level}"]))
              for level in levels]  # every scene is loaded (and checked) before any offline
    results = []
    for level, sc in cases:
        progress(f"{sc.name} level {level if level is not None else 'default'}: offline")
        res = reduce(sc, config)
        if res.hyper == "none":
            raise ValueError(f"hyper {res.hyper!r} builds no HF-independent model; use 'eim' "
                             "or 'affine'")
        results.append(res)
    timed = [OnlineTimes() for _ in results]
    with one_blas_thread(), gc_paused():
        for res in results:  # the protocol's warm-up, once per model
            res.model.solve(res.valid_mus[0])
        for _ in range(repeats):
            for k, res in enumerate(results):  # the model's online method: config's
                timed[k].extend(timed_online_solves(res.model, res.valid_mus, 1,
                                                    warm_up=False))
    rows = []
    medians = [float(np.median(t.times)) for t in timed]
    first = medians[1] if baseline is not None else medians[0]
    for (level, sc), res, t in zip(cases, results, timed, strict=True):
        s, on = res.summary(), t.summary()
        rows.append({"scene": sc.name, "level": level, "n_hf_dofs": s["n_hf_dofs"],
                     "n_contact": s["n_contact"],
                     "N": s["N"], "K_pga": s["K_pga"], "R": s["R"], "M_eim": s["M_eim"],
                     "err_u_max": s["err_u_max"], "err_lam_max": s["err_lam_max"],
                     "t_online_median_s": on["t_online_median_s"],
                     "t_online_iqr_s": on["t_online_iqr_s"],
                     "ratio_to_first": on["t_online_median_s"] / first,
                     "ratio_to_baseline": (on["t_online_median_s"] / medians[0]
                                           if baseline is not None else None),
                     "t_hf_median_s": s["t_hf_median_s"], "floor_s": s["floor_s"],
                     "online_method": on["online_method"], "online_path": on["online_path"],
                     "pairing_table_share": _table_share(res.model),
                     "online_protocol": ONLINE_PROTOCOL})
    return rows


def _table_share(model) -> float | None:
    """The share of 3D slave points the compiled pairing finds by its table (None: no
    such pairing)."""
    share = getattr(model, "pairing_table_share", None)
    return None if share is None else share()


def scaling_markdown(rows: list[dict]) -> str:
    """The rows of :func:`online_scaling` as a Markdown table (online times in us), followed
    by the name of the online-time protocol."""
    with_base = any(r.get("ratio_to_baseline") is not None for r in rows)
    head = ("scene", "level", "HF dofs", "contact rows", "N + K", "R", "EIM rows", "err u max",
            "err lam max", "online median (us)", "IQR (us)", "ratio to first level",
            *(("ratio to baseline",) if with_base else ()), "HF median (s)", "HF floor (s)",
            "online method", "online path", "points by table")
    table = markdown_table(head, (
        (r.get("scene", ""), "baseline" if r["level"] is None else r["level"], r["n_hf_dofs"],
         r["n_contact"], f"{r['N']} + {r['K_pga']}", r["R"],
         r["M_eim"], f"{r['err_u_max']:.2e}", f"{r['err_lam_max']:.2e}",
         f"{1e6 * r['t_online_median_s']:.1f}", f"{1e6 * r['t_online_iqr_s']:.1f}",
         f"{r['ratio_to_first']:.2f}",
         *((f"{r['ratio_to_baseline']:.2f}",) if with_base else ()),
         f"{r['t_hf_median_s']:.2f}",
         "" if r.get("floor_s") is None else f"{r['floor_s']:.3f}", r["online_method"],
         r["online_path"],
         "" if r.get("pairing_table_share") is None else f"{r['pairing_table_share']:.0%}")
        for r in rows))
    protocols = sorted({r.get("online_protocol") or ONLINE_PROTOCOL for r in rows})
    return (f"{table}\n\nOnline times: protocol {', '.join(protocols)} (one untimed warm-up "
            "solve per model, one BLAS thread, garbage collector paused, median over "
            "validation mus x repeats; rbbench reduce and run rows name the same protocol). "
            "HF floor: one factorisation + one solve of A(mu), median over the validation "
            "set.")


__getattr__ = deprecated_names(__name__)  # names that left this module (rbbench._compat)

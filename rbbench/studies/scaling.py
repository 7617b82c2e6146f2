"""Online time of one reduction at several mesh levels (``rbbench online-scaling``)."""

from __future__ import annotations

import gc
from contextlib import contextmanager

import numpy as np

from rbbench.runtime.threads import one_blas_thread
from rbbench.scene.loading import load_scene
from rbbench.studies.formatting import markdown_table

__all__ = ["gc_paused", "online_scaling", "scaling_markdown"]


def online_scaling(scene: str, config, levels=(0, 1), overrides=(), repeats: int = 30,
                   progress=print) -> list[dict]:
    """Online time of the same reduction at several mesh levels, timed side by side.

    One reduced model is built per ``discretization.level``; then every model
    solves every validation mu ``repeats`` times, the models interleaved in
    each round so that machine load hits them alike, under one BLAS thread and with the
    garbage collector paused (as :mod:`timeit` does: a collection of the heap the
    reductions left would land in one solve's time; :func:`gc_paused`). Reports
    per level the HF size, the reduced sizes, the median and inter-quartile range of
    the online time (s), its ratio to the first level and the online path that ran
    (``compiled`` or ``python``, :attr:`OnlineResult.path`) and the online method that ran
    (``online_method``; ``auto`` resolved, :attr:`OnlineResult.method`).
    """
    from rbbench.rb.offline import reduce

    results = []
    for level in levels:
        sc = load_scene(scene, [*overrides, f"discretization.level={level}"])
        progress(f"level {level}: offline")
        res = reduce(sc, config)
        if res.hyper == "none":
            raise ValueError(f"hyper {res.hyper!r} builds no HF-independent model; use 'eim' "
                             "or 'affine'")
        results.append(res)
    times: list[list[float]] = [[] for _ in results]
    paths: list[set[str]] = [set() for _ in results]
    methods: list[set[str]] = [set() for _ in results]
    with one_blas_thread(), gc_paused():
        for _ in range(repeats):
            for k, res in enumerate(results):
                for mu in res.valid_mus:
                    out = res.model.solve(mu)  # the model's online method: config's
                    times[k].append(out.time_s)
                    paths[k].add(str(getattr(out, "path", "python")))
                    methods[k].add(str(getattr(out, "method", "")))
    rows = []
    base = float(np.median(times[0]))
    for level, res, t, path, meth in zip(levels, results, times, paths, methods, strict=True):
        s = res.summary()
        med = float(np.median(t))
        rows.append({"level": level, "n_hf_dofs": s["n_hf_dofs"], "n_contact": s["n_contact"],
                     "N": s["N"], "K_pga": s["K_pga"], "R": s["R"], "M_eim": s["M_eim"],
                     "err_u_max": s["err_u_max"], "err_lam_max": s["err_lam_max"],
                     "t_online_median_s": med,
                     "t_online_iqr_s": float(np.subtract(*np.percentile(t, [75, 25]))),
                     "ratio_to_first": med / base, "t_hf_median_s": s["t_hf_median_s"],
                     "online_method": "/".join(sorted(meth)),
                     "online_path": "/".join(sorted(path))})
    return rows


@contextmanager
def gc_paused():
    """The garbage collector disabled inside (restored after, if it was enabled)."""
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was_enabled:
            gc.enable()


def scaling_markdown(rows: list[dict]) -> str:
    """The rows of :func:`online_scaling` as a Markdown table (online times in us)."""
    head = ("level", "HF dofs", "contact rows", "N + K", "R", "EIM rows", "err u max",
            "err lam max", "online median (us)", "IQR (us)", "ratio", "HF median (s)",
            "online method", "online path")
    return markdown_table(head, (
        (r["level"], r["n_hf_dofs"], r["n_contact"], f"{r['N']} + {r['K_pga']}", r["R"],
         r["M_eim"], f"{r['err_u_max']:.2e}", f"{r['err_lam_max']:.2e}",
         f"{1e6 * r['t_online_median_s']:.1f}", f"{1e6 * r['t_online_iqr_s']:.1f}",
         f"{r['ratio_to_first']:.2f}", f"{r['t_hf_median_s']:.2f}", r["online_method"],
         r["online_path"])
        for r in rows))

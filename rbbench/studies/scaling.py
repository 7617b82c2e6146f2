"""Online time of one reduction at several mesh levels (``rbbench online-scaling``)."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

import numpy as np

from rbbench._compat import deprecated_names
from rbbench.rb.online import OnlineTimes, timed_online_solves
from rbbench.runtime.threads import one_blas_thread
from rbbench.runtime.timing import ONLINE_PROTOCOL, gc_paused
from rbbench.scene.linear import is_linear
from rbbench.scene.loading import load_scene
from rbbench.studies.formatting import markdown_table

if TYPE_CHECKING:
    from rbbench.rb.config import ReduceConfig
    from rbbench.rb.validation import ReduceResult

__all__ = ["capped_config", "online_scaling", "scaling_markdown"]


def online_scaling(scene: str, config, levels=(0, 1), overrides=(), repeats: int = 30,
                   progress=print, baseline: str | None = None,
                   baseline_overrides=(), match_sizes: bool = False) -> list[dict]:
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

    With ``match_sizes`` the first level is built first and every later level is built
    with its reduced sizes capped at the first level's (:func:`capped_config`): the ratios
    then measure the HF size alone, at the same reduced problem (a coarse level may stop
    its cone or EIM early, or have no more to give: the default ratios mix both effects).
    ``sizes_from`` in the rows names the level whose sizes capped them (None without).
    """
    from rbbench.rb.offline import reduce

    cases = ([(None, load_scene(baseline, list(baseline_overrides)))] if baseline is not None
             else [])
    cases += [(level, load_scene(scene, [*overrides, f"discretization.level={level}"]))
              for level in levels]  # every scene is loaded (and checked) before any offline
    if match_sizes:
        kind = config.formulation or ("linear" if is_linear(cases[-1][1]) else "mixed")
        if kind != "mixed":
            raise ValueError(f"match_sizes: caps the mixed formulation's sizes (N, R, K, EIM "
                             f"terms), not {kind!r}'s")
    results, level_config, sizes_from = [], config, None
    for level, sc in cases:
        progress(f"{sc.name} level {level if level is not None else 'default'}: offline")
        res = reduce(sc, config if level is None else level_config)
        if match_sizes and level is not None and sizes_from is None:
            sizes_from, level_config = level, capped_config(config, res)
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
                     "sizes_from": None if level in (None, sizes_from) else sizes_from,
                     "online_protocol": ONLINE_PROTOCOL})
    return rows


def capped_config(config: ReduceConfig, result: ReduceResult) -> ReduceConfig:
    """``config`` with the reduced sizes capped at those ``result`` (a built reduction of
    the mixed formulation) reached: ``N``, the dual size ``R`` (and ``S`` on a friction
    scene), the supremizers ``k_pga_max`` (when it kept any) and the EIM terms ``m_eim``
    (the largest term count of its expansions)."""
    s = result.summary()
    caps = {"R": s["R"]}
    if s.get("S") is not None:
        caps["S"] = s["S"]
    if s.get("K_pga"):
        caps["k_pga_max"] = s["K_pga"]
    eim = result.histories.get("eim", {})
    terms = [int(v) for k, v in eim.items() if k.startswith("M_") and v is not None]
    if terms:
        caps["m_eim"] = max(terms)
    opts = config.options
    opts = (dataclasses.replace(opts, **caps) if dataclasses.is_dataclass(opts)
            else {**dict(opts), **caps})
    return dataclasses.replace(config, N=s["N"], options=opts)


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
    capped = sorted({r["sizes_from"] for r in rows if r.get("sizes_from") is not None})
    if capped:
        table += ("\n\nReduced sizes (N, R, K, EIM terms) of the later levels capped at level "
                  f"{', '.join(map(str, capped))}'s.")
    return (f"{table}\n\nOnline times: protocol {', '.join(protocols)} (one untimed warm-up "
            "solve per model, one BLAS thread, garbage collector paused, median over "
            "validation mus x repeats; rbbench reduce and run rows name the same protocol). "
            "HF floor: one factorisation + one solve of A(mu), median over the validation "
            "set.")


__getattr__ = deprecated_names(__name__)  # names that left this module (rbbench._compat)

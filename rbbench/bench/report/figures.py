"""The figures of a report drawn from the rows: error against size, speed-ups and status
counts (Pareto fronts: :mod:`~rbbench.bench.report.cost_figures`); :data:`_FIGURES` lists
every figure in report order."""

from __future__ import annotations

from typing import Any

import numpy as np

from rbbench.bench.report.analysis import _Ctx, _size, _size_req, status_counts
from rbbench.bench.report.bound_figures import _fig_bound
from rbbench.bench.report.common import _COL, _axis_label, _num, _pos
from rbbench.bench.report.cost_figures import _fig_offline, _fig_pareto
from rbbench.bench.report.detail_figures import _fig_histories, _fig_infsup
from rbbench.bench.report.friction_figures import _fig_gcns
from rbbench.bench.report.hf_figures import _fig_hf
from rbbench.bench.report.plotting import _combo_handles, _dodge, _empty, _figure, _Skip

_FLOOR_LABEL = "lam_best_max: best approximation\nin the dual's cone (floor)"

_STATUS_COLOUR = {"ok": "tab:green", "skip": "0.65", "error": "tab:red",
                  "timeout": "tab:orange", "diverged": "tab:purple",
                  "not_installed": "tab:blue"}


def _size_curve(ax, ctx: _Ctx, lab: str, cs: list[dict[str, Any]], m: str, s: str,
                span: float) -> None:
    """One combination: every case a marker, the line the smallest error at each size
    (for err_lam_max also the floor lam_best_max, thick dotted); the sizes shifted by the
    dual compressor's offset (:func:`_dodge`), the styles of :meth:`_Combos.style`."""
    st = ctx.combos.style(cs[0])
    dx = _dodge(ctx, ctx.combos._part(cs[0], "dual"), span)
    marker = {"marker": st["marker"], "color": st["color"], "zorder": st["zorder"],
              "markerfacecolor": st["markerfacecolor"],
              "markeredgewidth": st["markeredgewidth"]}
    xs = np.array([_size(c, s) for c in cs], dtype=float)
    ys = np.array([_num(c[m]) for c in cs])
    ax.plot(xs + dx, ys, linestyle="none", markersize=5, alpha=0.55, **marker)
    ux = np.unique(xs)
    best = [ys[xs == v].min() for v in ux]
    ax.plot(ux + dx, best, linestyle=st["linestyle"], markersize=6, label=lab, **marker)
    if m == "err_lam_max":  # the cone's floor: no model on that space does better
        fl = [(x, _num(c.get("lam_best_max"))) for x, c in zip(xs, cs, strict=True)
              if _pos(c.get("lam_best_max"))]
        if fl:
            fx = np.unique([x for x, _ in fl])
            fy = [min(y for x, y in fl if x == v) for v in fx]
            ax.plot(fx + dx, fy, label=_FLOOR_LABEL, **_floor_style(st["color"]))


def _floor_style(colour: Any) -> dict[str, Any]:
    """The lam_best_max floor: thick, dotted, pale, a bar at each size (no combination
    line is dotted: :data:`~rbbench.bench.report.common._LINESTYLES`)."""
    return {"color": colour, "linestyle": ":", "linewidth": 2.4, "alpha": 0.6,
            "marker": "_", "markersize": 12, "zorder": 2}


def _fig_error_vs_size(ctx: _Ctx):
    pairs = (("err_u_max", "N"), ("err_lam_max", "R"))
    pts = [c for c in ctx.cases if any(_pos(c.get(m)) and _size(c, s) is not None
                                       for m, s in pairs)]
    if not pts:
        raise _Skip("no ok case with an error and a size")
    fig, axes = _figure(2, len(ctx.scenes))
    for j, sc in enumerate(ctx.scenes):
        for i, (m, s) in enumerate(pairs):
            ax = axes[i, j]
            mine = [c for c in pts if str(c.get("scene")) == sc and _pos(c.get(m))
                    and _size(c, s) is not None]
            if not mine:
                _empty(ax, f"{sc}: no ok case with {m}")
                continue
            by: dict[str, list[dict[str, Any]]] = {}
            for c in mine:
                by.setdefault(ctx.combos.label(c), []).append(c)
            sizes = [_size(c, s) for c in mine]
            for lab in sorted(by):
                _size_curve(ax, ctx, lab, by[lab], m, s, max(sizes) - min(sizes))
            ax.set_yscale("log")
            ax.grid(True, which="major", alpha=0.3)
            ax.xaxis.get_major_locator().set_params(integer=True)
            ax.set_title(sc, fontsize=10)
            ax.set_xlabel(_axis_label(s), fontsize=8)
            ax.set_ylabel(_axis_label(m), fontsize=8)
    handles = _combo_handles(ctx, pts, line=True)
    if any(ln.get_label() == _FLOOR_LABEL for ax in axes.flat for ln in ax.lines):
        from matplotlib.lines import Line2D

        handles.append(Line2D([], [], label=_FLOOR_LABEL, **_floor_style("0.35")))
    fig.legend(handles=handles, loc="outside right upper", fontsize=8,
               title=ctx.combos.title, title_fontsize=8)
    fig.suptitle("Error against RB size (line: best case at each size)", fontsize=11)
    caption = ("Top: err_u_max against the primal size N obtained; bottom: err_lam_max "
               "against the dual size R obtained. Where the other size also varies, every "
               "case is a marker and the line joins the smallest error at each size. The "
               "markers of each dual compressor are shifted sideways by a small offset "
               "(2.5 % of the size axis per dual) and every other dual's markers are hollow "
               "and drawn on top, so duals with equal errors stay visible. Thick dotted, "
               "in the dual's colour (bottom): lam_best_max, " + _COL["lam_best_max"].doc
               + ".")
    return fig, caption


def _speedup_bars(ax, ctx: _Ctx, mine: list[dict[str, Any]], sizes: list, scol: dict) -> bool:
    """One scene's bars (one per case, grouped by combination); True if one is hatched."""
    labels = sorted({ctx.combos.label(c) for c in mine})
    width = 0.8 / len(sizes)
    vals = [_num(c["speedup"]) for c in mine]
    hatched = False
    for c in mine:
        k = labels.index(ctx.combos.label(c))
        s = sizes.index(_size_req(c))
        plain = c.get("hyper_used") == "none"
        hatched = hatched or plain
        ax.bar(k - 0.4 + width * (s + 0.5), _num(c["speedup"]), width=width * 0.95,
               color=scol[_size_req(c)], edgecolor="0.2", linewidth=0.4,
               hatch="//" if plain else None)
    if max(vals) / min(vals) > 30:
        ax.set_yscale("log")
    ax.set_xticks(range(len(labels)), labels, rotation=30, ha="right", fontsize=8)
    ax.set_xlim(-0.6, len(labels) - 0.4)
    return hatched


def _fig_speedup(ctx: _Ctx):
    pts = [c for c in ctx.cases if _pos(c.get("speedup"))]
    if not pts:
        raise _Skip("no ok case with a positive speed-up")
    sizes = sorted({_size_req(c) for c in pts})
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    scol = {s: cmap(0.15 + 0.7 * k / max(1, len(sizes) - 1)) for k, s in enumerate(sizes)}
    scenes = [sc for sc in ctx.scenes if any(str(c.get("scene")) == sc for c in pts)]
    n_comb = len({ctx.combos.label(c) for c in pts})
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    hatched = False
    fig = Figure(figsize=(max(6.0, 0.55 * n_comb * max(1, len(sizes)) + 3.5),
                          3.6 * len(scenes) + 0.6), layout="constrained")
    axes = fig.subplots(len(scenes), 1, squeeze=False)[:, 0]
    for ax, sc in zip(axes, scenes, strict=True):
        mine = [c for c in pts if str(c.get("scene")) == sc]
        hatched = _speedup_bars(ax, ctx, mine, sizes, scol) or hatched
        ax.grid(True, axis="y", which="major", alpha=0.3)
        ax.set_title(sc, fontsize=10)
        ax.set_ylabel(_axis_label("speedup"), fontsize=8)
    handles = [Patch(color=scol[s], label=f"N={s[0]}, R={s[1]}") for s in sizes]
    if hatched:
        handles.append(Patch(facecolor="white", edgecolor="0.2", hatch="//",
                             label="hyper none: online step\nstarts from HF operators"))
    fig.legend(handles=handles, loc="outside right upper", fontsize=8,
               title="size asked", title_fontsize=8)
    fig.suptitle("Speed-up of the online solve over the HF solve (ok cases; median over "
                 "repetitions)", fontsize=11)
    caption = (f"speedup = {_COL['speedup'].doc}; t_hf_median_s: {_COL['t_hf_median_s'].doc}; "
               f"t_online_median_s: {_COL['t_online_median_s'].doc}. One bar per case, "
               "grouped by combination, coloured by the size asked. Hatched: hyper_used "
               "none (no affine / EIM model: the online step assembles the HF operators at "
               "mu and projects them; that time is included), so that speed-up is not that "
               "of an HF-size independent online stage.")
    return fig, caption


def _fig_status(ctx: _Ctx):
    if not ctx.records:
        raise _Skip("the results table has no rows")
    counts = status_counts(ctx.run.rows)
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    fig = Figure(figsize=(8.0, 1.2 + 0.5 * len(counts)), layout="constrained")
    ax = fig.subplots()
    y = np.arange(len(counts))
    left = np.zeros(len(counts))
    statuses = [s for s in counts.columns if s != "total"]
    for s in statuses:
        v = counts[s].to_numpy(dtype=float)
        ax.barh(y, v, left=left, color=_STATUS_COLOUR.get(s, "0.5"), edgecolor="white")
        for yi, (lo, vi) in enumerate(zip(left, v, strict=True)):
            if vi > 0:
                ax.text(lo + vi / 2, yi, str(int(vi)), ha="center", va="center", fontsize=8,
                        color="white" if s != "skip" else "black")
        left += v
    ax.set_yticks(y, list(counts.index), fontsize=9)
    ax.invert_yaxis()
    ax.set_xlabel("rows (cases x repetitions)", fontsize=9)
    ax.xaxis.get_major_locator().set_params(integer=True)
    ax.set_title("Status of every row, per scene", fontsize=11)
    fig.legend(handles=[Patch(color=_STATUS_COLOUR.get(s, "0.5"), label=s) for s in statuses],
               loc="outside right upper", fontsize=8, title="status", title_fontsize=8)
    caption = f"status: {_COL['status'].doc}."
    return fig, caption


#: (name, builder) of every figure, in report order
_FIGURES = (("pareto", _fig_pareto), ("offline", _fig_offline),
            ("error_vs_size", _fig_error_vs_size),
            ("infsup", _fig_infsup), ("histories", _fig_histories), ("bound", _fig_bound),
            ("speedup", _fig_speedup), ("gcns", _fig_gcns), ("hf", _fig_hf),
            ("status", _fig_status))

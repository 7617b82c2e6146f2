"""The cost figures of a report: error against online time (Pareto fronts, with the sizes
N, R of every case and the HF solve time as reference)."""

from __future__ import annotations

from typing import Any

import numpy as np

from rbbench.bench.report.analysis import _Ctx, _size, pareto_front
from rbbench.bench.report.common import _COL, _axis_label, _num, _pos
from rbbench.bench.report.plotting import (
    _combo_handles,
    _empty,
    _figure,
    _log_axes,
    _short_log_ticks,
    _Skip,
)

_HF_COLOUR = "tab:red"
_HF_LABEL = "HF solve (median)"
_SLOWER_LABEL = "slower than the HF solve\n(speed-up < 1)"
_MS_MIN, _MS_MAX = 4.5, 10.0  # marker sizes of the smallest and the largest (N, R)


def _nr(c: dict[str, Any]) -> tuple[int, int]:
    """The sizes (N, R) of a case as built (``-1`` when unknown)."""
    n, r = _size(c, "N"), _size(c, "R")
    return (-1 if n is None else n, -1 if r is None else r)


def _size_marks(cases: list[dict[str, Any]]) -> dict[tuple[int, int], float]:
    """Marker size per (N, R) of the run: the larger the sizes, the larger the marker."""
    sizes = sorted({_nr(c) for c in cases})
    step = (_MS_MAX - _MS_MIN) / max(1, len(sizes) - 1)
    return {s: _MS_MIN + step * k if len(sizes) > 1 else 7.0 for k, s in enumerate(sizes)}


def _size_text(s: tuple[int, int]) -> str:
    if s[1] == -1 and s[0] != -1:  # no dual space (a scene without contact)
        return f"N={s[0]}"
    return f"N={s[0]}, R={s[1]}".replace("-1", "?")


def hf_median(cases: list[dict[str, Any]]) -> float | None:
    """The reference time of a panel: the median of the cases' ``t_hf_median_s`` (``None``
    when no case has one)."""
    t = [_num(c.get("t_hf_median_s")) for c in cases if _pos(c.get("t_hf_median_s"))]
    return float(np.median(t)) if t else None


def _hf_line(ax, t_hf: float, vertical: bool, x_online: np.ndarray) -> int:
    """The HF solve time as a line (vertical: on the time axis x; else horizontal, on y),
    the region slower than it shaded; the number of cases slower than it."""
    draw, span, lim, setlim = ((ax.axvline, ax.axvspan, ax.get_xlim, ax.set_xlim) if vertical
                               else (ax.axhline, ax.axhspan, ax.get_ylim, ax.set_ylim))
    lo, hi = lim()
    hi = max(hi, t_hf * 2.0)
    draw(t_hf, color=_HF_COLOUR, linewidth=1.4, zorder=1.5, label=_HF_LABEL)
    span(t_hf, hi, color=_HF_COLOUR, alpha=0.08, linewidth=0, zorder=0)
    setlim(min(lo, t_hf / 2.0), hi)
    return int(np.sum(x_online > t_hf))


def _front_labels(ax, front: list[dict[str, Any]], m: str) -> None:
    """N, R beside each Pareto point; a label equal to the last one written within a
    factor 1.5 in time and 1.1 in error (coinciding points) is written once."""
    done: list[tuple[str, float, float]] = []
    for c in sorted(front, key=lambda c: (_num(c["t_online_median_s"]), _num(c[m]))):
        text, x, y = _size_text(_nr(c)), _num(c["t_online_median_s"]), _num(c[m])
        if any(t == text and max(x / x0, x0 / x) < 1.5 and max(y / y0, y0 / y) < 1.1
               for t, x0, y0 in done):
            continue
        done.append((text, x, y))
        ax.annotate(text, (x, y), xytext=(8, 3), textcoords="offset points", fontsize=6.5,
                    color="0.2", zorder=6)


def _pareto_panel(ax, ctx: _Ctx, mine: list[dict[str, Any]], m: str,
                  marks: dict[tuple[int, int], float]) -> int:
    """One scene and error: every case (marker size: its N, R), the Pareto front circled,
    joined and labelled with N, R, and the HF solve time; the cases slower than HF."""
    x = np.array([_num(c["t_online_median_s"]) for c in mine])
    y = np.array([_num(c[m]) for c in mine])
    for c, xi, yi in zip(mine, x, y, strict=True):  # large markers first, small on top
        st = ctx.combos.style(c)
        ax.plot([xi], [yi], linestyle="none", marker=st["marker"], color=st["color"],
                markerfacecolor=st["markerfacecolor"], markeredgewidth=st["markeredgewidth"],
                markersize=marks[_nr(c)], alpha=0.9, zorder=st["zorder"] + 0.4 / marks[_nr(c)])
    front = pareto_front(x, y)
    o = np.argsort(x[front])
    fx, fy = x[front][o], y[front][o]
    ax.step(np.r_[fx, fx[-1] * 1.5], np.r_[fy, fy[-1]], where="post", color="0.3",
            linestyle="--", linewidth=1, zorder=2)
    ax.plot(fx, fy, linestyle="none", marker="o", markersize=_MS_MAX + 4,
            markerfacecolor="none", markeredgecolor="0.3", zorder=2)
    _front_labels(ax, [mine[i] for i in np.flatnonzero(front)], m)
    _log_axes(ax)
    t_hf = hf_median(mine)
    return 0 if t_hf is None else _hf_line(ax, t_hf, True, x)


def _pareto_legend(fig, ctx: _Ctx, pts: list[dict[str, Any]],
                   marks: dict[tuple[int, int], float], hf: bool) -> None:
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles = _combo_handles(ctx, pts, line=False)
    handles += [Line2D([], [], linestyle="none", marker="o", color="0.45", markersize=ms,
                       label=f"size {_size_text(s)}") for s, ms in marks.items()]
    handles.append(Line2D([], [], color="0.3", linestyle="--", marker="o", markersize=11,
                          markerfacecolor="none", label="Pareto front\n(non-dominated;\n"
                                                        "labelled N, R)"))
    if hf:
        handles += [Line2D([], [], color=_HF_COLOUR, linewidth=1.4, label=_HF_LABEL),
                    Patch(color=_HF_COLOUR, alpha=0.15, label=_SLOWER_LABEL)]
    fig.legend(handles=handles, loc="outside right upper", fontsize=8,
               title=ctx.combos.title, title_fontsize=8)


def _fig_pareto(ctx: _Ctx):
    metrics = ("err_u_max", "err_lam_max")
    pts = [c for c in ctx.cases if _pos(c.get("t_online_median_s"))
           and any(_pos(c.get(m)) for m in metrics)]
    if not pts:
        raise _Skip("no ok case with a positive online time and an error")
    marks = _size_marks(pts)
    fig, axes = _figure(2, len(ctx.scenes))
    slower: dict[str, int] = {}
    for j, sc in enumerate(ctx.scenes):
        for i, m in enumerate(metrics):
            ax = axes[i, j]
            mine = [c for c in pts if str(c.get("scene")) == sc and _pos(c.get(m))]
            if not mine:
                _empty(ax, f"{sc}: no ok case with {m}")
                continue
            slow = _pareto_panel(ax, ctx, mine, m, marks)
            slower[sc] = max(slow, slower.get(sc, 0))
            ax.set_title(f"{sc}: " + ("solution u" if i == 0 else "multiplier lam")
                         + (f"\n({slow} case(s) slower than the HF solve: shaded)"
                            if slow else ""), fontsize=10)
            ax.set_xlabel(_axis_label("t_online_median_s"), fontsize=8)
            ax.set_ylabel(_axis_label(m), fontsize=8)
    _pareto_legend(fig, ctx, pts, marks, hf=hf_median(pts) is not None)
    fig.suptitle("Error against online time, ok cases", fontsize=11)
    caption = ("Each point is one ok case (a combination at one size N, R; repetitions "
               "combined: error max, time median); the marker size grows with its sizes "
               "N, R as built. Top row: "
               f"err_u_max = {_COL['err_u_max'].doc}; bottom row: err_lam_max = "
               f"{_COL['err_lam_max'].doc}; x: t_online_median_s = "
               f"{_COL['t_online_median_s'].doc} (s). Circled and joined by the dashed "
               "staircase: the Pareto front of the scene (no other case is both faster "
               "and more accurate), labelled with N, R. Red line: the HF solve time "
               "(median over the panel's cases of t_hf_median_s, "
               f"{_COL['t_hf_median_s'].doc}; speed-up 1); shaded: slower than the HF "
               "solve.")
    if any(slower.values()):
        caption += " Slower than the HF solve: " + ", ".join(
            f"{sc}: {k} case(s)" for sc, k in slower.items() if k) + "."
    return fig, caption


# ------------------------------------------------------------ offline against online
_EST_TEXT = "t_offline_s - t_snapshots_s + n_train x t_hf_median_s"
_OFFLINE_X = ("offline wall time with the HF snapshot time (s), median over repetitions\n"
              "[t_offline_hf_s: training snapshots at their HF solve time + primal, dual,\n"
              "stabiliser and hyper-reduction steps]")
_OFFLINE_Y = ("online solve time (s), median over validation mu x repeats\n"
              "[t_online_median_s]")


def offline_hf(c: dict[str, Any]) -> tuple[float | None, bool]:
    """A case's offline cost with the real HF snapshot time, and whether it is measured.

    ``t_offline_hf_s`` when the row has it (``rbbench reduce``'s result: the training
    snapshots at their stored HF solve time, also when read from the cache); else, for rows
    written before that column, the estimate ``t_offline_s - t_snapshots_s + n_train *
    t_hf_median_s`` (``False``); ``(None, False)`` when neither can be formed.
    """
    if _pos(c.get("t_offline_hf_s")):
        return _num(c["t_offline_hf_s"]), True
    parts = [_num(c.get(k)) for k in ("t_offline_s", "t_snapshots_s", "n_train",
                                      "t_hf_median_s")]
    if all(np.isfinite(parts)):
        est = parts[0] - parts[1] + parts[2] * parts[3]
        return (est, False) if est > 0 else (None, False)
    return None, False


def _error_norm(cases: list[dict[str, Any]]) -> Any:
    """Log colour scale over the cases' err_u_max (a decade when they are all equal)."""
    from matplotlib.colors import LogNorm

    errs = [_num(c.get("err_u_max")) for c in cases if _pos(c.get("err_u_max"))]
    if not errs:
        return LogNorm(1e-3, 1e-1)
    lo, hi = min(errs), max(errs)
    return LogNorm(lo, hi) if hi > lo else LogNorm(lo / 3.0, lo * 3.0)


def _error_bar(ax, norm: Any, cmap: Any) -> None:
    """The err_u_max colour bar under a panel: ticks at 1 and 3 per decade, or evenly
    spaced within a decade (the default minor labels collide)."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.ticker import (
        LogFormatterSciNotation,
        LogLocator,
        MaxNLocator,
        NullFormatter,
        StrMethodFormatter,
    )

    bar = ax.figure.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, location="bottom",
                             label=_axis_label("err_u_max").replace("\n", " "), aspect=30,
                             pad=0.02)
    wide = norm.vmax / norm.vmin > 10
    bar.ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 3.0)) if wide else MaxNLocator(5))
    bar.ax.xaxis.set_major_formatter(LogFormatterSciNotation(labelOnlyBase=False) if wide
                                     else StrMethodFormatter("{x:.2g}"))
    bar.ax.xaxis.set_minor_formatter(NullFormatter())


def _offline_panel(ax, ctx: _Ctx, mine: list[dict[str, Any]],
                   marks: dict[tuple[int, int], float]) -> bool:
    """One scene: a marker per case at (offline, online), filled with the colour of its
    err_u_max, outlined in its dual's colour, shaped by the rest of its combination (as in
    the other figures), a black dot inside when the offline time is estimated; its colour
    bar below. True if one is estimated."""
    from matplotlib import colormaps

    cmap, norm = colormaps["viridis"], _error_norm(mine)
    estimated = False
    for c in mine:
        x, measured = offline_hf(c)
        y, err, st = _num(c["t_online_median_s"]), c.get("err_u_max"), ctx.combos.style(c)
        z = 3 + 0.4 / marks[_nr(c)]
        ax.plot([x], [y], linestyle="none", marker=st["marker"], markersize=marks[_nr(c)],
                markerfacecolor=cmap(norm(_num(err))) if _pos(err) else "0.6",
                markeredgecolor=st["color"], markeredgewidth=1.5, zorder=z)
        if not measured:
            estimated = True
            ax.plot([x], [y], linestyle="none", marker=".", color="black", markersize=3,
                    zorder=z + 0.01)
    _log_axes(ax)
    _error_bar(ax, norm, cmap)
    t_hf = hf_median(mine)
    if t_hf is not None:
        _hf_line(ax, t_hf, False, np.array([_num(c["t_online_median_s"]) for c in mine]))
    _short_log_ticks(ax)
    return estimated


def _offline_legend(fig, ctx: _Ctx, pts: list[dict[str, Any]], marks: dict,
                    estimated: bool) -> None:
    from matplotlib.lines import Line2D

    handles = _combo_handles(ctx, pts, line=False)
    for h in handles:  # the outline is the dual's colour, the fill the error's
        h.set_markerfacecolor("0.85")
        h.set_markeredgewidth(1.5)
    grey = {"linestyle": "none", "color": "0.45", "markeredgecolor": "0.15"}
    handles += [Line2D([], [], marker="o", markersize=ms, label=f"size {_size_text(s)}",
                       **grey) for s, ms in marks.items()]
    if hf_median(pts) is not None:
        handles.append(Line2D([], [], color=_HF_COLOUR, linewidth=1.4, label=_HF_LABEL))
    if estimated:
        handles.append(Line2D([], [], linestyle="none", marker=".", color="black",
                              markersize=5, label="offline time estimated\n"
                                                  f"({_EST_TEXT})"))
    fig.legend(handles=handles, loc="outside right upper", fontsize=7,
               title=f"{ctx.combos.title}\n(outline: dual, fill: error)", title_fontsize=8)


def _fig_offline(ctx: _Ctx):
    """Offline cost against online time, coloured by err_u_max (log colour scale)."""
    pts = [c for c in ctx.cases if _pos(c.get("t_online_median_s"))
           and offline_hf(c)[0] is not None]
    if not pts:
        raise _Skip("no ok case with an online time and an offline time (t_offline_hf_s, "
                    "or t_offline_s, t_snapshots_s, n_train and t_hf_median_s)")
    # larger than in the Pareto figure: the fill (the error) must show inside the outline
    marks = {s: ms + 3.0 for s, ms in _size_marks(pts).items()}
    scenes = [sc for sc in ctx.scenes if any(str(c.get("scene")) == sc for c in pts)]
    fig, axes = _figure(1, len(scenes), h=4.2)
    estimated = False
    for ax, sc in zip(axes[0], scenes, strict=True):
        estimated |= _offline_panel(ax, ctx, [c for c in pts if str(c.get("scene")) == sc],
                                    marks)
        ax.set_title(sc, fontsize=10)
        ax.set_xlabel(_OFFLINE_X, fontsize=7)
        ax.set_ylabel(_OFFLINE_Y, fontsize=7)
    _offline_legend(fig, ctx, pts, marks, estimated)
    fig.suptitle("Offline cost against online time, coloured by the error (ok cases)",
                 fontsize=11, x=0.02, ha="left")  # clear of the (tall) legend
    return fig, _offline_caption(pts, estimated)


def _offline_caption(pts: list[dict[str, Any]], estimated: bool) -> str:
    cached = sum(1 for c in pts if (_num(c.get("n_snapshots_cached")) or 0) > 0)
    text = ("Each marker is one ok case (repetitions combined: times median, error max); "
            "outline colour: its dual compressor, marker shape: the rest of its "
            "combination, marker size: its N, R, fill colour: err_u_max (log colour "
            f"scale of the scene, bar below the panel), {_COL['err_u_max'].doc}. x: "
            f"t_offline_hf_s, {_COL['t_offline_hf_s'].doc}"
            f"; y: t_online_median_s, {_COL['t_online_median_s'].doc}. Red line: one HF "
            "solve (median over the scene's cases of t_hf_median_s); shaded: online slower "
            "than the HF solve. A case pays off after about x / (t_HF - y) online solves.")
    if cached:
        text += (f" {cached} case(s) read snapshots from the cache (n_snapshots_cached > 0): "
                 "their t_offline_s counts the cache reads only, x counts the HF solves.")
    if estimated:
        text += (" Black dot: rows without t_offline_hf_s (written before that column), x "
                 f"estimated as {_EST_TEXT}.")
    return text

"""Matplotlib plumbing of the report figures (through :class:`matplotlib.figure.Figure`
only: no pyplot, no backend selected, no global figure state)."""

from __future__ import annotations

from typing import Any

from rbbench.bench.report.analysis import _Ctx
from rbbench.bench.report.common import _LINESTYLES, _MARKERS

_PANEL_W, _PANEL_H = 4.4, 3.3


class _Skip(Exception):
    """A figure has nothing to show (the message says why)."""


class _NotApplicable(_Skip):
    """A figure does not apply to the run (e.g. friction figures of a frictionless run):
    neither drawn nor listed as skipped."""


def _figure(nrows: int, ncols: int, w: float = _PANEL_W, h: float = _PANEL_H):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(max(w * ncols + 2.6, 9.0), h * nrows + 0.6), layout="constrained")
    axes = fig.subplots(nrows, ncols, squeeze=False)
    return fig, axes


def _empty(ax, text: str) -> None:
    ax.text(0.5, 0.5, text, ha="center", va="center", transform=ax.transAxes,
            fontsize=9, color="0.4", wrap=True)
    ax.set_xticks([])
    ax.set_yticks([])


def _combo_handles(ctx: _Ctx, recs: list[dict[str, Any]], line: bool) -> list:
    from matplotlib.lines import Line2D

    seen: dict[str, Any] = {}
    for r in sorted(recs, key=ctx.combos.label):
        lab = ctx.combos.label(r)
        if lab not in seen:
            st = ctx.combos.style(r)
            seen[lab] = Line2D([], [], color=st["color"], marker=st["marker"],
                               markerfacecolor=st["markerfacecolor"],
                               markeredgewidth=st["markeredgewidth"],
                               linestyle=st["linestyle"] if line else "none", label=lab)
    return list(seen.values())


def _dodge(ctx: _Ctx, dual: str, span: float) -> float:
    """Horizontal offset of a dual compressor's markers on an integer size axis (2.5 % of
    the axis span per dual, centred), so equal values of two duals sit side by side."""
    n = len(ctx.combos.duals)
    return (ctx.combos.dual_rank(dual) - (n - 1) / 2) * 0.025 * (span if span > 0 else 4.0)


def _dual_line(ctx: _Ctx, dual: str, rank: int | None = None) -> dict[str, Any]:
    """Line style of a dual compressor's curve where the curves of several duals can
    coincide: its colour, a line style and a marker of its own, the first dual the
    thickest and lowest, each next one thinner, smaller and above it (``rank``: another
    rank than the dual's among the run's, for several curves of one dual)."""
    k = ctx.combos.dual_rank(dual) if rank is None else rank
    colour = ctx.combos.dual_colour.get(dual, "k")
    return {"color": colour, "linestyle": _LINESTYLES[k % len(_LINESTYLES)],
            "linewidth": max(0.9, 3.2 - 0.9 * k), "marker": _MARKERS[k % len(_MARKERS)],
            "markersize": max(3.0, 7.0 - 1.5 * k),
            "markerfacecolor": "none" if k % 2 else colour, "zorder": 2.0 + 0.1 * k}


def _log_axes(ax) -> None:
    """Log scale on both axes, major grid, no minor tick labels (they collide)."""
    from matplotlib.ticker import NullFormatter

    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.grid(True, which="major", alpha=0.3)


def _short_log_ticks(ax) -> None:
    """On a log axis spanning less than a decade (one major tick or none), evenly spaced
    ticks labelled as plain numbers instead; call once the limits are final."""
    from matplotlib.ticker import MaxNLocator, NullFormatter, StrMethodFormatter

    for axis, (lo, hi) in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
        if axis.get_scale() == "log" and lo > 0 and hi / lo < 10:
            axis.set_major_locator(MaxNLocator(5))
            axis.set_major_formatter(StrMethodFormatter("{x:.3g}"))
            axis.set_minor_formatter(NullFormatter())

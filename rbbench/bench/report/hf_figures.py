"""The HF solves of a run (mode hf rows) in a report: time against the floor, and the
Hertz errors, one bar / marker per case; 2D and 3D rows alike (the Hertz errors are those
of the half-width in 2D, of the contact radius in 3D)."""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from rbbench.bench.report.analysis import _Ctx
from rbbench.bench.report.common import _COL, _num
from rbbench.bench.report.plotting import _NotApplicable, _Skip

_BACKEND_COLOUR = ("tab:blue", "tab:orange", "tab:green", "tab:purple")
#: the Hertz errors drawn: column, marker, label
_HERTZ = (("hertz_a_rel_error", "o", "a (quantised extent)"),
          ("hertz_a_gap_rel_error", "s", "a from the pointwise gap"),
          ("hertz_p0_rel_error", "^", "p0 (peak pressure)"))


def _options(params: Any) -> str:
    """The solver options of a row's ``params`` JSON (without ``hf_repeats``)."""
    try:
        p = json.loads(params) if isinstance(params, str) else {}
    except ValueError:
        return ""
    return " ".join(f"{k}={v}" for k, v in sorted(p.items()) if k != "hf_repeats")


def _label(r: dict[str, Any]) -> str:
    opts = _options(r.get("params"))
    return f"{r.get('scene')} {r.get('solver')}" + (f"\n{opts}" if opts else "")


def _fig_hf(ctx: _Ctx):
    """HF time (median over the repeats) and its floor per case, and the signed Hertz
    errors at each case's own force."""
    hf = [r for r in ctx.records if r.get("mode") == "hf"]
    if not hf:
        raise _NotApplicable("no HF rows")
    ok = [r for r in hf if r.get("status") == "ok" and _num(r.get("t_hf_median_s")) > 0]
    if not ok:
        raise _Skip("no ok HF row with a time")
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    backends = sorted({str(r.get("backend")) for r in ok})
    colour = {b: _BACKEND_COLOUR[i % len(_BACKEND_COLOUR)] for i, b in enumerate(backends)}
    ok.sort(key=lambda r: (str(r.get("scene")), str(r.get("solver")),
                           _options(r.get("params")), str(r.get("backend"))))
    y_of = {lab: i for i, lab in enumerate(dict.fromkeys(_label(r) for r in ok))}
    width = 0.8 / len(backends)
    hertz = any(np.isfinite(_num(r.get(c))) for r in ok for c, _, _ in _HERTZ)
    fig = Figure(figsize=(12.0 if hertz else 8.0, 1.4 + 0.42 * len(y_of)),
                 layout="constrained")
    axes = fig.subplots(1, 2 if hertz else 1, squeeze=False, sharey=True)[0]
    ax = axes[0]
    for r in ok:
        k = backends.index(str(r.get("backend")))
        y = y_of[_label(r)] - 0.4 + width * (k + 0.5)
        ax.barh(y, _num(r["t_hf_median_s"]), height=width * 0.9,
                color=colour[str(r.get("backend"))])
        if _num(r.get("floor_s")) > 0:
            ax.plot(_num(r["floor_s"]), y, marker="|", markersize=9, color="black")
    ax.set_yticks(list(y_of.values()), list(y_of), fontsize=7)
    ax.invert_yaxis()
    ax.set_xscale("log")
    from matplotlib.ticker import NullFormatter

    ax.xaxis.set_minor_formatter(NullFormatter())  # decade labels only: they do not overlap
    ax.set_xlabel("HF solve time, median over repeats [s]", fontsize=9)
    ax.set_title("HF time (bars) and its floor (|)", fontsize=10)
    if hertz:
        ax2 = axes[1]
        for r in ok:
            k = backends.index(str(r.get("backend")))
            y = y_of[_label(r)] - 0.4 + width * (k + 0.5)
            for col, mk, _ in _HERTZ:
                v = _num(r.get(col))
                if np.isfinite(v):
                    ax2.plot(100 * v, y, marker=mk, linestyle="none",
                             color=colour[str(r.get("backend"))])
        ax2.axvline(0.0, color="0.5", linewidth=0.8)
        ax2.set_xlabel("signed error against Hertz at the row's own force [%]", fontsize=9)
        ax2.set_title("Hertz errors (2D: half-width; 3D: contact radius)", fontsize=10)
    from matplotlib.lines import Line2D

    handles = [Patch(color=colour[b], label=b) for b in backends]
    handles.append(Line2D([], [], marker="|", linestyle="none", color="black",
                          markersize=9, label="floor_s"))
    if hertz:
        handles += [Line2D([], [], marker=mk, linestyle="none", color="0.3", label=lab)
                    for _, mk, lab in _HERTZ]
    fig.legend(handles=handles, loc="outside right upper", fontsize=8, title="backend",
               title_fontsize=8)
    fig.suptitle("HF solves (mode hf, ok rows)", fontsize=11)
    caption = (f"t_hf_median_s: {_COL['t_hf_median_s'].doc}; floor_s: {_COL['floor_s'].doc}. "
               f"hertz_a_rel_error: {_COL['hertz_a_rel_error'].doc}; hertz_a_gap_rel_error, "
               "hertz_p0_rel_error likewise (of the gap extent and of max_pressure). One row "
               "per scene x solver x solver options, one bar per backend.")
    return fig, caption

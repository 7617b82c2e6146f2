"""The figures of a report drawn from the per-case details (``cases/*.json``): inf-sup
constants per validation parameter, and the offline histories."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rbbench.bench.report.analysis import _Ctx, _size_req
from rbbench.bench.report.common import _COL, _LINESTYLES, _num
from rbbench.bench.report.plotting import (
    _PANEL_H,
    _PANEL_W,
    _dual_line,
    _empty,
    _figure,
    _Skip,
)

_KIND_TEXT = {"span-lower-bound": "span lower bound", "cone-exact": "cone, exact",
              "cone-upper": "cone, upper estimate"}
_KIND_MARKER = {"cone-exact": ("o", True), "cone-upper": ("o", False),
                "span-lower-bound": ("^", True)}
_BETA_COLOUR = {"hf": "black", "dec": "tab:blue", "on": "tab:green", "off": "tab:red"}
_BETA_TEXT = {"hf": "whole V vs HF cone", "dec": "V_N", "on": "V_N + S_R(mu), online",
              "off": "V_N + S_PGA, offline"}
_BETA_DOC = _COL["beta_dec_min"].doc.split(";")[0]
_INFSUP_CAPTION = (
    "Per scene and dual compressor, at the largest (N, R) asked, the inf-sup "
    "constants of every ok case of the first repetition, from the case details: "
    "beta_hf (whole V against the HF cone), beta_dec (V_N), beta_on (V_N + online "
    "supremizers), beta_off (V_N + S_PGA). A curve common to all the cases of a "
    "panel is drawn once, otherwise the cases (stabilizer+hyper) are named; "
    "constants whose values agree to 3 significant digits at every mu are drawn "
    "once, joined by '=' (equal) or '≈' (equal to 3 digits). "
    "x: the validation parameter when it is scalar, else its index. "
    "y: beta / c_HF(mu), the continuity constant of the same form at that mu "
    "(dimensionless, Benaceur et al.'s ratio), for every case that recorded c_HF; raw "
    "beta (X the V inner product) otherwise, as the axis label says. "
    "Markers give the kind of each value as stored: filled circle = exact cone "
    "value, open circle = cone upper estimate (best local minimum), triangle = "
    "span lower bound; x on the axis = the exact LP test found beta = 0. "
    f"Column beta_*_min: {_BETA_DOC}.")
_HIST_FLOOR = 1e-12
_HIST_TITLE = {"e_proj": "dual compressor, e_proj", "sigma_max": "PGA, sigma_max",
               "eim_error": "EIM, eim_error"}
#: (history, x label, y label, first x) of the three columns of the histories figure
_HISTORIES = (("e_proj", "number of cone generators r", "e_proj(r), rel. projection error", 1),
              ("sigma_max", "PGA iteration (vectors added so far)",
               "sigma_max over the training set", 0),
              ("eim_error", "EIM magic rows M", "EIM training error of B(mu) Z", 1))


def _beta_series(det: dict) -> dict[str, list[dict[str, Any]]]:
    beta = (det.get("per_mu") or {}).get("beta") or {}
    return {k: v for k, v in beta.items() if isinstance(v, list) and v}


def _kind_text(kinds: list[str | None]) -> str:
    ks = [k for k in kinds if k]
    if not ks:
        return "kind not given"
    uniq = sorted(set(ks))
    if len(uniq) == 1:
        return _KIND_TEXT.get(uniq[0], uniq[0])
    return ", ".join(f"{_KIND_TEXT.get(k, k)} at {ks.count(k)}/{len(ks)} mu" for k in uniq)


def _beta_rank(name: str) -> int:
    return list(_BETA_COLOUR).index(name) if name in _BETA_COLOUR else len(_BETA_COLOUR)


def _ok_details(ctx: _Ctx) -> list[tuple[dict[str, Any], dict]]:
    """``(row, details)`` of the ok rows that have case details."""
    out = []
    for r in ctx.records:
        if r.get("status") == "ok":
            det = ctx.run.details.get((str(r.get("case_id")), int(r.get("repetition") or 0)))
            if det:
                out.append((r, det))
    return out


def _panel_cases(group: list[tuple[dict, dict]]) -> tuple[tuple[int, int], list]:
    """The largest size asked of a panel, and its cases of the first repetition."""
    size = max(_size_req(r) for r, _ in group)
    group = [(r, d) for r, d in group if _size_req(r) == size]
    rep0 = min(int(r.get("repetition") or 0) for r, _ in group)
    return size, [(r, d) for r, d in group if int(r.get("repetition") or 0) == rep0]


def _merged_curves(ctx: _Ctx, group: list[tuple[dict, dict]]) -> list[list[dict[str, Any]]]:
    """The distinct beta curves of a panel (with the cases that share each), those that
    agree to 3 significant digits at every mu (and in kind) in one list."""
    curves: dict[tuple, dict[str, Any]] = {}
    for r, det in group:
        mus = det.get("valid_mus")
        for name, rows in _beta_series(det).items():
            vals = tuple(float(f"{_num(e.get('value')):.12g}") for e in rows)
            cur = curves.setdefault((name, vals), {"name": name, "rows": rows, "mus": mus,
                                                   "vals": vals, "cases": set()})
            cur["cases"].add(ctx.combos.label(r, without="dual"))
    # constants that agree to 3 significant digits at every mu (often beta_on and
    # beta_off) are drawn once: "=" when equal, "≈" when equal to 3 digits
    merged: dict[tuple, list[dict[str, Any]]] = {}
    for cur in sorted(curves.values(), key=lambda c: (_beta_rank(c["name"]),
                                                      sorted(c["cases"]))):
        kinds = tuple(str(e.get("kind")) for e in cur["rows"])
        zeros = tuple(bool(e.get("is_zero")) for e in cur["rows"])
        close = tuple(f"{v:.3g}" for v in cur["vals"])
        merged.setdefault((close, kinds, zeros), []).append(cur)
    return list(merged.values())


def _curve_x(ax, first: dict[str, Any]) -> tuple[np.ndarray, str]:
    """x of a curve: the validation mu when scalar, else the index of the parameter."""
    rows = first["rows"]
    mu = np.asarray(first["mus"], dtype=float) if first["mus"] is not None else None
    if mu is not None and mu.ndim == 2 and mu.shape[1] == 1 and len(mu) == len(rows):
        return mu[:, 0], "validation mu"
    if mu is not None and mu.ndim == 1 and len(mu) == len(rows):
        return mu, "validation mu"
    ax.xaxis.get_major_locator().set_params(integer=True)
    return np.arange(len(rows), dtype=float), "validation parameter (index)"


#: the widest line of an inf-sup legend entry (characters): longer lists of cases (e.g. the
#: friction models' combinations) are wrapped, so the legend fits under its panel
_LABEL_WIDTH = 80


def _curve_label(parts: list[dict[str, Any]], case_labels: set[str], kinds: list) -> str:
    import textwrap

    joiner = "\n  = " if len({c["vals"] for c in parts}) == 1 else "\n  ≈ "
    text = joiner.join(
        f"beta_{c['name']} ({_BETA_TEXT.get(c['name'], c['name'])})"
        + ("" if c["cases"] == case_labels else f" [{', '.join(sorted(c['cases']))}]")
        for c in parts) + f": {_kind_text(kinds)}"
    return "\n".join(textwrap.fill(line, _LABEL_WIDTH, subsequent_indent="    ",
                                    break_on_hyphens=False) for line in text.split("\n"))


def _draw_beta(ax, parts: list[dict[str, Any]], case_labels: set[str],
               used_styles: dict[str, int], seen: dict[str, Any]) -> str:
    """One (merged) beta curve: line, kind markers, x on the axis where beta = 0.

    Updates ``seen`` (``plotted``, ``zero``, ``kinds``) and ``used_styles``; returns the
    x label.
    """
    first = parts[0]
    rows, name = first["rows"], first["name"]
    x, xlab = _curve_x(ax, first)
    o = np.argsort(x, kind="stable")
    # beta / c_HF(mu) (dimensionless) when the case recorded it at every mu, else raw
    rel = all(np.isfinite(_num(e.get("value_rel"))) for e in rows)
    seen["raw"] = seen.get("raw", False) or not rel
    v = np.array([_num(e.get("value_rel" if rel else "value")) for e in rows])[o]
    kinds = [e.get("kind") for e in rows]
    kk = np.array([str(k) for k in kinds], dtype=object)[o]
    zero = np.array([bool(e.get("is_zero")) for e in rows])[o]
    xs = x[o]
    colour = _BETA_COLOUR.get(name, "tab:gray")
    ls = _LINESTYLES[used_styles.get(colour, 0) % len(_LINESTYLES)]
    used_styles[colour] = used_styles.get(colour, 0) + 1
    label = _curve_label(parts, case_labels, kinds)
    good = np.isfinite(v) & (v > 0)
    if good.any():
        seen["plotted"] = True
        ax.plot(xs[good], v[good], color=colour, linestyle=ls, linewidth=1.2, label=label)
        for kind in sorted(set(kk[good])):
            sel = good & (kk == kind)
            mk, filled = _KIND_MARKER.get(kind, ("d", True))
            seen["kinds"].add(kind)
            ax.plot(xs[sel], v[sel], linestyle="none", marker=mk, markersize=5,
                    color=colour, markerfacecolor=colour if filled else "white")
    if zero.any():
        seen["zero"] = True
        ax.plot(xs[zero], np.zeros(int(zero.sum())), linestyle="none", marker="x",
                color=colour, markersize=8, clip_on=False, transform=ax.get_xaxis_transform())
    if not good.any():
        ax.plot([], [], color=colour, linestyle=ls, label=label + " (no value > 0)")
    return xlab


def _infsup_panel(ax, ctx: _Ctx, sc: str, dual: str, group: list[tuple[dict, dict]],
                  seen: dict[str, Any]) -> None:
    """One scene and dual compressor: the beta curves at the largest size asked."""
    size, group = _panel_cases(group)
    case_labels = {ctx.combos.label(r, without="dual") for r, _ in group}
    seen["plotted"], seen["raw"] = False, False
    used_styles: dict[str, int] = {}
    for parts in _merged_curves(ctx, group):
        xlab = _draw_beta(ax, parts, case_labels, used_styles, seen)
    if seen["plotted"]:
        ax.set_yscale("log")
    else:
        ax.text(0.5, 0.5, "no positive beta value", transform=ax.transAxes, ha="center")
    ax.grid(True, which="major", alpha=0.3)
    ax.set_title(f"{sc} / dual {dual}: N={size[0]}, R={size[1]} (asked)", fontsize=9)
    ax.set_xlabel(xlab, fontsize=8)
    ax.set_ylabel("beta / c_HF(mu)" if not seen.get("raw") else
                  "beta (raw: X = V inner product) or beta / c_HF(mu)", fontsize=8)
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.2), fontsize=7, frameon=False)


def _kind_legend(fig, kinds_seen: set[str], any_zero: bool) -> None:
    from matplotlib.lines import Line2D

    handles = []
    for kind in sorted(kinds_seen):
        mk, filled = _KIND_MARKER.get(kind, ("d", True))
        handles.append(Line2D([], [], linestyle="none", marker=mk, color="0.2",
                              markerfacecolor="0.2" if filled else "white",
                              label=_KIND_TEXT.get(kind, kind)))
    if any_zero:
        handles.append(Line2D([], [], linestyle="none", marker="x", color="0.2",
                              label="beta = 0 (exact LP test)"))
    if handles:
        fig.legend(handles=handles, loc="outside lower center", ncols=len(handles),
                   fontsize=8, title="marker: kind of the value at that mu", title_fontsize=8)


def _fig_infsup(ctx: _Ctx):
    have = [(r, det) for r, det in _ok_details(ctx) if _beta_series(det)]
    if not have:
        raise _Skip("no ok case with per-mu inf-sup constants (details.per_mu.beta)")
    panels: dict[tuple[str, str], list[tuple[dict, dict]]] = {}
    for r, det in have:
        panels.setdefault((str(r.get("scene")), ctx.combos._part(r, "dual")), []).append(
            (r, det))
    keys = sorted(panels)
    ncols = min(3, len(keys))
    nrows = math.ceil(len(keys) / ncols)
    fig, axes = _figure(nrows, ncols, w=_PANEL_W + 0.8, h=_PANEL_H + 1.4)
    seen: dict[str, Any] = {"kinds": set(), "zero": False}
    for n, (sc, dual) in enumerate(keys):
        _infsup_panel(axes[n // ncols, n % ncols], ctx, sc, dual, panels[(sc, dual)], seen)
    for n in range(len(keys), nrows * ncols):
        axes[n // ncols, n % ncols].set_visible(False)
    _kind_legend(fig, seen["kinds"], seen["zero"])
    fig.suptitle("Inf-sup constants per validation parameter (largest size per dual)",
                 fontsize=11)
    return fig, _INFSUP_CAPTION


#: a history the wedge friction model records under another name: its cone of
#: ``F lam_n + lam_t`` (``e_proj_plus``) stands for the dual compressor's ``e_proj``
_HISTORY_ALIASES = {"e_proj": ("e_proj", "e_proj_plus")}


def _curve_key(r: dict[str, Any]) -> str:
    """The curve of a case in the histories figure: its dual compressor, and on friction rows
    its dual model too (``mcpg+collocation``, ``mcpg+wedge``: both models side by side)."""
    model = r.get("friction_dual")
    return str(r.get("dual")) + (f"+{model}" if model else "")


def _history(det: dict, name: str) -> list | None:
    """History ``name`` of a case (or its alias, :data:`_HISTORY_ALIASES`); None if absent."""
    hist = det.get("histories") or {}
    for key in _HISTORY_ALIASES.get(name, (name,)):
        h = hist.get(key)
        if isinstance(h, list) and h:
            return h
    return None


def _pick_history(cases: list[tuple[dict, dict]], name: str):
    """Per curve (:func:`_curve_key`), the case with the largest (N, R) that has history
    ``name``."""
    best: dict[str, tuple] = {}
    for r, det in cases:
        h = _history(det, name)
        if h is None:
            continue
        key = _curve_key(r)
        rank = (_size_req(r), len(h))
        if key not in best or rank > best[key][0]:
            best[key] = (rank, r, det)
    return {d: (r, det) for d, (_, r, det) in best.items()}


def _curve_line(ctx: _Ctx, key: str, keys: list[str]) -> dict[str, Any]:
    """The line of a histories curve: a dual compressor's own (:func:`_dual_line`); a friction
    model's the colour of its dual compressor and the line style, marker and width of its
    rank among the figure's curves (``keys``, sorted), so the two models stay apart."""
    if "+" not in key:
        return _dual_line(ctx, key)
    return _dual_line(ctx, key.split("+")[0], keys.index(key) if key in keys else 0)


def _draw_history(ax, ctx: _Ctx, picks: dict, name: str, start: int,
                  seen: dict[str, Any]) -> bool:
    """One scene and history, a curve per dual; True if a finite value was drawn.

    Updates ``seen`` (``duals``, ``delta``, ``floored``).
    """
    drew = False
    for dual in sorted(picks):
        r, det = picks[dual]
        h = np.array([_num(v) for v in _history(det, name)])
        x = np.arange(start, start + h.size)
        style = _curve_line(ctx, dual, seen["keys"])  # coinciding curves both visible
        colour = style["color"]
        seen["duals"].add(dual)
        # relative quantities: values at round-off level (or exactly 0) are drawn
        # on the floor, so they do not stretch the log axis over 15 decades
        tiny = np.isfinite(h) & (h < _HIST_FLOOR)
        good = np.isfinite(h)
        if good.any():
            drew = True
            hp = np.where(tiny, _HIST_FLOOR, h)
            ax.plot(x[good], hp[good], label=dual, markevery=max(1, int(good.sum()) // 16),
                    **style)
        if tiny.any():
            seen["floored"] = True
            ax.plot(x[tiny], np.full(int(tiny.sum()), _HIST_FLOOR), linestyle="none",
                    marker="v", color=colour, markersize=7, zorder=style["zorder"])
        if name == "sigma_max":
            d = _num(det["histories"].get("pga_delta"))
            if math.isfinite(d) and d > 0:
                ax.axhline(d, color=colour, linestyle=":", linewidth=1)
                seen["delta"] = True
    return drew


def _history_panel(ax, ctx: _Ctx, sc: str, picks: dict, spec: tuple,
                   seen: dict[str, Any]) -> None:
    name, xlab, ylab, start = spec
    if not picks:
        why = {"sigma_max": "no PGA case", "eim_error": "no EIM case"}.get(
            name, f"no {name} history")
        _empty(ax, f"{sc}: {why}")
        ax.set_title(f"{sc}: {_HIST_TITLE[name]}", fontsize=9)
        return
    if _draw_history(ax, ctx, picks, name, start, seen):
        ax.set_yscale("log")
    ax.xaxis.get_major_locator().set_params(integer=True)
    ax.grid(True, which="major", alpha=0.3)
    ax.set_title(f"{sc}: {_HIST_TITLE[name]}", fontsize=9)
    ax.set_xlabel(xlab, fontsize=8)
    ax.set_ylabel(ylab, fontsize=8)


def _history_legend(fig, ctx: _Ctx, seen: dict[str, Any]) -> None:
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], label=d, **_curve_line(ctx, d, seen["keys"]))
               for d in sorted(seen["duals"])]
    if seen["delta"]:
        handles.append(Line2D([], [], color="0.3", linestyle=":", label="PGA tolerance delta"))
    if seen["floored"]:
        handles.append(Line2D([], [], color="0.3", linestyle="none", marker="v",
                              label=f"< {_HIST_FLOOR:g} (round-off / 0),\n"
                                    f"drawn at {_HIST_FLOOR:g}"))
    fig.legend(handles=handles, loc="outside right upper", fontsize=8,
               title="dual compressor", title_fontsize=8)


def _fig_histories(ctx: _Ctx):
    ok = [(r, det) for r, det in _ok_details(ctx) if det.get("histories")]
    found = {name: {sc: _pick_history([p for p in ok if str(p[0].get("scene")) == sc], name)
                    for sc in ctx.scenes} for name, *_ in _HISTORIES}
    if not any(v for per in found.values() for v in per.values()):
        raise _Skip("no ok case with histories (e_proj, sigma_max, eim_error)")
    scenes = [sc for sc in ctx.scenes if any(found[n][sc] for n, *_ in _HISTORIES)]
    fig, axes = _figure(len(scenes), 3)
    keys = sorted({k for per in found.values() for picks in per.values() for k in picks})
    seen: dict[str, Any] = {"duals": set(), "delta": False, "floored": False, "keys": keys}
    for i, sc in enumerate(scenes):
        for j, spec in enumerate(_HISTORIES):
            _history_panel(axes[i, j], ctx, sc, found[spec[0]][sc], spec, seen)
    _history_legend(fig, ctx, seen)
    fig.suptitle("Offline histories (per dual: the ok case with the largest N, R)",
                 fontsize=11)
    caption = ("Per scene and dual compressor, from the ok case with the largest (N, R) "
               "that has the history. Left: e_proj(r), the relative max projection error of "
               "the multiplier snapshots on the cone after r generators. Middle: sigma_max, "
               "the PGA maximum over the training set before each addition (dotted: the "
               "tolerance delta). Right: the EIM training error of the contact rows after "
               f"each magic row (hyper eim). Values below {_HIST_FLOOR:g} (round-off, or 0) "
               f"are drawn at {_HIST_FLOOR:g} with a down-pointing triangle. Each dual has "
               "its own line style and marker, the first the thickest and the next ones "
               "thinner and on top, so equal histories of two duals both stay visible. "
               "Friction rows: one curve per dual compressor and friction dual model "
               "(e.g. mcpg+collocation, mcpg+wedge); the wedge model's e_proj is that of "
               "its F lam_n + lam_t cone (e_proj_plus), its EIM error that of Bn Z as the "
               "collocation model's.")
    return fig, caption

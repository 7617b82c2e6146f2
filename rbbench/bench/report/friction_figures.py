"""The reduced friction models in a report: the GCNS curves, lam_t of the HF against the
reduced solution, and the friction table of the summary.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slides "Greedy Collocation Node Selection (GCNS)"
(``e_GCNS(q)`` and ``e_GCNS^{n tau}(q)`` against ``q``) and "RB solutions" (``lam_t`` HF and
RB against ``x`` with the Coulomb bounds ``+- F lam_n`` at ``mu = 0.7, 1, 1.3``). The data are
the case details the runner keeps for a friction row (``gcns_history``, ``lam_t_profiles``,
:mod:`rbbench.bench.execution`); rows whose ``friction_dual`` is empty are not friction rows.
A figure without data raises :class:`~rbbench.bench.report.plotting._Skip` (the summary says
why).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from rbbench.bench.report.analysis import _Ctx
from rbbench.bench.report.common import _COL, _fmt, _header, _num, _param_dict, _varying_params
from rbbench.bench.report.detail_figures import _ok_details
from rbbench.bench.report.plotting import _figure, _NotApplicable, _Skip

__all__ = ["FIGURE_GROUPS", "friction_table", "profile_problem", "table_note"]

_FLOOR = 1e-12  # values at or below (0: constraint met exactly) drawn here on the log axis
#: (history key, panel title) of the GCNS figure
_GCNS_PANELS = (
    ("e_gcns", "e_GCNS(q) = max over training mu of\n||lam_t - lam_t,S||_W / ||lam_t||_W"),
    ("e_nt_rel", "e_GCNS^{n tau}(q) / max |lam_t| = max over training mu, HF nodes\n"
                 "of [|lam_t,S| - F lam_n,R]_+, relative"))
_PROFILE_KEYS = ("mu", "x", "lam_t_hf", "lam_t_rb", "bound_hf")


def _friction_details(ctx: _Ctx) -> list[tuple[dict[str, Any], dict]]:
    """``(row, details)`` of the ok friction rows, the first repetition of each case;
    :class:`_NotApplicable` if the run has no friction row at all."""
    if not any(r.get("friction_dual") is not None for r in ctx.records):
        raise _NotApplicable("no reduced friction row in the run")
    out: dict[str, tuple[dict[str, Any], dict]] = {}
    for r, det in _ok_details(ctx):
        if r.get("friction_dual") is None:
            continue
        cid = str(r.get("case_id"))
        if cid not in out or (r.get("repetition") or 0) < (out[cid][0].get("repetition") or 0):
            out[cid] = (r, det)
    return list(out.values())


def _labels(recs: list[dict[str, Any]]) -> list[str]:
    """Case names: friction_dual+hyper, then the scene, sizes and parameters that vary."""
    params = [_param_dict(r) or {} for r in recs]
    vary = _varying_params(recs) or []
    scenes = len({str(r.get("scene")) for r in recs}) > 1
    sizes = len({(r.get("N_req"), r.get("R_req")) for r in recs}) > 1
    out = []
    for r, p in zip(recs, params, strict=True):
        parts = [f"{r.get('friction_dual')}+{r.get('hyper_used') or r.get('hyper')}"]
        parts += [str(r.get("scene"))] if scenes else []
        parts += [f"N={r.get('N_req')},R={r.get('R_req')}"] if sizes else []
        parts += [f"{k}={p[k]}" for k in vary if k in p]
        out.append(" ".join(parts))
    return out


def _gcns_history(det: dict) -> list[dict[str, Any]]:
    h = det.get("gcns_history")
    return [e for e in h if isinstance(e, dict) and "q" in e] if isinstance(h, list) else []


def _gcns_curve(ax, hist: list[dict[str, Any]], key: str, chosen: Any, colour: Any,
                label: str) -> bool:
    """One case's ``key`` against q, the kept q circled; True if a value was floored."""
    q = np.array([_num(e.get("q")) for e in hist])
    v = np.array([_num(e.get(key)) for e in hist])
    good = np.isfinite(q) & np.isfinite(v)
    low = good & (v <= _FLOOR)
    vp = np.where(low, _FLOOR, v)
    ax.plot(q[good], vp[good], color=colour, marker=".", linewidth=1.3, label=label)
    if low.any():
        ax.plot(q[low], vp[low], linestyle="none", marker="v", color=colour, markersize=7)
    at = good & (q == _num(chosen))
    ax.plot(q[at], vp[at], linestyle="none", marker="o", markersize=11,
            markerfacecolor="none", markeredgecolor=colour, markeredgewidth=1.5)
    return bool(low.any())


def _fig_gcns(ctx: _Ctx):
    """GCNS curves of the collocation-model cases: e_GCNS(q) and the relative e_GCNS^{n tau}(q)."""
    have = [(r, d) for r, d in _friction_details(ctx) if _gcns_history(d)]
    if not have:
        raise _Skip("no ok friction case with a GCNS history (details.gcns_history: the "
                    "collocation model; the wedge model has no collocation)")
    from matplotlib import colormaps

    cmap = colormaps["tab10"]
    labels = _labels([r for r, _ in have])
    fig, axes = _figure(1, 2, h=3.8)
    floored = False
    for i, ((r, det), lab) in enumerate(zip(have, labels, strict=True)):
        lab += f" (kept q = {_fmt(r.get('gcns_iterations'))}, S_q = {_fmt(r.get('S_q'))})"
        for ax, (key, _) in zip(axes[0], _GCNS_PANELS, strict=True):
            floored |= _gcns_curve(ax, _gcns_history(det), key, r.get("gcns_iterations"),
                                   cmap(i % cmap.N), lab)
    for ax, (_, title) in zip(axes[0], _GCNS_PANELS, strict=True):
        ax.set_yscale("log")
        ax.grid(True, which="major", alpha=0.3)
        ax.xaxis.get_major_locator().set_params(integer=True)
        ax.set_xlabel("GCNS iteration q (collocation set C(q), S_q nodes)", fontsize=8)
        ax.set_title(title, fontsize=9)
    handles, names = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, names, loc="outside lower center", fontsize=8, ncols=1)
    fig.suptitle("GCNS curves (reduced friction, the collocation model)", fontsize=11)
    caption = ("Per ok friction case with the collocation model (first repetition), from "
               "its gcns_history: left, e_GCNS(q), the largest relative W-error of the "
               "reduced lam_t over the training set with the collocation set C(q); right, "
               "the largest violation of the Coulomb bound over the training set and all HF "
               "nodes, relative to the largest |lam_t| of the snapshots. Circled: the q "
               "kept (gcns_iterations; Benaceur et al.'s rule stops at e_GCNS(q) > e_GCNS(q-1), "
               "gcns_patience > 1 keeps going and keeps the best set).")
    if floored:
        caption += f" Values <= {_FLOOR:g} (e.g. 0) are drawn at {_FLOOR:g} as triangles."
    return fig, caption


def profile_problem(p: Any) -> str | None:
    """What is wrong with a ``lam_t_profiles`` entry (``None``: drawable).

    Drawable: a dict with ``mu``, ``x``, ``lam_t_hf``, ``lam_t_rb``, ``bound_hf``, one entry
    per mu each, the four profiles of a mu of one non-zero length.
    """
    if not isinstance(p, dict):
        return "not a table"
    missing = [k for k in _PROFILE_KEYS if not isinstance(p.get(k), list)]
    if missing:
        return f"no {', '.join(missing)}"
    n_mu = len(p["mu"])
    if n_mu == 0 or any(len(p[k]) != n_mu for k in _PROFILE_KEYS):
        return "not one profile per mu"
    for j in range(n_mu):
        lens = {len(p[k][j]) if isinstance(p[k][j], list) else -1 for k in _PROFILE_KEYS[1:]}
        if len(lens) != 1 or lens.pop() <= 0:
            return f"profiles of unequal length at mu {p['mu'][j]}"
    return None


def _mu_text(mu: Any) -> str:
    vals = mu if isinstance(mu, list) else [mu]
    return ", ".join(f"{_num(v):.3g}" for v in vals)


def _profile_panel(ax, p: dict[str, Any], j: int) -> None:
    """One mu: lam_t HF and RB against x, the HF bounds +- F lam_n dashed."""
    x = np.array([_num(v) for v in p["x"][j]])
    hf = np.array([_num(v) for v in p["lam_t_hf"][j]])
    rb = np.array([_num(v) for v in p["lam_t_rb"][j]])
    bound = np.array([_num(v) for v in p["bound_hf"][j]])
    ax.plot(x, bound, color="0.45", linestyle="--", linewidth=1, label="+- F lam_n (HF)")
    ax.plot(x, -bound, color="0.45", linestyle="--", linewidth=1)
    ax.plot(x, hf, color="black", linewidth=1.6, label="lam_t HF")
    ax.plot(x, rb, color="tab:red", linewidth=1.2, marker=".", markersize=3, label="lam_t RB")
    ax.axhline(0.0, color="0.8", linewidth=0.6, zorder=0)
    ax.grid(True, which="major", alpha=0.3)
    ax.set_title(f"mu = {_mu_text(p['mu'][j])}", fontsize=9)
    ax.set_xlabel("x of the contact node (m)", fontsize=8)
    ax.set_ylabel("tangential multiplier lam_t (Pa)", fontsize=8)


def _profile_figure(p: dict[str, Any], title: str):
    n = len(p["mu"])
    fig, axes = _figure(1, n, w=4.0, h=3.3)
    for j in range(n):
        _profile_panel(axes[0, j], p, j)
    handles, names = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, names, loc="outside lower center", ncols=len(names), fontsize=8)
    fig.suptitle(title, fontsize=10)
    return fig


def _figs_lam_t(ctx: _Ctx) -> list[tuple[str, Any, str]]:
    """One figure per ok friction case with drawable ``lam_t_profiles``:
    ``[(name, figure, caption)]``, name ``lam_t_<case_id>``."""
    cases = _friction_details(ctx)
    have = [(r, d) for r, d in cases if profile_problem(d.get("lam_t_profiles")) is None]
    if not have:
        bad = [f"{r.get('case_id')}: {profile_problem(d.get('lam_t_profiles'))}"
               for r, d in cases if d.get("lam_t_profiles") is not None]
        raise _Skip("no ok friction case with lam_t profiles (details.lam_t_profiles)"
                    + (f"; unusable: {'; '.join(bad)}" if bad else ""))
    out = []
    for (r, det), lab in zip(have, _labels([r for r, _ in have]), strict=True):
        title = (f"lam_t, HF against RB: {r.get('scene')} {lab} (N={_fmt(r.get('N'))}, "
                 f"R={_fmt(r.get('R'))}, S={_fmt(r.get('S_tau'))})")
        caption = (f"Case {r.get('case_id')} ({lab}): the tangential multiplier of the HF "
                   "solution (black) and of the reconstructed reduced solution (red) at the "
                   "contact nodes against x, with the HF Coulomb bounds +- F lam_n (dashed), "
                   "one panel per parameter (the training parameters nearest to the ends and "
                   "the centre of the parameter box, so the HF values are snapshots: as in the "
                   "published 'RB solutions'). The case's err_lam_t_max over the validation set: "
                   f"{_fmt(r.get('err_lam_t_max'))} (floor lam_t_best_max "
                   f"{_fmt(r.get('lam_t_best_max'))}).")
        out.append((f"lam_t_{r.get('case_id')}", _profile_figure(det["lam_t_profiles"], title),
                    caption))
    return out


#: (name, builder) of the figure groups: a builder returns ``[(file name, figure,
#: caption)]`` or raises ``_Skip``
FIGURE_GROUPS = (("lam_t", _figs_lam_t),)

#: the columns of the friction table (after the case's label)
_TABLE_COLUMNS = ("N", "R", "S_tau", "S_q", "err_u_max", "err_lam_t_max",
                  "friction_residual_max", "t_online_median_s", "speedup")


def _table_cell(c: dict[str, Any], col: str) -> str:
    if col == "err_lam_t_max" and c.get(col) is not None:
        return f"{_fmt(c.get(col))} ({_fmt(c.get('lam_t_best_max'))})"
    return _fmt(c.get(col))


def friction_table(ctx: _Ctx) -> tuple[list[str], list[list[str]], list[str]] | None:
    """The friction table of the summary: ``(headers, rows, columns used)``, or ``None``
    when the run has no friction row.

    One line per case: the ok cases combined over repetitions (errors max, times median),
    then the friction cases without an ok row with their status; ``err_lam_t_max`` with its
    floor ``lam_t_best_max`` in brackets.
    """
    fr = [r for r in ctx.records if r.get("friction_dual") is not None]
    if not fr:
        return None
    ok = [c for c in ctx.cases if c.get("friction_dual") is not None]
    seen = {str(c.get("case_id")) for c in ok}
    rest: dict[str, dict[str, Any]] = {}
    for r in fr:
        if r.get("status") != "ok" and str(r.get("case_id")) not in seen:
            rest.setdefault(str(r.get("case_id")), r)
    cases = ok + list(rest.values())
    heads = ["case", *(f"{c} (floor lam_t_best_max)" if c == "err_lam_t_max" else _header(c)
                       for c in _TABLE_COLUMNS), "status"]
    rows = [[lab, *(_table_cell(c, col) if c.get("status") == "ok" else "" for col in
                    _TABLE_COLUMNS), str(c.get("status"))]
            for c, lab in zip(cases, _labels(cases), strict=True)]
    return heads, rows, ["friction_dual", "hyper_used", *_TABLE_COLUMNS, "lam_t_best_max"]


def table_note() -> str:
    """The sentence under the friction table."""
    return ("One line per case (case: friction_dual+hyper, then what varies). "
            f"err_lam_t_max: {_COL['err_lam_t_max'].doc}; in brackets lam_t_best_max, its floor. "
            "Numbers only for ok cases (repetitions combined: errors max, times median).")

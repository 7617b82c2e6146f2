"""The report of a run directory: its figures written to disk, and the Markdown / HTML
summary (status counts, flagged cases, best combination per error level, figures with
captions, rows not ok, every row, column definitions)."""

from __future__ import annotations

import html
import json
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pandas as pd

from rbbench.bench import schema
from rbbench.bench.errors import ResultsError
from rbbench.bench.report.analysis import (
    _context,
    _Ctx,
    _size_req,
    best_per_level,
    status_counts,
)
from rbbench.bench.report.common import (
    _BETAS,
    _COL,
    _COMBO_IF_VARYING,
    ERROR_LEVELS,
    _fmt,
    _header,
    _md_table,
)
from rbbench.bench.report.figures import _FIGURES
from rbbench.bench.report.flags import FLAG_RULES, case_flags
from rbbench.bench.report.friction_figures import FIGURE_GROUPS, friction_table, table_note
from rbbench.bench.report.loading import load_run
from rbbench.bench.report.plotting import _NotApplicable, _Skip
from rbbench.bench.results import records
from rbbench.hf.snapshots.cache import atomic_write

_ROW_COLUMNS = ("scene", "backend", "formulation", "solver", "primal", "dual",
                "friction_dual", "stabilizer", "hyper_used", "params", "n_hf_dofs",
                "n_contact", "N", "R", "S", "S_tau", "S_q", "M_eim", "repetition", "status",
                "err_u_max", "err_lam_max", "lam_best_max", "err_lam_t_max",
                "friction_residual_max", "friction_law_residual_max",
                "penetration_max", "beta_dec_min", "beta_on_min", "beta_off_min",
                "contact_force", "tangential_force", "n_stick", "n_slip",
                "friction_residual", "hf_iterations", "max_pressure", "contact_half_width",
                "contact_radius", "hertz_a_rel_error", "hertz_p0_rel_error",
                "t_hf_median_s", "solve_over_floor", "t_offline_s",
                "t_online_median_s", "speedup", "floor_s", "speedup_floor", "case_id")
_TITLES = {"pareto": "Error against online time (Pareto fronts)",
           "offline": "Offline cost against online time",
           "error_vs_size": "Error against RB size", "infsup": "Inf-sup constants",
           "histories": "Offline histories", "bound": "Certified error bound",
           "speedup": "Speed-up", "hf": "HF solves: time and Hertz errors",
           "gcns": "GCNS curves (reduced friction)", "status": "Status counts",
           "lam_t": "lam_t, HF against RB (reduced friction)"}
_KIND_PREFIX = {"cone-upper": "≤ ", "span-lower-bound": "≥ "}
_CSS = ("body{font-family:sans-serif;max-width:1400px;margin:1em auto;padding:0 1em}"
        "table{border-collapse:collapse;font-size:0.85em;margin:0.5em 0 1em}"
        "th,td{border:1px solid #bbb;padding:2px 6px;text-align:left}"
        "th{background:#eee}img{max-width:100%}p,li{font-size:0.95em}")


@dataclass
class ReportOutput:
    """What :func:`report` wrote.

    Attributes
    ----------
    out_dir : Path
        The report directory.
    figures : dict
        Figure name -> paths written (one per format).
    summary_md, summary_html : Path
        The summaries.
    skipped : dict
        Figure name -> why it was not drawn (also stated in the summaries).
    """

    out_dir: Path
    figures: dict[str, list[Path]]
    summary_md: Path
    summary_html: Path
    skipped: dict[str, str] = field(default_factory=dict)

    @property
    def paths(self) -> list[Path]:
        """Every file written."""
        return [p for ps in self.figures.values() for p in ps] + [self.summary_md,
                                                                  self.summary_html]

    def __str__(self) -> str:
        names = ", ".join(p.name for p in self.paths)
        text = f"{self.out_dir}/: {names}"
        if self.skipped:
            text += "; not drawn: " + "; ".join(f"{k} ({v})" for k, v in self.skipped.items())
        return text


def _check_formats(formats: Sequence[str] | str) -> list[str]:
    from matplotlib.backend_bases import FigureCanvasBase

    if isinstance(formats, str):
        formats = (formats,)
    supported = FigureCanvasBase.get_supported_filetypes()
    out = []
    for f in formats:
        f = str(f).lower().lstrip(".")
        if f not in supported:
            raise ValueError(f"figure format {f!r}: valid: {', '.join(sorted(supported))}")
        if f not in out:
            out.append(f)
    if not out:
        raise ValueError("no figure format given")
    return out


@dataclass
class _Drawn:
    """The figures of a report: paths written, captions, and why the others were not."""

    figures: dict[str, list[Path]] = field(default_factory=dict)
    captions: dict[str, str] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)
    groups: dict[str, list[str]] = field(default_factory=dict)  # group -> figure names
    not_applicable: set[str] = field(default_factory=set)  # not mentioned in the summary

    def save(self, name: str, fig: Any, caption: str, out: Path, fmts: list[str]) -> None:
        """Write ``fig`` as ``out/<name>.<format>`` in every format."""
        self.figures[name] = []
        for f in fmts:
            p = out / f"{name}.{f}"
            # a new file renamed into place: a link of that name is replaced, not followed
            atomic_write(p, lambda fh, f=f: fig.savefig(fh, format=f, dpi=120))
            self.figures[name].append(p)
        self.captions[name] = caption


def _attempt(drawn: _Drawn, name: str, build: Any, ctx: _Ctx) -> Any:
    """``build(ctx)``, or ``None`` with the reason recorded (skipped / not applicable)."""
    try:
        return build(ctx)
    except _NotApplicable:
        drawn.not_applicable.add(name)
    except _Skip as exc:
        drawn.skipped[name] = str(exc)
    return None


def _draw_figures(ctx: _Ctx, out: Path, fmts: list[str]) -> _Drawn:
    """The figures of :data:`_FIGURES` and of the groups (one figure per case, e.g.
    ``lam_t_<case_id>``); a figure or group without data is recorded as skipped, one that
    does not apply to the run (friction figures of a frictionless run) is left out."""
    drawn = _Drawn()
    for name, build in _FIGURES:
        built = _attempt(drawn, name, build, ctx)
        if built is not None:
            drawn.save(name, *built, out, fmts)
    for group, build_all in FIGURE_GROUPS:
        for name, fig, caption in _attempt(drawn, group, build_all, ctx) or []:
            drawn.save(name, fig, caption, out, fmts)
            drawn.groups.setdefault(group, []).append(name)
    return drawn


def report(run_dir: str | Path, out_dir: str | Path | None = None,
           formats: Sequence[str] = ("png", "svg")) -> ReportOutput:
    """Figures and summary tables of a run directory.

    Parameters
    ----------
    run_dir : str or Path
        A run directory (``results.parquet``, ``manifest.json``, ``cases/``).
    out_dir : str or Path, optional
        Where to write; default ``run_dir/report``.
    formats : sequence of str
        Figure formats (any matplotlib can write: ``png``, ``svg``, ``pdf``...).

    Returns
    -------
    ReportOutput
        The paths written: ``pareto``, ``offline``, ``error_vs_size``, ``infsup``, ``histories``,
        ``speedup``, ``gcns``, ``status`` and, per ok friction case with profiles,
        ``lam_t_<case_id>`` (each in every format, unless skipped for lack of data: the
        summary says why), ``summary.md`` and ``summary.html`` (with a table of the
        reduced friction models when the run has friction rows).
    """
    fmts = _check_formats(formats)
    run = load_run(run_dir)
    out = Path(out_dir) if out_dir is not None else run.run_dir / "report"
    if out_dir is None and out.is_symlink():  # the default folder: never written through
        raise ResultsError(f"{out}: the report folder of the run is a symbolic link (to "
                           f"{os.readlink(out)}); remove it, or name a folder with --out")
    out.mkdir(parents=True, exist_ok=True)
    ctx = _context(run)
    drawn = _draw_figures(ctx, out, fmts)
    img_fmt = next((f for f in ("png", "svg") if f in fmts), fmts[0])
    md, doc = _summary(ctx, drawn, img_fmt)
    md_path, html_path = out / "summary.md", out / "summary.html"
    atomic_write(md_path, lambda fh: fh.write(md.encode("utf-8")))
    atomic_write(html_path, lambda fh: fh.write(doc.encode("utf-8")))
    return ReportOutput(out, drawn.figures, md_path, html_path, drawn.skipped)


class _Doc:
    """Builds the Markdown and HTML summaries side by side, and records the columns
    they use (defined at the end)."""

    def __init__(self) -> None:
        self.md: list[str] = []
        self.html: list[str] = []
        self.used: list[str] = []

    def use(self, *cols: str) -> None:
        for c in cols:
            if c in _COL and c not in self.used:
                self.used.append(c)

    def heading(self, text: str, level: int = 2) -> None:
        self.md.append(f"{'#' * level} {text}\n")
        self.html.append(f"<h{level}>{html.escape(text)}</h{level}>")

    def para(self, text: str) -> None:
        self.md.append(text + "\n")
        self.html.append(f"<p>{html.escape(text)}</p>")

    def bullets(self, items: Sequence[str]) -> None:
        self.md.append("\n".join(f"* {t}" for t in items) + "\n")
        self.html.append("<ul>" + "".join(f"<li>{html.escape(t)}</li>" for t in items)
                         + "</ul>")

    def image(self, src: str, alt: str) -> None:
        self.md.append(f"![{alt}]({src})\n")
        self.html.append(f'<p><img src="{html.escape(src)}" alt="{html.escape(alt)}"></p>')

    def table(self, headers: Sequence[str], rows: Sequence[Sequence[str]]) -> None:
        self.md.append("\n".join(_md_table(headers, rows)) + "\n")
        head = "".join(f"<th>{html.escape(str(h))}</th>" for h in headers)
        body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in r)
                       + "</tr>" for r in rows)
        self.html.append(f"<table><thead><tr>{head}</tr></thead><tbody>{body}</tbody>"
                         "</table>")

    def render(self, title: str) -> tuple[str, str]:
        doc = ("<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\">"
               f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>\n"
               + "\n".join(self.html) + "\n</body></html>\n")
        return "\n".join(self.md), doc


def _run_id(ctx: _Ctx) -> str:
    return ctx.run.manifest.get("run_id") or next(
        (r["run_id"] for r in ctx.records if r.get("run_id")), ctx.run.run_dir.name)


def _intro(d: _Doc, ctx: _Ctx, run_id: str) -> None:
    run, man = ctx.run, ctx.run.manifest
    d.heading(f"rbbench report: {run_id}", 1)
    facts = [f"run directory: {run.run_dir}", f"rows (cases x repetitions): {len(ctx.records)}"]
    for k in ("matrix_file", "started_at", "n_cases"):
        if man.get(k) is not None:
            facts.append(f"{k}: {man[k]}")
    prov = man.get("provenance") or {}
    if isinstance(prov, dict):
        facts += [f"{k}: {v}" for k, v in prov.items() if isinstance(v, str | int | float)]
    d.bullets(facts)
    d.para("Numbers are rounded to 3 significant digits; units in brackets; every column "
           "used is defined under 'Columns' at the end. Only rows with status ok are shown "
           "as numbers. In the plots and the best-per-level tables the repetitions of a "
           "case are combined: errors max, beta min, times and speed-up median.")
    if run.notes:
        d.heading("Reading notes", 3)
        d.bullets(run.notes)


def _status_section(d: _Doc, ctx: _Ctx) -> None:
    d.heading("Status counts")
    counts = status_counts(ctx.run.rows) if ctx.records else None
    if counts is None or counts.empty:
        d.para("The results table has no rows.")
    else:
        d.table(["scene", *counts.columns],
                [[sc, *(str(int(v)) for v in counts.loc[sc])] for sc in counts.index])
    d.use("status")


def _flags_section(d: _Doc, ctx: _Ctx) -> None:
    """The ok cases an error of which grows with N or sits far above its floor
    (:mod:`rbbench.bench.report.flags`)."""
    flags = case_flags(ctx.records)
    hit = [(r, f) for r, f in zip(ctx.records, flags, strict=True) if f]
    d.heading(f"Flagged cases ({len(hit)})")
    d.bullets([f"Rule: {rule}." for rule in FLAG_RULES])
    if not hit:
        d.para("No ok row is flagged.")
        return
    hit.sort(key=lambda rf: (str(rf[0].get("scene")), ctx.combos_all.label(rf[0]),
                             _size_req(rf[0]), rf[0].get("repetition") or 0))
    d.table(["scene", "combination", "N", "R", "repetition", "flags", "case_id"],
            [[str(r.get("scene")), ctx.combos_all.label(r), _fmt(r.get("N")),
              _fmt(r.get("R")), _fmt(r.get("repetition")), "; ".join(f),
              _fmt(r.get("case_id"))] for r, f in hit])
    d.use("N", "R", "repetition", "err_u_max", "err_lam_max", "lam_best_max",
          "err_lam_t_max", "lam_t_best_max", "case_id")


def _without_values(ctx: _Ctx, col: str) -> list[str]:
    """The scenes with ok rows, none of which has a value of ``col``."""
    ok = [r for r in ctx.records if r.get("status") == "ok"]
    scenes = sorted({r["scene"] for r in ok})
    return [sc for sc in scenes if all(pd.isna(r.get(col)) for r in ok if r["scene"] == sc)]


def _best_section(d: _Doc, ctx: _Ctx, col: str) -> None:
    d.heading(f"Best combination per scene at each error level ({col})")
    bp = best_per_level(ctx.run.rows, col, levels="front") if ctx.records else pd.DataFrame()
    na = _without_values(ctx, col)
    if na:  # e.g. err_lam_max of the linear scenes: no contact, no multiplier
        d.para(f"Not applicable to {', '.join(na)}: no ok row has a value of {col} (a "
               "scene without contact has no multiplier; the rows' reason says so).")
        bp = bp[~bp["scene"].isin(na)] if not bp.empty else bp
    if bp.empty:
        d.para("No rows.")
        return
    d.para(f"For each level: the ok case with the smallest t_online_median_s among those "
           f"with {col} <= level. The levels are chosen per scene so that each has its own "
           f"fastest case (fixed levels such as {', '.join(f'{v:g}' for v in ERROR_LEVELS)} "
           "can all be met by the fastest case): the errors of the scene's Pareto front "
           "(online time against error, see the Pareto figure) rounded up to 3 significant "
           "digits, loosest first, then the power of ten below the smallest error, which "
           "no case reaches.")
    heads = ["scene", f"{col} <=", "combination", "N", "R", "S", _header(col),
             _header("t_online_median_s"), _header("speedup"), "case_id"]
    rows = []
    for r in records(bp):
        if r["found"]:
            rows.append([r["scene"], f"{r['level']:g}", r["combination"], _fmt(r["N"]),
                         _fmt(r["R"]), _fmt(r["S"]), _fmt(r[col]),
                         _fmt(r["t_online_median_s"]), _fmt(r["speedup"]),
                         _fmt(r["case_id"])])
        else:
            rows.append([r["scene"], f"{r['level']:g}", "none reaches it", *[""] * 7])
    d.table(heads, rows)
    d.use(col, "t_online_median_s", "speedup", "N", "R", "S", "case_id")


def _friction_section(d: _Doc, ctx: _Ctx) -> None:
    """The reduced friction models side by side (only when the run has friction rows)."""
    table = friction_table(ctx)
    if table is None:
        return
    heads, rows, used = table
    d.heading("Reduced friction models")
    d.table(heads, rows)
    d.para(table_note())
    d.use(*used, "status")


#: The columns of the HF solves table: the contact extent is the half-width in 2D, the
#: radius in 3D (one column each, by the row's dim).
_HF_EXTENT = {2: ("contact_half_width", "contact_half_width_gap"),
              3: ("contact_radius", "contact_radius_gap")}


def _hf_section(d: _Doc, ctx: _Ctx) -> None:
    """The HF solves side by side (mode hf rows; only when the run has some): sizes,
    force, contact extent and Hertz errors, HF time and its floor."""
    hf = [r for r in ctx.records if r.get("mode") == "hf"]
    if not hf:
        return
    d.heading(f"HF solves ({len(hf)})")
    dims = sorted({int(r["dim"]) for r in hf if r.get("dim") in (2, 3)}) or [2]
    extent = [c for dim in dims for c in _HF_EXTENT[dim]]
    cols = ["n_hf_dofs", "n_contact", "hf_iterations", "hf_final_residual", "contact_force",
            "max_pressure", *extent, "hertz_a_rel_error", "hertz_a_gap_rel_error",
            "hertz_p0_rel_error", "t_hf_median_s", "floor_s", "solve_over_floor"]
    ok = [r for r in hf if r.get("status") == "ok"]
    cols = [c for c in cols if any(r.get(c) is not None for r in ok)]
    rows = sorted(hf, key=lambda r: (str(r.get("scene")), str(r.get("backend")),
                                      str(r.get("solver")), str(r.get("params"))))
    d.table(["scene", "backend", "formulation", "solver", "solver options", "status",
             *[_header(c) for c in cols]],
            [[str(r.get("scene")), str(r.get("backend")), str(r.get("formulation")),
              str(r.get("solver")), _solver_options(r.get("params")), str(r.get("status")),
              *[_fmt(r.get(c)) if r.get("status") == "ok" else "" for c in cols]]
             for r in rows])
    if 3 in dims:
        d.para("3D rows: contact_force of the whole bodies (N) when symmetry planes cut the "
               "mesh; contact_radius (quantised to multiplier supports) and "
               "contact_radius_gap (from the pointwise gap) in place of the 2D half-widths; "
               "the Hertz errors against 3D Hertz at each row's own force.")
    d.use("dim", *cols, "params")


def _solver_options(params: Any) -> str:
    """The solver options of a mode-hf row's parameters (its JSON ``params`` without
    ``hf_repeats``)."""
    try:
        p = json.loads(params) if isinstance(params, str) else dict(params or {})
    except (ValueError, TypeError):
        return ""
    return ", ".join(f"{k}={v}" for k, v in sorted(p.items()) if k != "hf_repeats")


def _figure_entry(d: _Doc, drawn: _Drawn, name: str, img_fmt: str) -> None:
    paths = drawn.figures[name]
    src = next((p.name for p in paths if p.suffix == f".{img_fmt}"), paths[0].name)
    d.image(src, name)
    d.para(drawn.captions[name])
    d.para("Files: " + ", ".join(p.name for p in paths))


def _figures_section(d: _Doc, drawn: _Drawn, img_fmt: str) -> None:
    d.heading("Figures")
    for name in [n for n, _ in _FIGURES] + [g for g, _ in FIGURE_GROUPS]:
        if name in drawn.not_applicable:
            continue
        names = drawn.groups.get(name) or ([name] if name in drawn.figures else [])
        if names:
            d.heading(_TITLES[name], 3)
            for n in names:
                _figure_entry(d, drawn, n, img_fmt)
        else:
            d.heading(f"{_TITLES[name]} (not drawn)", 3)
            d.para(f"Skipped: {drawn.skipped.get(name, 'no data')}.")
    d.use("err_u_max", "err_lam_max", "t_online_median_s", "N", "R", "speedup",
          "t_hf_median_s", "t_offline_s", "t_snapshots_s", "t_snapshots_hf_s",
          "t_offline_hf_s", "n_snapshots_cached", "n_train", "beta_hf_min", "beta_dec_min",
          "beta_on_min", "beta_off_min")


def _not_ok_section(d: _Doc, ctx: _Ctx) -> None:
    bad = [r for r in ctx.records if r.get("status") != "ok"]
    d.heading(f"Rows not ok ({len(bad)})")
    if not bad:
        d.para("Every row is ok.")
        return
    d.table(["scene", "combination", "N_req", "R_req", "repetition", "status", "reason",
             "case_id"],
            [[str(r.get("scene")), ctx.combos_all.label(r), _fmt(r.get("N_req")),
              _fmt(r.get("R_req")), _fmt(r.get("repetition")), str(r.get("status")),
              r.get("reason") or "(no reason given)", _fmt(r.get("case_id"))]
             for r in sorted(bad, key=lambda r: (str(r.get("scene")), str(r.get("status"))))])
    d.use("N_req", "R_req", "repetition", "status", "reason", "case_id")


def _cell(value: Any, col: str, kinds: dict[str, Any]) -> str:
    """A cell of the rows table; a beta value marked by its kind (≤ upper estimate,
    ≥ span lower bound)."""
    if col in _BETAS and value is not None:
        return _KIND_PREFIX.get(kinds.get(col) or "", "") + _fmt(value)
    return _fmt(value)


def _rows_section(d: _Doc, ctx: _Ctx) -> None:
    d.heading(f"All rows ({len(ctx.records)})")
    cols = [c for c in _ROW_COLUMNS
            if c not in _COMBO_IF_VARYING or c in ctx.combos_all.fields]
    rows_sorted = sorted(ctx.records, key=lambda r: (str(r.get("scene")),
                                                     ctx.combos_all.label(r), _size_req(r),
                                                     r.get("repetition") or 0))
    # numbers of a row that is not ok are not shown
    shown = [{c: (r.get(c) if r.get("status") == "ok" or _COL[c].dtype != "float" else None)
              for c in cols} for r in rows_sorted]
    keep = [c for c in cols if any(s[c] is not None for s in shown)]
    dropped = [c for c in cols if c not in keep]
    if dropped:
        d.para("Columns empty in every row, not shown: " + ", ".join(dropped) + ".")
    kinds = [{c: r.get(c.replace("_min", "_kind")) for c in _BETAS} for r in rows_sorted]
    flags = ["; ".join(f) for f in case_flags(rows_sorted)]
    extra = ["flags"] if any(flags) else []
    d.table([_header(c) for c in keep] + extra,
            [[_cell(s[c], c, k) for c in keep] + ([f] if extra else [])
             for s, k, f in zip(shown, kinds, flags, strict=True)])
    d.use(*keep)
    if extra:
        d.para("flags: see 'Flagged cases' (an error that grows with N in its configuration, "
               "or err_lam far above its cone floor lam_best).")
    if any(c in _BETAS for c in keep):
        d.para("beta columns: a value marked '≤' is a cone upper estimate (the true "
               "constant is at most this), '≥' a span lower bound; unmarked: exact cone "
               "value (from the beta_*_kind columns).")


def _columns_section(d: _Doc, ctx: _Ctx) -> None:
    man = ctx.run.manifest
    d.heading("Columns")
    defs = man.get("columns") if isinstance(man.get("columns"), dict) else {}
    items = []
    for c in [c.name for c in schema.COLUMNS if c.name in d.used]:
        info = defs.get(c) or {}
        doc = info.get("doc") or _COL[c].doc
        unit = info.get("unit", _COL[c].unit)
        unit_txt = {"": "", "1": " [dimensionless]"}.get(unit, f" [{unit}]")
        items.append(f"{c}{unit_txt}: {doc}")
    items.append(f"combination: {ctx.combos_all.title} in the tables, {ctx.combos.title} "
                 "in the figures (the components that vary, among all rows / the ok rows; "
                 "hyper is hyper_used, or hyper when that is empty)")
    d.bullets(items)


def _summary(ctx: _Ctx, drawn: _Drawn, img_fmt: str) -> tuple[str, str]:
    """The Markdown and HTML summaries of a report."""
    run_id = _run_id(ctx)
    d = _Doc()
    _intro(d, ctx, run_id)
    _status_section(d, ctx)
    _flags_section(d, ctx)
    if any(r.get("mode") != "hf" for r in ctx.records):  # an HF-only run has no errors
        for col in ("err_u_max", "err_lam_max"):
            _best_section(d, ctx, col)
    _friction_section(d, ctx)
    _hf_section(d, ctx)
    _figures_section(d, drawn, img_fmt)
    _not_ok_section(d, ctx)
    _rows_section(d, ctx)
    _columns_section(d, ctx)
    return d.render(f"rbbench report: {run_id}")

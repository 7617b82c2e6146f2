"""Plots and tables from a run directory (``rbbench report``) and the comparison of two
runs (``rbbench compare``).

A run directory (written by ``rbbench run``) holds::

    manifest.json                 run id, matrix, column definitions, provenance
    results.parquet               one row per case x repetition (rbbench.bench.schema.COLUMNS)
    results.csv                   optional, the same rows
    cases/<case_id>-r<rep>.json   {"row": {...}, "details": {"per_mu", "histories",
                                  "valid_mus"}}

:func:`report` reads it and writes figures (Pareto fronts, error against size, inf-sup
constants per validation parameter, compressor / PGA / EIM histories, speed-ups, status
counts) and ``summary.md`` / ``summary.html``. :func:`compare` matches the rows of two
runs on the identity of the case and lists regressions and improvements.

Only the columns declared in :mod:`rbbench.bench.schema` are read, by name; labels and
footnotes come from their docs. Rows whose status is not ``ok`` are never plotted or
tabulated as numbers. Matplotlib is used through :class:`matplotlib.figure.Figure` only
(no pyplot): no backend is selected and no global figure state is touched.
"""

from __future__ import annotations

import html
import json
import math
import statistics
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rbbench.bench import schema

__all__ = [
    "ERROR_LEVELS",
    "IDENTITY",
    "CompareResult",
    "ReportOutput",
    "RunData",
    "best_per_level",
    "compare",
    "format_compare",
    "load_results",
    "load_run",
    "pareto_front",
    "report",
    "status_counts",
]

#: Columns that identify a case across runs (``compare``); not ``run_id`` / ``case_id``.
IDENTITY: tuple[str, ...] = ("scene", "scene_overrides", "backend", "formulation", "solver",
                             "primal", "dual", "stabilizer", "hyper", "params", "N_req",
                             "R_req", "repetition")
#: Error levels of the "best combination per scene" tables.
ERROR_LEVELS: tuple[float, ...] = (1e-1, 1e-2, 1e-3)

_COL = {c.name: c for c in schema.COLUMNS}
_CASE_KEY = tuple(k for k in IDENTITY if k != "repetition")
# components that always name a combination, and those named only when they vary in a run
_COMBO_ALWAYS = ("dual", "stabilizer", "hyper_used")
_COMBO_IF_VARYING = ("backend", "formulation", "solver", "primal", "params")
_COMBO_ORDER = ("backend", "formulation", "solver", "primal", "dual", "stabilizer",
                "hyper_used", "params")
# how repetitions of one case are combined (plots, best-per-level)
_AGG_MAX = ("err_u_max", "err_u_mean", "err_lam_max", "err_lam_mean", "penetration_max",
            "complementarity_max", "energy_err_max")
_ERRORS = ("err_u_max", "err_lam_max")
_BETAS = ("beta_hf_min", "beta_dec_min", "beta_on_min", "beta_off_min")
_TIMES = ("t_online_median_s", "t_offline_s", "t_hf_median_s")
_ABS_FLOOR = 1e-12  # compare: absolute floor on error growth
_AGG_MIN = _BETAS
_AGG_MEDIAN = ("t_snapshots_s", "t_primal_s", "t_dual_s", "t_stabilizer_s", "t_hyper_s",
               "t_offline_s", "t_online_median_s", "t_online_iqr_s", "t_hf_median_s",
               "speedup", "t_case_s", "peak_rss_mb")
# short axis labels (the full meaning is the schema doc, quoted in the summary)
_SHORT = {
    "err_u_max": "max relative error of u (X norm)",
    "err_lam_max": "max relative error of lam (W norm)",
    "t_online_median_s": "online solve time, median",
    "speedup": "speed-up t_HF / t_online",
    "N": "primal RB size N",
    "R": "dual size R (cone generators)",
}
_KIND_TEXT = {"span-lower-bound": "span lower bound", "cone-exact": "cone, exact",
              "cone-upper": "cone, upper estimate"}
_KIND_MARKER = {"cone-exact": ("o", True), "cone-upper": ("o", False),
                "span-lower-bound": ("^", True)}
_BETA_COLOUR = {"hf": "black", "dec": "tab:blue", "on": "tab:green", "off": "tab:red"}
_BETA_TEXT = {"hf": "whole V vs HF cone", "dec": "V_N", "on": "V_N + S_R(mu), online",
              "off": "V_N + S_PGA, offline"}
_KIND_PREFIX = {"cone-upper": "≤ ", "span-lower-bound": "≥ "}
_STATUS_COLOUR = {"ok": "tab:green", "skip": "0.65", "error": "tab:red",
                  "timeout": "tab:orange", "diverged": "tab:purple",
                  "not_installed": "tab:blue"}
_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*", "<", ">", "h", "p")
_LINESTYLES = ("-", "--", "-.", ":")
_PANEL_W, _PANEL_H = 4.4, 3.3


# ---------------------------------------------------------------------------------------
# loading
# ---------------------------------------------------------------------------------------


@dataclass
class RunData:
    """One run directory, read.

    Attributes
    ----------
    run_dir : Path
        The directory.
    rows : pandas.DataFrame
        Every schema column (object dtype; ``None`` where empty), one row per case x
        repetition, in file order.
    manifest : dict
        ``manifest.json`` (empty if absent).
    details : dict
        ``(case_id, repetition) -> details`` from ``cases/*.json`` (``per_mu``,
        ``histories``, ``valid_mus``); absent cases have no entry.
    notes : list of str
        What was odd while reading (unknown columns, unreadable case files).
    """

    run_dir: Path
    rows: pd.DataFrame
    manifest: dict = field(default_factory=dict)
    details: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)

    def records(self) -> list[dict[str, Any]]:
        """The rows as a list of dicts (``None`` for empty cells)."""
        return _records(self.rows)


def _clean(v: Any) -> Any:
    """NaN / NA / numpy scalars -> ``None`` / plain Python."""
    if v is None:
        return None
    if isinstance(v, np.generic):
        v = v.item()
    try:
        if pd.isna(v):
            return None
    except (TypeError, ValueError):
        pass
    return v


def _coerce(raw: dict[str, Any], notes: list[str] | None = None) -> dict[str, Any]:
    """One raw row -> :func:`rbbench.bench.schema.normalise_row`, tolerant of file types."""
    row: dict[str, Any] = {}
    for k, v in raw.items():
        if k not in _COL:
            if notes is not None:
                msg = f"column {k!r} is not declared in rbbench/schema.py: ignored"
                if msg not in notes:
                    notes.append(msg)
            continue
        v = _clean(v)
        dtype = _COL[k].dtype
        if isinstance(v, str) and dtype != "str":
            s = v.strip()
            if s == "" or s.lower() in ("nan", "none", "null"):
                v = None
            elif dtype == "bool":
                v = s.lower() in ("true", "1", "yes")
            elif dtype == "int":
                v = int(float(s))
        elif dtype == "int" and isinstance(v, float):
            v = int(v)
        row[k] = v
    return schema.normalise_row(row)


def _frame(rows: Iterable[dict[str, Any]]) -> pd.DataFrame:
    return pd.DataFrame(list(rows), columns=schema.names(), dtype=object)


def _records(df: pd.DataFrame) -> list[dict[str, Any]]:
    return [{k: _clean(v) for k, v in r.items()} for r in df.to_dict("records")]


def _read_csv(path: Path) -> pd.DataFrame:
    header = pd.read_csv(path, nrows=0).columns
    dtype = {c: str for c in header if c in _COL and _COL[c].dtype in ("str", "bool")}
    return pd.read_csv(path, dtype=dtype, keep_default_na=False,
                       na_values={c: [""] for c in header})


def load_results(path: str | Path, notes: list[str] | None = None) -> pd.DataFrame:
    """The results table of a run directory or of one results file.

    Parameters
    ----------
    path : str or Path
        A run directory (``results.parquet``, else ``results.csv``, else the rows of
        ``cases/*.json``), or a ``.parquet`` / ``.csv`` file.
    notes : list of str, optional
        Receives what was odd (e.g. undeclared columns, ignored).

    Returns
    -------
    pandas.DataFrame
        Every column of :data:`rbbench.bench.schema.COLUMNS`, object dtype, ``None`` where empty.

    Raises
    ------
    FileNotFoundError
        If no results are found at ``path``.
    """
    p = Path(path)
    raw: list[dict[str, Any]]
    if p.is_dir():
        if (p / "results.parquet").is_file():
            return load_results(p / "results.parquet", notes)
        if (p / "results.csv").is_file():
            return load_results(p / "results.csv", notes)
        files = sorted((p / "cases").glob("*.json")) if (p / "cases").is_dir() else []
        raw = []
        for f in files:
            try:
                raw.append(json.loads(f.read_text())["row"])
            except (OSError, ValueError, KeyError) as exc:
                if notes is not None:
                    notes.append(f"{f.name}: unreadable ({exc})")
        if not raw:
            raise FileNotFoundError(f"{p}: no results.parquet, results.csv or cases/*.json")
        if notes is not None:
            notes.append("no results.parquet / results.csv: rows read from cases/*.json")
    elif p.is_file() and p.suffix == ".parquet":
        raw = pd.read_parquet(p).to_dict("records")
    elif p.is_file() and p.suffix == ".csv":
        raw = _read_csv(p).to_dict("records")
    elif p.is_file():
        raise ValueError(f"{p}: expected a run directory, a .parquet or a .csv file")
    else:
        raise FileNotFoundError(f"{p}: no such run directory or results file")
    return _frame(_coerce(r, notes) for r in raw)


def load_run(run_dir: str | Path) -> RunData:
    """Read a run directory: results, manifest and per-case details.

    Parameters
    ----------
    run_dir : str or Path
        The directory written by ``rbbench run``.

    Returns
    -------
    RunData
    """
    d = Path(run_dir)
    if not d.is_dir():
        raise FileNotFoundError(f"{d}: not a run directory")
    notes: list[str] = []
    rows = load_results(d, notes)
    manifest: dict = {}
    if (d / "manifest.json").is_file():
        try:
            manifest = json.loads((d / "manifest.json").read_text())
        except ValueError as exc:
            notes.append(f"manifest.json unreadable ({exc})")
    details: dict[tuple[str, int], dict] = {}
    if (d / "cases").is_dir():
        for f in sorted((d / "cases").glob("*.json")):
            try:
                doc = json.loads(f.read_text())
            except (OSError, ValueError) as exc:
                notes.append(f"cases/{f.name}: unreadable ({exc})")
                continue
            row = doc.get("row") or {}
            det = doc.get("details") or {}
            cid, rep = row.get("case_id"), row.get("repetition")
            if cid is None or rep is None:
                stem, _, r = f.stem.rpartition("-r")
                cid, rep = (stem, r) if r.isdigit() else (cid, rep)
            if cid is not None and rep is not None and det:
                details[(str(cid), int(rep))] = det
    return RunData(d, rows, manifest, details, notes)


# ---------------------------------------------------------------------------------------
# small helpers
# ---------------------------------------------------------------------------------------


def _num(v: Any) -> float:
    """A cell as float (NaN for empty / non-numeric)."""
    if v is None or isinstance(v, str):
        return math.nan
    try:
        return float(v)
    except (TypeError, ValueError):
        return math.nan


def _pos(v: Any) -> bool:
    """True for a finite positive number (plottable on a log axis)."""
    x = _num(v)
    return math.isfinite(x) and x > 0


def _fmt(v: Any) -> str:
    """A cell for a table: floats to 3 significant digits, empty as an en dash."""
    if v is None:
        return "–"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            return str(v)
        if v == 0:
            return "0"
        r = float(f"{v:.3g}")
        e = math.floor(math.log10(abs(r)))
        return f"{r:.{2 - e}f}" if -3 <= e <= 2 else (f"{r:.0f}" if 2 < e < 5 else f"{r:.2e}")
    return str(v)


def _unit(name: str) -> str:
    u = _COL[name].unit if name in _COL else ""
    return "" if u in ("", "1") else u


def _header(name: str) -> str:
    u = _unit(name)
    return f"{name} [{u}]" if u else name


def _axis_label(name: str) -> str:
    u = _unit(name)
    text = _SHORT.get(name, name)
    return f"{text} ({u})\n[{name}]" if u else f"{text}\n[{name}]"


def _key(rec: dict[str, Any], cols: Sequence[str]) -> tuple[str, ...]:
    return tuple("" if rec.get(c) is None else str(rec.get(c)) for c in cols)


def _varying(records: list[dict[str, Any]], cols: Sequence[str]) -> list[str]:
    return [c for c in cols if len({_key(r, (c,)) for r in records}) > 1]


def _compact(v: Any) -> str:
    if v is None:
        return "-"
    s = str(v)
    try:
        obj = json.loads(s)
    except ValueError:
        return s
    if isinstance(obj, dict):
        return ",".join(f"{k}={obj[k]}" for k in sorted(obj)) or "{}"
    return s


class _Combos:
    """Names and styles of the combinations of a run (colour by dual compressor, marker
    and line style by the rest of the combination)."""

    def __init__(self, records: list[dict[str, Any]]):
        varying = _varying(records, _COMBO_IF_VARYING)
        self.fields = [f for f in _COMBO_ORDER if f in _COMBO_ALWAYS or f in varying]
        duals = sorted({self._part(r, "dual") for r in records})
        rests = sorted({self.label(r, without="dual") for r in records})
        from matplotlib import colormaps

        cmap = colormaps["tab10" if len(duals) <= 10 else "tab20"]
        self.dual_colour = {d: cmap(i % cmap.N) for i, d in enumerate(duals)}
        self.rest_index = {r: i for i, r in enumerate(rests)}

    @staticmethod
    def _part(rec: dict[str, Any], f: str) -> str:
        v = rec.get(f)
        if f == "hyper_used" and v is None:
            v = rec.get("hyper")
        return _compact(v) if f == "params" else ("-" if v is None else str(v))

    @property
    def title(self) -> str:
        """What a label is made of, e.g. ``dual+stabilizer+hyper``."""
        return "+".join("hyper" if f == "hyper_used" else f for f in self.fields)

    def label(self, rec: dict[str, Any], without: str | None = None) -> str:
        return "+".join(self._part(rec, f) for f in self.fields if f != without)

    def style(self, rec: dict[str, Any]) -> dict[str, Any]:
        i = self.rest_index.get(self.label(rec, without="dual"), 0)
        return {"color": self.dual_colour.get(self._part(rec, "dual"), "k"),
                "marker": _MARKERS[i % len(_MARKERS)],
                "linestyle": _LINESTYLES[i % len(_LINESTYLES)]}


def _cases(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """The ok rows combined over repetitions: errors max, betas min, times median."""
    groups: dict[tuple[str, ...], list[dict[str, Any]]] = {}
    for r in records:
        if r.get("status") == "ok":
            groups.setdefault(_key(r, _CASE_KEY), []).append(r)
    out = []
    for reps in groups.values():
        reps = sorted(reps, key=lambda r: r.get("repetition") or 0)
        c = dict(reps[0])
        for cols, red in ((_AGG_MAX, max), (_AGG_MIN, min), (_AGG_MEDIAN, statistics.median)):
            for col in cols:
                vals = [_num(r.get(col)) for r in reps]
                vals = [v for v in vals if math.isfinite(v)]
                c[col] = float(red(vals)) if vals else None
        c["n_rep"] = len(reps)
        c["repetitions"] = [r.get("repetition") for r in reps]
        out.append(c)
    return out


def _size(rec: dict[str, Any], name: str) -> int | None:
    v = rec.get(name)
    if v is None:
        v = rec.get(f"{name}_req")
    return None if v is None else int(v)


def _size_req(rec: dict[str, Any]) -> tuple[int, int]:
    n = rec.get("N_req") if rec.get("N_req") is not None else rec.get("N")
    r = rec.get("R_req") if rec.get("R_req") is not None else rec.get("R")
    return (-1 if n is None else int(n), -1 if r is None else int(r))


def _scenes(records: list[dict[str, Any]]) -> list[str]:
    return sorted({str(r.get("scene")) for r in records})


# ---------------------------------------------------------------------------------------
# analysis functions
# ---------------------------------------------------------------------------------------


def pareto_front(x: Sequence[float] | np.ndarray, y: Sequence[float] | np.ndarray
                 ) -> np.ndarray:
    """Non-dominated points when both coordinates are minimised.

    Point ``i`` is dominated if some ``j`` has ``x_j <= x_i`` and ``y_j <= y_i`` with at
    least one strict inequality. Equal points do not dominate each other. Points with a
    NaN coordinate are neither on the front nor dominate anything.

    Parameters
    ----------
    x, y : array_like, shape (n,)
        Coordinates (e.g. online time and error).

    Returns
    -------
    numpy.ndarray of bool, shape (n,)
        True for the points on the Pareto front. O(n log n).
    """
    x = np.asarray(x, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    if x.shape != y.shape:
        raise ValueError(f"pareto_front: x and y differ in length ({x.size} vs {y.size})")
    on = np.zeros(x.size, dtype=bool)
    ok = np.flatnonzero(~(np.isnan(x) | np.isnan(y)))
    order = ok[np.lexsort((y[ok], x[ok]))]
    best: float | None = None  # smallest y among the points with a strictly smaller x
    i = 0
    while i < order.size:
        j = i
        while j + 1 < order.size and x[order[j + 1]] == x[order[i]]:
            j += 1
        grp = order[i:j + 1]
        ymin = y[grp[0]]
        if best is None or ymin < best:
            on[grp[y[grp] == ymin]] = True
            best = ymin
        i = j + 1
    return on


def status_counts(rows: pd.DataFrame | list[dict[str, Any]]) -> pd.DataFrame:
    """Rows per status and scene.

    Parameters
    ----------
    rows : pandas.DataFrame or list of dict
        Results rows.

    Returns
    -------
    pandas.DataFrame
        Index: scene; columns: the statuses that occur (in :data:`rbbench.bench.schema.STATUSES`
        order) and ``total``.
    """
    recs = _records(rows) if isinstance(rows, pd.DataFrame) else rows
    scenes = _scenes(recs)
    present = [s for s in schema.STATUSES if any(r.get("status") == s for r in recs)]
    data = {s: [sum(1 for r in recs if str(r.get("scene")) == sc and r.get("status") == s)
                for sc in scenes] for s in present}
    df = pd.DataFrame(data, index=pd.Index(scenes, name="scene"), columns=present)
    df["total"] = [sum(1 for r in recs if str(r.get("scene")) == sc) for sc in scenes]
    return df


_BEST_COLUMNS = ("scene", "level", "found", "combination", "dual", "stabilizer", "hyper_used",
                 "case_id", "repetitions", "N", "R", "S", "t_online_median_s", "speedup")


def best_per_level(rows: pd.DataFrame | list[dict[str, Any]], column: str = "err_u_max",
                   levels: Sequence[float] = ERROR_LEVELS) -> pd.DataFrame:
    """The fastest ok case per scene whose error is within each level.

    Repetitions of a case are combined first (error: max over the ok repetitions; online
    time: median); with one repetition a case is its row.

    Parameters
    ----------
    rows : pandas.DataFrame or list of dict
        Results rows (any statuses; only ``ok`` rows count).
    column : str
        The error column (``err_u_max`` or ``err_lam_max``).
    levels : sequence of float
        Error levels.

    Returns
    -------
    pandas.DataFrame
        One row per scene x level: ``scene``, ``level``, ``found`` (bool), ``combination``
        (its label), ``dual``, ``stabilizer``, ``hyper_used``, ``case_id``,
        ``repetitions`` (ok repetitions combined), ``N``, ``R``, ``S``, ``column`` value,
        ``t_online_median_s``, ``speedup`` (``None`` when no case reaches the level).
        Ties on time go to the smaller error.
    """
    recs = _records(rows) if isinstance(rows, pd.DataFrame) else list(rows)
    ok = [r for r in recs if r.get("status") == "ok"]
    combos = _Combos(ok or recs)
    cases = _cases(recs)
    out = []
    for sc in _scenes(recs):
        mine = [c for c in cases if str(c.get("scene")) == sc
                and math.isfinite(_num(c.get(column)))
                and math.isfinite(_num(c.get("t_online_median_s")))]
        for lev in levels:
            cand = [c for c in mine if _num(c[column]) <= lev]
            row: dict[str, Any] = {"scene": sc, "level": float(lev), "found": bool(cand)}
            if cand:
                b = min(cand, key=lambda c: (_num(c["t_online_median_s"]), _num(c[column]),
                                             combos.label(c), str(c.get("case_id"))))
                row.update({"combination": combos.label(b), "dual": b.get("dual"),
                            "stabilizer": b.get("stabilizer"),
                            "hyper_used": b.get("hyper_used"), "case_id": b.get("case_id"),
                            "repetitions": b["n_rep"], "N": b.get("N"), "R": b.get("R"),
                            "S": b.get("S"), column: b[column],
                            "t_online_median_s": b["t_online_median_s"],
                            "speedup": b.get("speedup")})
            else:
                row.update(dict.fromkeys(_BEST_COLUMNS[3:]))
                row[column] = None
            out.append(row)
    cols = [*_BEST_COLUMNS[:-3], column, *_BEST_COLUMNS[-3:]]
    return pd.DataFrame(out, columns=cols, dtype=object)


# ---------------------------------------------------------------------------------------
# figures
# ---------------------------------------------------------------------------------------


class _Skip(Exception):
    """A figure has nothing to show (the message says why)."""


@dataclass
class _Ctx:
    run: RunData
    records: list[dict[str, Any]]
    combos: _Combos  # named by the components that vary among the ok rows (plots)
    combos_all: _Combos  # ... among all rows (tables)
    cases: list[dict[str, Any]]
    scenes: list[str]


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
                               linestyle=st["linestyle"] if line else "none", label=lab)
    return list(seen.values())


def _fig_pareto(ctx: _Ctx):
    from matplotlib.lines import Line2D
    from matplotlib.ticker import NullFormatter

    metrics = ("err_u_max", "err_lam_max")
    pts = [c for c in ctx.cases if _pos(c.get("t_online_median_s"))
           and any(_pos(c.get(m)) for m in metrics)]
    if not pts:
        raise _Skip("no ok case with a positive online time and an error")
    fig, axes = _figure(2, len(ctx.scenes))
    for j, sc in enumerate(ctx.scenes):
        for i, m in enumerate(metrics):
            ax = axes[i, j]
            mine = [c for c in pts if str(c.get("scene")) == sc and _pos(c.get(m))]
            if not mine:
                _empty(ax, f"{sc}: no ok case with {m}")
                continue
            x = np.array([_num(c["t_online_median_s"]) for c in mine])
            y = np.array([_num(c[m]) for c in mine])
            for c, xi, yi in zip(mine, x, y, strict=True):
                st = ctx.combos.style(c)
                ax.plot([xi], [yi], linestyle="none", marker=st["marker"], color=st["color"],
                        markersize=6, alpha=0.9)
            front = pareto_front(x, y)
            o = np.argsort(x[front])
            fx, fy = x[front][o], y[front][o]
            ax.step(np.r_[fx, fx[-1] * 1.5], np.r_[fy, fy[-1]], where="post", color="0.3",
                    linestyle="--", linewidth=1, zorder=0)
            ax.plot(fx, fy, linestyle="none", marker="o", markersize=11, markerfacecolor="none",
                    markeredgecolor="0.3", zorder=0)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.xaxis.set_minor_formatter(NullFormatter())  # minor labels collide
            ax.grid(True, which="major", alpha=0.3)
            ax.set_title(f"{sc}: " + ("displacement u" if i == 0 else "multiplier lam"),
                         fontsize=10)
            ax.set_xlabel(_axis_label("t_online_median_s"), fontsize=8)
            ax.set_ylabel(_axis_label(m), fontsize=8)
    handles = _combo_handles(ctx, pts, line=False)
    handles.append(Line2D([], [], color="0.3", linestyle="--", marker="o", markersize=9,
                          markerfacecolor="none", label="Pareto front\n(non-dominated)"))
    fig.legend(handles=handles, loc="outside right upper", fontsize=8,
               title=ctx.combos.title, title_fontsize=8)
    fig.suptitle("Error against online time, ok cases", fontsize=11)
    caption = ("Each point is one ok case (a combination at one size N, R; repetitions "
               "combined: error max, time median). Top row: "
               f"err_u_max = {_COL['err_u_max'].doc}; bottom row: err_lam_max = "
               f"{_COL['err_lam_max'].doc}; x: t_online_median_s = "
               f"{_COL['t_online_median_s'].doc} (s). Circled and joined by the dashed "
               "staircase: the Pareto front of the scene (no other case is both faster "
               "and more accurate).")
    return fig, caption


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
            for lab in sorted(by):
                cs = by[lab]
                st = ctx.combos.style(cs[0])
                xs = np.array([_size(c, s) for c in cs], dtype=float)
                ys = np.array([_num(c[m]) for c in cs])
                ax.plot(xs, ys, linestyle="none", marker=st["marker"], color=st["color"],
                        markersize=5, alpha=0.55)
                ux = np.unique(xs)
                best = [ys[xs == v].min() for v in ux]
                ax.plot(ux, best, color=st["color"], linestyle=st["linestyle"],
                        marker=st["marker"], markersize=6, label=lab)
                if m == "err_lam_max":  # the cone's floor: no model on that space does better
                    fl = [(x, _num(c.get("lam_best_max"))) for x, c in zip(xs, cs, strict=True)
                          if _pos(c.get("lam_best_max"))]
                    if fl:
                        fx = np.unique([x for x, _ in fl])
                        fy = [min(y for x, y in fl if x == v) for v in fx]
                        ax.plot(fx, fy, color=st["color"], linestyle=":", linewidth=1.2)
            ax.set_yscale("log")
            ax.grid(True, which="major", alpha=0.3)
            ax.xaxis.get_major_locator().set_params(integer=True)
            ax.set_title(sc, fontsize=10)
            ax.set_xlabel(_axis_label(s), fontsize=8)
            ax.set_ylabel(_axis_label(m), fontsize=8)
    fig.legend(handles=_combo_handles(ctx, pts, line=True), loc="outside right upper",
               fontsize=8, title=ctx.combos.title, title_fontsize=8)
    fig.suptitle("Error against RB size (line: best case at each size)", fontsize=11)
    caption = ("Top: err_u_max against the primal size N obtained; bottom: err_lam_max "
               "against the dual size R obtained. Where the other size also varies, every "
               "case is a marker and the line joins the smallest error at each size. Dotted "
               "(bottom): lam_best_max, " + _COL["lam_best_max"].doc + ".")
    return fig, caption


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


def _ok_details(ctx: _Ctx) -> list[tuple[dict[str, Any], dict]]:
    """``(row, details)`` of the ok rows that have case details."""
    out = []
    for r in ctx.records:
        if r.get("status") == "ok":
            det = ctx.run.details.get((str(r.get("case_id")), int(r.get("repetition") or 0)))
            if det:
                out.append((r, det))
    return out


def _fig_infsup(ctx: _Ctx):
    from matplotlib.lines import Line2D

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
    kinds_seen: set[str] = set()
    any_zero = False
    for n, (sc, dual) in enumerate(keys):
        ax = axes[n // ncols, n % ncols]
        group = panels[(sc, dual)]
        size = max(_size_req(r) for r, _ in group)
        group = [(r, d) for r, d in group if _size_req(r) == size]
        rep0 = min(int(r.get("repetition") or 0) for r, _ in group)
        group = [(r, d) for r, d in group if int(r.get("repetition") or 0) == rep0]
        case_labels = {ctx.combos.label(r, without="dual") for r, _ in group}
        curves: dict[tuple, dict[str, Any]] = {}
        for r, det in group:
            mus = det.get("valid_mus")
            for name, rows in _beta_series(det).items():
                vals = tuple(float(f"{_num(e.get('value')):.12g}") for e in rows)
                ck = (name, vals)
                cur = curves.setdefault(ck, {"name": name, "rows": rows, "mus": mus,
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
        plotted = False
        used_styles: dict[str, int] = {}
        for parts in merged.values():
            first = parts[0]
            rows, name = first["rows"], first["name"]
            mu = np.asarray(first["mus"], dtype=float) if first["mus"] is not None else None
            if mu is not None and mu.ndim == 2 and mu.shape[1] == 1 and len(mu) == len(rows):
                x, xlab = mu[:, 0], "validation mu"
            elif mu is not None and mu.ndim == 1 and len(mu) == len(rows):
                x, xlab = mu, "validation mu"
            else:
                x, xlab = np.arange(len(rows), dtype=float), "validation parameter (index)"
                ax.xaxis.get_major_locator().set_params(integer=True)
            o = np.argsort(x, kind="stable")
            v = np.array([_num(e.get("value")) for e in rows])[o]
            kinds = [e.get("kind") for e in rows]
            kk = np.array([str(k) for k in kinds], dtype=object)[o]
            zero = np.array([bool(e.get("is_zero")) for e in rows])[o]
            xs = x[o]
            colour = _BETA_COLOUR.get(name, "tab:gray")
            ls = _LINESTYLES[used_styles.get(colour, 0) % len(_LINESTYLES)]
            used_styles[colour] = used_styles.get(colour, 0) + 1
            joiner = "\n  = " if len({c["vals"] for c in parts}) == 1 else "\n  ≈ "
            label = joiner.join(
                f"beta_{c['name']} ({_BETA_TEXT.get(c['name'], c['name'])})"
                + ("" if c["cases"] == case_labels else f" [{', '.join(sorted(c['cases']))}]")
                for c in parts) + f": {_kind_text(kinds)}"
            good = np.isfinite(v) & (v > 0)
            if good.any():
                plotted = True
                ax.plot(xs[good], v[good], color=colour, linestyle=ls, linewidth=1.2,
                        label=label)
                for kind in sorted(set(kk[good])):
                    sel = good & (kk == kind)
                    mk, filled = _KIND_MARKER.get(kind, ("d", True))
                    kinds_seen.add(kind)
                    ax.plot(xs[sel], v[sel], linestyle="none", marker=mk, markersize=5,
                            color=colour, markerfacecolor=colour if filled else "white")
            if zero.any():
                any_zero = True
                ax.plot(xs[zero], np.zeros(int(zero.sum())), linestyle="none", marker="x",
                        color=colour, markersize=8, clip_on=False,
                        transform=ax.get_xaxis_transform())
            if not good.any():
                ax.plot([], [], color=colour, linestyle=ls, label=label + " (no value > 0)")
        if plotted:
            ax.set_yscale("log")
        else:
            ax.text(0.5, 0.5, "no positive beta value", transform=ax.transAxes, ha="center")
        ax.grid(True, which="major", alpha=0.3)
        ax.set_title(f"{sc} / dual {dual}: N={size[0]}, R={size[1]} (asked)", fontsize=9)
        ax.set_xlabel(xlab, fontsize=8)
        ax.set_ylabel("inf-sup constant beta (X = V inner product)", fontsize=8)
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.2), fontsize=7, frameon=False)
    for n in range(len(keys), nrows * ncols):
        axes[n // ncols, n % ncols].set_visible(False)
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
    fig.suptitle("Inf-sup constants per validation parameter (largest size per dual)",
                 fontsize=11)
    caption = ("Per scene and dual compressor, at the largest (N, R) asked, the inf-sup "
               "constants of every ok case of the first repetition, from the case details: "
               "beta_hf (whole V against the HF cone), beta_dec (V_N), beta_on (V_N + online "
               "supremizers), beta_off (V_N + S_PGA). A curve common to all the cases of a "
               "panel is drawn once, otherwise the cases (stabilizer+hyper) are named; "
               "constants whose values agree to 3 significant digits at every mu are drawn "
               "once, joined by '=' (equal) or '≈' (equal to 3 digits). "
               "x: the validation parameter when it is scalar, else its index. "
               "Markers give the kind of each value as stored: filled circle = exact cone "
               "value, open circle = cone upper estimate (best local minimum), triangle = "
               "span lower bound; x on the axis = the exact LP test found beta = 0. "
               f"Column beta_*_min: {_BETA_DOC}.")
    return fig, caption


_BETA_DOC = _COL["beta_dec_min"].doc.split(";")[0]


def _beta_rank(name: str) -> int:
    return list(_BETA_COLOUR).index(name) if name in _BETA_COLOUR else len(_BETA_COLOUR)


def _pick_history(cases: list[tuple[dict, dict]], name: str):
    """Per dual, the case with the largest (N, R) that has history ``name``."""
    best: dict[str, tuple] = {}
    for r, det in cases:
        h = (det.get("histories") or {}).get(name)
        if not isinstance(h, list) or not h:
            continue
        dual = str(r.get("dual"))
        rank = (_size_req(r), len(h))
        if dual not in best or rank > best[dual][0]:
            best[dual] = (rank, r, det)
    return {d: (r, det) for d, (_, r, det) in best.items()}


_HIST_FLOOR = 1e-12
_HIST_TITLE = {"e_proj": "dual compressor, e_proj", "sigma_max": "PGA, sigma_max",
               "eim_error": "EIM, eim_error"}


def _fig_histories(ctx: _Ctx):
    from matplotlib.lines import Line2D

    hist = [("e_proj", "number of cone generators r",
             "e_proj(r), rel. projection error", 1),
            ("sigma_max", "PGA iteration (vectors added so far)",
             "sigma_max over the training set", 0),
            ("eim_error", "EIM magic rows M", "EIM training error of B(mu) Z", 1)]
    ok = [(r, det) for r, det in _ok_details(ctx) if det.get("histories")]
    found = {name: {sc: _pick_history([p for p in ok if str(p[0].get("scene")) == sc], name)
                    for sc in ctx.scenes} for name, *_ in hist}
    if not any(v for per in found.values() for v in per.values()):
        raise _Skip("no ok case with histories (e_proj, sigma_max, eim_error)")
    scenes = [sc for sc in ctx.scenes if any(found[n][sc] for n, *_ in hist)]
    fig, axes = _figure(len(scenes), 3)
    duals = set()
    delta_drawn = floored = False
    for i, sc in enumerate(scenes):
        for j, (name, xlab, ylab, start) in enumerate(hist):
            ax = axes[i, j]
            picks = found[name][sc]
            if not picks:
                why = {"sigma_max": "no PGA case", "eim_error": "no EIM case"}.get(
                    name, f"no {name} history")
                _empty(ax, f"{sc}: {why}")
                ax.set_title(f"{sc}: {_HIST_TITLE[name]}", fontsize=9)
                continue
            drew = False
            for dual in sorted(picks):
                r, det = picks[dual]
                h = np.array([_num(v) for v in det["histories"][name]])
                x = np.arange(start, start + h.size)
                colour = ctx.combos.dual_colour.get(dual, "k")
                duals.add(dual)
                # relative quantities: values at round-off level (or exactly 0) are drawn
                # on the floor, so they do not stretch the log axis over 15 decades
                tiny = np.isfinite(h) & (h < _HIST_FLOOR)
                good = np.isfinite(h)
                if good.any():
                    drew = True
                    hp = np.where(tiny, _HIST_FLOOR, h)
                    ax.plot(x[good], hp[good], color=colour, marker=".", linewidth=1.3)
                if tiny.any():
                    floored = True
                    ax.plot(x[tiny], np.full(int(tiny.sum()), _HIST_FLOOR), linestyle="none",
                            marker="v", color=colour, markersize=7)
                if name == "sigma_max":
                    d = _num(det["histories"].get("pga_delta"))
                    if math.isfinite(d) and d > 0:
                        ax.axhline(d, color=colour, linestyle=":", linewidth=1)
                        delta_drawn = True
            if drew:
                ax.set_yscale("log")
            ax.xaxis.get_major_locator().set_params(integer=True)
            ax.grid(True, which="major", alpha=0.3)
            ax.set_title(f"{sc}: {_HIST_TITLE[name]}", fontsize=9)
            ax.set_xlabel(xlab, fontsize=8)
            ax.set_ylabel(ylab, fontsize=8)
    handles = [Line2D([], [], color=ctx.combos.dual_colour.get(d, "k"), marker=".", label=d)
               for d in sorted(duals)]
    if delta_drawn:
        handles.append(Line2D([], [], color="0.3", linestyle=":", label="PGA tolerance delta"))
    if floored:
        handles.append(Line2D([], [], color="0.3", linestyle="none", marker="v",
                              label=f"< {_HIST_FLOOR:g} (round-off / 0),\n"
                                    f"drawn at {_HIST_FLOOR:g}"))
    fig.legend(handles=handles, loc="outside right upper", fontsize=8,
               title="dual compressor", title_fontsize=8)
    fig.suptitle("Offline histories (per dual: the ok case with the largest N, R)",
                 fontsize=11)
    caption = ("Per scene and dual compressor, from the ok case with the largest (N, R) "
               "that has the history. Left: e_proj(r), the relative max projection error of "
               "the multiplier snapshots on the cone after r generators. Middle: sigma_max, "
               "the PGA maximum over the training set before each addition (dotted: the "
               "tolerance delta). Right: the EIM training error of the contact rows after "
               f"each magic row (hyper eim). Values below {_HIST_FLOOR:g} (round-off, or 0) "
               f"are drawn at {_HIST_FLOOR:g} with a down-pointing triangle.")
    return fig, caption


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
        labels = sorted({ctx.combos.label(c) for c in mine})
        width = 0.8 / len(sizes)
        vals = [_num(c["speedup"]) for c in mine]
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
    counts = status_counts(ctx.records)
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


_FIGURES = (("pareto", _fig_pareto), ("error_vs_size", _fig_error_vs_size),
            ("infsup", _fig_infsup), ("histories", _fig_histories),
            ("speedup", _fig_speedup), ("status", _fig_status))


# ---------------------------------------------------------------------------------------
# report
# ---------------------------------------------------------------------------------------


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
        The paths written: ``pareto``, ``error_vs_size``, ``infsup``, ``histories``,
        ``speedup``, ``status`` (each in every format, unless skipped for lack of data),
        ``summary.md`` and ``summary.html``.
    """
    fmts = _check_formats(formats)
    run = load_run(run_dir)
    out = Path(out_dir) if out_dir is not None else run.run_dir / "report"
    out.mkdir(parents=True, exist_ok=True)
    records = run.records()
    ok = [r for r in records if r.get("status") == "ok"]
    ctx = _Ctx(run, records, _Combos(ok or records), _Combos(records), _cases(records),
               _scenes(records))
    figures: dict[str, list[Path]] = {}
    captions: dict[str, str] = {}
    skipped: dict[str, str] = {}
    for name, build in _FIGURES:
        try:
            fig, caption = build(ctx)
        except _Skip as exc:
            skipped[name] = str(exc)
            continue
        paths = []
        for f in fmts:
            p = out / f"{name}.{f}"
            fig.savefig(p, dpi=120)
            paths.append(p)
        figures[name] = paths
        captions[name] = caption
    img_fmt = next((f for f in ("png", "svg") if f in fmts), fmts[0])
    md, doc = _summary(ctx, figures, captions, skipped, img_fmt)
    md_path, html_path = out / "summary.md", out / "summary.html"
    md_path.write_text(md, encoding="utf-8")
    html_path.write_text(doc, encoding="utf-8")
    return ReportOutput(out, figures, md_path, html_path, skipped)


_ROW_COLUMNS = ("scene", "backend", "formulation", "solver", "primal", "dual", "stabilizer",
                "hyper_used", "params", "n_hf_dofs", "n_contact", "N", "R", "S", "M_eim",
                "repetition", "status", "err_u_max", "err_lam_max", "lam_best_max",
                "penetration_max", "beta_dec_min", "beta_on_min", "beta_off_min",
                "contact_force", "hf_iterations", "t_hf_median_s", "t_offline_s",
                "t_online_median_s", "speedup", "case_id")
_TITLES = {"pareto": "Error against online time (Pareto fronts)",
           "error_vs_size": "Error against RB size", "infsup": "Inf-sup constants",
           "histories": "Offline histories", "speedup": "Speed-up",
           "status": "Status counts"}


def _md_table(headers: Sequence[Any], rows: Sequence[Sequence[Any]]) -> list[str]:
    """The lines of a Markdown table (``|`` escaped, newlines as spaces in the cells)."""

    def line(cells: Sequence[Any]) -> str:
        return "| " + " | ".join(str(c).replace("|", "\\|").replace("\n", " ")
                                 for c in cells) + " |"

    return [line(headers), "|" + "|".join(" --- " for _ in headers) + "|",
            *(line(r) for r in rows)]


class _Doc:
    """Builds the Markdown and HTML summaries side by side."""

    def __init__(self) -> None:
        self.md: list[str] = []
        self.html: list[str] = []

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
        css = ("body{font-family:sans-serif;max-width:1400px;margin:1em auto;padding:0 1em}"
               "table{border-collapse:collapse;font-size:0.85em;margin:0.5em 0 1em}"
               "th,td{border:1px solid #bbb;padding:2px 6px;text-align:left}"
               "th{background:#eee}img{max-width:100%}p,li{font-size:0.95em}")
        doc = ("<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\">"
               f"<title>{html.escape(title)}</title><style>{css}</style></head><body>\n"
               + "\n".join(self.html) + "\n</body></html>\n")
        return "\n".join(self.md), doc


def _summary(ctx: _Ctx, figures: dict[str, list[Path]], captions: dict[str, str],
             skipped: dict[str, str], img_fmt: str) -> tuple[str, str]:
    run, recs, man = ctx.run, ctx.records, ctx.run.manifest
    used: list[str] = []

    def use(*cols: str) -> None:
        for c in cols:
            if c in _COL and c not in used:
                used.append(c)

    run_id = man.get("run_id") or next((r["run_id"] for r in recs if r.get("run_id")),
                                       run.run_dir.name)
    d = _Doc()
    d.heading(f"rbbench report: {run_id}", 1)
    facts = [f"run directory: {run.run_dir}", f"rows (cases x repetitions): {len(recs)}"]
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

    # status
    d.heading("Status counts")
    counts = status_counts(recs) if recs else None
    if counts is None or counts.empty:
        d.para("The results table has no rows.")
    else:
        d.table(["scene", *counts.columns],
                [[sc, *(str(int(v)) for v in counts.loc[sc])] for sc in counts.index])
    use("status")

    # best per level
    for col in ("err_u_max", "err_lam_max"):
        d.heading(f"Best combination per scene at each error level ({col})")
        bp = best_per_level(recs, col) if recs else pd.DataFrame()
        if bp.empty:
            d.para("No rows.")
            continue
        d.para(f"For each level: the ok case with the smallest t_online_median_s among those "
               f"with {col} <= level.")
        heads = ["scene", f"{col} <=", "combination", "N", "R", "S", _header(col),
                 _header("t_online_median_s"), _header("speedup"), "case_id"]
        rows = []
        for r in _records(bp):
            if r["found"]:
                rows.append([r["scene"], f"{r['level']:g}", r["combination"], _fmt(r["N"]),
                             _fmt(r["R"]), _fmt(r["S"]), _fmt(r[col]),
                             _fmt(r["t_online_median_s"]), _fmt(r["speedup"]),
                             _fmt(r["case_id"])])
            else:
                rows.append([r["scene"], f"{r['level']:g}", "none reaches it", *[""] * 7])
        d.table(heads, rows)
        use(col, "t_online_median_s", "speedup", "N", "R", "S", "case_id")

    # figures
    d.heading("Figures")
    for name, _ in _FIGURES:
        if name in figures:
            d.heading(_TITLES[name], 3)
            src = next((p.name for p in figures[name] if p.suffix == f".{img_fmt}"),
                       figures[name][0].name)
            d.image(src, name)
            d.para(captions[name])
            d.para("Files: " + ", ".join(p.name for p in figures[name]))
        else:
            d.heading(f"{_TITLES[name]} (not drawn)", 3)
            d.para(f"Skipped: {skipped.get(name, 'no data')}.")
    use("err_u_max", "err_lam_max", "t_online_median_s", "N", "R", "speedup",
        "t_hf_median_s", "beta_hf_min", "beta_dec_min", "beta_on_min", "beta_off_min")

    # non-ok rows
    bad = [r for r in recs if r.get("status") != "ok"]
    d.heading(f"Rows not ok ({len(bad)})")
    if bad:
        d.table(["scene", "combination", "N_req", "R_req", "repetition", "status", "reason",
                 "case_id"],
                [[str(r.get("scene")), ctx.combos_all.label(r), _fmt(r.get("N_req")),
                  _fmt(r.get("R_req")), _fmt(r.get("repetition")), str(r.get("status")),
                  r.get("reason") or "(no reason given)", _fmt(r.get("case_id"))]
                 for r in sorted(bad, key=lambda r: (str(r.get("scene")),
                                                     str(r.get("status"))))])
        use("N_req", "R_req", "repetition", "status", "reason", "case_id")
    else:
        d.para("Every row is ok.")

    # all rows
    d.heading(f"All rows ({len(recs)})")
    cols = [c for c in _ROW_COLUMNS
            if c not in _COMBO_IF_VARYING or c in ctx.combos_all.fields]
    shown = []
    rows_sorted = sorted(recs, key=lambda r: (str(r.get("scene")), ctx.combos_all.label(r),
                                              _size_req(r), r.get("repetition") or 0))
    for r in rows_sorted:
        ok = r.get("status") == "ok"
        shown.append({c: (r.get(c) if ok or _COL[c].dtype != "float" else None)
                      for c in cols})
    keep = [c for c in cols if any(s[c] is not None for s in shown)]
    dropped = [c for c in cols if c not in keep]
    if dropped:
        d.para("Columns empty in every row, not shown: " + ", ".join(dropped) + ".")
    kinds = [{c: r.get(c.replace("_min", "_kind")) for c in _BETAS} for r in rows_sorted]
    d.table([_header(c) for c in keep],
            [[_KIND_PREFIX.get(k.get(c) or "", "") + _fmt(s[c]) if c in _BETAS and s[c]
              is not None else _fmt(s[c]) for c in keep] for s, k in zip(shown, kinds,
                                                                           strict=True)])
    use(*keep)
    if any(c in _BETAS for c in keep):
        d.para("beta columns: a value marked '≤' is a cone upper estimate (the true "
               "constant is at most this), '≥' a span lower bound; unmarked: exact cone "
               "value (from the beta_*_kind columns).")

    # column definitions
    d.heading("Columns")
    defs = man.get("columns") if isinstance(man.get("columns"), dict) else {}
    items = []
    for c in [c.name for c in schema.COLUMNS if c.name in used]:
        info = defs.get(c) or {}
        doc = info.get("doc") or _COL[c].doc
        unit = info.get("unit", _COL[c].unit)
        unit_txt = {"": "", "1": " [dimensionless]"}.get(unit, f" [{unit}]")
        items.append(f"{c}{unit_txt}: {doc}")
    items.append(f"combination: {ctx.combos_all.title} in the tables, {ctx.combos.title} "
                 "in the figures (the components that vary, among all rows / the ok rows; "
                 "hyper is hyper_used, or hyper when that is empty)")
    d.bullets(items)
    return d.render(f"rbbench report: {run_id}")


# ---------------------------------------------------------------------------------------
# compare
# ---------------------------------------------------------------------------------------

@dataclass
class CompareResult:
    """Rows of a baseline run A and a new run B, matched on the identity of the case.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per matched case: the :data:`IDENTITY` columns, ``case_id_a/_b``,
        ``status_a/_b``, for each compared quantity ``<col>_a``, ``<col>_b`` and
        ``<col>_rel`` (relative change (B - A) / |A|), and ``regressions`` /
        ``improvements`` (the quantities flagged, comma separated).
    regressions : list of str
        Human-readable regressions (one per quantity and case, and per missing case).
    improvements : list of str
        Human-readable improvements.
    records : list of dict
        The same as structured records: ``kind`` (regression / improvement / new),
        ``case``, ``quantity``, ``a``, ``b``, ``change``.
    notes : list of str
        Cases new in B, other status changes, duplicates, reading notes.
    a_label, b_label : str
        Where A and B came from.
    threshold, time_threshold : float
        The thresholds used.
    """

    table: pd.DataFrame
    regressions: list[str]
    improvements: list[str]
    records: list[dict[str, Any]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    a_label: str = "A"
    b_label: str = "B"
    threshold: float = 0.1
    time_threshold: float = 0.5
    n_a: int = 0
    n_b: int = 0

    @property
    def n_regressions(self) -> int:
        """Number of regressions (the ``rbbench compare`` exit code is 1 when > 0)."""
        return len(self.regressions)


def _rel(a: float, b: float) -> float:
    if a == b:
        return 0.0
    if a == 0:
        return math.copysign(math.inf, b - a)
    return (b - a) / abs(a)


def compare(a: str | Path, b: str | Path, threshold: float = 0.1,
            time_threshold: float = 0.5) -> CompareResult:
    """Compare a new run B with a baseline run A.

    Rows are matched on :data:`IDENTITY` (scene and overrides, components, parameters,
    sizes asked, repetition; not ``run_id`` nor ``case_id``). Flagged as regressions:

    * a case of A missing in B;
    * status ``ok`` in A and not ``ok`` in B;
    * both ok: ``err_u_max`` / ``err_lam_max`` grew by more than ``threshold`` relative
      and by more than 1e-12 absolute (or is no longer reported);
      ``beta_*_min`` dropped by more than ``threshold`` relative (or became 0 by the
      exact test, ``beta_dec_zero_any``); ``t_online_median_s`` / ``t_offline_s`` /
      ``t_hf_median_s`` grew by more than ``time_threshold`` relative.

    The mirror images (non-ok -> ok, errors and times down, beta up by more than the
    thresholds) are listed as improvements.

    Parameters
    ----------
    a, b : str or Path
        Run directories or results files (``.parquet`` / ``.csv``): A the baseline.
    threshold : float
        Relative threshold for errors and inf-sup constants.
    time_threshold : float
        Relative threshold for times.

    Returns
    -------
    CompareResult
    """
    if threshold < 0 or time_threshold < 0:
        raise ValueError("compare: thresholds must be >= 0")
    notes: list[str] = []
    A = _records(load_results(a, notes))
    B = _records(load_results(b, notes))
    everything = A + B
    vary = _varying(everything, ("backend", "formulation", "solver", "primal", "params",
                                 "scene_overrides"))

    def name(r: dict[str, Any]) -> str:
        parts = [str(r.get("scene"))]
        parts += [f"{c}={_compact(r.get(c))}" for c in vary]
        parts.append("+".join(str(r.get(c)) for c in ("dual", "stabilizer", "hyper")))
        parts.append(f"N={_fmt(r.get('N_req'))} R={_fmt(r.get('R_req'))} "
                     f"rep={_fmt(r.get('repetition'))}")
        return " ".join(parts)

    def index(rows: list[dict[str, Any]], which: str) -> dict[tuple[str, ...], dict]:
        out: dict[tuple[str, ...], dict] = {}
        for r in rows:
            k = _key(r, IDENTITY)
            if k in out:
                notes.append(f"{which}: duplicate case {name(r)}; the first row is used")
                continue
            out[k] = r
        return out

    ia, ib = index(A, "A"), index(B, "B")
    records: list[dict[str, Any]] = []
    table_rows = []

    def flag(kind: str, r: dict, quantity: str, va: Any, vb: Any, change: str) -> None:
        records.append({"kind": kind, "case": name(r), "quantity": quantity, "a": va,
                        "b": vb, "change": change})

    for k, ra in ia.items():
        rb = ib.get(k)
        if rb is None:
            flag("regression", ra, "missing in B", ra.get("status"), None,
                 "case not in B")
            continue
        row: dict[str, Any] = {c: ra.get(c) for c in IDENTITY}
        row.update({"case_id_a": ra.get("case_id"), "case_id_b": rb.get("case_id"),
                    "status_a": ra.get("status"), "status_b": rb.get("status")})
        reg: list[str] = []
        imp: list[str] = []
        sa, sb = ra.get("status"), rb.get("status")
        if sa == "ok" and sb != "ok":
            reg.append("status")
            flag("regression", ra, "status", sa, sb, rb.get("reason") or "")
        elif sa != "ok" and sb == "ok":
            imp.append("status")
            flag("improvement", ra, "status", sa, sb, "")
        elif sa != sb:
            notes.append(f"{name(ra)}: status {sa} -> {sb} ({rb.get('reason') or ''})")
        both = sa == "ok" and sb == "ok"
        for cols, up_is_bad, thr in ((_ERRORS, True, threshold), (_BETAS, False, threshold),
                                     (_TIMES, True, time_threshold)):
            for c in cols:
                va, vb = _num(ra.get(c)), _num(rb.get(c))
                rel = _rel(va, vb) if math.isfinite(va) and math.isfinite(vb) else math.nan
                row[f"{c}_a"], row[f"{c}_b"], row[f"{c}_rel"] = ra.get(c), rb.get(c), rel
                if not both:
                    continue
                if math.isfinite(va) and not math.isfinite(vb) and c in _ERRORS + _BETAS:
                    reg.append(c)
                    flag("regression", ra, c, va, None, "no longer reported")
                    continue
                if math.isnan(rel):
                    continue
                floor = _ABS_FLOOR if c in _ERRORS else 0.0
                worse = rel > thr if up_is_bad else rel < -thr
                better = rel < -thr if up_is_bad else rel > thr
                if worse and abs(vb - va) > floor:
                    reg.append(c)
                    flag("regression", ra, c, va, vb, _pct(rel))
                elif better and abs(vb - va) > floor:
                    imp.append(c)
                    flag("improvement", ra, c, va, vb, _pct(rel))
        if both and ra.get("beta_dec_zero_any") is False and rb.get("beta_dec_zero_any"):
            reg.append("beta_dec_zero_any")
            flag("regression", ra, "beta_dec_zero_any", False, True,
                 "beta_dec = 0 at some validation mu")
        row["regressions"] = ", ".join(reg)
        row["improvements"] = ", ".join(imp)
        table_rows.append(row)
    for k, rb in ib.items():
        if k not in ia:
            records.append({"kind": "new", "case": name(rb), "quantity": "new in B",
                            "a": None, "b": rb.get("status"), "change": ""})
            notes.append(f"new in B: {name(rb)} ({rb.get('status')})")
    cols = [*IDENTITY, "case_id_a", "case_id_b", "status_a", "status_b"]
    for c in _ERRORS + _BETAS + _TIMES:
        cols += [f"{c}_a", f"{c}_b", f"{c}_rel"]
    cols += ["regressions", "improvements"]
    table = pd.DataFrame(table_rows, columns=cols, dtype=object)

    def text(rec: dict[str, Any]) -> str:
        q = rec["quantity"]
        if q == "missing in B":
            return f"{rec['case']}: missing in B (status in A: {rec['a']})"
        if q == "status":
            why = f" ({rec['change']})" if rec["change"] else ""
            return f"{rec['case']}: status {rec['a']} -> {rec['b']}{why}"
        if rec["b"] is None:
            return f"{rec['case']}: {q} {_fmt(rec['a'])} -> not reported"
        if q == "beta_dec_zero_any":
            return f"{rec['case']}: {rec['change']} (was not in A)"
        u = _unit(q)
        u = f" {u}" if u else ""
        return f"{rec['case']}: {q} {_fmt(rec['a'])}{u} -> {_fmt(rec['b'])}{u} ({rec['change']})"

    regs = [text(r) for r in records if r["kind"] == "regression"]
    imps = [text(r) for r in records if r["kind"] == "improvement"]
    return CompareResult(table, regs, imps, records, notes, str(a), str(b), threshold,
                         time_threshold, len(A), len(B))


def _pct(rel: float) -> str:
    if math.isinf(rel):
        return "from 0"
    return f"{100 * rel:+.3g} %"


def format_compare(result: CompareResult) -> str:
    """A Markdown report of :func:`compare` for the terminal.

    Parameters
    ----------
    result : CompareResult

    Returns
    -------
    str
        Header (what was compared, thresholds, counts), a table of regressions, one of
        improvements, and the notes (new cases, other status changes).
    """
    r = result
    n_missing = sum(1 for x in r.records if x["quantity"] == "missing in B")
    n_new = sum(1 for x in r.records if x["kind"] == "new")
    lines = [f"A (baseline): {r.a_label} ({r.n_a} rows)",
             f"B (new):      {r.b_label} ({r.n_b} rows)",
             f"matched {len(r.table)}, missing in B {n_missing}, new in B {n_new}; "
             f"thresholds: errors +{100 * r.threshold:g} % (and > {_ABS_FLOOR:g} absolute), "
             f"beta -{100 * r.threshold:g} %, times +{100 * r.time_threshold:g} %",
             ""]

    def table(kind: str, title: str) -> None:
        recs = [x for x in r.records if x["kind"] == kind]
        lines.append(f"## {title} ({len(recs)})")
        lines.append("")
        if not recs:
            lines.append("none")
            lines.append("")
            return
        lines.extend(_md_table(["case", "quantity", "A", "B", "change"],
                               [[x["case"], x["quantity"], _fmt(x["a"]), _fmt(x["b"]),
                                 x["change"]] for x in recs]))
        lines.append("")

    table("regression", "Regressions")
    table("improvement", "Improvements")
    other = [n for n in r.notes if not n.startswith("new in B: ")]
    if n_new or other:
        lines.append("## Notes")
        lines.append("")
        lines += [f"* {n}" for n in r.notes]
        lines.append("")
    lines.append(f"{r.n_regressions} regression(s).")
    return "\n".join(lines)

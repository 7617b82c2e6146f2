"""Shared vocabulary of the report package: the column groups it reads, and how a cell
is turned into a number or a table entry."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from typing import Any

from rbbench.bench import json_text, schema

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
_COMBO_IF_VARYING = ("backend", "formulation", "solver", "primal", "friction_dual", "params")
_COMBO_ORDER = ("backend", "formulation", "solver", "primal", "dual", "friction_dual",
                "stabilizer", "hyper_used", "params")
# how repetitions of one case are combined (plots, best-per-level)
_AGG_MAX = ("err_u_max", "err_u_mean", "err_lam_max", "err_lam_mean", "penetration_max",
            "complementarity_max", "energy_err_max", "err_lam_t_max", "err_lam_t_mean",
            "friction_residual_max", "friction_law_residual_max", "slip_law_residual_max")
_ERRORS = ("err_u_max", "err_lam_max")
_BETAS = ("beta_hf_min", "beta_dec_min", "beta_on_min", "beta_off_min")
_TIMES = ("t_online_median_s", "t_offline_s", "t_hf_median_s")
_ABS_FLOOR = 1e-12  # compare: absolute floor on error growth
_AGG_MIN = _BETAS
_AGG_MEDIAN = ("t_snapshots_s", "t_primal_s", "t_dual_s", "t_stabilizer_s", "t_hyper_s",
               "t_offline_s", "t_snapshots_hf_s", "t_offline_hf_s", "t_online_median_s",
               "t_online_iqr_s", "t_hf_median_s", "speedup", "floor_s", "speedup_floor",
               "t_case_s", "peak_rss_mb")
# short axis labels (the full meaning is the schema doc, quoted in the summary)
_SHORT = {
    "err_u_max": "max relative error of u (X norm)",
    "err_lam_max": "max relative error of lam (W norm)",
    "t_online_median_s": "online solve time, median",
    "speedup": "speed-up t_HF / t_online (timed HF solve)",
    "speedup_floor": "speed-up t_floor / t_online (HF floor)",
    "N": "primal RB size N",
    "R": "dual size R (cone generators)",
}
_MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*", "<", ">", "h", "p")
# ":" (dotted) is left to floors and tolerances (lam_best_max, PGA delta)
_LINESTYLES = ("-", "--", "-.", (0, (5, 1.5, 1, 1.5, 1, 1.5)))


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


def _compact(v: Any) -> str:
    if v is None:
        return "-"
    s = str(v)
    try:
        obj = json_text.loads(s)
    except ValueError:
        return s
    if isinstance(obj, dict):
        return ",".join(f"{k}={obj[k]}" for k in sorted(obj)) or "{}"
    return s


def _param_dict(rec: dict[str, Any]) -> dict[str, Any] | None:
    """A row's ``params`` (JSON) as a dict; ``None`` if it is not a JSON table."""
    try:
        p = json_text.loads(rec.get("params") or "{}")
    except (TypeError, ValueError):
        return None
    return p if isinstance(p, dict) else None


def _varying_params(recs: Sequence[dict[str, Any]],
                    skip: Sequence[str] = ("friction_dual",)) -> list[str] | None:
    """The parameters whose values differ among ``recs`` (absent counts as a value), except
    ``skip`` (shown in a column of their own); ``None`` if a row's params is not a table."""
    params = [_param_dict(r) for r in recs]
    if any(p is None for p in params):
        return None
    keys = sorted({k for p in params for k in p} - set(skip))
    return [k for k in keys
            if len({json.dumps(p.get(k), sort_keys=True) for p in params}) > 1]


def _md_table(headers: Sequence[Any], rows: Sequence[Sequence[Any]]) -> list[str]:
    """The lines of a Markdown table (``|`` escaped, newlines as spaces in the cells)."""

    def line(cells: Sequence[Any]) -> str:
        return "| " + " | ".join(str(c).replace("|", "\\|").replace("\n", " ")
                                 for c in cells) + " |"

    return [line(headers), "|" + "|".join(" --- " for _ in headers) + "|",
            *(line(r) for r in rows)]

"""``rbbench compare``: the rows of a new run B matched with those of a baseline run A on
the identity of the case; regressions and improvements beyond thresholds."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from rbbench.bench.report.analysis import _text, _varying
from rbbench.bench.report.common import (
    _ABS_FLOOR,
    _BETAS,
    _CASE_KEY,
    _ERRORS,
    _TIMES,
    IDENTITY,
    _compact,
    _fmt,
    _md_table,
    _num,
    _unit,
)
from rbbench.bench.results import load_results, records

#: columns named in a case's description when they vary among the rows compared
_NAMED_IF_VARYING = ("backend", "formulation", "solver", "primal", "params", "scene_overrides")


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
        Human-readable regressions (one per quantity and case).
    missing : list of str
        Cases of A that B does not have, listed apart from the regressions (a smaller
        matrix or a selection is not a regression of the code).
    improvements : list of str
        Human-readable improvements.
    records : list of dict
        The same as structured records: ``kind`` (regression / improvement / missing / new),
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
    missing: list[str] = field(default_factory=list)
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

    @property
    def n_missing(self) -> int:
        """Number of cases of A missing in B (not regressions)."""
        return len(self.missing)


def _rel(a: float, b: float) -> float:
    if a == b:
        return 0.0
    if a == 0:
        return math.copysign(math.inf, b - a)
    return (b - a) / abs(a)


def _pct(rel: float) -> str:
    if math.isinf(rel):
        return "from 0"
    return f"{100 * rel:+.3g} %"


def _table_columns() -> list[str]:
    cols = [*IDENTITY, "case_id_a", "case_id_b", "status_a", "status_b"]
    for c in _ERRORS + _BETAS + _TIMES:
        cols += [f"{c}_a", f"{c}_b", f"{c}_rel"]
    return [*cols, "regressions", "improvements"]


def _message(rec: dict[str, Any]) -> str:
    """One flagged record as a line of text."""
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


class _Comparison:
    """The state of one comparison: how cases are named, what was flagged and noted."""

    def __init__(self, rows: list[dict[str, Any]], threshold: float, time_threshold: float,
                 notes: list[str]):
        self.vary = _varying(rows, _NAMED_IF_VARYING)
        # times are judged per case over its repetitions (:meth:`times`), not per row
        self.thresholds = ((_ERRORS, True, threshold), (_BETAS, False, threshold),
                           (_TIMES, True, None))
        self.time_threshold = time_threshold
        self.notes = notes
        self.records: list[dict[str, Any]] = []

    def name(self, r: dict[str, Any]) -> str:
        parts = [str(r.get("scene"))]
        parts += [f"{c}={_compact(r.get(c))}" for c in self.vary]
        parts.append("+".join(str(r.get(c)) for c in ("dual", "stabilizer", "hyper")))
        parts.append(f"N={_fmt(r.get('N_req'))} R={_fmt(r.get('R_req'))} "
                     f"rep={_fmt(r.get('repetition'))}")
        return " ".join(parts)

    def index(self, rows: pd.DataFrame, which: str) -> dict[tuple[str, ...], dict]:
        """Identity -> row (the first of duplicates, the others noted)."""
        keys = pd.DataFrame({c: _text(rows[c]) for c in IDENTITY})
        dup = keys.duplicated().to_numpy()
        out: dict[tuple[str, ...], dict] = {}
        for r, k, d in zip(records(rows), keys.itertuples(index=False, name=None), dup,
                           strict=True):
            if d:
                self.notes.append(f"{which}: duplicate case {self.name(r)}; the first row is "
                                  "used")
            else:
                out[k] = r
        return out

    def flag(self, kind: str, r: dict, quantity: str, va: Any, vb: Any, change: str) -> None:
        self.records.append({"kind": kind, "case": self.name(r), "quantity": quantity,
                             "a": va, "b": vb, "change": change})

    def status(self, ra: dict, rb: dict, reg: list[str], imp: list[str]) -> None:
        sa, sb = ra.get("status"), rb.get("status")
        if sa == "ok" and sb != "ok":
            reg.append("status")
            self.flag("regression", ra, "status", sa, sb, rb.get("reason") or "")
        elif sa != "ok" and sb == "ok":
            imp.append("status")
            self.flag("improvement", ra, "status", sa, sb, "")
        elif sa != sb:
            self.notes.append(f"{self.name(ra)}: status {sa} -> {sb} "
                              f"({rb.get('reason') or ''})")

    def quantity(self, ra: dict, rb: dict, c: str, up_is_bad: bool, thr: float,
                 both: bool, row: dict, flagged: tuple[list[str], list[str]]) -> None:
        """One compared column: its values and change in ``row``; flagged if both ok."""
        reg, imp = flagged
        va, vb = _num(ra.get(c)), _num(rb.get(c))
        rel = _rel(va, vb) if math.isfinite(va) and math.isfinite(vb) else math.nan
        row[f"{c}_a"], row[f"{c}_b"], row[f"{c}_rel"] = ra.get(c), rb.get(c), rel
        if not both or thr is None:
            return
        if math.isfinite(va) and not math.isfinite(vb) and c in _ERRORS + _BETAS:
            reg.append(c)
            self.flag("regression", ra, c, va, None, "no longer reported")
            return
        if math.isnan(rel):
            return
        floor = _ABS_FLOOR if c in _ERRORS else 0.0
        worse = rel > thr if up_is_bad else rel < -thr
        better = rel < -thr if up_is_bad else rel > thr
        if worse and abs(vb - va) > floor:
            reg.append(c)
            self.flag("regression", ra, c, va, vb, _pct(rel))
        elif better and abs(vb - va) > floor:
            imp.append(c)
            self.flag("improvement", ra, c, va, vb, _pct(rel))

    def times(self, rows_a: list[dict], rows_b: list[dict]) -> int:
        """Judge the times of one case from its ok repetitions in A and in B: a regression
        (improvement) when the median grew (fell) by more than the time threshold and the
        ranges of the repetitions do not overlap. With one repetition on a side a time is
        not judged (a single timing on a loaded machine says nothing); returns how many
        such times changed beyond the threshold."""
        unjudged = 0
        for c in _TIMES:
            va = [v for v in (_num(r.get(c)) for r in rows_a) if math.isfinite(v)]
            vb = [v for v in (_num(r.get(c)) for r in rows_b) if math.isfinite(v)]
            if not va or not vb:
                continue
            ma, mb = float(np.median(va)), float(np.median(vb))
            rel = _rel(ma, mb)
            if abs(rel) <= self.time_threshold:
                continue
            if min(len(va), len(vb)) < 2:
                unjudged += 1
                continue
            spread = f"{_pct(rel)}, medians of {len(va)} and {len(vb)} repetitions, " \
                     "ranges disjoint"
            case = {**rows_a[0], "repetition": "all"}
            if rel > 0 and min(vb) > max(va):
                self.flag("regression", case, c, ma, mb, spread)
            elif rel < 0 and max(vb) < min(va):
                self.flag("improvement", case, c, ma, mb, spread)
        return unjudged

    def pair(self, ra: dict, rb: dict) -> dict[str, Any]:
        """The table row of a matched case (its flags recorded on the way)."""
        row: dict[str, Any] = {c: ra.get(c) for c in IDENTITY}
        row.update({"case_id_a": ra.get("case_id"), "case_id_b": rb.get("case_id"),
                    "status_a": ra.get("status"), "status_b": rb.get("status")})
        reg: list[str] = []
        imp: list[str] = []
        self.status(ra, rb, reg, imp)
        both = ra.get("status") == "ok" and rb.get("status") == "ok"
        for cols, up_is_bad, thr in self.thresholds:
            for c in cols:
                self.quantity(ra, rb, c, up_is_bad, thr, both, row, (reg, imp))
        if both and ra.get("beta_dec_zero_any") is False and rb.get("beta_dec_zero_any"):
            reg.append("beta_dec_zero_any")
            self.flag("regression", ra, "beta_dec_zero_any", False, True,
                      "beta_dec = 0 at some validation mu")
        row["regressions"] = ", ".join(reg)
        row["improvements"] = ", ".join(imp)
        return row


def compare(a: str | Path, b: str | Path, threshold: float = 0.1,
            time_threshold: float = 0.5) -> CompareResult:
    """Compare a new run B with a baseline run A.

    Rows are matched on :data:`IDENTITY` (scene and overrides, components, parameters,
    sizes asked, repetition; not ``run_id`` nor ``case_id``). Flagged as regressions:

    * status ``ok`` in A and not ``ok`` in B;
    * both ok: ``err_u_max`` / ``err_lam_max`` grew by more than ``threshold`` relative
      and by more than 1e-12 absolute (or is no longer reported);
      ``beta_*_min`` dropped by more than ``threshold`` relative (or became 0 by the
      exact test, ``beta_dec_zero_any``);
    * per case, over its ok repetitions: the median of ``t_online_median_s`` /
      ``t_offline_s`` / ``t_hf_median_s`` grew by more than ``time_threshold`` relative
      and the ranges of the repetitions do not overlap. A time measured in one repetition
      on a side is not judged (a note counts those beyond the threshold).

    The mirror images (non-ok -> ok, errors down, beta up, times down by the same rules)
    are listed as improvements. Cases of A missing in B are listed apart (``missing``),
    not as regressions.

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
    for name, value in (("threshold", threshold), ("time_threshold", time_threshold)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
            raise ValueError(f"compare: {name} = {value!r}: give a finite number >= 0 (a "
                             "relative change, e.g. 0.1 for 10 %)")
    notes: list[str] = []
    rows_a, rows_b = load_results(a, notes), load_results(b, notes)
    cmp = _Comparison(records(rows_a) + records(rows_b), threshold, time_threshold, notes)
    ia, ib = cmp.index(rows_a, "A"), cmp.index(rows_b, "B")
    table_rows = []
    for k, ra in ia.items():
        rb = ib.get(k)
        if rb is None:
            cmp.flag("missing", ra, "missing in B", ra.get("status"), None,
                     "case not in B")
        else:
            table_rows.append(cmp.pair(ra, rb))
    unjudged = 0
    groups_a, groups_b = _ok_groups(ia.values()), _ok_groups(ib.values())
    for key, rows in groups_a.items():
        if key in groups_b:
            unjudged += cmp.times(rows, groups_b[key])
    if unjudged:
        notes.append(f"{unjudged} time(s) changed by more than +-{100 * time_threshold:g} % "
                     "but were measured in one repetition on a side: not judged (run both "
                     "with repetitions >= 2; a time is flagged when the medians differ "
                     "beyond the threshold and the ranges do not overlap)")
    for k, rb in ib.items():
        if k not in ia:
            cmp.records.append({"kind": "new", "case": cmp.name(rb), "quantity": "new in B",
                                "a": None, "b": rb.get("status"), "change": ""})
            notes.append(f"new in B: {cmp.name(rb)} ({rb.get('status')})")
    table = pd.DataFrame(table_rows, columns=_table_columns(), dtype=object)
    regs = [_message(r) for r in cmp.records if r["kind"] == "regression"]
    imps = [_message(r) for r in cmp.records if r["kind"] == "improvement"]
    missing = [_message(r) for r in cmp.records if r["kind"] == "missing"]
    return CompareResult(table, regs, imps, cmp.records, missing, notes, str(a), str(b),
                         threshold, time_threshold, len(rows_a), len(rows_b))


def _ok_groups(rows) -> dict[tuple[str, ...], list[dict]]:
    """The ok rows by case (the identity without the repetition)."""
    out: dict[tuple[str, ...], list[dict]] = {}
    for r in rows:
        if r.get("status") == "ok":
            out.setdefault(tuple(str(r.get(c)) for c in _CASE_KEY), []).append(r)
    return out


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
    for kind, title in (("regression", "Regressions"), ("improvement", "Improvements"),
                        ("missing", "Missing in B")):
        recs = [x for x in r.records if x["kind"] == kind]
        lines += [f"## {title} ({len(recs)})", ""]
        if not recs:
            lines += ["none", ""]
            continue
        lines.extend(_md_table(["case", "quantity", "A", "B", "change"],
                               [[x["case"], x["quantity"], _fmt(x["a"]), _fmt(x["b"]),
                                 x["change"]] for x in recs]))
        lines.append("")
    other = [n for n in r.notes if not n.startswith("new in B: ")]
    if n_new or other:
        lines += ["## Notes", ""]
        lines += [f"* {n}" for n in r.notes]
        lines.append("")
    lines.append(f"{r.n_regressions} regression(s), {r.n_missing} case(s) missing in B.")
    return "\n".join(lines)

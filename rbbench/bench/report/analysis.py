"""Tables computed from the rows of a run: repetitions combined per case, status counts,
the best case per error level, Pareto fronts, and the names of the combinations."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from rbbench.bench import schema
from rbbench.bench.report.common import (
    _AGG_MAX,
    _AGG_MEDIAN,
    _AGG_MIN,
    _CASE_KEY,
    _COMBO_ALWAYS,
    _COMBO_IF_VARYING,
    _COMBO_ORDER,
    _LINESTYLES,
    _MARKERS,
    ERROR_LEVELS,
    _compact,
    _key,
    _num,
    _param_dict,
    _varying_params,
)
from rbbench.bench.report.loading import RunData
from rbbench.bench.results import plain, records, results_frame

RowsLike = pd.DataFrame | Iterable[dict[str, Any]]


def _text(values: pd.Series, empty: str = "") -> pd.Series:
    """A column as text: ``str`` of each value, ``empty`` for an empty cell."""
    return pd.Series([empty if plain(v) is None else str(plain(v)) for v in values],
                     index=values.index, dtype=object)


def _is_ok(rows: pd.DataFrame) -> pd.Series:
    return rows["status"].eq("ok").fillna(False).astype(bool)


def _varying(records: list[dict[str, Any]], cols: Sequence[str]) -> list[str]:
    return [c for c in cols if len({_key(r, (c,)) for r in records}) > 1]


class _Combos:
    """Names and styles of the combinations of a run (colour by dual compressor, marker
    and line style by the rest of the combination)."""

    def __init__(self, records: list[dict[str, Any]]):
        varying = _varying(records, _COMBO_IF_VARYING)
        # params named by the keys that vary (None: some params is not a table, all shown)
        self.param_keys = _varying_params(records)
        if self.param_keys == []:
            varying = [f for f in varying if f != "params"]
        self.fields = [f for f in _COMBO_ORDER if f in _COMBO_ALWAYS or f in varying]
        duals = sorted({self._part(r, "dual") for r in records})
        rests = sorted({self.label(r, without="dual") for r in records})
        from matplotlib import colormaps

        cmap = colormaps["tab10" if len(duals) <= 10 else "tab20"]
        self.dual_colour = {d: cmap(i % cmap.N) for i, d in enumerate(duals)}
        self.duals = duals
        self.rest_index = {r: i for i, r in enumerate(rests)}

    def dual_rank(self, dual: str) -> int:
        """Index of a dual compressor among the run's (sorted; 0 if unknown)."""
        return self.duals.index(dual) if dual in self.duals else 0

    def _part(self, rec: dict[str, Any], f: str) -> str:
        v = rec.get(f)
        if f == "hyper_used" and v is None:
            v = rec.get("hyper")
        if f == "params":
            p = _param_dict(rec)
            if self.param_keys is None or p is None:
                return _compact(v)
            return ",".join(f"{k}={p.get(k, '-')}" for k in self.param_keys)
        return "-" if v is None else str(v)

    @property
    def title(self) -> str:
        """What a label is made of, e.g. ``dual+stabilizer+hyper``."""
        return "+".join("hyper" if f == "hyper_used" else f for f in self.fields)

    def label(self, rec: dict[str, Any], without: str | None = None) -> str:
        return "+".join(self._part(rec, f) for f in self.fields if f != without)

    def style(self, rec: dict[str, Any]) -> dict[str, Any]:
        """Colour by dual compressor, marker and line style by the rest of the combination;
        every other dual's markers hollow and drawn above the filled ones (``zorder``), so
        two duals with equal numbers both stay visible."""
        i = self.rest_index.get(self.label(rec, without="dual"), 0)
        dual = self._part(rec, "dual")
        k = self.dual_rank(dual)
        colour = self.dual_colour.get(dual, "k")
        hollow = k % 2 == 1
        return {"color": colour, "marker": _MARKERS[i % len(_MARKERS)],
                "linestyle": _LINESTYLES[i % len(_LINESTYLES)],
                "markerfacecolor": "none" if hollow else colour,
                "markeredgewidth": 1.6 if hollow else 1.0,
                "zorder": 3.0 + (0.5 if hollow else 0.0) + 0.01 * k}


def _combined(ordered: pd.DataFrame, group: pd.Series) -> pd.DataFrame:
    """Per group: errors max, betas min, times median over the finite values."""
    parts = []
    for cols, how in ((_AGG_MAX, "max"), (_AGG_MIN, "min"), (_AGG_MEDIAN, "median")):
        vals = ordered[list(cols)].astype("float64")
        vals = vals.where(np.isfinite(vals))
        parts.append(vals.groupby(group).agg(how))
    return pd.concat(parts, axis=1)


def _cases(rows: pd.DataFrame) -> list[dict[str, Any]]:
    """The ok rows combined over repetitions: errors max, betas min, times median.

    One dict per case (the :data:`_CASE_KEY` columns), in the order of first appearance:
    the row of its first repetition with the combined columns, ``n_rep`` and
    ``repetitions``.
    """
    ok = rows[_is_ok(rows)]
    if ok.empty:
        return []
    keys = pd.DataFrame({c: _text(ok[c]) for c in _CASE_KEY})
    group = keys.groupby(list(_CASE_KEY), sort=False).ngroup()
    ordered = ok.assign(_group=group, _rep=ok["repetition"].fillna(0)).sort_values(
        ["_group", "_rep"], kind="stable")
    by = ordered.groupby("_group", sort=True)
    agg = _combined(ordered, ordered["_group"])
    reps = {g: [plain(v) for v in s] for g, s in by["repetition"]}
    out = records(by.head(1)[list(rows.columns)])
    for c, g in zip(out, agg.index, strict=True):
        c.update({col: plain(v) for col, v in agg.loc[g].items()})
        c["n_rep"] = len(reps[g])
        c["repetitions"] = reps[g]
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


def status_counts(rows: RowsLike) -> pd.DataFrame:
    """Rows per status and scene.

    Parameters
    ----------
    rows : pandas.DataFrame or list of dict
        Results rows.

    Returns
    -------
    pandas.DataFrame
        Index: scene; columns: the statuses that occur (in
        :data:`rbbench.bench.schema.STATUSES` order) and ``total``.
    """
    df = results_frame(rows)
    scene = _text(df["scene"], empty="None")
    scenes = sorted(set(scene))
    sizes = df.groupby([scene, df["status"]]).size()  # rows without a status not counted
    seen = set(df["status"].dropna())
    present = [s for s in schema.STATUSES if s in seen]
    data = {s: [int(sizes.get((sc, s), 0)) for sc in scenes] for s in present}
    out = pd.DataFrame(data, index=pd.Index(scenes, name="scene"), columns=present)
    totals = scene.groupby(scene).size()
    out["total"] = [int(totals[sc]) for sc in scenes]
    return out


_BEST_COLUMNS = ("scene", "level", "found", "combination", "dual", "stabilizer", "hyper_used",
                 "case_id", "repetitions", "N", "R", "S", "t_online_median_s", "speedup")


def _case_frame(cases: list[dict[str, Any]], column: str, combos: _Combos) -> pd.DataFrame:
    """Scene, online time ``t``, error ``e``, label and case id of the cases with a finite
    time and error, fastest first (ties: the smaller error, the label, the case id); the
    index is the position in ``cases``."""
    cf = pd.DataFrame({"scene": [str(c.get("scene")) for c in cases],
                       "t": pd.Series([_num(c.get("t_online_median_s")) for c in cases],
                                      dtype=float),
                       "e": pd.Series([_num(c.get(column)) for c in cases], dtype=float),
                       "label": [combos.label(c) for c in cases],
                       "case_id": [str(c.get("case_id")) for c in cases]})
    cf = cf[np.isfinite(cf["t"]) & np.isfinite(cf["e"])]
    return cf.sort_values(["t", "e", "label", "case_id"], kind="stable")


def _fastest(cf: pd.DataFrame, levels: dict[str, Sequence[float]]) -> dict[tuple, int]:
    """``(scene, level) -> index`` of the first case of ``cf`` (the fastest) with
    ``e <= level``, for each scene's levels; absent when no case reaches the level."""
    best = {}
    for sc, levs in levels.items():
        mine = cf[cf["scene"] == sc]
        for lev in levs:
            hit = mine.index[mine["e"].to_numpy() <= lev]
            if len(hit):
                best[(sc, float(lev))] = int(hit[0])
    return best


def _ceil_digits(e: float, digits: int = 3) -> float:
    """``e`` rounded up to ``digits`` significant digits (as the tables print it)."""
    q = 10.0 ** (math.floor(math.log10(e)) - digits + 1)
    lev = float(f"{math.ceil(e / q * (1 - 1e-12)) * q:.{digits}g}")
    return lev if lev >= e else float(f"{lev + q:.{digits}g}")


def _front_levels(cf: pd.DataFrame) -> dict[str, list[float]]:
    """Per scene, error levels that tell its cases apart (loosest first): the errors of the
    Pareto front of (online time, error) rounded up to 3 significant digits (errors equal
    to 3 digits give one level), a level whose fastest case is that of the looser level
    left out; then the power of ten below the smallest error (no case reaches it)."""
    out = {}
    for sc in sorted(set(cf["scene"])):
        mine = cf[(cf["scene"] == sc) & (cf["e"] > 0)]
        if mine.empty:
            continue
        t, e = mine["t"].to_numpy(), mine["e"].to_numpy()
        cand = sorted({_ceil_digits(x) for x in e[pareto_front(t, e)]}, reverse=True)
        found = _fastest(mine, {sc: cand})
        levels = [lev for k, lev in enumerate(cand)
                  if k == 0 or found[(sc, lev)] != found[(sc, cand[k - 1])]]
        below = 10.0 ** math.floor(math.log10(e.min()))
        out[sc] = [*levels, below / 10 if below >= e.min() else below]
    return out


def _best_row(sc: str, lev: float, b: dict[str, Any] | None, column: str,
              combos: _Combos) -> dict[str, Any]:
    """One line of :func:`best_per_level`: the level and its fastest case (or none)."""
    row: dict[str, Any] = {"scene": sc, "level": float(lev), "found": b is not None}
    if b is None:
        row.update(dict.fromkeys(_BEST_COLUMNS[3:]))
        row[column] = None
        return row
    row.update({"combination": combos.label(b), "dual": b.get("dual"),
                "stabilizer": b.get("stabilizer"), "hyper_used": b.get("hyper_used"),
                "case_id": b.get("case_id"), "repetitions": b["n_rep"], "N": b.get("N"),
                "R": b.get("R"), "S": b.get("S"), column: b[column],
                "t_online_median_s": b["t_online_median_s"], "speedup": b.get("speedup")})
    return row


def best_per_level(rows: RowsLike, column: str = "err_u_max",
                   levels: Sequence[float] | str = ERROR_LEVELS) -> pd.DataFrame:
    """The fastest ok case per scene whose error is within each level.

    Repetitions of a case are combined first (error: max over the ok repetitions; online
    time: median); with one repetition a case is its row.

    Parameters
    ----------
    rows : pandas.DataFrame or list of dict
        Results rows (any statuses; only ``ok`` rows count).
    column : str
        The error column (``err_u_max`` or ``err_lam_max``).
    levels : sequence of float, or ``"front"``
        Error levels, the same for every scene; ``"front"``: per scene, levels that tell
        its cases apart (fixed levels can all be met by the fastest case): the errors of
        its Pareto front of (online time, error), each rounded up to 3 significant digits
        (as the tables print them), a level whose fastest case is that of the looser one
        left out, then the power of ten below its smallest error (which no case
        reaches). A scene without a case with an error and a time gets
        :data:`ERROR_LEVELS`.

    Returns
    -------
    pandas.DataFrame
        One row per scene x level (loosest first): ``scene``, ``level``, ``found`` (bool),
        ``combination`` (its label), ``dual``, ``stabilizer``, ``hyper_used``,
        ``case_id``, ``repetitions`` (ok repetitions combined), ``N``, ``R``, ``S``,
        ``column`` value, ``t_online_median_s``, ``speedup`` (``None`` when no case
        reaches the level). Ties on time go to the smaller error.
    """
    if isinstance(levels, str) and levels != "front":
        raise ValueError(f"levels {levels!r}: valid: a sequence of floats, or 'front'")
    df = results_frame(rows)
    recs = records(df)
    ok = [r for r in recs if r.get("status") == "ok"]
    combos = _Combos(ok or recs)
    cases = _cases(df)
    cf = _case_frame(cases, column, combos)
    scenes = _scenes(recs)
    per_scene = _front_levels(cf) if levels == "front" else {}
    per_scene = {sc: per_scene.get(sc) or list(ERROR_LEVELS if levels == "front" else levels)
                 for sc in scenes}
    best = _fastest(cf, per_scene)
    out = [_best_row(sc, lev, cases[best[(sc, float(lev))]] if (sc, float(lev)) in best
                     else None, column, combos)
           for sc in scenes for lev in per_scene[sc]]
    cols = [*_BEST_COLUMNS[:-3], column, *_BEST_COLUMNS[-3:]]
    return pd.DataFrame(out, columns=cols, dtype=object)


@dataclass
class _Ctx:
    """What the figures and the summary are drawn from."""

    run: RunData
    records: list[dict[str, Any]]
    combos: _Combos  # named by the components that vary among the ok rows (plots)
    combos_all: _Combos  # ... among all rows (tables)
    cases: list[dict[str, Any]]
    scenes: list[str]


def _context(run: RunData) -> _Ctx:
    records = run.records()
    ok = [r for r in records if r.get("status") == "ok"]
    return _Ctx(run, records, _Combos(ok or records), _Combos(records), _cases(run.rows),
                _scenes(records))

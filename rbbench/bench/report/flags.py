"""Flags of suspicious cases: an error that grows with the reduced size, or an error far
above its floor.

A reduced model that is stable and consistent gets no worse when its spaces grow, and its
multiplier error stays within a small factor of the best approximation in its dual space
(``lam_best_max``, the W-projection onto the reduced cone). Benaceur et al.'s unstabilised
reductions break both (Hertz, no stabiliser, EIM: err_lam 0.24 -> 0.82 as N goes 6 -> 12,
against a cone floor of 0.017). :func:`case_flags` marks such rows; the report shows them in
a section of the summary page and in a ``flags`` column of its rows table.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from rbbench.bench.report.common import IDENTITY, _num

__all__ = ["FLAG_RULES", "FLOOR_FACTOR", "GROWTH_FACTOR", "NEGLIGIBLE", "case_flags"]

#: an error counts as grown when it exceeds this factor times the smallest error of the same
#: configuration at a smaller N
GROWTH_FACTOR = 1.5
#: an error counts as far above its floor beyond this factor times the floor
FLOOR_FACTOR = 10.0
#: errors at or below this (relative) are never flagged: at that level they are round-off and
#: solver tolerances (an exactly representable case, e.g. a rigid-flat scene, has floors of
#: 1e-14 and online errors of 1e-10), not a defect of the reduction
NEGLIGIBLE = 1e-8
#: (error column, its floor column) pairs of the floor rule
FLOORS = (("err_lam_max", "lam_best_max"), ("err_lam_t_max", "lam_t_best_max"))
#: the error columns of the growth rule
GROWING = ("err_u_max", "err_lam_max", "err_lam_t_max")
#: one configuration: every identity column but the sizes and the repetition
CONFIG_KEY = tuple(c for c in IDENTITY if c not in ("N_req", "R_req", "repetition"))

#: the rules in words (the summary page quotes them)
FLAG_RULES = (
    f"grows with N: over the ok rows of one configuration (same scene, overrides, "
    f"components and parameters; sizes differ), an error column ({', '.join(GROWING)}) at "
    f"a larger N exceeds {GROWTH_FACTOR:g} x the smallest value of that column at a smaller "
    "N (repetitions combined by their max); the row at the larger N is flagged",
    f"above floor: err_lam_max > {FLOOR_FACTOR:g} x lam_best_max (the W-projection of the "
    f"validation multipliers onto the reduced cone: the floor of err_lam on that dual space), "
    f"or err_lam_t_max > {FLOOR_FACTOR:g} x lam_t_best_max (friction)",
    f"neither rule flags an error <= {NEGLIGIBLE:g} (round-off and solver tolerances)",
)


def _finite_pos(v: Any) -> float | None:
    x = _num(v)
    return x if x == x and 0.0 <= x < float("inf") else None


def _key(rec: dict[str, Any], cols: Iterable[str]) -> tuple[str, ...]:
    return tuple("" if rec.get(c) is None else str(rec.get(c)) for c in cols)


def _size(rec: dict[str, Any]) -> float | None:
    n = rec.get("N") if rec.get("N") is not None else rec.get("N_req")
    return None if n is None else float(n)


def _growth(ok: list[dict[str, Any]], out: dict[int, list[str]]) -> None:
    """The growth rule, configuration by configuration (``out``: row index -> flags)."""
    groups: dict[tuple[str, ...], list[int]] = {}
    for i, r in enumerate(ok):
        if _size(r) is not None:
            groups.setdefault(_key(r, CONFIG_KEY), []).append(i)
    for members in groups.values():
        for col in GROWING:
            by_n: dict[float, float] = {}  # N -> max over repetitions
            for i in members:
                v = _finite_pos(ok[i].get(col))
                if v is not None:
                    n = _size(ok[i])
                    by_n[n] = max(v, by_n.get(n, v))
            for i in members:
                v, n = _finite_pos(ok[i].get(col)), _size(ok[i])
                smaller = [(e, m) for m, e in by_n.items() if m < n]
                if v is None or not smaller:
                    continue
                e_min, n_min = min(smaller)
                if v > GROWTH_FACTOR * e_min and v > NEGLIGIBLE:
                    out.setdefault(i, []).append(
                        f"{col} grows with N: {e_min:.3g} (N = {n_min:g}) -> {v:.3g} "
                        f"(N = {n:g})")


def _above_floor(ok: list[dict[str, Any]], out: dict[int, list[str]]) -> None:
    """The floor rule, row by row."""
    for i, r in enumerate(ok):
        for col, floor_col in FLOORS:
            v, floor = _finite_pos(r.get(col)), _finite_pos(r.get(floor_col))
            if v is not None and floor is not None and v > max(FLOOR_FACTOR * floor,
                                                                NEGLIGIBLE):
                ratio = f"{v / floor:.3g} x" if floor > 0 else "its floor is 0"
                out.setdefault(i, []).append(
                    f"{col} far above its floor: {v:.3g} against {floor_col} {floor:.3g} "
                    f"({ratio})")


def case_flags(records: list[dict[str, Any]]) -> list[list[str]]:
    """The flags of every row of ``records`` (one list of sentences per row, empty when
    none applies; rows that are not ok get none), by the rules :data:`FLAG_RULES`."""
    ok_index = [i for i, r in enumerate(records) if r.get("status") == "ok"]
    ok = [records[i] for i in ok_index]
    found: dict[int, list[str]] = {}
    _growth(ok, found)
    _above_floor(ok, found)
    flags: list[list[str]] = [[] for _ in records]
    for j, i in enumerate(ok_index):
        flags[i] = found.get(j, [])
    return flags

"""Compare two recordings of ``tools/regression/record.sh``: the same cases with the same
statuses, and every number that is not a time, a path or a provenance field equal to a
relative tolerance (default 1e-12; ``|a - b| / max(|a|, |b|)``, NaN equal to NaN).

    python -m tools.regression.compare BEFORE AFTER [--rtol 1e-12]

Prints how many numbers were compared, the largest relative difference and where, then
every difference (a key or column present on one side only, a string that changed, a
number beyond the tolerance); exits 1 if there is any.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

#: keys and columns left out: times, speeds, memory, paths, provenance
SKIPPED = re.compile(r"(^|_)(t|time|times|timings|wall|seconds|speedup|floor|s)(_|$)|_s$|^t_|"
                     r"time|provenance|git_sha|machine|versions|rbbench_version|started|"
                     r"finished|peak_rss|rss|memory|duration|path|dir|date|host|pid|"
                     r"blas_threads|^run_id$|cached|online_path|numba|iqr|solve_over|"
                     r"hf_median|speed", re.I)


class Comparison:
    """The running tally: numbers compared, the largest relative difference, differences."""

    def __init__(self, rtol: float) -> None:
        self.rtol = rtol
        self.n = 0
        self.max_rel = 0.0
        self.where = ""
        self.differences: list[str] = []

    def values(self, a: Any, b: Any, where: str) -> None:
        """Compare two JSON-like values recursively."""
        if isinstance(a, dict) and isinstance(b, dict):
            for k in sorted(set(a) | set(b)):
                if SKIPPED.search(str(k)):
                    continue
                if k not in a or k not in b:
                    side = "after" if k in b else "before"
                    self.differences.append(f"{where}.{k}: only in {side}")
                else:
                    self.values(a[k], b[k], f"{where}.{k}")
        elif isinstance(a, list) and isinstance(b, list):
            if len(a) != len(b):
                self.differences.append(f"{where}: length {len(a)} != {len(b)}")
                return
            for i, (x, y) in enumerate(zip(a, b, strict=True)):
                self.values(x, y, f"{where}[{i}]")
        elif _number(a) and _number(b):
            self.number(float(a), float(b), where)
        elif a != b:
            self.differences.append(f"{where}: {a!r} != {b!r}")

    def number(self, a: float, b: float, where: str) -> None:
        if math.isnan(a) and math.isnan(b):
            return
        d, s = abs(a - b), max(abs(a), abs(b))
        r = 0.0 if d == 0 else (d / s if s > 0 else d)
        self.n += 1
        if r > self.max_rel:
            self.max_rel, self.where = r, where
        if r > self.rtol:
            self.differences.append(f"{where}: {a!r} != {b!r} (relative {r:.2e})")


def _number(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def _missing(v: Any) -> bool:
    m = pd.isna(v)
    return bool(m) if isinstance(m, (bool, np.bool_)) else False


def _item(v: Any) -> Any:
    return v.item() if hasattr(v, "item") else v


def compare_runs(before: Path, after: Path, c: Comparison) -> None:
    """The results tables of two runs, row by case id, column by column."""
    tb = pd.read_parquet(before / "results.parquet").set_index("case_id").sort_index()
    ta = pd.read_parquet(after / "results.parquet").set_index("case_id").sort_index()
    if list(tb.index) != list(ta.index):
        c.differences.append(f"{before.name}: case ids differ: {set(tb.index) ^ set(ta.index)}")
    for col in sorted(set(tb.columns) | set(ta.columns)):
        if SKIPPED.search(col):
            continue
        if col not in tb or col not in ta:
            side = "after" if col in ta else "before"
            c.differences.append(f"{before.name}: column {col} only in {side}")
            continue
        for cid in tb.index.intersection(ta.index):
            x, y = tb.at[cid, col], ta.at[cid, col]
            if not (_missing(x) and _missing(y)):
                c.values(_item(x), _item(y), f"{before.name}[{cid}].{col}")


def tracked_values(folder: Path) -> dict[str, Any]:
    """The ``track_*`` values of an asv results folder (timing-like names left out)."""
    out: dict[str, Any] = {}
    for f in folder.rglob("*.json"):
        if f.name in ("machine.json", "benchmarks.json"):
            continue
        for k, v in json.loads(f.read_text()).get("results", {}).items():
            if ".track_" in k and not SKIPPED.search(k.split(".")[-1].replace("track_", "")):
                out[k] = v[0] if isinstance(v, list) else v
    return out


def compare_recordings(before: Path, after: Path, rtol: float = 1e-12) -> Comparison:
    """The four recordings: quick run, friction reduction, shape optimisation, asv values."""
    c = Comparison(rtol)
    compare_runs(before / "quick", after / "quick", c)
    for name in ("friction/result.json", "optimize/summary.json"):
        c.values(json.loads((before / name).read_text()), json.loads((after / name).read_text()),
                 name)
    hb, ha = (pd.read_csv(d / "optimize" / "history.csv") for d in (before, after))
    c.values(hb[[k for k in hb if not SKIPPED.search(k)]].to_dict("list"),
             ha[[k for k in ha if not SKIPPED.search(k)]].to_dict("list"), "optimize/history.csv")
    c.values(tracked_values(before / "asv_results"), tracked_values(after / "asv_results"), "asv")
    return c


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("before", type=Path)
    p.add_argument("after", type=Path)
    p.add_argument("--rtol", type=float, default=1e-12)
    args = p.parse_args(argv)
    c = compare_recordings(args.before, args.after, args.rtol)
    print(f"compared {c.n} numbers; largest relative difference {c.max_rel:.3e}"
          + (f" at {c.where}" if c.where else ""))
    print(f"{len(c.differences)} differences")
    for d in c.differences:
        print("  ", d)
    return 1 if c.differences else 0


if __name__ == "__main__":
    sys.exit(main())

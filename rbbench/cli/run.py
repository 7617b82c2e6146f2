"""``rbbench run`` (a run matrix), ``rbbench report``, ``rbbench compare``."""

from __future__ import annotations

import math
import sys
from pathlib import Path

from rbbench.cli.choices import component_arg
from rbbench.registry import default_registry
from rbbench.runtime import openblas_env as _openblas_env  # noqa: F401  (first: before numpy loads OpenBLAS)
from rbbench.scene.loading import SceneError


def cmd_run(args) -> int:
    from rbbench.bench.matrix import MatrixError, load_matrix
    from rbbench.bench.runner import run_matrix

    reg = default_registry()
    try:
        matrix = load_matrix(args.matrix, selectors=args.select or (), sets=args.set or (),
                             registry=reg)
    except MatrixError as exc:
        raise SceneError(str(exc)) from None
    if args.dry_run:
        _print_cases(matrix)
        return 0
    out = Path(args.out) if args.out else Path("results") / matrix.name
    opts = {"address": args.scheduler} if args.scheduler else {}
    retry = [x for x in (args.retry or "").split(",") if x]
    try:
        summary = run_matrix(matrix, out, executor=args.executor, jobs=args.jobs, registry=reg,
                             retry=retry, csv=args.csv, cache_dir=args.cache_dir,
                             progress=not args.quiet, executor_options=opts)
    except KeyboardInterrupt:
        print(f"interrupted: finished cases are kept in {out}; rerun the same command to "
              "resume", file=sys.stderr)
        return 130
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    _print_run_summary(summary, out)
    return 0


def _print_run_summary(summary, out: Path) -> None:
    """``rbbench run``: cases computed and kept, counts per status, wall time, files."""
    print(f"{len(summary.computed)} computed, {len(summary.kept)} kept from before; "
          + ", ".join(f"{v} {k}" for k, v in sorted(summary.counts.items()))
          + f"; {summary.wall_s:.0f} s")
    print(f"wrote: {out / 'results.parquet'} (report: rbbench report {out})")


def _print_cases(matrix) -> None:
    """``rbbench run --dry-run``: one line per case, then the counts per status."""
    counts: dict[str, int] = {}
    for c in matrix.cases:
        print(f"{c.key}  {c.status:<13} {c.label}" + (f"  ({c.reason})" if c.reason else ""))
        counts[c.status] = counts.get(c.status, 0) + 1
    print(f"{len(matrix.cases)} cases: " + ", ".join(f"{v} {k}" for k, v in counts.items()))


def cmd_report(args) -> int:
    from rbbench.bench.report import report

    res = report(args.run_dir, out_dir=args.out, formats=tuple(args.format))
    print(f"wrote: {res}")
    return 0


def cmd_compare(args) -> int:
    from rbbench.bench.report import compare, format_compare

    for flag, value in (("--threshold", args.threshold),
                        ("--time-threshold", args.time_threshold)):
        if not (math.isfinite(value) and value >= 0):
            print(f"rbbench: error: {flag} {value:g}: give a finite number >= 0 (a relative "
                  "change, e.g. 0.1 for 10 %)", file=sys.stderr)
            return 2
    res = compare(args.a, args.b, threshold=args.threshold, time_threshold=args.time_threshold)
    print(format_compare(res))
    return 1 if res.n_regressions else 0


def _add_run_parsers(sub) -> None:
    r = sub.add_parser("run", help="run a matrix of cases (problems/matrices/*.toml): one "
                                   "results row per case, resumable")
    r.add_argument("matrix", help="matrix file, or a name in problems/matrices/")
    r.add_argument("-s", "--select", action="append", metavar="ROLE=NAME[,NAME]",
                   help="keep only these (globs allowed; roles: scene, backend, formulation, "
                        "solver, primal, dual, stabilizer, hyper, friction_dual, N, R); repeatable")
    r.add_argument("--set", action="append", metavar="FIELD=VALUE",
                   help="override a [reduce] field for every case (repeatable)")
    r.add_argument("--dry-run", action="store_true", help="list the cases and exit")
    component_arg(r, "--executor", "executor", "where the cases run", default="processes")
    r.add_argument("--jobs", type=int, default=None,
                   help="concurrent cases (default: the CPUs)")
    r.add_argument("--scheduler", help="dask scheduler address (executor dask)")
    r.add_argument("--out", help="run directory (default results/<matrix name>)")
    r.add_argument("--retry", help="recompute finished cases with these statuses, e.g. "
                                   "error,timeout")
    r.add_argument("--csv", action="store_true", help="also write results.csv")
    r.add_argument("--cache-dir", default=".rbbench_cache", help="HF snapshot cache")
    r.add_argument("--quiet", action="store_true", help="no progress lines")
    r.set_defaults(func=cmd_run)
    rp = sub.add_parser("report", help="plots and HTML / Markdown tables of a run directory")
    rp.add_argument("run_dir", help="run directory (rbbench run's output)")
    rp.add_argument("--out", help="output directory (default RUN_DIR/report)")
    rp.add_argument("--format", nargs="+", default=["png", "svg"], choices=["png", "svg"],
                    help="figure formats")
    rp.set_defaults(func=cmd_report)
    cp = sub.add_parser("compare", help="compare two runs; exit code 1 on a regression")
    cp.add_argument("a", help="baseline run directory or results.parquet")
    cp.add_argument("b", help="new run directory or results.parquet")
    cp.add_argument("--threshold", type=float, default=0.1,
                    help="relative growth of an error / drop of a beta counted as a regression")
    cp.add_argument("--time-threshold", type=float, default=0.5,
                    help="relative growth of a time counted as a regression")
    cp.set_defaults(func=cmd_compare)

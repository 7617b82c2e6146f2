"""``rbbench.bench.report``: figures and summaries of a run directory, and run comparison.

The run directories are synthetic (layout of ``rbbench run``): rows built with
:func:`rbbench.bench.schema.normalise_row`, numbers chosen so that the answers are known.
"""

from __future__ import annotations

import html
import itertools
import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rbbench.bench import schema
from rbbench.bench.report import (
    IDENTITY,
    best_per_level,
    compare,
    format_compare,
    load_results,
    load_run,
    pareto_front,
    report,
    status_counts,
)

SCENES = ("hertz", "membrane")
DUALS = ("pod", "cpg", "mcpg")
STABS = ("none", "pga")
SIZES = ((4, 3), (8, 6))
VALID_MUS = [[0.55], [0.6], [0.7], [0.8], [0.9]]

# hertz: the fastest row within each level is known (see _numbers)
BEST_U = {("hertz", 1e-1): ("pod", "none", (4, 3)),
          ("hertz", 1e-2): ("cpg", "none", (8, 6)),
          ("hertz", 1e-3): ("mcpg", "pga", (8, 6)),
          ("membrane", 1e-1): ("pod", "none", (4, 3)),
          ("membrane", 1e-2): ("cpg", "none", (8, 6)),
          ("membrane", 1e-3): None}


def _numbers(scene: str, dual: str, stab: str, size: tuple[int, int]) -> tuple[float, float]:
    """(err_u_max, t_online_median_s) of an ok case."""
    special = {("pod", "none", (4, 3)): (5e-2, 1e-5),
               ("cpg", "none", (8, 6)): (5e-3, 1e-4),
               ("mcpg", "pga", (8, 6)): (5e-4 if scene == "hertz" else 2e-3, 5e-4)}
    if (dual, stab, size) in special:
        return special[(dual, stab, size)]
    i = DUALS.index(dual) + 3 * STABS.index(stab) + 6 * SIZES.index(size)
    return 0.2 / (1 + i), 1e-3 * (1 + i)  # slower than every special case, err > 1e-3


def _details(dual: str, stab: str, hyper: str, k: int) -> dict:
    n = len(VALID_MUS)
    beta = {"hf": [{"value": 1e-7 * (1 + 0.1 * j), "kind": "span-lower-bound",
                    "span": 1e-7, "is_zero": False} for j in range(n)],
            "dec": [{"value": (0.0 if dual == "pod" and j == 2 else 3e-7 * (1 + j) / (1 + k)),
                     "kind": "cone-exact" if j % 2 else "cone-upper", "span": 1e-8,
                     "is_zero": dual == "pod" and j == 2} for j in range(n)],
            "on": [{"value": 9e-7 * (1 + 0.05 * j), "kind": "cone-exact", "span": 1e-8,
                    "is_zero": False} for j in range(n)]}
    hist = {"pod_singular_values": [10.0 ** -j for j in range(8)],
            "e_proj": [0.3 / (1 + j) ** (1 + k + DUALS.index(dual)) for j in range(6)]
            + [0.0],
            "e_orth": [0.5] * 7}
    if stab == "pga":
        beta["off"] = [{"value": 9e-7 * (1 - 0.02 * j), "kind": "cone-exact",
                        "span": 1e-8, "is_zero": False} for j in range(n)]
        hist["sigma_max"] = [1.0 / (1 + j + k) ** (1 + DUALS.index(dual) / 4)
                             for j in range(12)]
        hist["pga_delta"] = 0.1
    if hyper == "eim":
        hist["eim_error"] = [0.5 * 0.7 ** j for j in range(15)]
    return {"per_mu": {"err_u": [1e-3] * n, "err_lam": [1e-2] * n,
                       "err_bound_u": [1e-3 * (2 + j) for j in range(n)],
                       "penetration": [0.0] * n, "beta": beta},
            "histories": hist, "valid_mus": VALID_MUS}


def _rows(run_id: str = "run-a") -> list[tuple[dict, dict]]:
    """(row, details) of the synthetic run: 24 ok rows, 3 non-ok rows."""
    out = []
    for n, (scene, dual, stab, size) in enumerate(
            itertools.product(SCENES, DUALS, STABS, SIZES)):
        err, t = _numbers(scene, dual, stab, size)
        hyper = "eim" if stab == "pga" and scene == "membrane" else "affine"
        row = {"run_id": run_id, "case_id": f"c{n:03d}", "repetition": 0, "seed": 1,
               "scene": scene, "scene_overrides": "{}", "backend": "skfem",
               "formulation": "mixed", "solver": "ssn", "primal": "pod", "dual": dual,
               "stabilizer": stab, "hyper": "auto", "hyper_used": hyper, "params": "{}",
               "status": "ok", "N_req": size[0], "R_req": size[1], "N": size[0],
               "R": size[1], "S": 5 if stab == "pga" else 0, "n_valid": len(VALID_MUS),
               "err_u_max": err, "err_u_mean": err / 2, "err_lam_max": 10 * err,
               "beta_hf_min": 1e-7, "beta_hf_kind": "span-lower-bound",
               "beta_dec_min": 2e-7,
               "beta_dec_kind": "cone-upper" if dual == "cpg" else "cone-exact",
               "beta_dec_zero_any": dual == "pod",
               "beta_on_min": 9e-7, "beta_on_kind": "cone-exact",
               "beta_off_min": 8e-7 if stab == "pga" else None,
               "t_offline_s": 30.0 + n, "t_offline_hf_s": 40.0 + n,
               "t_online_median_s": t, "t_hf_median_s": 5.0,
               "speedup": 5.0 / t, "M_eim": 15 if hyper == "eim" else None,
               "err_bound_u_max": 6 * err, "certified": "rigorous"}
        out.append((schema.normalise_row(row), _details(dual, stab, hyper, size[0] // 4)))
    bad = [("error", "ValueError: boom\nsecond line | with a pipe"),
           ("timeout", "killed after 600 s"),
           ("not_installed", "pip install rbbench[petsc]")]
    for n, (status, reason) in enumerate(bad):
        row = {"run_id": run_id, "case_id": f"x{n:03d}", "repetition": 0,
               "scene": SCENES[n % 2], "scene_overrides": "{}", "backend": "skfem",
               "formulation": "mixed", "solver": "petsc-vi" if status == "not_installed"
               else "ssn", "primal": "pod", "dual": "nnmf", "stabilizer": "supremizer",
               "hyper": "auto", "params": "{}", "status": status, "reason": reason,
               "N_req": 4, "R_req": 3,
               # numbers of a non-ok row must never win or be plotted
               "err_u_max": 1e-9, "t_online_median_s": 1e-9}
        out.append((schema.normalise_row(row), {}))
    return out


def write_run(d: Path, rows: list[tuple[dict, dict]], csv: bool = False) -> Path:
    """A run directory in the layout of ``rbbench run``."""
    d.mkdir(parents=True, exist_ok=True)
    (d / "cases").mkdir(exist_ok=True)
    df = pd.DataFrame([r for r, _ in rows], columns=schema.names())
    for c in schema.COLUMNS:  # nullable dtypes, as the runner writes them
        df[c.name] = df[c.name].astype({"float": "float64", "int": "Int64",
                                        "bool": "boolean", "str": "string"}[c.dtype])
    df.to_parquet(d / "results.parquet", index=False)
    if csv:
        df.to_csv(d / "results.csv", index=False)
    manifest = {"run_id": rows[0][0]["run_id"] if rows else d.name, "matrix": {},
                "matrix_file": "quick.toml", "started_at": "2026-11-01T00:00:00Z",
                "columns": schema.column_definitions(), "n_cases": len(rows),
                "provenance": {"git_sha": "abc123"}}
    (d / "manifest.json").write_text(json.dumps(manifest))
    for r, det in rows:
        (d / "cases" / f"{r['case_id']}-r{r['repetition']}.json").write_text(
            json.dumps({"row": r, "details": det}))
    return d


@pytest.fixture(scope="module")
def run_a(tmp_path_factory) -> Path:
    return write_run(tmp_path_factory.mktemp("runs") / "run-a", _rows(), csv=True)


@pytest.fixture(scope="module")
def reported(run_a):
    return report(run_a)


FIGS = ("pareto", "offline", "error_vs_size", "infsup", "histories", "bound", "speedup",
        "status")


def test_report_writes_every_file(run_a, reported):
    assert reported.out_dir == run_a / "report"
    assert not reported.skipped
    for name in FIGS:
        png, svg = run_a / "report" / f"{name}.png", run_a / "report" / f"{name}.svg"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name
        assert b"<svg" in svg.read_bytes()[:2000], name
        assert reported.figures[name] == [png, svg]
    md = reported.summary_md.read_text()
    doc = reported.summary_html.read_text()
    for text in (md, doc):
        for name in FIGS:
            assert f"{name}.png" in text
        assert "killed after 600 s" in text and "pip install rbbench[petsc]" in text
        assert "none reaches it" in text
        assert "t_online_median_s [s]" in text
    err_doc = next(c.doc for c in schema.COLUMNS if c.name == "err_u_max")
    assert err_doc in md and html.escape(err_doc) in doc
    assert doc.startswith("<!DOCTYPE html>") and "<table>" in doc
    # beta kinds are marked in the rows table: cpg's beta_dec is an upper estimate
    assert "≤ 2.00e-07" in md and "≥ 1.00e-07" not in md  # beta_hf is not tabulated
    # the pipe of the error reason is escaped in the Markdown table
    assert "second line \\| with a pipe" in md
    assert all(p.stat().st_size > 0 for p in reported.paths)
    assert "summary.html" in str(reported)


def test_status_counts(run_a):
    c = status_counts(load_results(run_a))
    assert c.loc["hertz", "ok"] == 12 and c.loc["membrane", "ok"] == 12
    assert c.loc["hertz", "error"] == 1 and c.loc["membrane", "timeout"] == 1
    assert c.loc["hertz", "not_installed"] == 1
    assert c["total"].sum() == 27


def test_best_per_level_picks_the_known_rows(run_a):
    bp = best_per_level(load_results(run_a), "err_u_max")
    assert len(bp) == 6
    for r in bp.to_dict("records"):
        want = BEST_U[(r["scene"], r["level"])]
        if want is None:
            assert not r["found"] and r["combination"] is None
            continue
        dual, stab, size = want
        assert r["found"]
        assert (r["dual"], r["stabilizer"]) == (dual, stab)
        assert f"{dual}+{stab}+" in r["combination"]
        assert (r["N"], r["R"]) == size
        assert r["err_u_max"] <= r["level"]
    # err_lam_max = 10 err_u_max: at 1e-2 only the row with err_u 5e-4 (hertz) qualifies
    bl = best_per_level(load_results(run_a), "err_lam_max", levels=(1e-2,))
    got = {r["scene"]: r for r in bl.to_dict("records")}
    assert (got["hertz"]["dual"], got["hertz"]["stabilizer"]) == ("mcpg", "pga")
    assert not got["membrane"]["found"]


def test_best_per_level_combines_repetitions():
    base = {"scene": "s", "dual": "pod", "stabilizer": "none", "hyper_used": "affine",
            "status": "ok", "N_req": 2, "R_req": 2, "N": 2, "R": 2}
    rows = [schema.normalise_row({**base, "repetition": k, "case_id": f"a{k}",
                                  "err_u_max": e, "t_online_median_s": t})
            for k, (e, t) in enumerate([(1e-3, 1.0), (2e-2, 3.0), (1e-3, 2.0)])]
    rows.append(schema.normalise_row({**base, "dual": "cpg", "repetition": 0,
                                      "case_id": "b0", "err_u_max": 5e-2,
                                      "t_online_median_s": 2.5}))
    bp = best_per_level(rows, levels=(1e-1, 1e-2))
    r1, r2 = bp.to_dict("records")
    # pod: error max over repetitions 2e-2, time median 2.0 -> wins at 1e-1, not at 1e-2
    assert r1["dual"] == "pod" and r1["t_online_median_s"] == 2.0
    assert r1["repetitions"] == 3
    assert not r2["found"]


def _brute_front(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    n = len(x)
    out = np.zeros(n, dtype=bool)
    for i in range(n):
        if np.isnan(x[i]) or np.isnan(y[i]):
            continue
        out[i] = not any(
            x[j] <= x[i] and y[j] <= y[i] and (x[j] < x[i] or y[j] < y[i])
            for j in range(n) if j != i and not (np.isnan(x[j]) or np.isnan(y[j])))
    return out


_coord = st.one_of(st.integers(0, 6).map(float), st.floats(0, 10, allow_nan=False),
                   st.just(float("nan")), st.just(float("inf")))


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(_coord, _coord), max_size=25))
def test_pareto_front_matches_brute_force(pts):
    x = np.array([p[0] for p in pts], dtype=float)
    y = np.array([p[1] for p in pts], dtype=float)
    np.testing.assert_array_equal(pareto_front(x, y), _brute_front(x, y))


def test_pareto_front_small_example():
    x = [1.0, 2.0, 3.0, 2.0, 1.0]
    y = [5.0, 2.0, 1.0, 3.0, 5.0]
    assert pareto_front(x, y).tolist() == [True, True, True, False, True]
    assert pareto_front([], []).tolist() == []
    with pytest.raises(ValueError):
        pareto_front([1.0], [1.0, 2.0])


def test_compare_identical_runs_and_new_ids(run_a, tmp_path):
    res = compare(run_a, run_a)
    assert res.n_regressions == 0 and not res.improvements
    assert len(res.table) == 27
    # another run of the same cases: other run_id and case_ids, identical numbers
    rows = []
    for r, det in _rows("run-b"):
        rows.append(({**r, "case_id": "n" + r["case_id"]}, det))
    b = write_run(tmp_path / "run-b", rows)
    res = compare(run_a, b)
    assert res.n_regressions == 0 and not res.improvements
    assert "0 regression(s)" in format_compare(res)
    # a results file instead of a directory (CSV read back with its types)
    res = compare(run_a / "results.csv", b / "results.parquet")
    assert res.n_regressions == 0, res.regressions


def test_compare_flags_injected_regressions(run_a, tmp_path):
    rows = _rows("run-b")
    by_id = {r["case_id"]: i for i, (r, _) in enumerate(rows)}
    r, det = rows[by_id["c000"]]
    rows[by_id["c000"]] = ({**r, "err_u_max": r["err_u_max"] * 1.5}, det)     # error +50 %
    r, _ = rows[by_id["c001"]]
    rows[by_id["c001"]] = (schema.normalise_row(                              # ok -> error
        {**{k: r[k] for k in ("run_id", "case_id", *IDENTITY)},
         "status": "error", "reason": "RuntimeError: injected"}), {})
    r, det = rows[by_id["c002"]]
    rows[by_id["c002"]] = ({**r, "err_u_max": r["err_u_max"] * 0.5,          # improvements
                            "t_online_median_s": r["t_online_median_s"] / 4}, det)
    r, det = rows[by_id["c003"]]
    rows[by_id["c003"]] = ({**r, "err_u_max": r["err_u_max"] * 1.05,         # below threshold
                            "t_online_median_s": r["t_online_median_s"] * 1.4}, det)
    del rows[by_id["c004"]]                                                  # missing in B
    b = write_run(tmp_path / "run-b", rows)
    res = compare(run_a, b)
    assert res.n_regressions == 2, res.regressions
    text = "\n".join(res.regressions)
    assert "err_u_max" in text and "+50 %" in text
    assert "status ok -> error (RuntimeError: injected)" in text
    # a missing case is listed apart, not as a regression
    assert res.n_missing == 1 and "missing in B" in res.missing[0]
    # one repetition per side: the 4x faster online time is not judged, only noted
    assert {x["quantity"] for x in res.records if x["kind"] == "improvement"} == {"err_u_max"}
    assert any("not judged" in n for n in res.notes)
    assert len(res.improvements) == 1
    tab = res.table.set_index("case_id_a")
    assert tab.loc["c000", "regressions"] == "err_u_max"
    assert tab.loc["c000", "err_u_max_rel"] == pytest.approx(0.5)
    assert tab.loc["c002", "t_online_median_s_rel"] == pytest.approx(-0.75)
    out = format_compare(res)
    assert "## Regressions (2)" in out and "## Improvements (1)" in out
    assert "## Missing in B (1)" in out
    assert "2 regression(s), 1 case(s) missing in B." in out
    # the other direction: B as baseline, A new; c004 is new, c001 error -> ok
    back = compare(b, run_a)
    assert any("status error -> ok" in s for s in back.improvements)
    assert any(n.startswith("new in B") for n in back.notes)
    # a drop of beta beyond the threshold is a regression
    rows2 = _rows("run-c")
    r, det = rows2[0]
    rows2[0] = ({**r, "beta_dec_min": r["beta_dec_min"] * 0.5}, det)
    res2 = compare(run_a, write_run(tmp_path / "run-c", rows2))
    assert {x["quantity"] for x in res2.records if x["kind"] == "regression"} == \
        {"beta_dec_min"}


def _repeated(run_id: str, factors: tuple[float, ...]) -> list[tuple[dict, dict]]:
    """The ok rows of the synthetic run, one repetition per factor, every time of the
    first case multiplied by that repetition's factor."""
    out = []
    for rep, f in enumerate(factors):
        for n, (r, det) in enumerate(x for x in _rows(run_id) if x[0]["status"] == "ok"):
            row = {**r, "repetition": rep, "case_id": f"{r['case_id']}-{rep}"}
            if n == 0:
                row.update({c: r[c] * f for c in ("t_online_median_s", "t_offline_s",
                                                  "t_hf_median_s")})
            out.append((row, det))
    return out


def test_compare_judges_times_over_repetitions(tmp_path):
    """Times are flagged when the medians over the repetitions differ beyond the threshold
    and the ranges do not overlap; overlapping ranges are not flagged."""
    a = write_run(tmp_path / "a", _repeated("a", (1.0, 1.1, 0.95)))
    slow = compare(a, write_run(tmp_path / "b", _repeated("b", (3.0, 2.8, 3.2))))
    assert {x["quantity"] for x in slow.records if x["kind"] == "regression"} == \
        {"t_online_median_s", "t_offline_s", "t_hf_median_s"}
    assert "medians of 3 and 3 repetitions" in slow.regressions[0]
    fast = compare(a, write_run(tmp_path / "c", _repeated("c", (0.3, 0.32, 0.29))))
    assert fast.n_regressions == 0
    assert {x["quantity"] for x in fast.records if x["kind"] == "improvement"} == \
        {"t_online_median_s", "t_offline_s", "t_hf_median_s"}
    # a median 2x larger, but one repetition as fast as A's slowest: ranges overlap
    noisy = compare(a, write_run(tmp_path / "d", _repeated("d", (2.0, 2.2, 1.05))))
    assert noisy.n_regressions == 0 and not noisy.improvements


def test_all_none_columns_do_not_crash(tmp_path):
    # only failures: every number None, no details
    fails = [(schema.normalise_row({"run_id": "f", "case_id": f"f{k}", "repetition": 0,
                                    "scene": "hertz", "dual": "cpg", "stabilizer": "none",
                                    "hyper": "auto", "status": s, "reason": f"why {k}"}),
              {}) for k, s in enumerate(("error", "timeout", "skip"))]
    d = write_run(tmp_path / "fails", fails)
    out = report(d, formats=("png",))
    assert set(out.skipped) == {"pareto", "offline", "error_vs_size", "infsup", "histories",
                                "bound", "speedup"}
    assert list(out.figures) == ["status"]
    md = out.summary_md.read_text()
    assert "(not drawn)" in md and "why 2" in md
    assert compare(d, d).n_regressions == 0
    # ok rows without beta, PGA, EIM, timings: plots that need them are skipped
    bare = [(schema.normalise_row({"run_id": "b", "case_id": f"b{k}", "repetition": 0,
                                   "scene": "membrane", "dual": "pod",
                                   "stabilizer": "none", "hyper": "auto", "status": "ok",
                                   "N": 2 + k, "R": 2, "err_u_max": 10.0 ** -k}),
             {"histories": {"e_proj": [0.5, 0.1]}}) for k in range(3)]
    d2 = write_run(tmp_path / "bare", bare)
    out2 = report(d2, tmp_path / "bare-report", formats=("svg",))
    assert {"pareto", "infsup", "speedup"} <= set(out2.skipped)
    assert {"error_vs_size", "histories", "status"} <= set(out2.figures)
    assert (tmp_path / "bare-report" / "summary.html").is_file()


def test_run_without_results_file_reads_case_rows(run_a, tmp_path):
    d = tmp_path / "partial"
    shutil.copytree(run_a / "cases", d / "cases")
    run = load_run(d)
    assert len(run.rows) == 27 and len(run.details) == 24
    assert any("cases/*.json" in n for n in run.notes)
    with pytest.raises(FileNotFoundError):
        load_results(tmp_path / "nothing-here")
    with pytest.raises(ValueError):
        report(run_a, tmp_path / "r", formats=("bogus",))


def test_infsup_figure_plots_beta_over_c_hf_when_recorded(tmp_path):
    """The inf-sup figure plots beta / c_HF(mu) (dimensionless) where the case recorded it,
    not the raw values (about 1e-7 on Hertz, meaningless without the norm of X)."""
    import matplotlib.pyplot as plt

    from rbbench.bench.report.analysis import _context
    from rbbench.bench.report.detail_figures import _fig_infsup
    from rbbench.bench.report.loading import load_run

    row, det = _rows()[0]
    rel = {}
    for name, entries in det["per_mu"]["beta"].items():
        for j, e in enumerate(entries):
            e["value_rel"] = 0.1 + 0.01 * j + 0.001 * len(name)
        rel[name] = sorted(e["value_rel"] for e in entries)
    ctx = _context(load_run(write_run(tmp_path / "run", [(row, det)])))
    fig, _caption = _fig_infsup(ctx)
    ax = fig.axes[0]
    plotted = sorted(sorted(line.get_ydata().tolist()) for line in ax.get_lines()
                     if len(line.get_ydata()) == len(VALID_MUS))
    assert all(sorted(v) in plotted for v in rel.values() if v[0] > 0)
    assert ax.get_ylabel() == "beta / c_HF(mu)"
    plt.close(fig)


@pytest.mark.parametrize("bad", [float("nan"), -1.0, float("inf")])
def test_compare_refuses_bad_thresholds(run_a, bad, capsys):
    from rbbench.cli import main

    with pytest.raises(ValueError, match="give a finite number >= 0"):
        compare(run_a, run_a, threshold=bad)
    assert main(["compare", str(run_a), str(run_a), "--time-threshold", str(bad)]) == 2
    assert "--time-threshold" in capsys.readouterr().err


def test_report_replaces_links_instead_of_writing_through_them(run_a, tmp_path):
    """A file of the report directory that is a link to a file outside is replaced by the
    report's own file; the outside file is untouched."""
    outside = tmp_path / "outside.html"
    outside.write_text("precious")
    out = tmp_path / "rep"
    out.mkdir()
    (out / "summary.html").symlink_to(outside)
    (out / "status.png").symlink_to(outside)
    res = report(run_a, out_dir=out, formats=("png",))
    assert outside.read_text() == "precious"
    assert not (out / "summary.html").is_symlink() and not (out / "status.png").is_symlink()
    assert "<html" in (out / "summary.html").read_text().lower()
    assert (out / "status.png") in res.figures["status"]

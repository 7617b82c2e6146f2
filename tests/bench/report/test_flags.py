"""Flags of the report: an error that grows with N in one configuration, an err_lam far
above its cone floor. Synthetic results tables whose flags are known by construction."""

from __future__ import annotations

from pathlib import Path

from support.run_records import write_run_dir

from rbbench.bench import schema
from rbbench.bench.report import report
from rbbench.bench.report.flags import FLOOR_FACTOR, GROWTH_FACTOR, NEGLIGIBLE, case_flags


def write_run(d: Path, rows: list[dict]) -> Path:
    return write_run_dir(d, [{"row": r, "details": {}} for r in rows])


def _row(case: str, stab: str, n: int, err_u: float, err_lam: float, floor: float,
         rep: int = 0, status: str = "ok") -> dict:
    return schema.normalise_row({
        "run_id": "flags", "case_id": case, "repetition": rep, "seed": 1, "scene": "hertz",
        "scene_overrides": "[]", "backend": "skfem", "formulation": "mixed", "solver": "ssn",
        "primal": "pod", "dual": "mcpg", "stabilizer": stab, "hyper": "eim",
        "hyper_used": "eim", "params": "{}", "status": status, "N_req": n, "R_req": n,
        "N": n, "R": n, "err_u_max": err_u, "err_lam_max": err_lam, "lam_best_max": floor,
        "t_online_median_s": 1e-4, "t_hf_median_s": 1.0, "speedup": 1e4})


def _table() -> list[dict]:
    return [
        # unstable: no stabiliser + EIM, err_lam 0.24 -> 0.82 as N goes 6 -> 12, floor 0.017
        _row("u6", "none", 6, 1e-2, 0.24, 0.017),
        _row("u9", "none", 9, 5e-3, 0.30, 0.015),  # 0.30 < 1.5 x 0.24: not grown
        _row("u12", "none", 12, 2e-3, 0.82, 0.012),
        # stable: errors fall with N, err_lam within 2x its floor
        _row("s6", "pga", 6, 1e-2, 2e-2, 1.5e-2),
        _row("s9", "pga", 9, 4e-3, 1.2e-2, 0.9e-2),
        _row("s12", "pga", 12, 1e-3, 0.8e-2, 0.7e-2),
        # not ok: its numbers are never judged
        _row("x12", "pga", 12, 1.0, 9.0, 1e-3, status="error"),
    ]


def test_the_flags_of_a_known_table():
    flags = case_flags(_table())
    by_case = dict(zip([r["case_id"] for r in _table()], flags, strict=True))
    assert by_case["s6"] == by_case["s9"] == by_case["s12"] == by_case["x12"] == []
    # u6: above its floor only (0.24 > 10 x 0.017), the first N cannot have grown
    assert len(by_case["u6"]) == 1 and "far above its floor" in by_case["u6"][0]
    assert "14.1 x" in by_case["u6"][0]  # 0.24 / 0.017
    # u9: above its floor (0.30 > 0.15), not grown (0.30 < 1.5 x 0.24)
    assert [f.split(":")[0] for f in by_case["u9"]] == ["err_lam_max far above its floor"]
    # u12: grown against the smallest err_lam at a smaller N, and above its floor
    grown = [f for f in by_case["u12"] if "grows with N" in f]
    assert grown == ["err_lam_max grows with N: 0.24 (N = 6) -> 0.82 (N = 12)"]
    assert any("far above its floor" in f for f in by_case["u12"])


def test_thresholds_are_the_documented_ones():
    """Just above and just below each threshold (the rules' factors, not loosened)."""
    g, f = GROWTH_FACTOR, FLOOR_FACTOR
    below = [_row("a", "pga", 4, 1e-2, 1.0, 1.0 / (0.999 * f)),
             _row("b", "pga", 8, 0.999 * g * 1e-2, 1.0, 1.0 / (0.999 * f))]
    above = [_row("a", "pga", 4, 1e-2, 1.0, 1.0 / (1.001 * f)),
             _row("b", "pga", 8, 1.001 * g * 1e-2, 1.0, 1.0 / (1.001 * f))]
    assert case_flags(below) == [[], []]
    fa, fb = case_flags(above)
    assert len(fa) == 1 and len(fb) == 2 and fb[0].startswith("err_u_max grows with N")


def test_errors_at_round_off_are_not_flagged():
    """An exactly representable case (the rigid-flat 3D variant: floor 1e-14, online err_lam
    1e-10): far above its floor and grown in ratio, but at or below NEGLIGIBLE; just above
    NEGLIGIBLE the rules apply again."""
    tiny = [_row("a", "pga", 4, 1e-14, 1.4e-10, 1.25e-14),
            _row("b", "pga", 8, 3e-12, NEGLIGIBLE, 1.25e-14)]
    assert case_flags(tiny) == [[], []]
    above = [_row("a", "pga", 4, 1e-14, 1.4e-10, 1.25e-14),
             _row("b", "pga", 8, 3e-12, 1.001 * NEGLIGIBLE, 1.25e-14)]
    fa, fb = case_flags(above)
    assert fa == [] and len(fb) == 2 and fb[0].startswith("err_lam_max grows with N")


def test_repetitions_are_combined_by_their_max():
    """A smaller N whose worst repetition is already as bad is no growth."""
    rows = [_row("a", "pga", 4, 1e-3, 1e-2, 1e-2, rep=0),
            _row("a", "pga", 4, 1e-2, 1e-2, 1e-2, rep=1),
            _row("b", "pga", 8, 1.2e-2, 1e-2, 1e-2)]
    assert case_flags(rows) == [[], [], []]


def test_configurations_are_judged_apart():
    """A larger error at a larger N of another configuration is no growth."""
    rows = [_row("a", "pga", 4, 1e-3, 1e-2, 1e-2), _row("b", "none", 8, 1e-1, 1e-2, 1e-2)]
    assert case_flags(rows) == [[], []]


def test_the_report_shows_the_flags(tmp_path: Path):
    d = write_run(tmp_path / "flags", _table())
    out = report(d, formats=("png",))
    md, doc = out.summary_md.read_text(), out.summary_html.read_text()
    for text in (md, doc):
        assert "Flagged cases (3)" in text
    assert "err_lam_max grows with N: 0.24 (N = 6) -> 0.82 (N = 12)" in md
    assert "err_lam_max grows with N: 0.24 (N = 6) -&gt; 0.82 (N = 12)" in doc
    # the rows table has a flags column: its header, and u12's cell
    rows_part = md.split("## All rows")[1]
    header = next(line for line in rows_part.splitlines() if line.startswith("|"))
    u12 = next(line for line in rows_part.splitlines() if "| u12 |" in line)
    assert header.rstrip().endswith("| flags |")
    assert u12.rstrip().endswith("0.82 (N = 12); err_lam_max far above its floor: 0.82 "
                                 "against lam_best_max 0.012 (68.3 x) |")
    stable = report(write_run(tmp_path / "stable", _table()[3:6]),
                    formats=("png",))
    assert "Flagged cases (0)" in stable.summary_md.read_text()
    assert "No ok row is flagged." in stable.summary_md.read_text()

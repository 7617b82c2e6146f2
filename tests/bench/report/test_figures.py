"""``rbbench report`` read as a researcher would: the Pareto figure names the sizes
N, R and draws the HF solve time, every dual compressor stays visible where two of them
give the same numbers, the offline cost is drawn, and the best-per-level table tells the
levels apart.

The run directory is synthetic, written by the runner's own writer
(:func:`rbbench.bench.runner.write_table`); the numbers are chosen so that what is drawn
can be checked against them: eng and mcpg give identical errors (the case of the quick
matrix where eng was hidden under mcpg), one case is slower than the HF solve, and the HF
times differ between cases so that their median is not any first row's.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from matplotlib import colormaps
from support.run_records import write_run_dir

from rbbench.bench import schema
from rbbench.bench.execution import _fill
from rbbench.bench.report import best_per_level, load_run, report
from rbbench.bench.report.analysis import _context
from rbbench.bench.report.common import _LINESTYLES
from rbbench.bench.report.cost_figures import _HF_LABEL, _error_norm, _fig_offline, _fig_pareto
from rbbench.bench.report.detail_figures import _fig_histories
from rbbench.bench.report.figures import _FLOOR_LABEL, _fig_error_vs_size
from rbbench.rb.validation import _offline_times

DUALS = ("cpg", "eng", "mcpg")
STABS = ("none", "pga")
SIZES = (6, 12)
T_HF = (1.0, 2.0, 10.0)  # cycled over the cases: the median is 2.0, the mean 4.33
SLOW = "slow"  # the case slower than the HF solve


def _err(dual: str, stab: str, n: int) -> float:
    """err_u_max: eng and mcpg equal (the hidden-marker case), cpg apart."""
    base = (3e-2 if stab == "none" else 1e-2) * (6 / n) ** 2
    return base * (1.7 if dual == "cpg" else 1.0)


def _record(cid: str, dual: str, stab: str, n: int, t_on: float, t_hf: float, **extra) -> dict:
    err = _err(dual, stab, n)
    hyper = "eim" if stab == "pga" else "affine"
    row = {"run_id": "fig", "case_id": cid, "repetition": 0, "seed": 0, "scene": "hertz",
           "scene_overrides": "[]", "backend": "skfem", "formulation": "mixed",
           "solver": "ssn", "primal": "pod", "dual": dual, "stabilizer": stab,
           "hyper": hyper, "hyper_used": hyper, "params": "{}", "status": "ok",
           "N_req": n, "R_req": n, "N": n, "R": n, "S": 0, "n_train": 10,
           "err_u_max": err, "err_lam_max": 10 * err, "lam_best_max": 2 * err,
           "t_online_median_s": t_on, "t_hf_median_s": t_hf, "speedup": t_hf / t_on,
           "t_offline_s": 3.0 + n / 6, "t_snapshots_s": 0.2, **extra}
    e_proj = [0.5 / (1 + j) ** (2 if dual == "cpg" else 3) for j in range(n)]
    det = {"per_mu": {}, "valid_mus": [[0.5], [1.0]],
           "histories": {"e_proj": e_proj, "sigma_max": [1.0, 0.3, 0.05], "pga_delta": 0.1}}
    return {"row": schema.normalise_row(row), "details": det}


def _records() -> list[dict]:
    out = []
    for k, (dual, stab, n) in enumerate(itertools.product(DUALS, STABS, SIZES)):
        t_on = 1e-3 * (1 + 0.05 * k)
        # snapshots from the cache: t_offline_s counts the reads, t_offline_hf_s the solves
        out.append(_record(f"c{k:02d}", dual, stab, n, t_on, T_HF[k % len(T_HF)],
                           t_offline_hf_s=50.0 + k, n_snapshots_cached=13))
    # online supremizers at N = 12: slower than the HF solve (speed-up < 1); a row written
    # before t_offline_hf_s existed (its offline cost is estimated)
    out.append(_record(SLOW, "eng", "supremizer", 12, 5.0, 2.0))
    return out


@pytest.fixture(scope="module")
def ctx(tmp_path_factory):
    return _context(load_run(write_run_dir(tmp_path_factory.mktemp("fig") / "run", _records())))


def _legend_texts(fig) -> list[str]:
    return [t.get_text() for leg in fig.legends for t in leg.get_texts()]


# ------------------------------------------------------------------------ 1. Pareto
def test_pareto_names_the_sizes_and_draws_the_hf_median(ctx):
    fig, caption = _fig_pareto(ctx)
    ax = fig.axes[0]  # hertz, err_u_max
    t_hf = [r["row"]["t_hf_median_s"] for r in _records()]
    hf = [ln for ln in ax.lines if ln.get_label() == _HF_LABEL]
    assert len(hf) == 1
    assert set(hf[0].get_xdata()) == {np.median(t_hf)} == {2.0}  # a vertical line; mean 4.33
    # the case slower than the HF solve is inside the axes and called out
    assert ax.get_xlim()[1] > 5.0
    assert "1 case(s) slower than the HF solve" in ax.get_title()
    assert "Slower than the HF solve: hertz: 1 case(s)." in caption
    # every size in the legend; the marker of a case grows with N, R
    legend = _legend_texts(fig)
    assert {"size N=6, R=6", "size N=12, R=12", _HF_LABEL} <= set(legend)
    sizes = {}
    for r in _records():
        pt = [ln for ln in ax.lines if list(ln.get_xdata()) == [r["row"]["t_online_median_s"]]
              and list(ln.get_ydata()) == [r["row"]["err_u_max"]]]
        assert len(pt) == 1, r["row"]["case_id"]
        sizes.setdefault(r["row"]["N"], set()).add(pt[0].get_markersize())
    assert len(sizes[6]) == len(sizes[12]) == 1 and max(sizes[6]) < min(sizes[12])
    # the Pareto points are labelled with their N, R
    labels = {t.get_text() for t in ax.texts}
    assert "N=12, R=12" in labels


# ------------------------------------------------------- 2. every dual compressor visible
def _named(ax, label: str):
    lines = [ln for ln in ax.lines if ln.get_label() == label]
    assert len(lines) == 1, (label, [ln.get_label() for ln in ax.lines])
    return lines[0]


def test_error_vs_size_keeps_equal_duals_apart(ctx):
    """eng and mcpg have equal errors: their markers sit side by side (offset < 0.5 of a
    size step), eng's hollow and drawn above mcpg's filled ones."""
    fig, caption = _fig_error_vs_size(ctx)
    ax = fig.axes[0]  # err_u_max against N
    eng, mcpg = _named(ax, "eng+none+affine"), _named(ax, "mcpg+none+affine")
    np.testing.assert_array_equal(eng.get_ydata(), mcpg.get_ydata())  # the hidden case
    assert not np.allclose(eng.get_xdata(), mcpg.get_xdata())
    for ln in (eng, mcpg):
        assert np.all(np.abs(np.asarray(ln.get_xdata()) - np.array(SIZES)) < 0.5)
    assert eng.get_markerfacecolor() == "none" and mcpg.get_markerfacecolor() != "none"
    assert eng.get_zorder() > mcpg.get_zorder()
    assert "offset" in caption and "hollow" in caption


def test_floor_lines_have_a_legend_entry_and_a_style_of_their_own(ctx):
    fig, caption = _fig_error_vs_size(ctx)
    ax = fig.axes[1]  # err_lam_max against R
    floors = [ln for ln in ax.lines if ln.get_label() == _FLOOR_LABEL]
    assert len(floors) == len(DUALS) * len(STABS) + 1  # one per combination
    combos = [ln for ln in ax.lines if not ln.get_label().startswith("_")
              and ln.get_label() != _FLOOR_LABEL]
    assert combos and all(ln.get_linestyle() != ":" for ln in combos)
    assert all(ln.get_linestyle() == ":" for ln in floors)
    assert ":" not in _LINESTYLES  # no combination (e.g. pga + eim) is dotted
    # the floor is drawn at lam_best_max, per size, shifted like its dual
    want = {(r["row"]["dual"], r["row"]["stabilizer"], r["row"]["R"]): r["row"]["lam_best_max"]
            for r in _records()}
    for ln in floors:
        for x, y in zip(ln.get_xdata(), ln.get_ydata(), strict=True):
            assert any(abs(x - k[2]) < 0.5 and y == v for k, v in want.items())
    assert _FLOOR_LABEL in _legend_texts(fig)
    assert "lam_best_max" in caption


def test_histories_draw_every_dual_visibly(ctx):
    """Equal e_proj histories of eng and mcpg: each dual its own line style and marker,
    the later ones thinner and above the earlier ones."""
    fig, _ = _fig_histories(ctx)
    ax = fig.axes[0]  # e_proj
    lines = {d: _named(ax, d) for d in DUALS}
    np.testing.assert_array_equal(lines["eng"].get_ydata(), lines["mcpg"].get_ydata())
    assert len({ln.get_linestyle() for ln in lines.values()}) == len(DUALS)
    assert len({ln.get_marker() for ln in lines.values()}) == len(DUALS)
    widths = [lines[d].get_linewidth() for d in DUALS]
    orders = [lines[d].get_zorder() for d in DUALS]
    assert widths == sorted(widths, reverse=True) and len(set(widths)) == len(DUALS)
    assert orders == sorted(orders) and len(set(orders)) == len(DUALS)
    assert set(DUALS) <= set(_legend_texts(fig))


# ------------------------------------------------------------------ 3. offline cost
def test_rows_copy_the_offline_hf_times():
    """A reduction summary's t_offline_hf_s / t_snapshots_hf_s / n_snapshots_cached reach
    the row (the definition t_offline_s - snapshots_s + HF time checked by hand)."""
    timings = {"offline_s": 4.0, "snapshots_s": 0.25, "snapshots_hf_train_s": 13 * 0.655,
               "snapshots_hf_valid_s": 2.0, "snapshots_cached": 20}
    s = {**_offline_times(timings), "timings": timings, "hyper": "eim", "K_pga": 0,
         "R": 6, "config": {"stabilizer": "none"}}
    row: dict = {}
    _fill(row, s)
    assert row["t_offline_s"] == 4.0 and row["t_snapshots_s"] == 0.25
    assert row["t_snapshots_hf_s"] == pytest.approx(8.515)
    assert row["t_offline_hf_s"] == pytest.approx(4.0 - 0.25 + 8.515)
    assert row["n_snapshots_cached"] == 20
    names = schema.names()
    assert {"t_offline_hf_s", "t_snapshots_hf_s", "n_snapshots_cached"} <= set(names)
    assert schema.normalise_row(row)["t_offline_hf_s"] == row["t_offline_hf_s"]


def test_offline_figure_uses_the_hf_snapshot_time(ctx, tmp_path):
    fig, caption = _fig_offline(ctx)
    ax = fig.axes[0]
    recs = {r["row"]["case_id"]: r["row"] for r in _records()}
    pts = [ln for ln in ax.lines if ln.get_linestyle() == "None" and ln.get_marker() != "."]
    dots = [ln for ln in ax.lines if ln.get_marker() == "."]
    assert len(pts) == len(recs)
    at = {(ln.get_xdata()[0], ln.get_ydata()[0]): ln for ln in pts}
    norm = _error_norm(list(recs.values()))
    for cid, r in recs.items():
        want = colormaps["viridis"](norm(r["err_u_max"]))
        if cid == SLOW:  # no t_offline_hf_s: estimated, a black dot inside
            x = r["t_offline_s"] - r["t_snapshots_s"] + r["n_train"] * r["t_hf_median_s"]
            ln = at[next(k for k in at if k[1] == r["t_online_median_s"])]
            assert ln.get_xdata()[0] == pytest.approx(x)
            assert len(dots) == 1 and dots[0].get_xdata()[0] == ln.get_xdata()[0]
        else:
            ln = at[(r["t_offline_hf_s"], r["t_online_median_s"])]  # not t_offline_s
        np.testing.assert_allclose(ln.get_markerfacecolor(), want)
        assert ln.get_markeredgecolor() == ctx.combos.dual_colour[r["dual"]]
    assert norm.vmin == min(r["err_u_max"] for r in recs.values())
    # HF line at the median HF time (horizontal: y is the online time), axes labelled
    hf = [ln for ln in ax.lines if ln.get_label() == _HF_LABEL]
    assert len(hf) == 1 and set(hf[0].get_ydata()) == {2.0}
    assert "t_offline_hf_s" in ax.get_xlabel() and "median" in ax.get_xlabel()
    assert "HF solve time" in ax.get_xlabel() and "primal, dual" in ax.get_xlabel()
    assert "t_online_median_s" in ax.get_ylabel() and "median" in ax.get_ylabel()
    cbar = [a for a in fig.axes if "err_u_max" in a.get_xlabel() + a.get_ylabel()]
    assert cbar and cbar[0].get_xscale() == "log"
    assert "cache" in caption and "estimated" in caption
    out = report(write_run_dir(tmp_path / "run", _records()), formats=("png",))
    assert (tmp_path / "run" / "report" / "offline.png").is_file()
    assert "offline.png" in out.summary_md.read_text()


# ------------------------------------------------------------ 4. best per error level
#: (scene, case, online time, err_u_max): all of "h" under 1e-3, as Hertz in the quick run
TABLE = (("h", "A", 1e-3, 4.0e-4), ("h", "B", 2e-3, 3.5e-4), ("h", "C", 3e-3, 3.5e-4),
         ("h", "D", 0.5, 2.2e-4), ("h", "E", 0.6, 3.0e-4),
         ("m", "G", 1e-4, 0.019), ("m", "H", 2e-4, 0.0104), ("m", "I", 3e-4, 0.05))


def _table_rows(table=TABLE) -> list[dict]:
    return [schema.normalise_row(
        {"scene": sc, "case_id": cid, "repetition": 0, "status": "ok", "dual": cid,
         "stabilizer": "none", "hyper_used": "affine", "N": 6, "R": 6, "N_req": 6,
         "R_req": 6, "err_u_max": e, "t_online_median_s": t}) for sc, cid, t, e in table]


def test_fixed_levels_repeat_the_fastest_case_front_levels_do_not():
    fixed = best_per_level(_table_rows())  # the old table: A at 0.1, 0.01 and 0.001
    assert list(fixed[fixed["scene"] == "h"]["case_id"]) == ["A", "A", "A"]
    bp = best_per_level(_table_rows(), levels="front")
    got = {sc: [(r["level"], r["case_id"]) for r in bp.to_dict("records") if r["scene"] == sc]
           for sc in ("h", "m")}
    # h: the front A, B, D (C equals B but is slower, E is dominated by D); none at 1e-4
    assert got["h"] == [(4.0e-4, "A"), (3.5e-4, "B"), (2.2e-4, "D"), (1e-4, None)]
    assert got["m"] == [(0.019, "G"), (0.0104, "H"), (0.01, None)]
    none = bp[~bp["found"].astype(bool)]
    assert none["combination"].isna().all() and len(none) == 2


def _brute(table, scene: str, level: float) -> str | None:
    ok = [(t, e, c) for sc, c, t, e in table if sc == scene and e <= level]
    return min(ok)[2] if ok else None


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(1e-5, 1.0), st.floats(1e-6, 1.0)), min_size=1,
                max_size=12, unique_by=lambda p: p[0]))
def test_front_levels_each_the_fastest_case_within_it(pts):
    """Every level: the case a brute-force search finds (fastest with err <= level); no two
    consecutive levels give the same case; the levels fall; the last one no case meets."""
    table = [("s", f"c{k}", t, e) for k, (t, e) in enumerate(pts)]
    recs = best_per_level(_table_rows(table), levels="front").to_dict("records")
    levels = [r["level"] for r in recs]
    assert levels == sorted(levels, reverse=True) and len(set(levels)) == len(levels)
    for r in recs:
        assert r["case_id"] == _brute(table, "s", r["level"]), r
        if r["found"]:
            assert r["err_u_max"] <= r["level"] <= r["err_u_max"] * (1 + 1e-2)
    ids = [r["case_id"] for r in recs]
    assert all(a != b for a, b in zip(ids, ids[1:], strict=False))
    assert ids[0] == _brute(table, "s", 1.0) and ids[-1] is None
    assert levels[-1] < min(e for _, e in pts)


def test_best_per_level_rejects_unknown_levels_and_report_states_the_levels(tmp_path):
    with pytest.raises(ValueError, match="'front'"):
        best_per_level(_table_rows(), levels="auto")
    d = tmp_path / "t"
    write_run_dir(d, [{"row": r, "details": {}} for r in _table_rows()])
    md = report(d, formats=("png",)).summary_md.read_text()
    section = md.split("(err_u_max)")[1].split("## ")[0]
    assert "Pareto front" in section and "power of ten below" in section
    for lev, cid in ((0.0004, "A"), (0.00035, "B"), (0.00022, "D")):
        assert f"| h | {lev:g} |" in section and f"| {cid} |" in section
    assert "| h | 0.0001 | none reaches it |" in section

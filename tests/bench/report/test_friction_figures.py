"""``rbbench report`` on runs with reduced friction rows: the GCNS curves,
lam_t HF against RB, the friction table of the summary, and quiet skips without the data.

The run directories are synthetic, written by the runner's own writers
(:func:`rbbench.bench.runner.write_table`, ``cases/<case_id>-r<rep>.json``); the numbers
are chosen so that what is drawn can be checked against them.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from support.run_records import write_run_dir

from rbbench.bench import schema
from rbbench.bench.report import load_run, report
from rbbench.bench.report.analysis import _context
from rbbench.bench.report.document import _attempt, _Doc, _Drawn, _figures_section
from rbbench.bench.report.friction_figures import _fig_gcns, _figs_lam_t, profile_problem
from rbbench.bench.report.plotting import _NotApplicable, _Skip

MUS = [[0.7], [1.0], [1.3]]


def _history(kept: int, n: int) -> list[dict]:
    """A GCNS history falling to ``kept`` then rising; e_nt_rel exactly 0 at ``kept``."""
    e = [3.0 / (1 + q) if q <= kept else 3.0 / (1 + kept) * (1.5 + q - kept)
         for q in range(n)]
    return [{"q": q, "S_q": 2 * q, "e_nt": 10.0 * e[q], "e_nt_rel": 0.0 if q == kept else
             0.5 * e[q], "e_gcns": e[q], "mu_index": q % 3} for q in range(n)]


def _profiles(scale: float) -> dict:
    x = np.linspace(-0.2, 0.2, 9)
    bound = 1e9 * np.maximum(0.0, 1 - (x / 0.2) ** 2)
    hf = -0.8 * bound * np.sign(x)
    return {"mu": MUS, "x": [x.tolist()] * 3, "lam_t_hf": [(hf * (1 + j)).tolist()
                                                            for j in range(3)],
            "lam_t_rb": [(scale * hf * (1 + j)).tolist() for j in range(3)],
            "bound_hf": [(bound * (1 + j)).tolist() for j in range(3)],
            "lam_n_hf": [(5 * bound).tolist()] * 3, "lam_n_rb": [(5 * bound).tolist()] * 3}


def _row(cid: str, dual: str | None, hyper: str, status: str = "ok", **extra) -> dict:
    params = {"S": 20, "n_train": 41} | ({"friction_dual": dual} if dual else {}) | \
        extra.pop("params", {})
    row = {"run_id": "fr", "case_id": cid, "repetition": 0, "seed": 0,
           "scene": "hertz_friction" if dual else "hertz_halfdisks", "scene_overrides": "[]",
           "backend": "skfem", "formulation": "mixed", "solver": "friction-ssn",
           "primal": "pod", "dual": "mcpg", "stabilizer": "pga", "hyper": hyper,
           "params": json.dumps(params, sort_keys=True), "status": status, "N_req": 30,
           "R_req": 20, "friction_dual": dual, "reason": "" if status == "ok" else "refused"}
    if status == "ok":
        row.update(hyper_used=hyper, N=30, R=20, S=40, err_u_max=2.4e-4, err_lam_max=0.06,
                   t_online_median_s=0.3, t_hf_median_s=37.0, speedup=123.0)
    row.update(extra)
    return schema.normalise_row(row)


def _friction(cid: str, dual: str, hyper: str, kept: int | None, err_t: float, **extra):
    row = _row(cid, dual, hyper, err_lam_t_max=err_t, err_lam_t_mean=err_t / 2,
               lam_t_best_max=0.091, friction_residual_max=0.0 if dual == "wedge" else 1.49,
               S_tau=20, S_q=2 * kept if kept is not None else 0,
               gcns_iterations=kept or 0, online_iterations_max=6, dim_v_off=70,
               delta_pga=0.072, **extra)
    det = {"per_mu": {}, "histories": {}, "valid_mus": MUS,
           "gcns_history": _history(kept, kept + 2) if kept is not None else [],
           "lam_t_profiles": _profiles(1.0 + err_t)}
    return row, det


def _records(friction: bool = True) -> list[dict]:
    recs = [{"row": _row("plain", None, "eim"), "details": {"valid_mus": MUS}}]
    if friction:
        recs += [dict(zip(("row", "details"), _friction(*a, **kw), strict=True)) for a, kw in (
            (("seed1", "collocation", "none", 3, 6.35), {"params": {"gcns_patience": 1}}),
            (("seed10", "collocation", "none", 5, 1.0), {"params": {"gcns_patience": 10}}),
            (("wedge", "wedge", "none", None, 0.187), {}),
            (("wedgeeim", "wedge", "eim", None, 0.181), {}))]
        recs.append({"row": _row("seedeim", "collocation", "eim", status="skip"), "details": {}})
    return recs


@pytest.fixture
def run_dir(tmp_path: Path) -> Path:
    return write_run_dir(tmp_path / "fr", _records())


# ------------------------------------------------------------------------------ figures
def test_gcns_figure_draws_each_collocation_history_and_circles_the_kept_q(run_dir):
    """One curve per collocation-model case in each panel (e_GCNS left, e_nt_rel right), values as
    stored (0 drawn at the 1e-12 floor), the kept q circled at its own value."""
    ctx = _context(load_run(run_dir))
    fig, caption = _fig_gcns(ctx)
    recs = {r["row"]["case_id"]: r for r in _records()}
    for ax, key in zip(fig.axes[:2], ("e_gcns", "e_nt_rel"), strict=True):
        assert ax.get_yscale() == "log"
        curves = [ln for ln in ax.lines if ln.get_label() and not ln.get_label().startswith("_")]
        assert len(curves) == 2  # the two collocation cases, not the wedge ones
        circles = [ln for ln in ax.lines if ln.get_marker() == "o"]
        for cid in ("seed1", "seed10"):
            hist = recs[cid]["details"]["gcns_history"]
            kept = recs[cid]["row"]["gcns_iterations"]
            want = [max(e[key], 1e-12) for e in hist]
            assert any(np.array_equal(ln.get_ydata(), want) for ln in curves), (cid, key)
            at = [max(e[key], 1e-12) for e in hist if e["q"] == kept]
            assert any(list(c.get_xdata()) == [kept] and list(c.get_ydata()) == at
                       for c in circles), (cid, key)
    assert "kept" in caption and "1e-12" in caption  # e_nt_rel = 0 was floored


def test_histories_figure_draws_both_friction_models(tmp_path):
    """The offline histories of a friction run: one curve per dual model (mcpg+collocation,
    mcpg+wedge) in each panel, with the values stored: the collocation model's e_proj, the
    wedge model's e_proj_plus (its F lam_n + lam_t cone), both sigma_max and eim_error."""
    from rbbench.bench.report.detail_figures import _fig_histories

    hist = {"collocation": {"e_proj": [0.5, 0.1, 0.02], "sigma_max": [1.0, 0.4, 0.1],
                            "eim_error": [1.0, 1e-2, 1e-5]},
            "wedge": {"e_proj_plus": [0.4, 0.05], "e_proj_minus": [0.3, 0.2],
                      "sigma_max": [1.0, 0.6], "eim_error": [1.0, 1e-3]}}
    recs = []
    for dual, kept in (("collocation", 3), ("wedge", None)):
        row, det = _friction(f"{dual}eim", dual, "eim", kept, 0.2)
        det["histories"] = hist[dual]
        recs.append({"row": row, "details": det})
    fig, caption = _fig_histories(_context(load_run(write_run_dir(tmp_path / "h", recs))))
    want = {"mcpg+collocation": hist["collocation"], "mcpg+wedge": hist["wedge"]}
    for ax, name in zip(fig.axes[:3], ("e_proj", "sigma_max", "eim_error"), strict=True):
        curves = {ln.get_label(): ln for ln in ax.lines if not ln.get_label().startswith("_")}
        assert set(curves) == set(want), (name, set(curves))
        for key, h in want.items():
            stored = h.get(name, h.get("e_proj_plus"))
            np.testing.assert_array_equal(curves[key].get_ydata(), stored)
        styles = {(ln.get_linestyle(), ln.get_marker()) for ln in curves.values()}
        assert len(styles) == 2  # the two models apart
    assert "e_proj_plus" in caption


def test_lam_t_figure_per_case_one_panel_per_mu(run_dir):
    """One figure per ok friction case with profiles; in each panel (one per mu) the HF and
    RB lam_t and the bounds +- F lam_n exactly as stored, against x."""
    ctx = _context(load_run(run_dir))
    figs = _figs_lam_t(ctx)
    assert sorted(n for n, _, _ in figs) == ["lam_t_seed1", "lam_t_seed10", "lam_t_wedge",
                                             "lam_t_wedgeeim"]
    recs = {r["row"]["case_id"]: r for r in _records()}
    for name, fig, caption in figs:
        prof = recs[name.removeprefix("lam_t_")]["details"]["lam_t_profiles"]
        axes = [ax for ax in fig.axes if ax.get_visible()]
        assert len(axes) == 3
        for j, ax in enumerate(axes):
            ys = {ln.get_label(): ln.get_ydata() for ln in ax.lines}
            assert np.array_equal(ys["lam_t HF"], prof["lam_t_hf"][j])
            assert np.array_equal(ys["lam_t RB"], prof["lam_t_rb"][j])
            assert np.array_equal(ys["+- F lam_n (HF)"], prof["bound_hf"][j])
            assert any(np.array_equal(y, -np.asarray(prof["bound_hf"][j])) for y in ys.values())
            assert f"mu = {MUS[j][0]:.3g}" in ax.get_title()
        assert "err_lam_t_max" in caption


def test_report_writes_friction_figures_and_table(tmp_path):
    """The report of a run with friction rows: the figures written (lam_t for the cases
    with profiles only), one table line per friction case, the columns defined."""
    recs = _records()
    for r in recs:
        if r["row"]["case_id"] in ("seed10", "wedge"):
            del r["details"]["lam_t_profiles"]
    out = report(write_run_dir(tmp_path / "fr", recs), formats=("png",))
    for name in ("gcns", "lam_t_seed1", "lam_t_wedgeeim"):
        assert out.figures[name][0].stat().st_size > 0, name
    assert not {"lam_t_seed10", "lam_t_wedge"} & set(out.figures)
    assert "gcns" not in out.skipped and "lam_t" not in out.skipped
    md = out.summary_md.read_text()
    table = md.split("## Reduced friction models")[1].split("\n\n")[1]
    lines = [ln for ln in table.splitlines() if ln.startswith("| ") and "case" not in ln
             and "---" not in ln]
    assert len(lines) == 5  # 4 ok cases + the skip row; the frictionless row is not there
    by = {ln.split(" | ")[0].removeprefix("| "): ln for ln in lines}
    assert set(by) == {"collocation+none gcns_patience=1", "collocation+none gcns_patience=10",
                       "wedge+none", "wedge+eim", "collocation+eim"}
    assert "| 6.35 (0.0910) |" in by["collocation+none gcns_patience=1"]
    assert by["collocation+eim"].rstrip().endswith("| skip |")
    assert "![gcns](gcns.png)" in md and "![lam_t_wedgeeim](lam_t_wedgeeim.png)" in md
    assert "S_tau: friction scenes" in md  # the column definitions


def test_without_friction_data_figures_skip_quietly(tmp_path):
    """A frictionless run: no friction table or figure, none listed as skipped (they do not
    apply); friction rows without the data: the figure not drawn and the summary says why,
    unusable profiles say which."""
    out = report(write_run_dir(tmp_path / "plain", _records(friction=False)), formats=("png",))
    md = out.summary_md.read_text()
    assert "Reduced friction models" not in md and "### GCNS" not in md
    assert "### lam_t" not in md
    assert not {"gcns", "lam_t"} & (set(out.skipped) | set(out.figures))
    recs = [r for r in _records() if r["row"]["friction_dual"] != "collocation"]  # wedge: no GCNS
    ctx = _context(load_run(write_run_dir(tmp_path / "wedge", recs)))
    with pytest.raises(_Skip, match="no ok friction case with a GCNS history") as exc:
        _fig_gcns(ctx)
    assert not isinstance(exc.value, _NotApplicable)
    assert {n for n, _, _ in _figs_lam_t(ctx)} == {"lam_t_wedge", "lam_t_wedgeeim"}
    drawn = _Drawn()
    assert _attempt(drawn, "gcns", _fig_gcns, ctx) is None
    doc = _Doc()
    _figures_section(doc, drawn, "png")
    md = "\n".join(doc.md)
    assert "### GCNS curves (reduced friction) (not drawn)" in md
    assert "Skipped: no ok friction case with a GCNS history" in md
    recs = _records()
    for r in recs:
        if "lam_t_profiles" in r["details"]:
            r["details"]["lam_t_profiles"]["x"][1] = []
    ctx = _context(load_run(write_run_dir(tmp_path / "bad", recs)))
    with pytest.raises(_Skip, match=r"unusable: seed1: profiles of unequal length at mu "
                                    r"\[1.0\]"):
        _figs_lam_t(ctx)
    _fig_gcns(ctx)  # the GCNS histories are still drawn


@pytest.mark.parametrize("bad, why", [
    (None, "not a table"), ({"mu": []}, "no x, lam_t_hf, lam_t_rb, bound_hf"),
    ({"mu": [[1.0]], "x": [], "lam_t_hf": [], "lam_t_rb": [], "bound_hf": []},
     "not one profile per mu"),
    ({"mu": [[1.0]], "x": [[0.0]], "lam_t_hf": [[1.0]], "lam_t_rb": [[1.0, 2.0]],
      "bound_hf": [[1.0]]}, "unequal length"),
])
def test_profile_problem(bad, why):
    assert why in profile_problem(bad)
    assert profile_problem(_profiles(1.0)) is None

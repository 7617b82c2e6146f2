"""Hardening of the HF solve: multiplier supports coarser than the contact zone are
flagged (not "converged" with zero force), and the contact half-width from the pointwise gap
is reported beside the one quantised to multiplier supports."""

from __future__ import annotations

import json

import numpy as np
import pytest

from rbbench.cli import main
from rbbench.hf.geometry.checks import GAP_RTOL, gap_edge_half_width
from rbbench.hf.model import solve_hf
from rbbench.hf.output import write_summary
from rbbench.hf.snapshots.cache import SnapshotError
from rbbench.hf.snapshots.compute import compute_snapshots
from rbbench.scene.loading import load_scene

#: the coarsest mesh: one or two LAC patches over the whole potential zone
COARSEST = ["discretization.h_contact=0.5", "discretization.h_max=1", "discretization.grading=2"]


@pytest.mark.parametrize("patch", [2, 1000])
def test_patches_coarser_than_contact_zone_are_flagged(patch, tmp_path):
    """Mixed LAC on the coarsest mesh: every multiplier 0 while the bodies overlap. Nitsche on
    the same mesh (independent: no multipliers) carries a positive force there, and the
    mixed solution's pointwise penetration is far beyond the tolerance. The solve is
    flagged, with the warning in summary.json."""
    scene = load_scene("hertz_halfdisks", [*COARSEST, f"discretization.lac_patch={patch}"])
    nit = solve_hf(scene, formulation="nitsche")
    assert nit.result.converged and nit.metrics["contact_force"] > 1e9  # measured 3.37e9
    sol = solve_hf(scene)
    m = sol.metrics
    assert m["n_active"] == 0 and m["contact_force"] == 0.0
    assert m["penetration_pointwise_max"] > 100 * m["contact_half_width_gap_tol"]
    assert m["stop_reason"] == sol.result.stop_reason == "flagged" and not m["converged"]
    assert m["solver_stop_reason"] == "converged" and m["flagged"]
    assert len(m["warnings"]) == 1 and f"lac_patch = {patch}" in m["warnings"][0]
    assert "flagged" in m["definitions"]["stop_reason"]
    saved = json.loads(write_summary(sol, tmp_path).read_text())
    assert saved["stop_reason"] == "flagged" and saved["warnings"] == m["warnings"]


def test_flagged_solve_cli_and_snapshots(tmp_path, capsys):
    """``rbbench solve`` prints the warning and exits 1; the snapshot cache refuses the
    flagged solve as a training snapshot (SnapshotError naming 'flagged')."""
    sets = [x for s in COARSEST for x in ("--set", s)]
    assert main(["solve", "hertz_halfdisks", *sets, "--out", str(tmp_path / "s"),
                 "--no-plot", "--quiet"]) == 1
    out = capsys.readouterr().out
    assert "stop_reason                flagged" in out and "WARNING: every multiplier is 0" in out
    scene = load_scene("hertz_halfdisks", COARSEST)
    with pytest.raises(SnapshotError, match="flagged"):
        compute_snapshots(scene, [1.0], cache_dir=tmp_path / "cache", n_jobs=1,
                          progress=False)


def test_resolved_solves_are_not_flagged():
    """The membrane (nodal multipliers) and a Hertz mesh that resolves the zone: no warning,
    converged."""
    for name, sets in (("membrane_obstacle", ["discretization.n_cells=8"]),
                       ("hertz_halfdisks", ["discretization.h_contact=0.05"])):
        m = solve_hf(load_scene(name, sets)).metrics
        assert m["stop_reason"] == "converged" and m["warnings"] == [], name
        assert m["n_active"] > 0


def test_gap_edge_exact_on_piecewise_linear_gap():
    """g = k (|x| - a)_+ (+ noise below tol inside) at uneven points with nodes at the kinks
    +-a: g is linear between nodes, so the interpolated crossing of tol is exactly
    a + tol / k on both sides; closed end points are their own edge; nothing closed: 0."""
    rng = np.random.default_rng(0)
    a, k, tol = 0.3, 2.0, 1e-3
    x = rng.permutation(np.r_[rng.uniform(-1.0, 1.0, 60), -a, a])  # unsorted on purpose
    inside = np.abs(x) < a
    g = k * np.clip(np.abs(x) - a, 0.0, None) + 0.5 * tol * rng.uniform(-1, 1, x.size) * inside
    assert gap_edge_half_width(x, g, tol) == pytest.approx(a + tol / k, abs=1e-12)
    assert gap_edge_half_width(x, np.zeros_like(x), tol) == pytest.approx(
        0.5 * (x.max() - x.min()))
    assert gap_edge_half_width(x, np.ones_like(x), tol) == 0.0


def test_gap_edge_against_hertz_and_labelled():
    """Hertz half-disks (h_contact 0.02, d = 0.05): the pointwise edge is within 5 % of
    2D Hertz (measured -2.44 %) and within one multiplier support of the quantised
    half-width; the tolerance is GAP_RTOL max |Un u|; definitions say 'quantised'."""
    sol = solve_hf(load_scene("hertz_halfdisks", ["discretization.h_contact=0.02"]))
    m, c = sol.metrics, sol.disc.contact
    un = np.asarray(c.Un @ sol.result.u).ravel()
    assert m["contact_half_width_gap_tol"] == pytest.approx(GAP_RTOL * np.abs(un).max())
    a = m["hertz"]["a"]
    assert abs(m["contact_half_width_gap"] / a - 1) < 0.05
    assert m["hertz"]["a_gap_rel_error"] == pytest.approx(m["contact_half_width_gap"] / a - 1)
    support = float(np.max(np.diff(c.mult_extent, axis=1)))
    assert abs(m["contact_half_width_gap"] - m["contact_half_width"]) <= support
    assert "QUANTISED" in m["definitions"]["contact_half_width"]
    assert "interpolated" in m["definitions"]["contact_half_width_gap"]

"""The friction case ``hertz_friction`` of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order
reduction methods: parametric variational inequalities" (talk), and the friction outputs of
``rbbench solve`` and of HF-mode rows.

Coarse meshes (P1, h_contact = 0.02): about 9k dofs and 130 friction nodes, a few seconds.
"""

from __future__ import annotations

import numpy as np
import pytest

from rbbench.hf.model import solve_hf
from rbbench.scene.loading import load_scene

COARSE = ["discretization.h_contact=0.02", "discretization.h_max=0.25",
          "discretization.degree=1"]


@pytest.fixture(scope="module")
def solution():
    """hertz_friction at mu = 0.7 on the coarse mesh."""
    return solve_hf(load_scene("hertz_friction", COARSE), [0.7])


def test_scene_is_the_published_friction_case():
    sc = load_scene("hertz_friction")
    assert sc.param_names == ["mu"]
    assert sc.parameters[0].low == 0.7 and sc.parameters[0].high == 1.3
    assert sc.get("friction", "law") == "coulomb"
    assert sc.get("friction", "coefficient") == 0.2
    assert sc.get("load", "displacement") == 0.09
    assert sc.get("geometry", "initial_gap") == 0.001
    assert sc.get("discretization", "degree") == 2  # P2 displacements, P1 multipliers
    assert tuple(sc.get("geometry", "contact_zone")) == (-0.625, -0.375)


def test_stick_and_slip_coexist_without_a_tangential_load(solution):
    """Friction is active through the linearised kinematics and the gap alone (scene
    comment): both states occur, the raw multipliers satisfy the Coulomb bound, the slip
    nodes sit on it, and the traction is odd (net tangential force ~ 0)."""
    res = solution.result
    lam_n, lam_t = res.lam, np.asarray(res.info["lam_t"])
    states = np.asarray(res.info["states"])
    assert res.converged
    n_stick, n_slip = int(np.sum(states == "stick")), int(np.sum(states == "slip"))
    assert n_stick >= 10 and n_slip >= 10, (n_stick, n_slip)
    F, scale = 0.2, lam_n.max()
    assert lam_n.min() >= -1e-12 * scale
    assert (np.abs(lam_t) - F * lam_n).max() <= 1e-10 * scale
    slip = states == "slip"
    np.testing.assert_allclose(np.abs(lam_t[slip]), F * lam_n[slip], rtol=1e-8,
                               atol=1e-10 * scale)
    m = solution.metrics
    assert m["n_stick"] == n_stick and m["n_slip"] == n_slip
    assert abs(m["tangential_force"]) < 1e-4 * F * m["contact_force"]
    assert np.max(np.abs(lam_t)) > 0.5 * F * scale  # but locally large


def test_png_has_the_friction_panel(solution, tmp_path):
    import matplotlib.image as mpimg

    from rbbench.hf.output import write_png

    img = mpimg.imread(write_png(solution, tmp_path))
    assert img.shape[1] > 2000  # four panels (three without friction: 1760 px)


def test_solve_prints_the_friction_and_mindlin_lines(capsys):
    from rbbench.cli.console import print_summary

    sc = load_scene("mindlin_cylinders", ["discretization.h_contact=0.002"])
    sol = solve_hf(sc, None)
    print_summary(sol.metrics, sc.mu_dict(sol.mu))
    out = capsys.readouterr().out
    for key in ("tangential_force", "n_stick", "n_slip", "n_open", "stick_half_width",
                "friction_residual", "Cattaneo-Mindlin", "rel. error", "L2(-a, a) error"):
        assert key in out, key
    b = sol.metrics["mindlin"]
    assert f"{100 * b['c_rel_error']:+.2f} %" in out


def test_hf_rows_carry_the_friction_columns(tmp_path):
    import pandas as pd

    from rbbench.bench.matrix import load_matrix
    from rbbench.bench.runner import run_matrix
    from rbbench.registry import default_registry

    p = tmp_path / "hf.toml"
    p.write_text("""
[matrix]
name = "fhf"
mode = "hf"
scenes = ["hertz_friction"]
[components]
solver = ["friction-ssn", "ssn"]
[hf]
repeats = 1
[scene_overrides]
"hertz_friction" = ["discretization.h_contact=0.02", "discretization.h_max=0.25",
                    "discretization.degree=1", "parameters.mu.default=0.7"]
""")
    m = load_matrix(p, registry=default_registry())
    run_matrix(m, tmp_path / "run", jobs=1, cache_dir=tmp_path / "cache", progress=False)
    df = pd.read_parquet(tmp_path / "run" / "results.parquet").set_index("solver")
    assert df.loc["ssn", "status"] == "skip" and "coulomb" in df.loc["ssn", "reason"]
    row = df.loc["friction-ssn"]
    assert row["status"] == "ok"
    assert row["n_stick"] >= 10 and row["n_slip"] >= 10
    assert row["friction_residual"] < 1e-10
    assert abs(row["tangential_force"]) < 1e-4 * 0.2 * row["contact_force"]


def test_nitsche_friction_contact_table_is_per_point():
    """A Nitsche friction solve writes its point tractions (mixed signs) and states."""
    from rbbench.hf.output import contact_table

    sc = load_scene("mindlin_cylinders", ["discretization.h_contact=0.002"])
    sol = solve_hf(sc, None, formulation="nitsche")
    t = contact_table(sol)
    c, info = sol.disc.contact, sol.result.info
    assert t["x"].size == c.points.shape[0] == np.asarray(info["lam_t_points"]).size
    assert set(t["state"]) <= {"open", "stick", "slip"} and "stick" in set(t["state"])
    act = t["pressure"] > 0
    F = 0.2
    assert (np.abs(t["lam_t"]) - F * t["pressure"]).max() <= 1e-9 * t["pressure"].max()
    assert np.all(t["lam_t"][~act] == 0.0)

"""The ``rbbench`` command line: solve / plugins / scenes, output files, bad input."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rbbench.cli import main
from rbbench.registry import default_registry
from rbbench.scene.loading import load_scene

RBBENCH = Path(sys.executable).parent / "rbbench"
COARSE = ["--set", "discretization.h_contact=0.02", "--set", "discretization.h_max=0.2"]
COARSE_OVERRIDES = ["discretization.h_contact=0.02", "discretization.h_max=0.2"]
SUMMARY_KEYS = {"n_dofs", "n_contact", "iterations", "converged", "stop_reason", "solve_time_s",
                "contact_force", "contact_half_width", "max_pressure", "complementarity",
                "penetration_max", "definitions"}
HERTZ_UNITS_HEADER = ["x (m)", "y (m)", "pressure (Pa)", "gap_initial (m)", "gap (m)"]


def run_main(argv: list[str]) -> tuple[int, str, str]:
    """``main(argv)`` in-process, capturing stdout and stderr (usable in module fixtures)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main(argv)
    return rc, out.getvalue(), err.getvalue()


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    return rows[0], np.array(rows[1:], dtype=float)


def body_ids(vtu: Path) -> np.ndarray:
    import meshio

    mesh = meshio.read(vtu)
    assert "displacement" in mesh.point_data
    assert mesh.point_data["displacement"].shape == (mesh.points.shape[0], 3)
    ids = np.concatenate(mesh.cell_data["body"])
    assert ids.size == sum(len(block.data) for block in mesh.cells)
    return ids


# ---------------------------------------------------------------------------
# solves shared by several tests (each well under a second)
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def hertz_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("hertz")
    rc, stdout, stderr = run_main(["solve", "hertz_halfdisks", "--mu", "0.9", *COARSE,
                                   "--out", str(out), "--quiet"])
    return rc, stdout, stderr, out


@pytest.fixture(scope="module")
def rigid_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("rigid")
    rc, stdout, stderr = run_main(["solve", "hertz_halfdisks", *COARSE,
                                   "--set", 'geometry.lower="rigid_flat"',
                                   "--out", str(out), "--quiet", "--no-plot"])
    return rc, stdout, stderr, out


@pytest.fixture(scope="module")
def membrane_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("membrane")
    rc, stdout, stderr = run_main(["solve", "membrane_obstacle", "--out", str(out)])
    return rc, stdout, stderr, out


# ---------------------------------------------------------------------------
# rbbench solve
# ---------------------------------------------------------------------------
def test_console_script_solve_membrane(tmp_path):
    assert RBBENCH.exists(), f"console script not installed next to {sys.executable}"
    out = tmp_path / "out"
    proc = subprocess.run([str(RBBENCH), "solve", "membrane_obstacle", "--out", str(out),
                           "--quiet"], capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "meshing" not in proc.stderr  # --quiet: no progress lines
    for name in ("summary.json", "contact.csv", "solution.vtu", "solution.png"):
        assert (out / name).is_file(), name
        assert (out / name).stat().st_size > 0, name
        assert str(out / name) in proc.stdout  # "wrote: ..."
    summary = json.loads((out / "summary.json").read_text())
    assert SUMMARY_KEYS <= set(summary)
    assert summary["converged"] is True
    assert summary["scene"] == "membrane_obstacle"
    assert summary["mu"] == {"height": 0.25, "curvature": 4.0}


def test_membrane_in_process(membrane_run):
    rc, stdout, stderr, out = membrane_run
    assert rc == 0
    assert "mu: height = 0.25, curvature = 4" in stdout
    assert re.search(r"^\s+n_dofs\s+\d+$", stdout, re.M)
    assert re.search(r"^\s+stop_reason\s+converged$", stdout, re.M)
    assert "meshing" in stderr and "writing" in stderr  # progress lines without --quiet
    assert sorted(p.name for p in out.iterdir()) == ["contact.csv", "solution.png",
                                                     "solution.vtu", "summary.json"]


def test_membrane_summary(membrane_run):
    out = membrane_run[3]
    s = json.loads((out / "summary.json").read_text())
    assert SUMMARY_KEYS <= set(s)
    assert isinstance(s["n_dofs"], int) and s["n_dofs"] > 0
    assert isinstance(s["n_contact"], int) and s["n_contact"] > 0
    assert isinstance(s["iterations"], int) and s["iterations"] >= 1
    assert s["converged"] is True and s["stop_reason"] == "converged"
    assert s["solve_time_s"] >= 0
    assert s["contact_force"] > 0
    assert s["contact_half_width"] > 0
    assert s["max_pressure"] > 0
    assert 0 <= s["complementarity"] < 1e-8
    assert 0 <= s["penetration_max"] < 1e-8
    for key in ("contact_force", "contact_half_width", "max_pressure", "complementarity",
                "penetration_max"):
        assert isinstance(s["definitions"][key], str) and s["definitions"][key], key
    assert s["backend"] == "skfem" and s["formulation"] == "mixed" and s["solver"] == "ssn"
    assert s["scene_fingerprint"] == load_scene("membrane_obstacle").fingerprint()
    assert s["overrides"] == []
    assert "hertz" not in s and "radii" not in s  # elasticity-only blocks


def test_membrane_contact_csv(membrane_run):
    out = membrane_run[3]
    n_contact = json.loads((out / "summary.json").read_text())["n_contact"]
    header, rows = read_csv(out / "contact.csv")
    assert header == ["x", "y", "pressure", "gap_initial", "gap"]  # dimensionless scene
    assert rows.shape == (n_contact, 5)
    assert np.all(rows[:, 2] >= 0)  # multipliers are non-negative
    assert np.all((rows[:, :2] >= 0) & (rows[:, :2] <= 1))  # nodes of the unit square


def test_membrane_vtu(membrane_run):
    assert set(np.unique(body_ids(membrane_run[3] / "solution.vtu"))) == {0}


def test_default_output_directory(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    rc, stdout, _ = run_main(["solve", "membrane_obstacle", "--mu", "0.3", "5", "--quiet",
                              "--no-plot"])
    assert rc == 0
    out = tmp_path / "results" / "solve" / "membrane_obstacle_height0.3_curvature5"
    assert (out / "summary.json").is_file()
    assert not (out / "solution.png").exists()  # --no-plot
    assert json.loads((out / "summary.json").read_text())["mu"] == {"height": 0.3,
                                                                    "curvature": 5.0}


def test_hertz_summary(hertz_run):
    rc, stdout, stderr, out = hertz_run
    assert rc == 0
    assert "meshing" not in stderr  # --quiet
    for name in ("summary.json", "contact.csv", "solution.vtu", "solution.png"):
        assert (out / name).is_file(), name
    s = json.loads((out / "summary.json").read_text())
    assert SUMMARY_KEYS <= set(s)
    assert s["converged"] is True
    assert s["mu"] == {"mu": 0.9}
    assert s["overrides"] == COARSE_OVERRIDES
    assert s["scene_fingerprint"] == load_scene("hertz_halfdisks",
                                                overrides=COARSE_OVERRIDES).fingerprint()
    assert s["material"]["upper"] == {"E": 2.0e11, "nu": 0.3}
    assert s["material"]["lower"] == {"E": 2.0e11, "nu": 0.3}
    assert s["material"]["plane_strain"] is True
    assert s["radii"]["R1"] == pytest.approx(0.9)  # R1 = mu
    assert s["radii"]["R2"] == 1.0
    h = s["hertz"]
    for key in ("a", "p0", "a_rel_error", "p0_rel_error"):
        assert isinstance(h[key], float), key
    assert h["a"] > 0 and h["p0"] > 0
    assert h["a_rel_error"] == pytest.approx((s["contact_half_width"] - h["a"]) / h["a"])
    assert h["p0_rel_error"] == pytest.approx((s["max_pressure"] - h["p0"]) / h["p0"])
    assert abs(h["a_rel_error"]) < 0.3 and abs(h["p0_rel_error"]) < 0.3  # coarse mesh
    assert s["contact_force"] > 0
    assert s["penetration_max"] < 1e-8
    # printed summary
    assert "mu: mu = 0.9" in stdout
    assert "2D Hertz at the computed force P" in stdout


def test_hertz_console_and_summary_carry_the_units(hertz_run):
    """Each dimensional number of the summary lines ends with its unit, read from
    summary.json's ``units`` (rbbench.hf.metrics.SI_UNITS); the parameter with the scene's."""
    from rbbench.hf.metrics import SI_UNITS

    stdout, out = hertz_run[1], hertz_run[3]
    s = json.loads((out / "summary.json").read_text())
    assert s["units"] == SI_UNITS and "units" in s["definitions"]
    assert "(N/m)" in s["definitions"]["contact_force"]  # the definitions say the same unit
    assert re.search(r"^mu: mu = 0\.9 m$", stdout, re.M)
    for key, unit in (("contact_force", "N/m"), ("max_pressure", "Pa"),
                      ("contact_half_width", "m"), ("penetration_max", "m"),
                      ("solve_time_s", "s"), ("floor_s", "s")):
        assert re.search(rf"^  {key}\s+\S+ {re.escape(unit)}(  \(.*\))?$", stdout, re.M), key
    assert re.search(r"^  complementarity\s+\S+$", stdout, re.M)  # dimensionless: no unit
    assert re.search(r"^    p0  = \S+ Pa  computed \S+ Pa", stdout, re.M)
    assert "nondimensional" not in stdout


def test_membrane_is_nondimensional(membrane_run):
    stdout, out = membrane_run[1], membrane_run[3]
    s = json.loads((out / "summary.json").read_text())
    assert set(s["units"].values()) == {"1"} and "contact_force" in s["units"]
    assert re.search(r"^  contact_force\s+\S+$", stdout, re.M)  # no unit
    assert re.search(r"^  solve_time_s\s+\S+ s$", stdout, re.M)
    assert "(nondimensional scene: its numbers carry no unit; times in s)" in stdout


def test_reduce_summary_units(capsys):
    """``rbbench reduce``'s lines: penetration_max in the scene's unit, times in s."""
    from rbbench.cli.console import _print_reduce_summary
    from rbbench.hf.metrics import units_of

    s = {"N": 5, "err_u_max": 0.01, "penetration_max": 1e-6, "t_offline_s": 2.5,
         "speedup": 10.0, "histories": {}}
    _print_reduce_summary(s, "mixed", units_of("elasticity"))
    out = capsys.readouterr().out
    assert re.search(r"^  penetration_max\s+1e-06 m$", out, re.M)
    assert re.search(r"^  t_offline_s\s+2\.5 s$", out, re.M)
    for key in ("N", "err_u_max"):
        assert re.search(rf"^  {key}\s+\S+$", out, re.M), key
    # a speed-up says against what it is measured
    assert re.search(r"^  speedup\s+10 \s*\(against the timed HF solve: t_hf_median_s / "
                     r"t_online_median_s\)$", out, re.M)
    _print_reduce_summary(s, "mixed", units_of("poisson"))
    out = capsys.readouterr().out
    assert re.search(r"^  penetration_max\s+1e-06$", out, re.M)
    assert "nondimensional scene" in out


def test_hertz_contact_csv(hertz_run):
    out = hertz_run[3]
    n_contact = json.loads((out / "summary.json").read_text())["n_contact"]
    header, rows = read_csv(out / "contact.csv")
    assert header == HERTZ_UNITS_HEADER
    assert rows.shape == (n_contact, 5)
    assert np.all(np.isfinite(rows))
    assert np.all(rows[:, 2] >= 0)
    assert np.any(rows[:, 2] > 0)  # some contact
    assert np.all(rows[:, 3] >= 1e-3 - 1e-12)  # initial gap >= g0 = 0.001 m


def test_hertz_vtu_has_two_bodies(hertz_run):
    ids = body_ids(hertz_run[3] / "solution.vtu")
    assert set(np.unique(ids)) == {0, 1}


def test_rigid_flat(rigid_run):
    rc, stdout, stderr, out = rigid_run
    assert rc == 0
    assert not (out / "solution.png").exists()  # --no-plot
    s = json.loads((out / "summary.json").read_text())
    assert s["converged"] is True
    assert 'geometry.lower="rigid_flat"' in s["overrides"]
    assert s["radii"]["R1"] == 1.0  # default mu
    assert s["radii"]["R2"] is None
    assert "lower" not in s["material"]
    assert s["material"]["plane_strain"] is True
    assert s["hertz"]["a"] > 0
    header, rows = read_csv(out / "contact.csv")
    assert header == HERTZ_UNITS_HEADER
    assert rows.shape == (s["n_contact"], 5)
    assert set(np.unique(body_ids(out / "solution.vtu"))) == {0}


# ---------------------------------------------------------------------------
# bad input: exit status 2, a message naming what is wrong, no output written
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("mu", ["0.5", "1.31", "nan"])
def test_solve_mu_out_of_domain(capsys, tmp_path, mu):
    out = tmp_path / "out"
    rc = main(["solve", "hertz_halfdisks", "--mu", mu, "--out", str(out), "--quiet"])
    captured = capsys.readouterr()
    assert rc == 2
    assert captured.err.startswith("rbbench: error:")
    assert "parameter mu" in captured.err
    assert "[0.7, 1.3]" in captured.err
    assert not out.exists()


def test_solve_mu_wrong_count(capsys, tmp_path):
    rc = main(["solve", "membrane_obstacle", "--mu", "0.2", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2
    assert "height" in err and "curvature" in err and "got 1 value" in err


def test_solve_mu_not_a_number(capsys):
    with pytest.raises(SystemExit) as info:
        main(["solve", "hertz_halfdisks", "--mu", "big"])
    assert info.value.code == 2
    assert "--mu" in capsys.readouterr().err


@pytest.mark.parametrize(("option", "role", "valid"), [
    ("--solver", "solver", ["ssn", "uzawa"]),
    ("--backend", "backend", ["skfem"]),
    ("--formulation", "formulation", ["mixed"]),
])
def test_solve_unknown_component(capsys, tmp_path, option, role, valid):
    """The choices of a component option are the registered names of its role: an unknown
    one exits 2 before any work, naming the option and the valid names."""
    out = tmp_path / "out"
    with pytest.raises(SystemExit) as info:
        main(["solve", "membrane_obstacle", option, "nope", "--out", str(out), "--quiet"])
    err = " ".join(capsys.readouterr().err.split()).replace("'", "")  # quoted or not
    assert info.value.code == 2
    assert f"argument {option}: invalid choice: nope" in err
    for name in valid:
        assert name in err.split("choose from")[1], err
    assert set(valid) <= set(default_registry().names(role))
    assert not out.exists()


def test_solve_unknown_scene(capsys):
    rc = main(["solve", "no_such_scene", "--quiet"])
    err = capsys.readouterr().err
    assert rc == 2
    assert "no_such_scene" in err
    assert "available scenes" in err
    assert "hertz_halfdisks" in err and "membrane_obstacle" in err


@pytest.mark.parametrize("override", ["nokey", "a=1", "load.displacement.x=1"])
def test_solve_malformed_set(capsys, tmp_path, override):
    out = tmp_path / "out"
    rc = main(["solve", "hertz_halfdisks", "--set", override, "--out", str(out), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 2
    assert repr(override) in err
    assert not out.exists()


def test_solve_invalid_set_value(capsys, tmp_path):
    rc = main(["solve", "hertz_halfdisks", "--set", "material.upper.nu=0.5",
               "--out", str(tmp_path / "o"), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 2
    assert "[material.upper] nu" in err and "< 0.5" in err


def test_solve_scene_file_with_error(capsys, tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text((Path(load_scene("hertz_halfdisks").path).read_text())
                   .replace('multiplier = "lac"', 'multiplier = "p3"'))
    rc = main(["solve", str(bad), "--quiet"])
    err = capsys.readouterr().err
    assert rc == 2
    assert str(bad) in err and "[discretization] multiplier" in err and "'nodal'" in err


def test_no_command_is_a_usage_error(capsys):
    with pytest.raises(SystemExit) as info:
        main([])
    assert info.value.code == 2
    assert "usage" in capsys.readouterr().err


# ---------------------------------------------------------------------------
# rbbench --version
# ---------------------------------------------------------------------------
def test_version_prints_the_package_version(capsys):
    import rbbench

    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out == f"rbbench {rbbench.__version__}\n"


def test_console_script_version():
    import rbbench

    proc = subprocess.run([str(RBBENCH), "--version"], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == f"rbbench {rbbench.__version__}"


# ---------------------------------------------------------------------------
# rbbench plugins / scenes
# ---------------------------------------------------------------------------
BUILTINS = [("backend", "skfem"), ("formulation", "mixed"), ("solver", "ssn"),
            ("solver", "uzawa")]


def test_plugins_table(capsys):
    assert main(["plugins"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert lines[0].split()[:3] == ["role", "name", "package"]
    for role, name in BUILTINS:
        assert re.search(rf"^{role}\s+{name}\s+rbbench\b.*\byes\b", out, re.M), (role, name)


def test_plugins_json(capsys):
    assert main(["plugins", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert isinstance(rows, list)
    by_key = {(r["role"], r["name"]): r for r in rows}
    for key in BUILTINS:
        row = by_key[key]
        assert row["package"] == "rbbench"
        assert row["importable"] is True
        assert row["description"]
        for field in ("version", "extras", "hint", "capabilities"):
            assert field in row
    assert "elasticity" in by_key[("backend", "skfem")]["capabilities"]["physics"]


def test_scenes(capsys):
    assert main(["scenes"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^hertz_halfdisks\s+mu in \[0\.7, 1\.3\] m\s", out, re.M)  # its unit
    assert re.search(r"^membrane_obstacle\s+height in \[0\.1, 0\.4\], curvature in \[2, 6\]",
                     out, re.M)


def _columns(lines: list[str], header: list[str]) -> list[dict[str, str]]:
    """The rows of a wrapped side-by-side table: each column's text over the row's lines
    (cut at the header's column starts; a row starts where a line does not begin with a
    space), whitespace normalised."""
    starts = [lines[0].index(h) for h in header] + [None]
    rows: list[dict[str, list[str]]] = []
    for line in lines[1:]:
        if not line.startswith(" "):
            rows.append({h: [] for h in header})
        for h, a, b in zip(header, starts, starts[1:], strict=False):
            rows[-1][h].append(line[a:b])
    return [{h: " ".join(" ".join(parts).split()) for h, parts in r.items()} for r in rows]


@pytest.mark.parametrize("columns", [80, 100])
def test_scenes_table_fits_the_terminal_and_keeps_every_word(columns, monkeypatch, capsys):
    monkeypatch.setenv("COLUMNS", str(columns))
    assert main(["scenes"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert max(map(len, lines)) <= columns
    rows = _columns(lines, ["scene", "parameters", "description"])
    from rbbench.scene.loading import PROBLEMS_DIR

    scenes = [load_scene(p) for p in sorted(PROBLEMS_DIR.glob("*.toml"))]
    assert [r["scene"] for r in rows] == [s.name for s in scenes]
    for r, sc in zip(rows, scenes, strict=True):
        assert r["description"] == " ".join(sc.data["scene"]["description"].split())
        assert r["parameters"].count(" in [") == len(sc.parameters)  # nothing cut


@pytest.mark.parametrize("columns", [80, 100])
def test_plugins_table_fits_the_terminal_and_keeps_every_word(columns, monkeypatch, capsys):
    from rbbench.cli.solve import _plugin_rows
    from rbbench.registry import default_registry

    monkeypatch.setenv("COLUMNS", str(columns))
    assert main(["plugins"]) == 0
    out = capsys.readouterr().out
    assert max(map(len, out.splitlines())) <= columns
    flat = " ".join(out.split())
    for r in _plugin_rows(default_registry()):
        assert " ".join(r["description"].split()) in flat, r["name"]  # wrapped, not cut
        assert re.search(rf"^{r['role']}\s+{re.escape(r['name'])}\s", out, re.M)


def test_tables_are_not_wrapped_off_a_terminal(monkeypatch, capsys):
    """Piped, with COLUMNS unset: one line per row (for grep)."""
    import os

    from rbbench.cli.console import terminal_width

    def no_terminal(*args):
        raise OSError("not a terminal")

    monkeypatch.delenv("COLUMNS", raising=False)
    monkeypatch.setattr(os, "get_terminal_size", no_terminal)
    assert terminal_width() is None
    assert main(["scenes"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert not any(line.startswith(" ") for line in lines)
    assert any("mu_1 in [0.1, 1], mu_2 in [0.1, 1], mu_3 in [0.1, 1], mu_4 in [0.1, 1]" in line
               for line in lines)


def test_cells_wrap_between_items_and_are_never_cut():
    from rbbench.cli.console import _wrap_cell, format_table

    items = ["alpha in [1, 2]", "beta in [3, 4]", "gamma in [5, 6]"]
    assert _wrap_cell(items, 34) == ["alpha in [1, 2], beta in [3, 4],", "gamma in [5, 6]"]
    assert _wrap_cell(items, 5) == ["alpha in [1, 2],", "beta in [3, 4],", "gamma in [5, 6]"]
    assert _wrap_cell("a long_unbreakable_word", 6) == ["a", "long_unbreakable_word"]
    rows = [["name", "text"], ["x", "a b c d e f g h i j k l m n o p q r s t u v w x y z"]]
    assert format_table(rows, wrap={1}, width=None)[1] == ["x     " + rows[1][1]]
    wrapped = format_table(rows, wrap={1}, width=30)  # text 24 wide, beside the name
    assert wrapped[1][0].startswith("x     a b c") and wrapped[1][1].startswith("      ")
    stacked = format_table(rows, wrap={1}, width=20)  # text under 24: under its row
    assert stacked[0] == ["name", "    text"] and stacked[1][0] == "x"
    assert " ".join(" ".join(stacked[1][1:]).split()) == rows[1][1]


@pytest.mark.parametrize("argv", [["report", "{missing}"], ["report", "{garbage}"],
                                  ["compare", "{missing}", "{garbage}"]])
def test_report_and_compare_on_a_bad_directory_exit_2_naming_it(tmp_path, capsys, argv):
    garbage = tmp_path / "garbage"
    garbage.mkdir()
    (garbage / "results.parquet").write_text("not parquet")
    paths = {"missing": str(tmp_path / "missing"), "garbage": str(garbage)}
    assert main([a.format(**paths) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rbbench: error: ") and str(tmp_path) in err

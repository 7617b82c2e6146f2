"""Bad command-line options exit 2 with a message naming the option, before any solve
(the cases that used to end in a traceback or in a model of size 0)."""

from __future__ import annotations

import pytest

from rbbench.cli import main


@pytest.mark.parametrize("argv, expected", [
    (["reduce", "membrane_obstacle", "-R", "0"], "-R 0: must be an integer >= 1"),
    (["reduce", "membrane_obstacle", "-R", "-5"], "-R -5"),
    (["reduce", "membrane_obstacle", "-N", "0"], "-N 0"),
    (["reduce", "membrane_obstacle", "-N", "-5"], "-N -5"),
    (["reduce", "membrane_obstacle", "--n-train", "0"], "--n-train 0"),
    (["reduce", "membrane_obstacle", "--n-valid", "-1"], "--n-valid -1"),
    (["solve", "membrane_obstacle", "--solver", "newton"],
     "solver 'newton' solves the 'nitsche' formulation(s), not 'mixed'"),
    (["solve", "hertz_halfdisks", "--formulation", "nitsche", "--formulation-option",
      "gamma0=abc"], "gamma0 = 'abc' must be a number"),
])
def test_bad_option_exits_2_naming_it(argv, expected, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    assert expected in capsys.readouterr().err
    assert not (tmp_path / "results").exists()  # nothing solved, nothing written


def test_solve_out_that_is_a_file_exits_2(capsys, tmp_path):
    f = tmp_path / "afile"
    f.write_text("x")
    assert main(["solve", "membrane_obstacle", "--out", str(f)]) == 2
    assert "exists and is not a directory" in capsys.readouterr().err
    assert f.read_text() == "x"


def test_friction_dual_is_checked_on_the_command_line_and_in_a_matrix(tmp_path, capsys):
    from rbbench.bench.matrix import load_matrix
    from rbbench.bench.matrix_checks import MatrixError
    from rbbench.registry import default_registry

    with pytest.raises(SystemExit) as exc:  # argparse choices
        main(["reduce", "hertz_friction", "--friction-dual", "bogus"])
    assert exc.value.code == 2 and "--friction-dual" in capsys.readouterr().err
    p = tmp_path / "m.toml"
    p.write_text('[matrix]\nname = "m"\nscenes = ["membrane_obstacle"]\n[components]\n'
                 'dual = ["cpg"]\nstabilizer = ["none"]\n[sizes]\nN = [3]\nR = [3]\n'
                 '[reduce]\nfriction_dual = "bogus"\n')
    with pytest.raises(MatrixError,
                       match="friction_dual = 'bogus'; valid: auto, collocation, wedge, seed"):
        load_matrix(p, registry=default_registry())

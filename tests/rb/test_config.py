"""Options belong to the formulation that reads them: an option of another formulation is an
error naming it and the formulations that take it, on the command line (exit 2, the flag) and
in Python (ValueError), before any HF work; in a run matrix it makes a skip row."""

from __future__ import annotations

import pytest

import rbbench
from rbbench.cli import main
from rbbench.rb.config import OptionError, ReduceConfig, make_config
from rbbench.registry import default_registry

FRICTION = "the mixed formulation on friction scenes"


@pytest.fixture
def no_hf_work(monkeypatch):
    """Any snapshot computed fails the test: the refusal comes first."""
    import rbbench.rb.offline as skeleton

    def refuse(*a, **k):
        raise AssertionError("HF work before the option check")

    monkeypatch.setattr(skeleton, "training_snapshots", refuse)


def test_the_command_line_names_the_flag_and_who_takes_it(capsys, no_hf_work):
    assert main(["reduce", "membrane_obstacle", "-S", "5"]) == 2
    err = capsys.readouterr().err
    assert "option -S: not an option of the mixed formulation (frictionless scenes)" in err
    assert f"-S is an option of {FRICTION}" in err
    assert "--dual" in err and "-R" in err  # the options it takes, as flags
    assert main(["reduce", "membrane_obstacle", "-S", "5", "--friction-dual", "wedge",
                 "--gcns-patience", "3"]) == 2
    assert main(["reduce", "hertz_halfdisks", "--formulation", "nitsche", "-R", "4"]) == 2
    err = capsys.readouterr().err
    assert "option -R: not an option of the nitsche formulation" in err
    assert "the mixed formulation (frictionless scenes)" in err and FRICTION in err


def test_the_python_api_raises_a_value_error(no_hf_work):
    with pytest.raises(ValueError, match=f"option 'S': .* 'S' is an option of {FRICTION}"):
        rbbench.reduce("membrane_obstacle", S=5)
    with pytest.raises(OptionError) as exc:
        rbbench.reduce("thermal_block", dual="cpg")
    assert exc.value.option == "dual" and exc.value.where == "the linear formulation"
    assert exc.value.owners == ["the mixed formulation (frictionless scenes)", FRICTION]
    with pytest.raises(ValueError, match="no option of any installed formulation|of no "
                       "installed formulation"):
        rbbench.reduce("membrane_obstacle", tol_dul=0.1)  # a typo: nobody takes it


def test_values_are_checked_by_the_options_dataclass(no_hf_work):
    with pytest.raises(ValueError, match="online_method = 'fast'"):
        rbbench.reduce("membrane_obstacle", online_method="fast")
    with pytest.raises(ValueError, match="friction_dual = 'box'"):
        rbbench.reduce("hertz_friction", friction_dual="box")


def test_make_config_splits_shared_fields_from_options():
    cfg = make_config(N=4, R=3, dual="cpg", hyper="eim", stabilizer="", tol_eim=None)
    assert isinstance(cfg, ReduceConfig) and cfg.N == 4 and cfg.hyper == "eim"
    assert cfg.options == {"R": 3, "dual": "cpg"}  # "" and None: not given
    assert cfg.formulation is None and cfg.solver is None  # the scene decides


def test_a_matrix_case_whose_formulation_refuses_an_option_is_a_skip_row(tmp_path):
    from rbbench.bench.matrix import load_matrix

    p = tmp_path / "m.toml"
    p.write_text('[matrix]\nname = "m"\nscenes = ["membrane_obstacle", "hertz_friction"]\n'
                 '[components]\nsolver = ["friction-ssn"]\ndual = ["cpg"]\n'
                 'stabilizer = ["none"]\n[sizes]\nN = [3]\n'
                 'R = [3]\n[reduce]\nS = 2\n')
    cases = {c.scene: c for c in load_matrix(p, registry=default_registry()).cases}
    assert cases["membrane_obstacle"].status == "skip"
    assert "option 'S': not an option of the mixed formulation" in \
        cases["membrane_obstacle"].reason
    assert cases["hertz_friction"].status == "run"
    bad = tmp_path / "bad.toml"
    bad.write_text(p.read_text().replace("S = 2", "tol_dul = 0.1"))
    from rbbench.bench.matrix_checks import MatrixError

    with pytest.raises(MatrixError, match="unknown field 'tol_dul'"):
        load_matrix(bad, registry=default_registry())


BAD_VALUES = [
    ("N", 0, r"give an integer in \[1, 100000\]"), ("N", 3.7, "give an integer"),
    ("N", True, "give an integer"), ("n_valid", "5", "give an integer"),
    ("tol_pod", -1.0, r"tolerance in \[0, 1\)"), ("tol_pod", float("nan"), "finite number"),
    ("R", -1, r"integer in \[1, "), ("k_pga_max", 0, r"integer in \[1, "),
    ("tol_eim", float("nan"), "finite number"), ("tol_dual", -1e-3, r"tolerance in \[0, 1\)"),
    ("delta_pga", -1.0, r"in \(0, 1\]"), ("delta_pga", float("inf"), "finite number"),
    ("exact_max_r", -1, r"integer in \[0, "), ("m_eim", 2.5, "give an integer"),
    ("n_train", 10**6, r"integer in \[1, 100000\]"), ("tol_eim", 1.0, r"in \[0, 1\)"),
    ("online_repeats", 10**5, r"integer in \[1, 10000\]"), ("backend", 5, "give a name"),
]


@pytest.mark.parametrize("field, value, match", BAD_VALUES)
def test_the_python_api_refuses_bad_values_before_hf_work(no_hf_work, field, value, match):
    """What the command line refuses, the Python API refuses too, naming the field and what
    is valid, before any snapshot."""
    with pytest.raises(ValueError, match=f"{field} = .*{match}"):
        rbbench.reduce("membrane_obstacle", **{field: value})


@pytest.mark.parametrize("field, value", [("gcns_patience", 0), ("gcns_per_iteration", 0),
                                          ("S", 0), ("gcns_max", -2)])
def test_friction_counts_are_refused(no_hf_work, field, value):
    with pytest.raises(ValueError, match=rf"{field} = {value}: give an integer in \[1, "):
        rbbench.reduce("hertz_friction", **{field: value})


def test_zero_exact_cones_is_valid():
    assert make_config(exact_max_r=0).options == {"exact_max_r": 0}

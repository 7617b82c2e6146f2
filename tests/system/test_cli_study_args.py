"""The studies refuse an argument out of range, and a --json file in a missing folder,
before any work (exit 2 naming the flag)."""

from __future__ import annotations

import pytest

from rbbench.cli import main


@pytest.fixture
def no_study_work(monkeypatch):
    """Any study that starts fails the test: the refusal comes first."""
    import rbbench.studies.heat_robin as hr
    import rbbench.studies.pymor_thermal_block as tb

    def refuse(*a, **k):
        raise AssertionError("the study ran before its arguments were checked")

    monkeypatch.setattr(tb, "side_by_side", refuse)
    monkeypatch.setattr(hr, "heat_robin_study", refuse)


@pytest.mark.parametrize("argv, flag", [
    (["studies", "pymor-thermal-block", "-N", "0"], "-N 0"),
    (["studies", "pymor-thermal-block", "--n-train", "0"], "--n-train 0"),
    (["studies", "pymor-thermal-block", "--repeats", "0"], "--repeats 0"),
    (["studies", "pymor-thermal-block", "--n-cells", "100000"], "--n-cells 100000"),
    (["studies", "heat-robin", "-N", "0"], "-N 0"),
    (["studies", "heat-seed", "-N", "-3"], "-N -3"),
    (["studies", "heat-robin", "--json", "/nonexistent-folder/x.json"], "--json"),
    (["studies", "snapshot-workers", "--pause", "1e9"], "--pause 1e+09"),
    (["studies", "snapshot-workers", "--pause", "nan"], "--pause nan"),
    (["studies", "shape-side-by-side", "--eps", "nan"], "--eps nan"),
    (["studies", "shape-side-by-side", "--max-iter", "0"], "--max-iter 0"),
    (["studies", "shape-strategy", "--max-evals", "0"], "--max-evals 0"),
    (["studies", "shape-strategy", "--eps", "-1"], "--eps -1"),
    (["nitsche-compare", "-R", "10", "0"], "-R 0"),
    (["nitsche-compare", "--n-valid", "0"], "--n-valid 0"),
])
def test_bad_study_arguments_exit_2_before_work(argv, flag, capsys, no_study_work):
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"rbbench: error: {flag}" in err

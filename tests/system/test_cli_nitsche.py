"""rbbench solve with the Nitsche formulation and rbbench studies nitsche-table."""

from __future__ import annotations

import contextlib
import io
import json

import pytest

from rbbench.cli import main
from rbbench.testing import HERTZ_COARSE

COARSE = list(HERTZ_COARSE)


def _run(argv):
    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(io.StringIO()):
        code = main(argv)
    return code, out.getvalue()


def test_cli_solve_nitsche_picks_newton_and_writes_e_ac(tmp_path):
    args = ["solve", "hertz_halfdisks", "--formulation", "nitsche", "--mu", "0.7", "--no-plot",
            "--quiet", "--out", str(tmp_path)]
    for s in COARSE:
        args += ["--set", s]
    code, text = _run(args)
    assert code == 0, text
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["solver"] == "newton" and summary["formulation"] == "nitsche"
    assert 0.0 < summary["e_ac"] < 1.0 and summary["converged"]
    assert "e_ac" in text


def test_renamed_study_names_still_import_with_a_deprecation_warning():
    import rbbench.studies as studies
    from rbbench.studies.nitsche_eac import published_h_overrides
    from rbbench.studies.published import PUBLISHED_H

    with pytest.warns(DeprecationWarning, match="SEED_H is now PUBLISHED_H"):
        assert studies.SEED_H == PUBLISHED_H
    with pytest.warns(DeprecationWarning, match="seed_h_overrides is now published_h_overrides"):
        assert studies.seed_h_overrides is published_h_overrides


def test_cli_nitsche_table(tmp_path):
    code, text = _run(["nitsche-table", "--h", "10", "5", "--mu", "1.0", "--quiet",
                       "--degree", "1", "--set", "discretization.h_max=0.2"])
    assert code == 0, text
    assert "| 1 | 10 |" in text and "published e_AC" in text and "| 1 | 5 |" in text
    assert "e_AC nodal" in text and "e_AC L2" in text and "e_AC quad:" in text

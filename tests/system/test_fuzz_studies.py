"""Generated hostile arguments of the studies (``rbbench studies STUDY``, ``hertz-table``,
``nitsche-table``, ``nitsche-compare``): every numeric flag crossed with values of the wrong
type, non-finite, out of range and huge; unknown backends and scenes; ``--json`` into a
missing folder or onto a directory.

Each is refused with exit 2 naming the flag, before the study starts (every study function
and every HF solve fails the test if called), within a hard time limit, writing nothing
outside the output directory.
"""

from __future__ import annotations

import pytest
from support.fuzz import assert_rejected, hf_work, refuse_work, run_cli

pytestmark = pytest.mark.timeout(120)


@pytest.fixture(autouse=True)
def no_study_work(monkeypatch):
    import rbbench.studies.heat_robin as hr
    import rbbench.studies.hertz as hz
    import rbbench.studies.nitsche_compare as nc
    import rbbench.studies.nitsche_eac as ne
    import rbbench.studies.pymor_thermal_block as tb
    import rbbench.studies.shape_side_by_side as ss
    import rbbench.studies.snapshot_workers as sw

    refuse_work(monkeypatch, [(tb, "side_by_side"), (hr, "heat_robin_study"),
                              (ss, "shape_side_by_side"), (sw, "snapshot_workers"),
                              (hz, "hertz_table"), (ne, "nitsche_table"),
                              (nc, "formulation_comparison"), *hf_work()])


#: the command of each study, and its flags: ``flag -> "int" | "float" | "floats" | "ints"``
STUDIES = {
    ("studies", "pymor-thermal-block"): {"--n-cells": "int", "-N": "int", "--n-train": "int",
                                         "--n-valid": "int", "--repeats": "int"},
    ("studies", "heat-robin"): {"--n-cells": "int", "-N": "int", "--repeats": "int"},
    ("studies", "shape-side-by-side"): {"--max-iter": "int", "--max-evals": "int",
                                        "--eps": "float", "--ny": "ints"},
    ("studies", "snapshot-workers"): {"-P": "int", "--jobs": "int", "--rounds": "int",
                                      "--pause": "float"},
    ("hertz-table",): {"--loads": "floats", "--levels": "ints", "--mu": "float"},
    ("nitsche-table",): {"--h": "floats", "--mu": "floats", "--theta": "float",
                         "--gamma0": "float", "--load": "float", "--quadrature": "int"},
    ("nitsche-compare",): {"-N": "int", "-R": "ints", "--n-train": "int", "--n-valid": "int"},
}
#: bad values by kind (each refused by the flag's type or its range)
BAD = {"int": ["0", "-1", "2.5", "abc", "nan", "1000000000000000000000000000000"],
       "float": ["nan", "inf", "-inf", "abc", "-1", "1e308"]}
BAD["ints"], BAD["floats"] = BAD["int"], BAD["float"]
#: flags whose valid range holds some of those: their own bad values
OWN = {"--theta": ["nan", "inf", "abc", "5", "-1.5", "1e308"],
       "--levels": ["-1", "2.5", "abc", "99", "1000000000000000000000000000000"],
       "--quadrature": ["-1", "2.5", "abc", "7", "1000000000000000000000000000000"]}

TABLE = [(cmd, flag, v) for cmd, flags in STUDIES.items() for flag, kind in flags.items()
         for v in OWN.get(flag, BAD[kind])]


@pytest.mark.parametrize("cmd, flag, value", TABLE,
                         ids=[f"{c[-1]} {f} {v[:12]}" for c, f, v in TABLE])
def test_study_numbers(cmd, flag, value):
    code, err, outside = run_cli(lambda d, out: [*cmd, flag, value])
    assert_rejected(code, err, outside, flag)


OTHER = [
    (("studies", "pymor-thermal-block"), ["--backend", "bogus"], "bogus"),
    (("studies", "heat-robin"), ["--backend", "bogus"], "bogus"),
    (("nitsche-table",), ["--backend", "bogus"], "bogus"),
    (("studies", "snapshot-workers"), ["no_such_scene"], "no_such_scene"),
    (("hertz-table",), ["no_such_scene"], "no_such_scene"),
    (("nitsche-compare",), ["no_such_scene"], "no_such_scene"),
    (("studies", "shape-side-by-side"), ["--scene", "no_such_scene"], "no_such_scene"),
    (("studies", "shape-side-by-side"), ["--set", "design.CO=1"], "CO"),
    (("studies", "shape-side-by-side"), ["--ny", "40", "20000"], "--ny 20000"),
    (("studies", "snapshot-workers"), ["--set", "discretization.level=99"], "level"),
    (("hertz-table",), ["--set", "load.displacement=nan"], "displacement"),
    (("nitsche-table",), ["--degree", "3"], "--degree"),
    (("nitsche-table",), ["--normals", "bogus"], "--normals"),
    (("studies", "pymor-thermal-block"), ["--blocks", "4"], "--blocks"),
]


@pytest.mark.parametrize("cmd, extra, named", OTHER,
                         ids=[f"{c[-1]} {' '.join(e)}" for c, e, _ in OTHER])
def test_study_choices(cmd, extra, named):
    code, err, outside = run_cli(lambda d, out: [*cmd, *extra])
    assert_rejected(code, err, outside, named)


JSON_STUDIES = [("studies", s) for s in ("pymor-thermal-block", "heat-robin",
                                         "shape-side-by-side", "snapshot-workers")]


@pytest.mark.parametrize("cmd", JSON_STUDIES, ids=[c[-1] for c in JSON_STUDIES])
@pytest.mark.parametrize("target", ["missing/x.json", "adir"])
def test_study_json_target(cmd, target):
    def argv(d, out):
        (d / "adir").mkdir()
        return [*cmd, "--json", str(d / target)]

    code, err, outside = run_cli(argv)
    assert_rejected(code, err, outside, "--json")

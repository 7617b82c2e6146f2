"""Generated hostile values of the reduction's fields, through ``rbbench reduce`` and through
the Python API (:func:`rbbench.reduce`, :func:`rbbench.solve`, :func:`rbbench.load_scene`):
every field of :class:`~rbbench.rb.config.ReduceConfig` and of the formulations' options
(mixed, friction, Nitsche) crossed with values of the wrong type, non-finite, out of range
and huge; unknown fields; bad parameters and component options.

The command line exits 2 naming the flag; the API raises the documented exception
(``ValueError``: :class:`~rbbench.scene.loading.SceneError`,
:class:`~rbbench.rb.config.OptionError`; an unknown component name:
:class:`~rbbench.registry.UnknownComponentError`) naming the field. Both refuse before any
HF work: the HF entry points fail the test if called.
"""

from __future__ import annotations

import dataclasses
import math
import typing

import pytest
from support.fuzz import assert_rejected, hard_limit, hf_work, refuse_work, run_cli

import rbbench
from rbbench.cli.reduce import flag
from rbbench.rb.config import ReduceConfig
from rbbench.rb.friction.options import FrictionOptions
from rbbench.rb.mixed.options import MixedOptions
from rbbench.rb.nitsche.options import NitscheOptions
from rbbench.registry import UnknownComponentError

pytestmark = pytest.mark.timeout(120)
API_ERRORS = (ValueError, UnknownComponentError)


@pytest.fixture(autouse=True)
def no_hf_work(monkeypatch):
    refuse_work(monkeypatch, hf_work())


#: where each dataclass's fields are tried: scene and fixed fields
WHERE = {ReduceConfig: ("membrane_obstacle", {}), MixedOptions: ("membrane_obstacle", {}),
         FrictionOptions: ("hertz_friction", {}),
         NitscheOptions: ("hertz_halfdisks", {"formulation": "nitsche"})}
#: bad values by kind: ``label -> (Python value, command-line text)``
INT_BAD = {"nan": (math.nan, "nan"), "inf": (math.inf, "inf"), "-1": (-1, "-1"),
           "0": (0, "0"), "2.5": (2.5, "2.5"), "1e308": (1e308, "1e308"),
           "str": ("abc", "abc"), "bool": (True, "true"), "list": ([1], "[1]"),
           "10**30": (10**30, str(10**30))}
FLOAT_BAD = {"nan": (math.nan, "nan"), "inf": (math.inf, "inf"), "-inf": (-math.inf, "-inf"),
             "-1": (-1.0, "-1"), "1e308": (1e308, "1e308"), "str": ("abc", "abc"),
             "bool": (True, "true"), "list": ([1.0], "[1.0]")}
STR_BAD = {"bogus": ("bogus", "bogus"), "int": (5, "5"), "bool": (True, "true"),
           "list": (["pod"], "[pod]")}
#: fields whose valid range holds one of those (0 for exact_max_r), or that are not tried
SKIP = {("exact_max_r", "0"), ("cache_dir", None), ("backend_options", None),
        ("formulation_options", None), ("n_jobs", "10**30")}
#: string fields that take the empty string as "the default"
DEFAULT_WHEN_EMPTY = {"solver", "formulation"}


def _table() -> list[tuple]:
    rows, seen = [], set()
    for cls, (scene, fixed) in WHERE.items():
        hints = typing.get_type_hints(cls)
        for f in dataclasses.fields(cls):
            if f.name == "options" or (f.name, None) in SKIP:
                continue
            if f.name in seen and cls is not FrictionOptions:
                continue  # a shared option, tried once (friction scenes try their own)
            seen.add(f.name)
            hint = str(hints[f.name])
            bad = (INT_BAD if "int" in hint else FLOAT_BAD if "float" in hint else STR_BAD)
            for label, (value, text) in bad.items():
                if (f.name, label) not in SKIP:
                    rows.append((scene, fixed, f.name, label, value, text))
    return rows


TABLE = _table()
IDS = [f"{r[0]}:{r[2]}={r[3]}" for r in TABLE]


@pytest.mark.parametrize("scene, fixed, field, label, value, text", TABLE, ids=IDS)
def test_api_refuses_before_hf_work(scene, fixed, field, label, value, text):
    with hard_limit(), pytest.raises(API_ERRORS) as exc:
        rbbench.reduce(scene, **fixed, **{field: value})
    assert field in str(exc.value), str(exc.value)


#: the command line: int and float flags (argparse's types refuse strings and lists), every
#: component name
CLI_TABLE = [r for r in TABLE if r[3] not in ("list", "bool") or isinstance(r[4], str)]


@pytest.mark.parametrize("scene, fixed, field, label, value, text", CLI_TABLE[::2],
                         ids=[f"{r[0]}:{r[2]}={r[3]}" for r in CLI_TABLE[::2]])
def test_cli_refuses_before_hf_work(scene, fixed, field, label, value, text):
    extra = [x for k, v in fixed.items() for x in (flag(k), v)]
    code, err, outside = run_cli(lambda d, out: ["reduce", scene, *extra, flag(field), text,
                                                 "--out", str(out), "--quiet"])
    assert_rejected(code, err, outside, flag(field))


OTHER = [
    ("membrane_obstacle", {"ntrain": 4}, "ntrain"),
    ("membrane_obstacle", {"Nmax": 4}, "Nmax"),
    ("membrane_obstacle", {"friction_dual": "wedge"}, "friction_dual"),
    ("membrane_obstacle", {"gcns_patience": 2}, "gcns_patience"),
    ("heat_robin", {"dual": "cpg"}, "dual"),
    ("heat_robin", {"solver": "ssn"}, "solver"),
    ("membrane_obstacle", {"hyper": "eim"}, "eim"),
    ("membrane_obstacle", {"dual": "cgp"}, "cgp"),
    ("membrane_obstacle", {"formulation": "nitsche"}, "nitsche"),
    ("hertz_halfdisks", {"formulation": "nitsche", "formulation_options": {"theta": 5}},
     "theta"),
    ("hertz_halfdisks", {"formulation": "nitsche", "formulation_options": {"gamma0": -1}},
     "gamma0"),
    ("hertz_halfdisks", {"formulation": "nitsche", "formulation_options": {"bogus": 1}},
     "bogus"),
    ("hertz_halfdisks", {"formulation": "nitsche", "formulation_options": 5},
     "formulation_options"),
    ("membrane_obstacle", {"backend_options": {"bogus": 1}}, "bogus"),
    ("membrane_obstacle", {"backend_options": "mesh=skfem"}, "backend_options"),
    ("hertz_friction", {"delta_pga": 0.0}, "delta_pga"),
    ("hertz_friction", {"delta_pga": 1.5}, "delta_pga"),
    ("hertz_friction", {"tol_eim": 2.0}, "tol_eim"),
    ("membrane_obstacle", {"tol_pod": 1.0}, "tol_pod"),
    ("membrane_obstacle", {"cache_dir": 5}, "cache_dir"),
]


@pytest.mark.parametrize("scene, fields, named", OTHER,
                         ids=[f"{s}:{','.join(f)}" for s, f, _ in OTHER])
def test_api_other_fields(scene, fields, named):
    with hard_limit(), pytest.raises(API_ERRORS) as exc:
        rbbench.reduce(scene, **fields)
    assert named in str(exc.value), str(exc.value)


MUS = [("nan", math.nan), ("inf", math.inf), ("outside", 5.0), ("str", "abc"),
       ("bool", True), ("two", [0.5, 5.0, 1.0]), ("empty", []), ("nested", [[1.0]]),
       ("dict-unknown", {"bogus": 1.0}), ("dict-nan", {"height": math.nan}),
       ("object", object()), ("huge", 10**400)]


@pytest.mark.parametrize("label, mu", MUS, ids=[m[0] for m in MUS])
def test_api_solve_refuses_bad_mu(label, mu):
    with hard_limit(), pytest.raises(ValueError) as exc:
        rbbench.solve("membrane_obstacle", mu=mu)
    assert "membrane_obstacle" in str(exc.value), str(exc.value)


SOLVE_OPTIONS = [({"backend": "bogus"}, "bogus"), ({"formulation": "bogus"}, "bogus"),
                 ({"solver": "newton"}, "newton"),
                 ({"backend_options": {"bogus": 1}}, "bogus"),
                 ({"formulation": "nitsche", "formulation_options": {"theta": math.nan}},
                  "theta"),
                 ({"formulation": "nitsche", "formulation_options": {"gamma0": 1e308}},
                  "gamma0")]


@pytest.mark.parametrize("options, named", SOLVE_OPTIONS, ids=[n for _, n in SOLVE_OPTIONS])
def test_api_solve_refuses_bad_options(options, named):
    with hard_limit(), pytest.raises(API_ERRORS) as exc:
        rbbench.solve("hertz_halfdisks", **options)
    assert named in str(exc.value), str(exc.value)


OVERRIDES = [["discretization.n_cells=abc"], ["nosection.key=1"], ["x=" + "[" * 100_000],
             ["load.source=nan"], ["discretization.level=-1"], ["noequals"], [5]]


@pytest.mark.parametrize("overrides", OVERRIDES, ids=range(len(OVERRIDES)))
def test_api_load_scene_refuses_bad_overrides(overrides):
    with hard_limit(), pytest.raises(ValueError):
        rbbench.load_scene("membrane_obstacle", overrides)

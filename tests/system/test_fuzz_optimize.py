"""Generated hostile inputs of ``rbbench optimize``: every shape-scene key crossed with values
of the wrong type, non-finite and out-of-range values (``--set`` and scene files), unknown
sections and keys, the optimiser's flags; huge, binary and deeply nested scene files.

Each is refused with exit 2 and a message naming the key (or flag, or file) and what is
valid, before the optimisation starts (its entry point fails the test if called), within a
hard time limit, writing nothing outside the output directory.
"""

from __future__ import annotations

import pytest
from support.fuzz import (
    HUGE_INTS,
    NOT_FINITE,
    NOT_INTEGERS,
    NOT_NUMBERS,
    assert_rejected,
    ids,
    refuse_work,
    run_cli,
)

import rbbench.optim.run as optim_run
from rbbench.optim.shape_scene import _FIELDS, SHAPE_DIR

pytestmark = pytest.mark.timeout(120)

SCENE = (SHAPE_DIR / "shape_coulomb.toml").read_text()


@pytest.fixture(autouse=True)
def no_optimization(monkeypatch):
    refuse_work(monkeypatch, [(optim_run, "run_optimization")])


#: out-of-range values per key (TOML literals), beside the type-generic ones
OUT_OF_RANGE = {
    "geometry.a": ["2.0", "5", "1e308", "-1e308"],
    "geometry.b": ["0.0", "-1", "1e308", "-1e308"],
    "geometry.gamma": ["0", "-1", "0.5", "1e308"],
    "geometry.contact_nodes": ["1", "0", "-1", "10002"],
    "geometry.ny": ["0", "-1", "1000000"],
    "material.E": ["0", "-1", "-1e308", "1e-300"],
    "material.nu": ["0.5", "-0.1", "1", "0.7"],
    "load.pressure": ["0", "-1", "1e308", "-1e308"],
    "load.traction": ["1e308", "-1e308"],
    "friction.coefficient": ["-1", "-1e-9", "1e308"],
    "friction.slip_scale": ["0", "-1", "1e-320"],
    "design.C0": ["0", "-1", "1.0", "1e308"],
    "design.C1": ["0", "-1"],
    "design.C2": ["2.5", "1e308"],
    "design.C3": ["1.0", "-1"],
    "design.initial_height": ["-1", "1e308", "5"],
    "objective.power": ["1", "0", "-1", "33", "1000"],
}


def _table() -> list[tuple[str, str, str]]:
    rows = []
    for sec, keys in _FIELDS.items():
        for key, typ in keys.items():
            k = f"{sec}.{key}"
            generic = dict(NOT_NUMBERS) if typ is not str else {
                "int": ("5", 5), "bool": ("true", True), "list": ('["flat"]', ["flat"]),
                "other": ('"circle"', "circle"), "empty": ('""', "")}
            if typ is float:
                generic |= NOT_FINITE
            if typ is int:
                generic |= NOT_FINITE | NOT_INTEGERS | HUGE_INTS
            rows += [(k, label, lit) for label, (lit, _) in generic.items()]
            rows += [(k, v, v) for v in OUT_OF_RANGE.get(k, [])]
    return rows


TABLE = _table()


@pytest.mark.parametrize("key, label, literal", TABLE, ids=ids(TABLE))
def test_shape_key_by_set(key, label, literal):
    code, err, outside = run_cli(lambda d, out: ["optimize", "--set", f"{key}={literal}",
                                                 "--out", str(out), "--quiet"])
    assert_rejected(code, err, outside, key.split(".")[1])


#: a sample of the table written into scene files (the loader, not only --set)
FILE_TABLE = TABLE[::4]


@pytest.mark.parametrize("key, label, literal", FILE_TABLE, ids=ids(FILE_TABLE))
def test_shape_key_in_a_file(key, label, literal):
    sec, k = key.split(".")
    lines = []
    for line in SCENE.splitlines():
        lines.append(f"{k} = {literal}" if line.split("=")[0].strip() == k else line)
    code, err, outside = run_cli(
        lambda d, out: ["optimize", str(d / "s.toml"), "--out", str(out), "--quiet"],
        {"s.toml": "\n".join(lines) + "\n"})
    assert_rejected(code, err, outside, "s.toml", k)


UNKNOWN = [("design.CO", "CO"), ("geometry.A", "A"), ("nosection.x", "[nosection]"),
           ("scene.nme", "nme"), ("objective.Power", "Power"), ("design", "SECTION.KEY"),
           ("=1", "SECTION.KEY"), ("material.E.x", "E.x")]


@pytest.mark.parametrize("key, named", UNKNOWN)
def test_unknown_keys(key, named):
    code, err, outside = run_cli(lambda d, out: ["optimize", "--set", f"{key}=1",
                                                 "--out", str(out), "--quiet"])
    assert_rejected(code, err, outside, named)


NAMES = ['"../x"', '"a/b"', '".hidden"', '""', '"x y"', "5", '"' + "x" * 100 + '"',
         '"/tmp/x"', '".."', '"a\\u0000b"']


@pytest.mark.parametrize("name", NAMES)
def test_unsafe_scene_names(name):
    code, err, outside = run_cli(lambda d, out: ["optimize", "--set", f"scene.name={name}",
                                                 "--quiet"])
    assert_rejected(code, err, outside, "scene.name")


FLAGS = [("--eps", v) for v in ("nan", "inf", "-1", "0", "-inf", "abc", "1e309", "2")] + \
        [("--max-iter", v) for v in ("0", "-1", "2.5", "abc", "1e9")] + \
        [("--max-evals", v) for v in ("0", "-3", "x")] + \
        [("--driver", "fem"), ("--method", "newton"), ("--metric", "l2")]


@pytest.mark.parametrize("flag, value", FLAGS)
def test_optimizer_flags(flag, value):
    code, err, outside = run_cli(lambda d, out: ["optimize", flag, value, "--out", str(out),
                                                 "--quiet"])
    assert_rejected(code, err, outside, flag.lstrip("-").split("-")[0])


FILES = [
    ("binary", b"\x00\x01\xff\xfe" * 64, "UTF-8"),
    ("huge", b"# " + b"x" * 2_000_000 + b"\n", "bytes"),
    ("deep", ("a = " + "[" * 100_000 + "]" * 100_000).encode(), "s.toml"),
    ("not toml", b"[geometry\nb = 2", "TOML"),
    ("empty table", b"geometry = 5\n", "[geometry]"),
    ("directory", None, "directory"),
]


@pytest.mark.parametrize("label, content, named", FILES, ids=[f[0] for f in FILES])
def test_unreadable_scene_files(label, content, named):
    files = {"s.toml/keep": "x"} if content is None else {"s.toml": content}
    code, err, outside = run_cli(
        lambda d, out: ["optimize", str(d / "s.toml"), "--out", str(out), "--quiet"], files)
    assert_rejected(code, err, outside, "s.toml", named)


def test_a_contact_scene_is_not_a_shape_scene():
    code, err, outside = run_cli(
        lambda d, out: ["optimize", "problems/hertz_halfdisks.toml", "--out", str(out)])
    assert_rejected(code, err, outside, "hertz_halfdisks")

"""Malformed scene files, matrix files and command lines: rejected before anything runs.

Generated inputs (hypothesis, derandomized) are run through ``rbbench.cli.main`` in this
process, each under a hard time limit (SIGALRM), from an empty working directory. Every
one must exit with status 2 and a message naming the file (or option) and the key, with
no traceback, and nothing may be written outside the output directory given.
"""

from __future__ import annotations

import contextlib
import io
import json
import math
import os
import tempfile
from pathlib import Path

import pytest
import tomllib

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from support.fuzz import hard_limit  # noqa: E402

from rbbench.cli import main  # noqa: E402
from rbbench.scene.limits import NAME_PATTERN, PARAMETER_PATTERN, check_name  # noqa: E402
from rbbench.scene.loading import PROBLEMS_DIR  # noqa: E402
from rbbench.scene.schema import SCHEMA  # noqa: E402

pytestmark = pytest.mark.timeout(300)

LIMIT_S = 30  # per input
SETTINGS = settings(derandomize=True, deadline=None, database=None,
                    suppress_health_check=list(HealthCheck), max_examples=70)
MEMBRANE = (PROBLEMS_DIR / "membrane_obstacle.toml").read_text()
HERTZ = (PROBLEMS_DIR / "hertz_halfdisks.toml").read_text()
MATRIX = """[matrix]
name = "fz"
scenes = ["membrane_obstacle"]
timeout_s = 60
repetitions = 1
seed = 0

[components]
dual = ["cpg"]
stabilizer = ["none"]

[sizes]
pairs = [[3, 3]]

[reduce]
n_train = 5
n_valid = 3

[scene_overrides]
membrane_obstacle = ["discretization.n_cells=6"]
"""


def _an_int(text: str, parse) -> bool:
    """Whether ``text`` parses (TOML or JSON) to an integer: such values may be valid."""
    try:
        v = parse(text)
    except Exception:  # noqa: BLE001 - not a literal: a string
        return False
    return isinstance(v, int)


def _toml_int(text: str) -> bool:
    return _an_int(text, lambda t: tomllib.loads(f"v = {t}")["v"])


def _json_int(text: str) -> bool:
    return _an_int(text, lambda t: json.loads(t) if t.strip() else None)


def _files(root: Path) -> set[str]:
    return {str(p.relative_to(root)) for p in root.rglob("*")
            if p.is_file() or p.is_symlink()}


def run_cli(argv_of, files: dict[str, bytes | str]) -> tuple[int, str, list[str]]:
    """Write ``files`` into a fresh ``inputs/`` directory, run ``main(argv_of(inputs, out))``
    from an empty ``work/`` directory; return the exit code, stderr and the files written
    outside ``work/out`` (and outside ``inputs/``)."""
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp)
        inputs, work = base / "inputs", base / "work" / "deep"
        inputs.mkdir()
        work.mkdir(parents=True)
        out = work / "out"
        for name, content in files.items():
            p = inputs / name
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_bytes(content.encode() if isinstance(content, str) else content)
        before = _files(base)
        err, cwd = io.StringIO(), os.getcwd()
        os.chdir(work)
        try:
            with hard_limit(LIMIT_S), contextlib.redirect_stderr(err), \
                    contextlib.redirect_stdout(io.StringIO()):
                try:
                    code = main(argv_of(inputs, out))
                except SystemExit as exc:  # argparse
                    code = exc.code
        finally:
            os.chdir(cwd)
        outside = sorted(f for f in _files(base) - before
                         if not (base / f).is_relative_to(out))
        return code, err.getvalue(), outside


def assert_rejected(code: int, err: str, outside: list[str], *names: str) -> None:
    assert "Traceback" not in err, err
    assert code == 2, f"exit {code}; stderr: {err}"
    assert err.startswith("rbbench: error:"), err
    for n in names:
        assert n in err, f"{n!r} not named in: {err}"
    assert outside == [], f"written outside the output directory: {outside}"


# ---------------------------------------------------------------------- value generators
def toml_value(v) -> str:
    """A Python value as a TOML literal."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, int):
        return str(v)
    if isinstance(v, str):
        return '"' + "".join(c if c not in '"\\' and 0x20 <= ord(c) != 0x7F else f"\\u{ord(c):04x}"
                             for c in v) + '"'
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(v)


_text = st.text(st.characters(codec="utf-8", exclude_categories=("Cs",)), max_size=12)
_non_numbers = st.one_of(_text, st.booleans(), st.lists(st.integers(), max_size=2),
                         st.just({"a": 1}))
_non_finite = st.sampled_from([math.nan, math.inf, -math.inf])


def bad_value(f) -> st.SearchStrategy:
    """Values that the scene field ``f`` must reject."""
    if f.kind == "float":
        bad = [_non_numbers.filter(lambda v: not (isinstance(v, str) and v.startswith("mu."))),
               _non_finite]
        if f.low is not None:
            bad.append(st.floats(max_value=f.low, allow_nan=False, allow_infinity=False,
                                 exclude_max=not f.low_open).filter(lambda v: v != f.low
                                                                    or f.low_open))
        if f.high is not None:
            bad.append(st.floats(min_value=f.high, allow_nan=False, allow_infinity=False,
                                 exclude_min=not f.high_open))
        return st.one_of(*bad)
    if f.kind == "int":
        bad = [_non_numbers, _non_finite, st.floats(allow_nan=False, allow_infinity=False)
               .filter(lambda v: v != int(v))]
        if f.low is not None:
            bad.append(st.integers(max_value=int(f.low) - 1, min_value=-10**12))
        if f.high is not None:
            bad.append(st.integers(min_value=int(f.high) + 1, max_value=10**12))
        if f.choices is not None:
            bad.append(st.integers().filter(lambda v: v not in f.choices))
        return st.one_of(*bad)
    if f.kind == "str":
        bad = [st.integers(), st.booleans(), st.lists(_text, max_size=2)]
        if f.choices is not None:
            bad.append(_text.filter(lambda v: v not in f.choices))
        return st.one_of(*bad)
    if f.kind == "bool":
        return st.one_of(st.integers(), _text, st.floats())
    if f.kind in ("pair", "point"):
        return st.one_of(_text, st.integers(), st.lists(st.floats(), min_size=3, max_size=4),
                         st.lists(_text, min_size=2, max_size=2))
    return st.one_of(st.integers(), _text)


def _fields(kinds=("float", "int", "str", "bool", "pair", "point")):
    out = []
    for section, fields in SCHEMA.items():
        for key, f in fields.items():
            if f.kind not in kinds or (f.kind == "str" and f.choices is None):
                continue  # any string is a valid description
            out.append((section, key, f))
    return out


def set_key(text: str, section: str, key: str, value: str) -> str:
    """``text`` with ``[section] key = value`` (replaced, or added to the section)."""
    lines = text.splitlines()
    head = f"[{section}]"
    out, in_sec, done = [], False, False
    for line in lines:
        stripped = line.strip()
        if stripped.startswith("["):
            if in_sec and not done:
                out.append(f"{key} = {value}")
                done = True
            in_sec = stripped == head
        elif in_sec and stripped.split("=", 1)[0].strip() == key:
            out.append(f"{key} = {value}")
            done = True
            continue
        out.append(line)
    if not done:
        out += ([] if in_sec else [head]) + [f"{key} = {value}"]
    return "\n".join(out) + "\n"


# ------------------------------------------------------------------------------ scenes
@SETTINGS
@given(data=st.data(), hertz=st.booleans())
def test_fuzz_scene_values(data, hertz):
    section, key, f = data.draw(st.sampled_from(_fields()), label="field")
    value = data.draw(bad_value(f), label="value")
    text = set_key(HERTZ if hertz else MEMBRANE, section, key, toml_value(value))
    code, err, outside = run_cli(
        lambda d, out: ["solve", str(d / "s.toml"), "--out", str(out), "--quiet", "--no-plot"],
        {"s.toml": text})
    assert_rejected(code, err, outside, "s.toml", key)


_UNSAFE = st.one_of(
    st.sampled_from(["../../x/S14", "..", "../..", "a/b", "/tmp/x", ".hidden", "x" * 300,
                     "a\u0000b", "a\nb", "", " ", "a b", "C:\\x", "-rf"]),
    st.text(min_size=1, max_size=8).filter(lambda s: not s.isidentifier()))


@SETTINGS
@given(name=_UNSAFE, where=st.sampled_from(["scene", "parameter"]))
def test_fuzz_unsafe_names(name, where):
    """Names that become paths: refused, nothing written outside the output directory."""
    hypothesis.assume(not check_name(name, NAME_PATTERN if where == "scene"
                                     else PARAMETER_PATTERN))
    if where == "scene":
        text = set_key(MEMBRANE, "scene", "name", toml_value(name))
        key = "[scene] name"
    else:
        text = MEMBRANE.replace("[parameters.height]", f"[parameters.{toml_value(name)}]")
        text = text.replace('"mu.height"', toml_value(f"mu.{name}"))
        key = "[parameters]"
    code, err, outside = run_cli(
        lambda d, out: ["solve", str(d / "s.toml"), "--quiet", "--no-plot"], {"s.toml": text})
    assert_rejected(code, err, outside, "s.toml", key)


@pytest.mark.parametrize("section, key, value", [
    ("discretization", "level", "6"), ("discretization", "h_max", "1e-9"),
    ("discretization", "h_contact", "1e-7"), ("discretization", "level", "4"),
])
def test_sizes_beyond_the_bound_are_refused_before_meshing(section, key, value):
    text = set_key(HERTZ, section, key, value)
    code, err, outside = run_cli(
        lambda d, out: ["solve", str(d / "s.toml"), "--out", str(out), "--quiet"],
        {"s.toml": text})
    assert_rejected(code, err, outside, "s.toml", "[discretization]", key, "HF dofs",
                    "RBBENCH_MAX_DOFS")


@pytest.mark.parametrize("content, what", [
    (b"\xff\xfe[scene]\nname = 1\n", "UTF-8"),
    ("[scene\nname=", "not valid TOML"),
    ("a = " + "[" * 2000 + "]" * 2000, "s.toml"),
    ("", "[parameters]"),
])
def test_unreadable_scene_files(content, what):
    code, err, outside = run_cli(lambda d, out: ["solve", str(d / "s.toml"), "--quiet"],
                                 {"s.toml": content})
    assert_rejected(code, err, outside, "s.toml", what)


def test_a_directory_as_a_scene_or_matrix():
    for cmd in ("solve", "run"):
        code, err, outside = run_cli(lambda d, out, c=cmd: [c, str(d / "x.toml")],
                                     {"x.toml/keep": "x"})
        assert_rejected(code, err, outside, "x.toml", "directory")


# ---------------------------------------------------------------------------- matrices
_MATRIX_BAD = {
    ("matrix", "timeout_s"): st.one_of(_non_numbers, _non_finite,
                                       st.floats(max_value=0, allow_nan=False), st.just(1e9)),
    ("matrix", "repetitions"): st.one_of(_non_numbers, st.floats(), st.integers(max_value=0),
                                         st.integers(min_value=1001)),
    ("matrix", "seed"): st.one_of(_non_numbers, st.floats(), st.integers(max_value=-1)),
    ("matrix", "name"): _UNSAFE.filter(lambda v: not check_name(v, NAME_PATTERN)),
    ("matrix", "mode"): st.one_of(_text.filter(lambda v: v not in ("rb", "hf")), st.integers()),
    ("matrix", "scenes"): st.one_of(st.just([{"a": 1}]), st.just([]), st.integers(),
                                    st.just([1, 2]), st.just(["membrane_obstacle@../x"])),
    ("reduce", "n_train"): st.one_of(_non_numbers, st.floats(), st.integers(max_value=0),
                                     st.integers(min_value=100_001)),
    ("reduce", "n_valid"): st.one_of(_non_numbers, st.floats(), st.integers(max_value=0)),
    ("reduce", "online_method"): st.one_of(_text, st.integers()),
    ("reduce", "tol_pod"): st.one_of(_non_numbers, _non_finite, st.floats(max_value=0)),
    ("reduce", "online_repeats"): st.one_of(st.floats(), st.integers(max_value=0)),
    ("reduce", "backend_options"): st.one_of(st.integers(), _text),
    ("sizes", "pairs"): st.one_of(st.just([[10**9, 3]]), st.just([[0, 3]]), st.just([[1.5, 2]]),
                                  st.just([3]), st.just([["a", "b"]])),
    ("components", "dual"): st.one_of(st.integers(), st.just([1]), st.just([]),
                                      st.just(["no-such-dual"])),
    ("hf", "repeats"): st.one_of(_non_numbers, st.integers(max_value=0), st.floats()),
}


@SETTINGS
@given(data=st.data(), dry=st.booleans())
def test_fuzz_matrix_values(data, dry):
    (section, key) = data.draw(st.sampled_from(sorted(_MATRIX_BAD)), label="field")
    value = data.draw(_MATRIX_BAD[(section, key)], label="value")
    if section == "reduce" and key == "online_method" and value in ("auto", "nnls", "daqp", "pdas"):
        value = "bogus"
    text = set_key(MATRIX, section, key, toml_value(value))
    if section == "hf":
        text = ('[matrix]\nname = "fz"\nmode = "hf"\nscenes = ["membrane_obstacle"]\n'
                f'[hf]\nrepeats = {toml_value(value)}\n')
    code, err, outside = run_cli(
        lambda d, out: ["run", str(d / "m.toml"), "--out", str(out), "--quiet",
                        "--cache-dir", str(out / "cache"), *(["--dry-run"] if dry else [])],
        {"m.toml": text})
    assert_rejected(code, err, outside, "m.toml", key)


@pytest.mark.parametrize("text, key", [
    ("matrix = 5\n", "matrix"),
    ('[matrix]\nscenes = ["membrane_obstacle"]\n[params]\ndual = 5\n', "[params] dual"),
    ('[matrix]\nscenes = [{a = 1}]\n', "scenes"),
    ('[matrix]\nscenes = ["membrane_obstacle"]\nsizes = 3\n', "sizes"),
    ('[matrix]\nscenes = ["membrane_obstacle"]\n[params.dual.mcpg]\ntol_dual = "x"\n',
     "tol_dual"),
    ('[matrix]\nscenes = ["membrane_obstacle"]\n[params.dual]\nmcpg = 3\n', "mcpg"),
    ('[matrix]\nscenes = ["membrane_obstacle"]\n[scene_overrides]\nmembrane_obstacle = '
     '["discretization.n_cells=abc"]\n', "n_cells"),
    ('[matrix]\nscenes = ["membrane_obstacle"]\nrepetitions = 1000\n[components]\n'
     'dual = ["cpg", "mcpg", "eng", "pod"]\nstabilizer = ["none", "pga", "supremizer"]\n'
     '[sizes]\nN = [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]\n', "cases"),
    (b"\xc3\x28[matrix]\n", "UTF-8"),
])
def test_fixed_matrix_shapes(text, key):
    code, err, outside = run_cli(
        lambda d, out: ["run", str(d / "m.toml"), "--out", str(out), "--dry-run"],
        {"m.toml": text})
    assert_rejected(code, err, outside, "m.toml", key)


# -------------------------------------------------------------------------- command line
_SETS = st.one_of(
    st.sampled_from(["n_valid=abc", "n_valid=-1", "n_valid=0", "n_valid=2.5", "n_train=0",
                     "tol_pod=nan", "tol_pod=-1", "online_method=bogus", "n_train=1e9",
                     "n_valid=true", "k_pga_max=[1]", "exact_max_r=-2"]),
    st.tuples(st.sampled_from(["n_train", "n_valid", "online_repeats", "m_eim"]),
              st.one_of(_text.filter(lambda s: not _json_int(s)),
                        st.integers(max_value=0))).map(lambda t: f"{t[0]}={t[1]}"))


@SETTINGS
@given(s=_SETS, dry=st.booleans())
def test_fuzz_run_set(s, dry):
    key = s.split("=", 1)[0]
    code, err, outside = run_cli(
        lambda d, out: ["run", str(d / "m.toml"), "--out", str(out), "--set", s, "--quiet",
                        *(["--dry-run"] if dry else [])], {"m.toml": MATRIX})
    assert_rejected(code, err, outside, "m.toml", key)


_SCENE_SETS = st.one_of(
    st.sampled_from(["discretization.n_cells=abc", "discretization.n_cells=2.5",
                     "discretization.n_cells=1000000000", "discretization.level=-1",
                     "discretization.level=7", "sampling.n_train=0", "sampling.seed=-1",
                     "obstacle.height=nan", "discretization.degree=3", "scene.name='../x'",
                     "discretization.multiplier=5", "load.source=inf", "nosection.key=1"]),
    st.tuples(st.sampled_from(["discretization.n_cells", "discretization.level",
                               "sampling.n_valid", "discretization.degree"]),
              _text.filter(lambda s: "=" not in s and not _toml_int(s)))
    .map(lambda t: f"{t[0]}={t[1]}"))


@SETTINGS
@given(s=_SCENE_SETS)
def test_fuzz_solve_set(s):
    key = s.split("=", 1)[0].split(".")[-1]
    code, err, outside = run_cli(
        lambda d, out: ["solve", "membrane_obstacle", "--set", s, "--quiet", "--no-plot"], {})
    assert_rejected(code, err, outside, key, "membrane_obstacle")


@pytest.mark.parametrize("extra, what", [
    (["--cache-dir", "FILE"], "--cache-dir"), (["--out", "FILE"], "--out"),
    (["-s", "dual"], "selector"), (["-s", "duel=cpg"], "duel"), (["--jobs", "0"], "jobs"),
    (["--retry", "bogus"], "bogus"),
])
def test_run_options(extra, what):
    def argv(d, out):
        (d / "FILE").write_text("x")
        return ["run", str(d / "m.toml"), "--quiet",
                *[str(d / "FILE") if x == "FILE" else x for x in extra],
                *([] if "--out" in extra else ["--out", str(out)])]

    code, err, outside = run_cli(argv, {"m.toml": MATRIX})
    assert_rejected(code, err, [f for f in outside if not f.endswith("FILE")], what)

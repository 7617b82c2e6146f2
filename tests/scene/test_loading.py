"""Scene files: loading, defaults, validation messages, overrides, parameter domain."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest

from rbbench.scene.loading import PROBLEMS_DIR, Scene, SceneError, load_scene, parse_override
from rbbench.scene.schema import SCHEMA

HERTZ = PROBLEMS_DIR / "hertz_halfdisks.toml"
MEMBRANE = PROBLEMS_DIR / "membrane_obstacle.toml"
HERTZ_TEXT = HERTZ.read_text()


# ---------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------
def write_scene(tmp_path: Path, *edits: tuple[str, str], text: str = HERTZ_TEXT,
                name: str = "bad_scene.toml") -> Path:
    """Write ``text`` with each (old, new) replacement applied exactly once."""
    for old, new in edits:
        assert text.count(old) == 1, f"edit target {old!r} must occur exactly once"
        text = text.replace(old, new)
    path = tmp_path / name
    path.write_text(text)
    return path


def scene_error(path: Path, *fragments: str) -> str:
    """Load ``path``; it must fail with a SceneError naming the file and every fragment."""
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert str(path) in msg, f"file path missing from: {msg}"
    for frag in fragments:
        assert frag in msg, f"{frag!r} missing from: {msg}"
    return msg


# ---------------------------------------------------------------------------
# shipped scenes
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["hertz_halfdisks", "membrane_obstacle"])
def test_shipped_scene_loads_by_name_and_by_path(name):
    by_name = load_scene(name)
    by_path = load_scene(PROBLEMS_DIR / f"{name}.toml")
    assert isinstance(by_name, Scene)
    assert by_name.name == name
    assert by_name.fingerprint() == by_path.fingerprint()
    assert set(SCHEMA) <= set(by_name.data)  # every section present after validation
    for p in by_name.parameters:
        assert p.low < p.high
        assert p.low <= p.default <= p.high
    by_name.check_mu(by_name.default_mu)  # the default lies in D


def test_hertz_scene_contents():
    sc = load_scene("hertz_halfdisks")
    assert sc.param_names == ["mu"]
    np.testing.assert_array_equal(sc.bounds, [[0.7, 1.3]])
    np.testing.assert_array_equal(sc.default_mu, [1.0])
    assert sc.parameters[0].unit == "m"
    assert sc.get("geometry", "kind") == "halfdisks"
    assert sc.is_parametric("geometry", "upper_radius")
    assert not sc.is_parametric("geometry", "lower_radius")
    assert sc.get("geometry", "contact_zone") == (-0.625, -0.375)
    assert sc.material("upper") == (2.0e11, 0.3)
    assert sc.material("lower") == (2.0e11, 0.3)
    assert sc.get("reference", "hertz") is True


def test_membrane_scene_contents():
    sc = load_scene("membrane_obstacle")
    assert sc.param_names == ["height", "curvature"]
    np.testing.assert_array_equal(sc.bounds, [[0.1, 0.4], [2.0, 6.0]])
    np.testing.assert_array_equal(sc.default_mu, [0.25, 4.0])
    assert sc.get("geometry", "kind") == "unit_square"
    assert sc.get("discretization", "multiplier") == "nodal"
    assert sc.value("load", "source") == -8.0
    assert sc.value("obstacle", "height", np.array([0.3, 5.0])) == 0.3
    assert sc.value("obstacle", "curvature", np.array([0.3, 5.0])) == 5.0


def test_defaults_are_filled(tmp_path):
    # membrane does not set these; the schema defaults must appear after validation
    sc = load_scene("membrane_obstacle")
    assert sc.get("scene", "friction") == "none"
    assert sc.get("discretization", "lac_patch") == 2
    assert sc.get("discretization", "level") == 0
    assert sc.get("discretization", "quadrature") == 0
    assert sc.get("geometry", "initial_gap") == 0.0
    assert sc.get("geometry", "lower") == "half_disk"
    assert sc.get("material", "plane") == "strain"
    # a minimal hertz file (optional sections/keys removed) gets the same defaults
    minimal = HERTZ_TEXT.split("[sampling]")[0]  # drops [sampling], [discretization], [reference]
    path = write_scene(tmp_path, text=minimal, name="minimal.toml")
    sc = load_scene(path)
    for key, f in SCHEMA["sampling"].items():
        assert sc.get("sampling", key) == f.default, key
    for key in ("degree", "multiplier", "h_contact", "h_max", "grading", "inner_product"):
        assert sc.get("discretization", key) == SCHEMA["discretization"][key].default, key
    assert sc.get("reference", "hertz") is False
    assert sc.get("scene", "description") != ""  # the file's own value is kept


def test_scene_value_resolves_parameter_reference():
    sc = load_scene("hertz_halfdisks")
    assert sc.get("geometry", "upper_radius") == "mu.mu"
    assert sc.value("geometry", "upper_radius") == 1.0  # default mu
    assert sc.value("geometry", "upper_radius", np.array([0.9])) == pytest.approx(0.9)
    assert sc.value("geometry", "upper_radius", 1.2) == pytest.approx(1.2)
    assert sc.resolve("mu.mu", [0.75]) == pytest.approx(0.75)
    assert sc.value("geometry", "lower_radius", np.array([0.9])) == 1.0  # plain numbers pass
    assert sc.mu_dict(np.array([0.8])) == {"mu": 0.8}


def test_find_unknown_scene_lists_available():
    with pytest.raises(SceneError) as info:
        load_scene("no_such_scene")
    msg = str(info.value)
    assert "no_such_scene" in msg
    assert "hertz_halfdisks" in msg and "membrane_obstacle" in msg


# ---------------------------------------------------------------------------
# malformed files: each message names the file, the key and what is valid
# ---------------------------------------------------------------------------
def test_unknown_top_level_section(tmp_path):
    path = write_scene(tmp_path, ("[reference]", "[bogus]\nx = 1\n\n[reference]"))
    msg = scene_error(path, "'bogus'", "top level")
    for section in ("geometry", "material", "load", "parameters", "discretization"):
        assert section in msg


def test_unknown_key_in_section_lists_valid_keys(tmp_path):
    path = write_scene(tmp_path, ("displacement = 0.05", "displacment = 0.05"))
    msg = scene_error(path, "[load]", "'displacment'", "valid keys")
    assert "displacement" in msg.split("valid keys")[1]
    assert "source" in msg.split("valid keys")[1]


def test_unknown_key_in_material_lists_valid_keys(tmp_path):
    path = write_scene(tmp_path, ("[material.upper]\nE = 2.0e11",
                                  "[material.upper]\nYoung = 1.0\nE = 2.0e11"))
    scene_error(path, "[material.upper]", "'Young'", "valid keys: E, nu")


def test_unknown_key_in_parameter_table(tmp_path):
    path = write_scene(tmp_path, ('unit = "m"', 'units = "m"'))
    scene_error(path, "[parameters.mu]", "'units'", "valid keys", "unit")


def test_string_where_number_expected(tmp_path):
    path = write_scene(tmp_path, ("displacement = 0.05", 'displacement = "five"'))
    scene_error(path, "[load] displacement", "'five'", "a number", "mu.NAME")


def test_string_where_integer_expected(tmp_path):
    path = write_scene(tmp_path, ("n_train = 21", 'n_train = "21"'))
    scene_error(path, "[sampling] n_train", "an integer")


def test_float_where_integer_expected(tmp_path):
    path = write_scene(tmp_path, ("n_valid = 20", "n_valid = 2.5"))
    scene_error(path, "[sampling] n_valid", "an integer", "2.5")


def test_number_where_bool_expected(tmp_path):
    path = write_scene(tmp_path, ("hertz = true", "hertz = 1"))
    scene_error(path, "[reference] hertz", "true or false")


@pytest.mark.parametrize(
    ("edit", "key", "valid"),
    [
        (("[material.upper]\nE = 2.0e11\nnu = 0.3", "[material.upper]\nE = 2.0e11\nnu = 0.5"),
         "[material.upper] nu", "< 0.5"),
        (("[material.lower]\nE = 2.0e11\nnu = 0.3", "[material.lower]\nE = 2.0e11\nnu = -0.1"),
         "[material.lower] nu", ">= 0"),
        (("[material.upper]\nE = 2.0e11", "[material.upper]\nE = -1"),
         "[material.upper] E", "> 0"),
        (("[material.lower]\nE = 2.0e11", "[material.lower]\nE = 0"),
         "[material.lower] E", "> 0"),
        (("initial_gap = 0.001", "initial_gap = -0.001"), "[geometry] initial_gap", ">= 0"),
        (("lower_radius = 1.0", "lower_radius = 0.0"), "[geometry] lower_radius", "> 0"),
        (("displacement = 0.05", "displacement = -0.01"), "[load] displacement", ">= 0"),
        (("h_max = 0.1", "h_max = 1.5"), "[discretization] h_max", "<= 1"),
        (("level = 0", "level = 7"), "[discretization] level", "<= 6"),
        (("n_train = 21", "n_train = 0"), "[sampling] n_train", ">= 1"),
        (("seed = 0", "seed = -3"), "[sampling] seed", ">= 0"),
    ],
    ids=["nu=0.5", "nu<0", "E=-1", "E=0", "gap<0", "R2=0", "d<0", "h_max", "level",
         "n_train", "seed"],
)
def test_out_of_range_value(tmp_path, edit, key, valid):
    path = write_scene(tmp_path, edit)
    scene_error(path, key, "out of range", valid)


def test_non_finite_number(tmp_path):
    path = write_scene(tmp_path, ("displacement = 0.05", "displacement = nan"))
    scene_error(path, "[load] displacement", "finite")


@pytest.mark.parametrize(
    ("edit", "key", "choices"),
    [
        (('multiplier = "lac"', 'multiplier = "p3"'), "[discretization] multiplier",
         ("'lac'", "'p0'", "'p1'", "'nodal'")),
        (('kind = "halfdisks"', 'kind = "disks"'), "[geometry] kind",
         ("'halfdisks'", "'unit_square'")),
        (('lower = "half_disk"', 'lower = "rigid"'), "[geometry] lower",
         ("'half_disk'", "'rigid_flat'")),
        (("degree = 1", "degree = 3"), "[discretization] degree", ("1", "2")),
        (('physics = "elasticity"', 'physics = "plasticity"'), "[scene] physics",
         ("'elasticity'", "'poisson'")),
        (('train = "uniform"', 'train = "sobol"'), "[sampling] train",
         ("'uniform'", "'random'", "'lhs'")),
    ],
    ids=["multiplier", "geometry.kind", "geometry.lower", "degree", "physics", "train"],
)
def test_bad_choice_lists_valid_choices(tmp_path, edit, key, choices):
    path = write_scene(tmp_path, edit)
    msg = scene_error(path, key, "one of")
    for c in choices:
        assert c in msg.split("one of")[1], f"{c} missing from {msg}"


@pytest.mark.parametrize(
    ("edit", "key", "valid"),
    [
        (('kind = "halfdisks"\n', ""), "[geometry] kind", "'halfdisks'"),
        (('name = "hertz_halfdisks"\n', ""), "[scene] name", "a string"),
        (("[material.upper]\nE = 2.0e11\nnu = 0.3\n", ""), "[material] upper", "halfdisks"),
        (("[material.lower]\nE = 2.0e11\nnu = 0.3\n", ""), "[material.lower]", "half_disk"),
        (("[material.upper]\nE = 2.0e11\n", "[material.upper]\n"), "[material.upper] E",
         "a number"),
        (("displacement = 0.05\n", ""), "[load] displacement", "halfdisks"),
        (("lower_radius = 1.0\n", ""), "[geometry] lower_radius", "half_disk"),
        (("range = [0.7, 1.3]\n", ""), "[parameters.mu]", "range"),
    ],
    ids=["geometry.kind", "scene.name", "material.upper", "material.lower", "upper.E",
         "load.displacement", "lower_radius", "parameter range"],
)
def test_missing_required_key(tmp_path, edit, key, valid):
    path = write_scene(tmp_path, edit)
    msg = scene_error(path, key, valid)
    assert "required" in msg or "missing" in msg


def test_rigid_flat_does_not_need_lower_material(tmp_path):
    path = write_scene(tmp_path, ('lower = "half_disk"', 'lower = "rigid_flat"'),
                       ("[material.lower]\nE = 2.0e11\nnu = 0.3\n", ""))
    sc = load_scene(path)
    assert sc.get("geometry", "lower") == "rigid_flat"
    with pytest.raises(SceneError, match=r"\[material\.lower\]"):
        sc.material("lower")


def test_physics_must_match_geometry(tmp_path):
    path = write_scene(tmp_path, ('physics = "elasticity"', 'physics = "poisson"'))
    scene_error(path, "[scene] physics", "'elasticity'")


@pytest.mark.parametrize(
    ("edit", "key"),
    [
        (("contact_zone = [-0.625, -0.375]", "contact_zone = [0.1, -0.1]"),
         "[geometry] contact_zone"),
        (("contact_zone = [-0.625, -0.375]", "contact_zone = [-0.5, -0.5]"),
         "[geometry] contact_zone"),
        (("master_zone = [0.25, 0.75]", "master_zone = [0.25]"), "[geometry] master_zone"),
        (("master_zone = [0.25, 0.75]", 'master_zone = ["a", "b"]'), "[geometry] master_zone"),
        (("range = [0.7, 1.3]", "range = [1.3, 0.7]"), "[parameters.mu] range"),
    ],
    ids=["decreasing", "equal", "one value", "strings", "parameter range"],
)
def test_pair_not_increasing(tmp_path, edit, key):
    path = write_scene(tmp_path, edit)
    scene_error(path, key, "a < b")


def test_pair_outside_its_bounds(tmp_path):
    path = write_scene(tmp_path, ("contact_zone = [-0.625, -0.375]",
                                  "contact_zone = [-0.625, 0.375]"))
    scene_error(path, "[geometry] contact_zone", "[-1, 0]")


def test_reference_to_undeclared_parameter(tmp_path):
    path = write_scene(tmp_path, ('upper_radius = "mu.mu"', 'upper_radius = "mu.nope"'))
    scene_error(path, "[geometry] upper_radius", "'nope'", "not declared", "declared: mu")


def test_reference_in_material_to_undeclared_parameter(tmp_path):
    path = write_scene(tmp_path, ("[material.lower]\nE = 2.0e11",
                                  '[material.lower]\nE = "mu.E"'))
    scene_error(path, "[material.lower] E", "'E'", "not declared", "declared: mu")


def test_parametric_reference_whose_range_is_invalid(tmp_path):
    path = write_scene(
        tmp_path,
        ("[geometry]", "[parameters.E]\nrange = [-1, 1]\n\n[geometry]"),
        ("[material.upper]\nE = 2.0e11", '[material.upper]\nE = "mu.E"'),
    )
    scene_error(path, "[material.upper] E", "E = -1", "out of range", "> 0")


def test_parametric_reference_with_valid_range(tmp_path):
    path = write_scene(
        tmp_path,
        ("[geometry]", "[parameters.E]\nrange = [1.0e11, 3.0e11]\n\n[geometry]"),
        ("[material.upper]\nE = 2.0e11", '[material.upper]\nE = "mu.E"'),
    )
    sc = load_scene(path)
    assert sc.param_names == ["mu", "E"]
    np.testing.assert_allclose(sc.default_mu, [1.0, 2.0e11])  # default: mid-range
    assert sc.material("upper", np.array([1.0, 1.5e11])) == (1.5e11, 0.3)
    with pytest.raises(SceneError, match=r"E = 5e\+11 is outside its domain"):
        sc.check_mu([1.0, 5.0e11])


def test_parametric_reference_invalid_at_upper_end(tmp_path):
    path = write_scene(
        tmp_path,
        ("[geometry]", "[parameters.nu]\nrange = [0.2, 0.5]\n\n[geometry]"),
        ("[material.upper]\nE = 2.0e11\nnu = 0.3", '[material.upper]\nE = 2.0e11\nnu = "mu.nu"'),
    )
    scene_error(path, "[material.upper] nu", "nu = 0.5", "< 0.5")


def test_reference_where_no_reference_allowed(tmp_path):
    path = write_scene(tmp_path, ("h_max = 0.1", 'h_max = "mu.mu"'))
    scene_error(path, "[discretization] h_max", "a number")


def test_invalid_toml_syntax(tmp_path):
    path = write_scene(tmp_path, ("displacement = 0.05", "displacement = = 0.05"))
    msg = scene_error(path, "not valid TOML")
    assert re.search(r"line \d+", msg), msg


def test_parameter_default_outside_range(tmp_path):
    path = write_scene(tmp_path, ("default = 1.0", "default = 2.0"))
    scene_error(path, "[parameters.mu] default", "2", "outside range [0.7, 1.3]")


def test_parameter_default_not_a_number(tmp_path):
    path = write_scene(tmp_path, ("default = 1.0", 'default = "one"'))
    scene_error(path, "[parameters.mu] default", "a number")


def test_parameter_without_default_uses_midpoint(tmp_path):
    path = write_scene(tmp_path, ("range = [0.7, 1.3]\ndefault = 1.0",
                                  "range = [0.7, 1.1]"))
    sc = load_scene(path)
    assert sc.default_mu[0] == pytest.approx(0.9)


def test_no_parameters_at_all(tmp_path):
    block = ('[parameters.mu]\nrange = [0.7, 1.3]\ndefault = 1.0\nunit = "m"\n'
             'description = "radius R1 of the upper half-disk"\n')
    path = write_scene(tmp_path, (block, ""), ('upper_radius = "mu.mu"', "upper_radius = 1.0"))
    scene_error(path, "[parameters]", "declare at least one parameter", "range")


def test_section_that_is_not_a_table(tmp_path):
    path = write_scene(tmp_path, ("[load]\ndisplacement = 0.05\n", ""),
                       ("[scene]", "load = 3\n\n[scene]"))
    scene_error(path, "[load]", "expected a table")


def test_material_body_that_is_not_a_table(tmp_path):
    path = write_scene(tmp_path, ("[material.lower]\nE = 2.0e11\nnu = 0.3\n", ""),
                       ('plane = "strain"', 'plane = "strain"\nlower = 5'))
    scene_error(path, "[material] lower", "expected a table")


# ---------------------------------------------------------------------------
# overrides
# ---------------------------------------------------------------------------
def test_override_float():
    sc = load_scene("hertz_halfdisks", overrides=["load.displacement=0.01"])
    assert sc.get("load", "displacement") == 0.01
    assert isinstance(sc.get("load", "displacement"), float)
    assert sc.overrides == ("load.displacement=0.01",)


def test_override_int_to_float_field_and_int_field():
    sc = load_scene("hertz_halfdisks", overrides=["geometry.lower_radius=2",
                                                  "sampling.n_train = 5"])
    assert sc.get("geometry", "lower_radius") == 2.0
    assert isinstance(sc.get("geometry", "lower_radius"), float)
    assert sc.get("sampling", "n_train") == 5


def test_override_quoted_and_bare_string():
    quoted = load_scene("hertz_halfdisks", overrides=['geometry.lower="rigid_flat"'])
    bare = load_scene("hertz_halfdisks", overrides=["geometry.lower=rigid_flat"])
    assert quoted.get("geometry", "lower") == "rigid_flat"
    assert bare.get("geometry", "lower") == "rigid_flat"
    assert quoted.fingerprint() == bare.fingerprint()


def test_override_bool_and_array():
    sc = load_scene("hertz_halfdisks", overrides=["reference.hertz=false",
                                                  "geometry.contact_zone=[-0.6, -0.4]"])
    assert sc.get("reference", "hertz") is False
    assert sc.get("geometry", "contact_zone") == (-0.6, -0.4)


def test_override_parameter_reference_and_nested_key():
    sc = load_scene("hertz_halfdisks", overrides=['load.displacement="mu.mu"',
                                                  "geometry.upper_radius=2.0",
                                                  "material.upper.nu=0.25",
                                                  "parameters.mu.range=[0.8, 1.2]"])
    assert sc.value("load", "displacement", np.array([0.9])) == pytest.approx(0.9)
    assert sc.material("upper") == (2.0e11, 0.25)
    np.testing.assert_array_equal(sc.bounds, [[0.8, 1.2]])


def test_an_approach_beyond_the_radius_is_refused():
    with pytest.raises(SceneError, match=r"\[load\] displacement.*upper_radius = 'mu.mu'"):
        load_scene("hertz_halfdisks", overrides=["load.displacement=0.7"])  # R1 in [0.7, 1.3]
    assert load_scene("hertz_halfdisks", overrides=["load.displacement=0.69"])


def test_override_applies_in_order():
    sc = load_scene("hertz_halfdisks", overrides=["load.displacement=0.01",
                                                  "load.displacement=0.02"])
    assert sc.get("load", "displacement") == 0.02


def test_with_overrides_accumulates():
    sc = load_scene("hertz_halfdisks", overrides=["load.displacement=0.01"])
    sc2 = sc.with_overrides(["discretization.h_max=0.2"])
    assert sc2.overrides == ("load.displacement=0.01", "discretization.h_max=0.2")
    assert sc2.get("load", "displacement") == 0.01
    assert sc2.get("discretization", "h_max") == 0.2


def test_parse_override():
    assert parse_override("load.displacement=0.01") == (["load", "displacement"], 0.01)
    assert parse_override(" a.b = 'x' ") == (["a", "b"], "x")
    assert parse_override("a.b=true") == (["a", "b"], True)
    assert parse_override("a.b=x=y") == (["a", "b"], "x=y")  # split on the first '='


@pytest.mark.parametrize("text", ["nokey", "a=1", "=1", ".a=1", "load.=1"])
def test_malformed_override(text):
    with pytest.raises(SceneError) as info:
        load_scene("hertz_halfdisks", overrides=[text])
    msg = str(info.value)
    assert repr(text) in msg
    assert "section.key" in msg


def test_override_through_a_non_table():
    with pytest.raises(SceneError, match=r"'displacement' is not a table"):
        load_scene("hertz_halfdisks", overrides=["load.displacement.x=1"])


def test_override_with_invalid_value_names_the_key():
    with pytest.raises(SceneError) as info:
        load_scene("hertz_halfdisks", overrides=["material.upper.nu=0.5"])
    msg = str(info.value)
    assert str(HERTZ) in msg and "[material.upper] nu" in msg


def test_override_unknown_key_lists_valid_keys():
    with pytest.raises(SceneError, match=r"\[load\]: unknown key 'displacment'; valid keys"):
        load_scene("hertz_halfdisks", overrides=["load.displacment=0.01"])


def test_override_bad_choice():
    with pytest.raises(SceneError, match=r"'p3' is not valid; expected one of 'lac'"):
        load_scene("hertz_halfdisks", overrides=['discretization.multiplier="p3"'])


def test_overrides_do_not_touch_the_file():
    before = HERTZ.read_text()
    load_scene("hertz_halfdisks", overrides=["load.displacement=0.01"])
    assert HERTZ.read_text() == before
    assert load_scene("hertz_halfdisks").get("load", "displacement") == 0.05


# ---------------------------------------------------------------------------
# fingerprint
# ---------------------------------------------------------------------------
def test_fingerprint_stable():
    a = load_scene("hertz_halfdisks")
    b = load_scene("hertz_halfdisks")
    assert a.fingerprint() == b.fingerprint()
    assert re.fullmatch(r"[0-9a-f]{16}", a.fingerprint())
    # an override that restates the file's value changes nothing
    same = load_scene("hertz_halfdisks", overrides=["load.displacement=0.05"])
    assert same.fingerprint() == a.fingerprint()
    # int vs float spelling of the same number: validated content is the same
    same2 = load_scene("hertz_halfdisks", overrides=["geometry.lower_radius=1"])
    assert same2.fingerprint() == a.fingerprint()


def test_fingerprint_stable_across_paths(tmp_path):
    copy_path = write_scene(tmp_path, name="copy.toml")
    assert load_scene(copy_path).fingerprint() == load_scene("hertz_halfdisks").fingerprint()


@pytest.mark.parametrize("override", ["load.displacement=0.01", "discretization.h_max=0.2",
                                      'geometry.lower="rigid_flat"', "reference.hertz=false",
                                      "parameters.mu.default=0.9"])
def test_fingerprint_changes_with_content(override):
    base = load_scene("hertz_halfdisks").fingerprint()
    assert load_scene("hertz_halfdisks", overrides=[override]).fingerprint() != base


def test_fingerprint_differs_between_scenes():
    assert (load_scene("hertz_halfdisks").fingerprint()
            != load_scene("membrane_obstacle").fingerprint())


# ---------------------------------------------------------------------------
# check_mu: the parameter domain D is closed
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("mu", [0.7, 1.3, 1.0, [0.7], np.array([1.3])])
def test_check_mu_accepts_domain_and_bounds(mu):
    sc = load_scene("hertz_halfdisks")
    out = sc.check_mu(mu)
    assert isinstance(out, np.ndarray) and out.shape == (1,)
    assert out[0] == pytest.approx(float(np.ravel(mu)[0]))


@pytest.mark.parametrize("mu", [0.5, 1.31, 0.6999, float("nan"), float("inf"), -1.0])
def test_check_mu_rejects_outside_domain(mu):
    sc = load_scene("hertz_halfdisks")
    with pytest.raises(SceneError) as info:
        sc.check_mu(mu)
    msg = str(info.value)
    assert "parameter mu" in msg
    assert "[0.7, 1.3]" in msg
    assert "outside its domain" in msg
    assert str(HERTZ) in msg
    if math.isfinite(mu):
        assert f"{mu:g}" in msg
    else:
        assert str(mu) in msg  # 'nan' / 'inf'


def test_check_mu_membrane():
    sc = load_scene("membrane_obstacle")
    np.testing.assert_array_equal(sc.check_mu([0.1, 6.0]), [0.1, 6.0])
    np.testing.assert_array_equal(sc.check_mu([0.4, 2.0]), [0.4, 2.0])
    with pytest.raises(SceneError, match=r"parameter curvature = 7 is outside its domain \[2, 6\]"):
        sc.check_mu([0.2, 7.0])
    with pytest.raises(SceneError, match=r"parameter height = 0\.05 is outside its domain"):
        sc.check_mu([0.05, 4.0])
    with pytest.raises(SceneError, match=r"parameter height = nan"):
        sc.check_mu([float("nan"), 4.0])


@pytest.mark.parametrize("mu", [[0.2], [0.2, 4.0, 1.0], []])
def test_check_mu_wrong_count(mu):
    sc = load_scene("membrane_obstacle")
    with pytest.raises(SceneError) as info:
        sc.check_mu(mu)
    msg = str(info.value)
    assert "2 parameter(s)" in msg
    assert "height" in msg and "curvature" in msg
    assert f"got {len(mu)} value(s)" in msg
    assert str(MEMBRANE) in msg


def test_check_mu_wrong_count_hertz():
    sc = load_scene("hertz_halfdisks")
    with pytest.raises(SceneError, match=r"1 parameter\(s\) \(mu in \[0.7, 1.3\]\); got 2 value"):
        sc.check_mu([1.0, 1.0])

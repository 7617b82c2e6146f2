"""The ``hemispheres`` geometry kind (3D Hertz): the shipped scene, its defaults and the
messages of bad values."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from rbbench.scene.limits import estimate_dofs
from rbbench.scene.loading import PROBLEMS_DIR, SceneError, load_scene

SPHERE = PROBLEMS_DIR / "hertz_sphere.toml"
HALFDISKS = PROBLEMS_DIR / "hertz_halfdisks.toml"


def _write(tmp_path: Path, text: str, *edits: tuple[str, str]) -> Path:
    for old, new in edits:
        assert text.count(old) == 1, old
        text = text.replace(old, new)
    path = tmp_path / "scene.toml"
    path.write_text(text)
    return path


def _error(path: Path, *fragments: str) -> None:
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    for frag in (str(path), *fragments):
        assert frag in msg, f"{frag!r} missing from: {msg}"


def test_hertz_sphere_loads_with_its_keys():
    s = load_scene("hertz_sphere")
    g = s.data["geometry"]
    assert g["kind"] == "hemispheres" and g["symmetry"] == "quarter"
    assert g["contact_cap"] == 0.1 and g["master_cap"] == 0.2
    # the half-disk arcs are not part of a hemispheres scene (nor of its cache key)
    assert "contact_zone" not in g and "master_zone" not in g
    assert s.value("geometry", "upper_radius", [0.8]) == 0.8


def test_rigid_flat_variant_needs_no_lower_body(tmp_path):
    text = SPHERE.read_text().replace('lower = "hemisphere"', 'lower = "rigid_flat"')
    text = text.replace("[material.lower]\nE = 2.0e11\nnu = 0.3\n", "")
    text = text.replace("lower_radius = 1.0\n", "")
    s = load_scene(_write(tmp_path, text))
    assert s.data["geometry"]["lower"] == "rigid_flat"
    two = load_scene("hertz_sphere")
    assert abs(2 * estimate_dofs(s.data) - estimate_dofs(two.data)) <= 2  # ceil per count


def test_cap_defaults_are_filled(tmp_path):
    text = SPHERE.read_text()
    text = "\n".join(line for line in text.splitlines()
                     if not line.startswith(("contact_cap", "master_cap")))
    g = load_scene(_write(tmp_path, text)).data["geometry"]
    assert (g["contact_cap"], g["master_cap"]) == (0.1, 0.2)


@pytest.mark.parametrize("edit, fragments", [
    (('symmetry = "quarter"', 'symmetry = "half"'),
     ("[geometry] symmetry", "'half' is not valid", "'quarter'")),
    (('symmetry = "quarter"', ''), ("[geometry] symmetry", "is required", "hemispheres")),
    (("contact_cap = 0.1 ", "contact_cap = 0.7 "), ("[geometry] contact_cap", "out of range",
                                                     "<= 0.5")),
    (("grading = 0.3", "grading = 1.5"), ("[discretization] grading", "<= 1")),
    (("initial_gap = 0.001", "initial_gap = 0.001\ncontact_zone = [-0.6, -0.4]"),
     ("[geometry] contact_zone", "'halfdisks'", "contact_cap")),
    (('physics = "elasticity"', 'physics = "poisson"'),
     ("[scene] physics", "'hemispheres' needs 'elasticity'")),
])
def test_bad_values_name_key_and_valid_values(tmp_path, edit, fragments):
    _error(_write(tmp_path, SPHERE.read_text(), edit), *fragments)


def test_hemisphere_keys_refused_on_halfdisks(tmp_path):
    path = _write(tmp_path, HALFDISKS.read_text(),
                  ("initial_gap = 0.001", "initial_gap = 0.001\ncontact_cap = 0.1"))
    _error(path, "[geometry] contact_cap", "'hemispheres' only", "'halfdisks'")


def test_displacement_below_the_radius(tmp_path):
    path = _write(tmp_path, SPHERE.read_text(), ("displacement = 0.03", "displacement = 0.8"))
    _error(path, "[load] displacement", "below its radius")


def test_estimated_dofs_grow_with_the_level():
    s = load_scene("hertz_sphere")
    dofs = [estimate_dofs(s.with_overrides([f"discretization.level={k}"]).data)
            for k in range(3)]
    assert dofs[0] < 10_000 and dofs[2] >= 100_000
    assert dofs[0] < dofs[1] < dofs[2]


@pytest.mark.parametrize("kind_file, lower, valid", [
    ("hertz_sphere", "half_disk", "'hemisphere' or 'rigid_flat'"),
    ("hertz_halfdisks", "hemisphere", "'half_disk' or 'rigid_flat'"),
])
def test_lower_body_of_the_other_dimension_is_refused(tmp_path, kind_file, lower, valid):
    text = (PROBLEMS_DIR / f"{kind_file}.toml").read_text()
    text = re.sub(r'(?m)^lower = "[a-z_]+"', f'lower = "{lower}"', text)
    p = tmp_path / "s.toml"
    p.write_text(text)
    with pytest.raises(SceneError, match=r"\[geometry\] lower.*" + re.escape(valid)):
        load_scene(str(p))

"""The optional [reduce] section of a scene: the scene's reduction defaults."""

from __future__ import annotations

import pytest

from rbbench.hf.snapshots.key import snapshot_key
from rbbench.scene.loading import PROBLEMS_DIR, SceneError, load_scene

HERTZ_TEXT = (PROBLEMS_DIR / "hertz_halfdisks.toml").read_text()


def _scene(tmp_path, section: str):
    path = tmp_path / "with_reduce.toml"
    path.write_text(HERTZ_TEXT + "\n" + section + "\n")
    return path


def test_hertz_sphere_caps_the_pga_supremizers():
    assert load_scene("hertz_sphere").data["reduce"] == {"k_pga_max": 20}


def test_absent_section_is_not_filled():
    assert "reduce" not in load_scene("hertz_halfdisks").data


def test_section_is_outside_the_snapshot_key(tmp_path):
    plain = load_scene("hertz_halfdisks")
    capped = load_scene(_scene(tmp_path, "[reduce]\nk_pga_max = 5"))
    assert capped.data["reduce"] == {"k_pga_max": 5}
    assert snapshot_key(capped) == snapshot_key(plain)
    assert capped.fingerprint() != plain.fingerprint()  # the scene's content did change


def test_unknown_key_names_the_valid_ones(tmp_path):
    path = _scene(tmp_path, "[reduce]\nk_max = 5")
    with pytest.raises(SceneError, match=r"\[reduce\].*'k_max'.*valid keys: k_pga_max"):
        load_scene(path)


@pytest.mark.parametrize("value", ["0", "2.5", '"20"', "true"])
def test_bad_cap_names_the_field_and_the_range(tmp_path, value):
    path = _scene(tmp_path, f"[reduce]\nk_pga_max = {value}")
    with pytest.raises(SceneError, match=r"\[reduce\] k_pga_max.*integer"):
        load_scene(path)

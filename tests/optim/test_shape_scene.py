"""Shape scenes: unknown keys, non-finite or unbounded values, names that would become
paths outside the output folder, and files that are not TOML are SceneErrors naming the
file and the key, before any solve."""

from __future__ import annotations

import pytest

from rbbench.optim.shape_scene import MAX_NODES, load_shape_scene
from rbbench.scene.loading import PROBLEMS_DIR, SceneError


@pytest.mark.parametrize("overrides, match", [
    ({"design.CO": 0.5}, r"unknown key design\.CO; \[design\] takes C0"),
    ({"extras.x": 1}, r"unknown section \[extras\]"),
    ({"scene.name": "../../outside"}, r"scene\.name = '\.\./\.\./outside'"),
    ({"design.initial_height": float("nan")}, r"design\.initial_height = nan: expected a finite"),
    ({"geometry.b": float("inf")}, r"geometry\.b = inf: expected a finite"),
    ({"objective.power": 1000}, r"objective\.power = 1000: need an integer in \[2, 32\]"),
    ({"geometry.contact_nodes": 100_000_000}, f"need I <= {MAX_NODES}"),
    ({"geometry.ny": 10**6}, r"geometry\.ny = 1000000: need \(I - 1\) x ny"),
])
def test_bad_shape_scene_values(overrides, match):
    with pytest.raises(SceneError, match=match):
        load_shape_scene("shape_coulomb", overrides)


def test_a_contact_scene_is_not_a_shape_scene():
    with pytest.raises(SceneError, match=r"unknown (section|key)"):
        load_shape_scene(PROBLEMS_DIR / "hertz_halfdisks.toml")


def test_a_binary_file_is_refused(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_bytes(bytes(range(256)))
    with pytest.raises(SceneError, match="bad.toml: not a UTF-8 text file"):
        load_shape_scene(bad)


def test_the_shipped_scene_loads():
    assert load_shape_scene("shape_coulomb").name == "shape_coulomb"

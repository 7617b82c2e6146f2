"""scene.parameters.ParameterSpace.check: mu as numbers or by name; anything else is a
SceneError naming the scene, the parameters and their domains."""

from __future__ import annotations

import numpy as np
import pytest

import rbbench
from rbbench.scene.loading import SceneError, load_scene


@pytest.fixture(scope="module")
def space():
    return load_scene("membrane_obstacle").parameter_space


def test_mu_by_name_equals_mu_by_position(space):
    by_name = space.check({"curvature": 5.0, "height": 0.3})
    assert by_name.tolist() == space.check([0.3, 5.0]).tolist() == [0.3, 5.0]


@pytest.mark.parametrize("mu, match", [
    ("abc", "give 2 number"), (["0.3", 5.0], "give 2 number"), (True, "give 2 number"),
    ({"height": 0.3}, r"missing: \['curvature'\]"),
    ({"height": 0.3, "curvature": 5.0, "width": 1.0}, r"unknown: \['width'\]"),
    ([0.3], "has 2 parameter"), ([0.3, np.nan], "curvature = nan is outside"),
    ([0.3, 7.0], r"curvature = 7 is outside its domain \[2, 6\]"),
])
def test_bad_mu_is_a_scene_error(space, mu, match):
    with pytest.raises(SceneError, match=match) as err:
        space.check(mu)
    assert "membrane_obstacle" in str(err.value)


def test_the_api_takes_mu_by_name():
    sol = rbbench.solve("membrane_obstacle", mu={"height": 0.3, "curvature": 5.0})
    assert sol.result.converged

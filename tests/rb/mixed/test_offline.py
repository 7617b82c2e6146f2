"""The mixed reduction's checks before any HF work: the scene's [reduce] defaults."""

from __future__ import annotations

import pytest

from rbbench.rb.config import make_config
from rbbench.rb.offline import prepare_config
from rbbench.registry import default_registry
from rbbench.scene.loading import load_scene

#: a 3D scene's checks mesh it (Netgen, an extra): skipped without it
_NETGEN = pytest.mark.netgen


@pytest.mark.parametrize(("scene", "given", "expected"), [
    pytest.param("hertz_sphere", {}, 20, marks=_NETGEN),  # the scene's cap where none is given
    pytest.param("hertz_sphere", {"k_pga_max": 50}, 50, marks=_NETGEN),  # a given cap wins
    ("hertz_halfdisks", {}, None),  # a scene without [reduce]: uncapped
])
def test_scene_cap_applies_where_none_is_given(scene, given, expected):
    _, config = prepare_config(load_scene(scene), make_config(N=20, R=20, **given),
                               default_registry())
    assert config.options.k_pga_max == expected


@_NETGEN
def test_scene_cap_leaves_other_stabilizers_alone():
    _, config = prepare_config(load_scene("hertz_sphere"),
                               make_config(N=20, R=20, stabilizer="none"), default_registry())
    assert config.options.k_pga_max is None

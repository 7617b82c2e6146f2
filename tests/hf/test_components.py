"""The checks of the HF component names against a scene, before any meshing."""

from __future__ import annotations

import pytest

from rbbench.hf.components import check_names
from rbbench.registry import default_registry
from rbbench.scene.loading import SceneError, load_scene


def test_3d_scene_refuses_a_backend_without_hemispheres():
    """A backend that declares its geometry kinds without 'hemispheres' is refused (a copy
    of the registry with ngsolve's declaration narrowed)."""
    from rbbench.registry import ComponentSpec, Registry

    reg = Registry()
    for spec in default_registry().specs():
        if spec.role == "backend" and spec.name == "ngsolve":
            caps = {**spec.capabilities, "geometry": ("halfdisks", "unit_square")}
            spec = ComponentSpec(**{**spec.__dict__, "capabilities": caps})
        reg.add(spec)
    scene = load_scene("hertz_sphere")
    with pytest.raises(SceneError, match=r"'ngsolve' backend supports 'halfdisks', "
                                         r"'unit_square'; backends for 'hemispheres': 'skfem'"):
        check_names(scene, reg, "ngsolve", "mixed", None)


def test_3d_scene_takes_nitsche_and_refuses_a_formulation_needing_more(monkeypatch):
    """Nitsche needs the slave normal stress, which the 3D backends build; a formulation that
    needs the tangential operators too (Nitsche's needs widened for the test) is refused,
    naming the valid formulations."""
    from rbbench_plugins.formulations.nitsche import NitscheFormulation

    scene = load_scene("hertz_sphere")
    for backend in ("skfem", "ngsolve"):
        assert check_names(scene, default_registry(), backend, "nitsche", None) == "newton"
    monkeypatch.setattr(NitscheFormulation, "needs", frozenset({"stress", "tangential"}))
    with pytest.raises(SceneError, match=r"'nitsche' needs tangential operators \(valid "
                                         r"formulations: 'mixed', 'nitsche'\)"):
        check_names(scene, default_registry(), "skfem", "nitsche", None)


def test_3d_scene_takes_skfem_mixed_and_2d_scenes_are_unchanged():
    reg = default_registry()
    for backend in ("skfem", "ngsolve"):
        assert check_names(load_scene("hertz_sphere"), reg, backend, "mixed", None)
    for backend in ("skfem", "ngsolve"):
        assert check_names(load_scene("hertz_halfdisks"), reg, backend, "nitsche", None)


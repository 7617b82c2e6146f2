"""The checks of the HF component names against a scene, before any meshing."""

from __future__ import annotations

import importlib.util

import pytest

from rbbench.hf.components import check_names
from rbbench.registry import default_registry
from rbbench.scene.loading import SceneError, load_scene

HAS_NETGEN = importlib.util.find_spec("netgen") is not None


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


@pytest.mark.skipif(not HAS_NETGEN, reason='Netgen not installed: pip install "rbbench[ngsolve]"')
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



@pytest.mark.skipif(not HAS_NETGEN, reason='Netgen not installed: pip install "rbbench[ngsolve]"')
def test_3d_scene_takes_skfem_and_ngsolve_mixed():
    reg = default_registry()
    for backend in ("skfem", "ngsolve"):
        assert check_names(load_scene("hertz_sphere"), reg, backend, "mixed", None)


def test_3d_scene_without_netgen_is_refused_before_meshing(monkeypatch):
    """Without Netgen (a base install), the 3D scene is refused by the HF name check and by
    the reduction's configuration check, naming the extra that brings it; 2D scenes are
    not affected."""
    import rbbench
    from rbbench.rb.config import ReduceConfig
    from rbbench.rb.offline import prepare_config

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "netgen" else real(name, *a))
    reg = default_registry()
    msg = r"meshed by Netgen, which comes with NGSolve and is not installed: pip install"
    with pytest.raises(SceneError, match=msg):
        check_names(load_scene("hertz_sphere"), reg, "skfem", "mixed", None)
    with pytest.raises(SceneError, match=msg):
        rbbench.solve("hertz_sphere")
    with pytest.raises(SceneError, match=msg):
        prepare_config(load_scene("hertz_sphere"), ReduceConfig(), reg)
    assert check_names(load_scene("hertz_halfdisks"), reg, "skfem", "mixed", None) == "ssn"


def test_2d_scenes_take_both_backends_with_nitsche():
    reg = default_registry()
    for backend in ("skfem", "ngsolve"):
        assert check_names(load_scene("hertz_halfdisks"), reg, backend, "nitsche", None)


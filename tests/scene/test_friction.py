"""Scene section ``[friction]`` and the friction loads of ``[load]``:
valid input, the value at mu, cache keys of frictionless scenes, bad input naming the key."""

from __future__ import annotations

import re

import numpy as np
import pytest

from rbbench.hf.algebra.friction import COEFFICIENT_LAWS
from rbbench.hf.snapshots.key import snapshot_key
from rbbench.scene.friction import (
    COEFFICIENT_LAW_NAMES,
    Friction,
    friction_of,
    friction_value,
    tangential_displacement,
)
from rbbench.scene.loading import PROBLEMS_DIR, SceneError, load_scene

HERTZ = "hertz_halfdisks"
COULOMB = ['friction.law="coulomb"', "friction.coefficient=0.2"]
TRESCA = ['friction.law="tresca"', "friction.threshold=1e6"]
SHEAR = ["load.tangential_displacement=0.002",
         "load.load_steps=[{normal = 1.0}, {normal = 1.0, tangential = 1.0}]"]


def _error(overrides: list[str], scene: str = HERTZ) -> str:
    with pytest.raises(SceneError) as info:
        load_scene(scene, overrides)
    return str(info.value)


# ---------------------------------------------------------------------------
# valid input
# ---------------------------------------------------------------------------
def test_absent_section_is_frictionless_and_adds_nothing():
    for name in ("hertz_halfdisks", "membrane_obstacle"):
        sc = load_scene(name)
        assert "friction" not in sc.data
        assert not any(k in sc.data["load"] for k in ("tangential_displacement", "load_steps"))
        f = friction_of(sc)
        assert f == Friction() and not f.active and f.steps == ((1.0, 1.0),)
        assert tangential_displacement(sc) == 0.0
        assert friction_value(sc, "coefficient") is None


@pytest.mark.parametrize("name", ["hertz_halfdisks", "membrane_obstacle"])
def test_defaults_stay_out_of_fingerprints_and_snapshot_keys(name):
    """``[friction] law = "none"`` (the default) keeps the cache keys of the scene without
    the section; a friction scene gets other keys."""
    base = load_scene(name)
    same = load_scene(name, ['friction.law="none"'])
    assert same.data["friction"] == {"law": "none"}
    assert same.fingerprint() == base.fingerprint()
    for kw in ({}, {"backend": "ngsolve", "formulation": "nitsche", "solver": "newton"}):
        assert snapshot_key(same, **kw) == snapshot_key(base, **kw)
    if name == HERTZ:
        for extra in (COULOMB, TRESCA, COULOMB + SHEAR):
            other = load_scene(name, extra)
            assert other.fingerprint() != base.fingerprint()
            assert snapshot_key(other) != snapshot_key(base)


def test_coulomb_constant_parametric_and_coefficient_law():
    sc = load_scene(HERTZ, COULOMB)
    f = friction_of(sc)
    assert f.law == "coulomb" and f.active and f.coefficient == 0.2 and f.threshold is None
    assert f.coefficient_law is None and friction_value(sc, "coefficient") == 0.2
    sc = load_scene(HERTZ, ['friction.law="coulomb"', 'friction.coefficient="mu.mu"'])
    assert friction_value(sc, "coefficient", np.array([0.8])) == 0.8
    sc = load_scene(HERTZ, ['friction.law="coulomb"', 'friction.coefficient="model_b"'])
    assert friction_of(sc).coefficient_law == "model_b"
    assert friction_value(sc, "coefficient", sc.default_mu) == "model_b"
    # the boundary values are valid: nu_F = 0 reproduces the frictionless problem
    assert friction_of(load_scene(HERTZ, COULOMB[:1] + ["friction.coefficient=0"])).active


def test_tresca_threshold_and_load_steps():
    sc = load_scene(HERTZ, TRESCA + SHEAR)
    f = friction_of(sc)
    assert f.law == "tresca" and f.threshold == 1e6 and f.coefficient is None
    assert f.tangential_displacement == 0.002 and tangential_displacement(sc) == 0.002
    assert f.steps == ((1.0, 0.0), (1.0, 1.0))
    assert sc.data["load"]["load_steps"] == [{"normal": 1.0, "tangential": 0.0},
                                             {"normal": 1.0, "tangential": 1.0}]
    sc = load_scene(HERTZ, ['friction.law="tresca"', "friction.threshold=0",
                            'load.tangential_displacement="mu.mu"'])
    assert tangential_displacement(sc, np.array([1.2])) == 1.2
    assert friction_of(sc).steps == ((1.0, 1.0),)  # one step with the full loads
    # a negative tangential fraction (reverse shear) is a valid step
    sc = load_scene(HERTZ, TRESCA + ["load.tangential_displacement=0.001",
                                     "load.load_steps=[{normal=1.0, tangential=-0.5}]"])
    assert friction_of(sc).steps == ((1.0, -0.5),)


def test_old_coefficient_law_name_still_loads_with_a_deprecation_warning():
    """``"seed001"`` (the deprecated alias), the former name of ``"model_b"``, loads as
    ``"model_b"`` and warns."""
    with pytest.warns(DeprecationWarning, match="'seed001' is now 'model_b'"):
        sc = load_scene(HERTZ, ['friction.law="coulomb"', 'friction.coefficient="seed001"'])
    assert friction_of(sc).coefficient_law == "model_b"
    new = load_scene(HERTZ, ['friction.law="coulomb"', 'friction.coefficient="model_b"'])
    assert sc.fingerprint() == new.fingerprint()


def test_coefficient_law_names_match_the_hf_registry():
    """The scene layer names the laws that :mod:`rbbench.hf.algebra.friction` defines."""
    assert set(COEFFICIENT_LAW_NAMES) == set(COEFFICIENT_LAWS)


def test_scene_file_with_a_friction_section(tmp_path):
    text = (PROBLEMS_DIR / "hertz_halfdisks.toml").read_text()
    text += '\n[friction]\nlaw = "coulomb"\ncoefficient = 0.2\n'
    path = tmp_path / "fric.toml"
    path.write_text(text)
    assert friction_of(load_scene(path)).coefficient == 0.2
    path.write_text(text.replace("coefficient = 0.2", "coefficient = -1.0"))
    with pytest.raises(SceneError, match=re.escape(f"{path}: [friction] coefficient")):
        load_scene(path)


# ---------------------------------------------------------------------------
# bad input: the file, the key, what is valid
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("overrides, fragments", [
    (['friction.law="coulomb"', "friction.coefficient=-0.2"],
     ["[friction] coefficient", "-0.2 is out of range", "a number >= 0", "'model_b'"]),
    (['friction.law="coulomb"', 'friction.coefficient="model_c"'],
     ["[friction] coefficient", "'model_c' is not valid", "'model_b'"]),
    (['friction.law="coulomb"', 'friction.coefficient="mu.radius"'],
     ["[friction] coefficient", "parameter 'radius'", "declared: mu"]),
    (['friction.law="coulomb"', "friction.coefficient=true"],
     ["[friction] coefficient", "expected a number >= 0"]),
    (['friction.law="coulomb"'], ["[friction] coefficient", "is required for law = 'coulomb'"]),
    (['friction.law="tresca"', "friction.threshold=inf"],
     ["[friction] threshold", "expected a finite number", "inf"]),
    (['friction.law="tresca"', "friction.threshold=nan"], ["[friction] threshold", "finite"]),
    (['friction.law="tresca"', "friction.threshold=-1.0"],
     ["[friction] threshold", "out of range", ">= 0"]),
    (['friction.law="tresca"'], ["[friction] threshold", "is required for law = 'tresca'"]),
    (['friction.law="tresca"', "friction.threshold=1.0", "friction.coefficient=0.1"],
     ["[friction] coefficient", "applies to law = 'coulomb' only", "law = 'tresca'"]),
    (["friction.threshold=1.0"], ["[friction] threshold", "applies to law = 'tresca' only"]),
    (['friction.law="stick"'],
     ["[friction] law", "'stick' is not valid", "'none', 'tresca', 'coulomb'"]),
    (["friction.nu_F=0.2"], ["[friction]", "unknown key 'nu_F'", "coefficient, law, threshold"]),
    (["load.tangential_displacement=0.001"],
     ["[load] tangential_displacement", "need friction", "[friction] law = 'tresca'"]),
    (['friction.law="none"', "load.load_steps=[{normal=1.0}]"],
     ["[load] load_steps", "need friction"]),
    (COULOMB + ["load.tangential_displacement=inf"],
     ["[load] tangential_displacement", "finite"]),
    (COULOMB + ["load.load_steps=[]"], ["[load] load_steps", "non-empty list of tables"]),
    (COULOMB + ["load.load_steps=[1.0, 2.0]"], ["[load] load_steps", "non-empty list"]),
    (COULOMB + ["load.load_steps=[{normal=1.0, shear=1.0}]"],
     ["[load] load_steps[0]", "unknown key 'shear'", "normal, tangential"]),
    (COULOMB + ["load.load_steps=[{normal=-1.0}]"],
     ["[load] load_steps[0] normal", "out of range", ">= 0"]),
    (COULOMB + ["load.load_steps=[{normal=1.0}, {normal=1.0, tangential=1.0}]"],
     ["[load] load_steps[1] tangential", "needs [load] tangential_displacement"]),
    (COULOMB + ["load.load_steps=[" + ", ".join(["{normal=1.0}"] * 2000) + "]"],
     ["[load] load_steps", "2000 steps; at most 100"]),
    (COULOMB + ["load.load_steps=[{normal=1e300}]"],
     ["[load] load_steps[0] normal", "out of range", "at most 10"]),
    (COULOMB + ["load.tangential_displacement=0.001",
                "load.load_steps=[{normal=1.0, tangential=-11.0}]"],
     ["[load] load_steps[0] tangential", "out of range", "at most 10"]),
])
def test_bad_input_names_the_file_and_the_key(overrides, fragments):
    msg = _error(overrides)
    assert msg.startswith(str(PROBLEMS_DIR / "hertz_halfdisks.toml") + ": "), msg
    for fragment in fragments:
        assert fragment in msg, (fragment, msg)


def test_the_largest_number_of_load_steps_loads():
    steps = "[" + ", ".join(["{normal=1.0}"] * 100) + "]"
    sc = load_scene("hertz_halfdisks", COULOMB + [f"load.load_steps={steps}"])
    assert len(sc.data["load"]["load_steps"]) == 100


def test_friction_on_a_scalar_scene_is_an_error():
    msg = _error(COULOMB, scene="membrane_obstacle")
    assert "[friction] law" in msg and "halfdisks" in msg
    msg = _error(["load.tangential_displacement=0.1"], scene="membrane_obstacle")
    assert "[load] tangential_displacement" in msg


def test_parametric_threshold_checked_over_the_whole_range(tmp_path):
    text = (PROBLEMS_DIR / "hertz_halfdisks.toml").read_text().replace(
        "[geometry]", "[parameters.s]\nrange = [-1.0, 1.0]\n\n[geometry]")
    path = tmp_path / "s.toml"
    path.write_text(text)
    with pytest.raises(SceneError, match=re.escape("[friction] threshold (at s = -1)")):
        load_scene(path, ['friction.law="tresca"', 'friction.threshold="mu.s"'])

"""hf.metrics: the volumetric-locking warning of P1 displacements near nu = 1/2."""

from __future__ import annotations

import pytest

import rbbench
from rbbench.hf.metrics import NU_LOCKING, locking_warnings
from rbbench.testing import HERTZ_COARSE


def test_locking_warning_only_for_p1_and_nu_near_one_half():
    assert locking_warnings(1, {"upper": 0.3, "lower": NU_LOCKING - 1e-9}) == []
    assert locking_warnings(2, {"upper": 0.4999}) == []
    (msg,) = locking_warnings(1, {"upper": 0.3, "lower": 0.4999})
    assert "'lower'" in msg and "0.4999" in msg and "degree = 2" in msg


@pytest.mark.parametrize("nu, warned", [(0.3, False), (0.4999, True)])
def test_a_locking_solve_says_so(nu, warned):
    """On the coarse Hertz mesh with P1 displacements, nu = 0.4999 puts the peak pressure
    far from 2D Hertz (the locking the warning names) and the summary warns; nu = 0.3
    neither."""
    scene = rbbench.load_scene("hertz_halfdisks", overrides=[
        *HERTZ_COARSE, "discretization.degree=1", f"material.upper.nu={nu}",
        f"material.lower.nu={nu}"])
    m = rbbench.solve(scene, mu=1.0).metrics
    locking = [w for w in m["warnings"] if "volumetric locking" in w]
    assert bool(locking) == warned
    if warned:
        assert abs(m["hertz"]["p0_rel_error"]) > 0.5


def test_nitsche_discretization_warning_names_both_keys_and_the_remedy():
    """Facet normals or Gauss-point-to-segment integration: a warning naming the key(s) and
    the converging settings; smooth + segmented: none."""
    from rbbench.hf.metrics import nitsche_discretization_warnings as warn

    assert warn({"normals": "smooth", "contact_integration": "segmented"}) == []
    for data in ({}, {"normals": "smooth"}, {"contact_integration": "segmented"}):
        (msg,) = warn(data)
        assert "discretization.normals" in msg and "e_AC does not converge" in msg
        assert 'normals = "smooth"' in msg and 'contact_integration = "segmented"' in msg

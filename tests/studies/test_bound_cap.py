"""The bound-cap study on a coarse two-body scene: one reduction, every cap's bound above the
true error at every validation parameter, the rows as the table prints them; a scene without
the two-body online bound refused with the reason."""

from __future__ import annotations

import numpy as np
import pytest

from rbbench.scene.loading import SceneError, load_scene
from rbbench.studies.bound_cap import bound_cap_study, markdown

COARSE = ["discretization.h_contact=0.04", "discretization.h_max=0.3"]


def test_every_cap_bounds_the_error(tmp_path):
    sc = load_scene("hertz_halfdisks", COARSE)
    out = bound_cap_study(sc, caps=(3, 40, 12), N=4, R=3, n_valid=3, repeats=2,
                          cache_dir=str(tmp_path), n_train=5)
    rows = out["rows"]
    assert [r["cap"] for r in rows] == [40, 12, 3]  # largest first, as built
    for r in rows:
        assert 1 <= r["modes"] <= r["cap"]
        assert r["effectivity_min"] >= 1.0  # the bound holds at every validation mu
        assert r["effectivity_min"] <= r["effectivity_median"] <= r["effectivity_max"]
        assert r["t_bound_ratio"] == pytest.approx(r["t_bound_median_s"]
                                                   / r["t_bound_solve_median_s"])
    # the remainder's part of rho is larger with 3 modes than with all of them
    assert rows[-1]["remainder_share_median"] > rows[0]["remainder_share_median"]
    table = markdown(out).splitlines()
    assert table[0].startswith("hertz_halfdisks: N = 4 + ")
    assert len([t for t in table if t.startswith("| ") and t[2].isdigit()]) == 3
    assert np.isfinite(out["bound_build_s"])


def test_a_scene_without_the_two_body_bound_is_refused(tmp_path):
    sc = load_scene("membrane_obstacle", ["discretization.n_cells=8"])
    with pytest.raises(SceneError, match="no two-body online bound"):
        bound_cap_study(sc, caps=(10,), N=4, R=4, n_valid=2, repeats=1,
                        cache_dir=str(tmp_path), n_train=4)

"""The Netgen-graded unit quarter hemisphere: volume, faces, orientation, grading."""

from __future__ import annotations

import numpy as np
import pytest
from rbbench_plugins.backends.hemisphere_mesh import (
    boundary_triangles,
    cap_chord,
    face_groups,
    mirror_z,
    quarter_hemisphere,
    signed_volumes,
)

pytestmark = pytest.mark.netgen

COARSE = (0.1, 0.08, 0.4, 0.3)  # cap, h_contact, h_max, grading
FINER = (0.1, 0.05, 0.25, 0.3)


def _areas(points, tri):
    p = points[tri]
    return 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)


@pytest.mark.parametrize("sizes", [COARSE, FINER])
def test_volume_and_faces_against_the_quarter_hemisphere(sizes):
    m = quarter_hemisphere(*sizes)
    assert np.all(signed_volumes(m.points, m.tets) > 0)
    # an inscribed polyhedron: a small deficit of the volume pi / 6, O(h_max^2)
    deficit = 1.0 - m.volume / (np.pi / 6)
    assert 0.0 < deficit < 0.5 * sizes[2] ** 2
    tri = boundary_triangles(m.tets)
    groups = face_groups(m.points, tri)
    area = _areas(m.points, tri)
    for name in ("flat", "sym_x", "sym_y"):  # quarter discs of radius 1
        assert 0.0 < 1.0 - area[groups[name]].sum() / (np.pi / 4) < 0.5 * sizes[2] ** 2
    # the sphere's nodes lie on it; the curved area (pi, a quarter of 2 pi) from below
    curved_nodes = np.unique(tri[groups["curved"]])
    np.testing.assert_allclose(np.linalg.norm(m.points[curved_nodes], axis=1), 1.0,
                               atol=1e-9)
    assert 0.0 < 1.0 - area[groups["curved"]].sum() / (np.pi / 2) < 0.5 * sizes[2] ** 2


def test_volume_deficit_falls_under_refinement():
    coarse, finer = (1.0 - quarter_hemisphere(*s).volume / (np.pi / 6) for s in (COARSE, FINER))
    assert finer < 0.5 * coarse


def test_graded_toward_the_pole():
    """Netgen's maxh is a target, not a bound: the median edge near the pole is
    1.21 / 1.32 / 1.27 h_contact at h_contact = 0.08 / 0.05 / 0.03 (measured), so 1.5 here;
    the median edge far from the pole is 5 to 10 times longer (4 asserted)."""
    m = quarter_hemisphere(*FINER)
    t = m.tets
    edge = np.linalg.norm(m.points[t[:, 0]] - m.points[t[:, 1]], axis=1)
    dist = np.linalg.norm(m.points[t].mean(axis=1) - [0.0, 0.0, -1.0], axis=1)
    near = dist < 0.5 * cap_chord(FINER[0])
    assert near.sum() > 10
    assert np.median(edge[near]) <= 1.5 * FINER[1]
    assert np.median(edge[dist > 0.8]) > 4.0 * np.median(edge[near])


def test_mirror_keeps_orientation_and_volume():
    m = quarter_hemisphere(*COARSE)
    up = mirror_z(m)
    assert np.all(signed_volumes(up.points, up.tets) > 0)
    assert up.volume == pytest.approx(m.volume, rel=1e-14)
    assert up.points[:, 2].max() == pytest.approx(1.0, abs=1e-9)


def test_disk_cache_returns_the_same_mesh(tmp_path, monkeypatch):
    import rbbench_plugins.backends.hemisphere_mesh as hm

    monkeypatch.setenv("RBBENCH_MESH_CACHE", str(tmp_path))
    sizes = (0.1, 0.09, 0.45, 0.3)
    hm.quarter_hemisphere.cache_clear()
    first = hm.quarter_hemisphere(*sizes)
    (cached,) = tmp_path.glob("quarter_hemisphere_*.npz")
    hm.quarter_hemisphere.cache_clear()
    calls = []
    monkeypatch.setattr(hm, "_netgen_quarter_hemisphere", lambda *a: calls.append(a))
    again = hm.quarter_hemisphere(*sizes)
    assert not calls  # read from disk, not meshed
    np.testing.assert_array_equal(again.points, first.points)
    np.testing.assert_array_equal(again.tets, first.tets)
    assert not again.points.flags.writeable
    hm.quarter_hemisphere.cache_clear()
    monkeypatch.setenv("RBBENCH_MESH_CACHE", "0")
    assert hm.mesh_cache_dir() is None and cached.exists()

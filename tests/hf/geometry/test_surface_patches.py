"""LAC patches of slave triangles and the radial extent of triangles (3D contact geometry),
and the inf-sup stability of the multiplier spaces with the displacement trace."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sl
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.sparse.csgraph import connected_components
from support.surface_meshes import grid

from rbbench.hf.geometry.surface import SurfaceLayout, contact_operators_3d
from rbbench.hf.geometry.surface_patches import lac_patches, radial_range, triangle_adjacency


def _wavy(x, y):
    return 0.05 * np.sin(3 * x + 1) * np.cos(2 * y)


@settings(max_examples=30, deadline=None)
@given(st.integers(2, 12), st.integers(3, 12))
def test_lac_patches_cover_hold_a_vertex_star_and_are_connected_and_round(size, n):
    s = grid(n, (0.0, 0.0), (1.0, 1.3), _wavy, 1, [0.5, 0.5, -1.0])
    tri = s.triangles
    cen = s.points[tri].mean(axis=1)
    lab = lac_patches(tri, cen, size)
    assert lab.shape == (tri.shape[0],)
    assert np.array_equal(np.unique(lab), np.arange(lab.max() + 1))
    adj = triangle_adjacency(tri)
    counts = np.bincount(lab)
    assert counts.min() >= int(np.ceil(size / 2))
    h = np.hypot(1.0 / n, 1.3 / n)
    for p in range(lab.max() + 1):
        idx = np.flatnonzero(lab == p)
        assert connected_components(adj[idx][:, idx], directed=False)[0] == 1
        # some vertex has its whole star in the patch (an interior vertex of the patch)
        verts = np.unique(tri[idx])
        assert any(np.all(lab[np.any(tri == v, axis=1)] == p) for v in verts)
        # round: diameter of order sqrt(triangles) h on this uniform grid
        pts = s.points[verts]
        diam = np.max(np.linalg.norm(pts[:, None] - pts[None], axis=2))
        assert diam <= 2.5 * np.sqrt(counts[p]) * h


def test_lac_patch_one_is_p0():
    s = grid(3, (0.0, 0.0), (1.0, 1.0), _wavy, 1, [0.5, 0.5, -1.0])
    assert np.array_equal(lac_patches(s.triangles, s.points[s.triangles].mean(axis=1), 1),
                          np.arange(s.n_tri))


@settings(max_examples=50, deadline=None)
@given(st.integers(0, 10**6))
def test_radial_range_brackets_a_dense_sample(seed):
    rng = np.random.default_rng(seed)
    v = rng.uniform(-1.0, 1.0, (3, 20, 3))
    lo, hi = radial_range(*v)
    bary = np.vstack([rng.dirichlet(np.ones(3), 3000), np.eye(3)])
    pts = np.einsum("sk,ktd->tsd", bary, v)
    r = np.hypot(pts[..., 0], pts[..., 1])
    assert np.all(lo <= r.min(axis=1) + 1e-12)
    assert np.all(r.min(axis=1) - lo < 0.05)
    assert np.allclose(hi, r.max(axis=1), rtol=1e-12)


def _l2_inf_sup(n: int, degree: int, multiplier: str, patch: int) -> float:
    """``min_lam max_v (lam, v_n) / (|lam| |v_n|)`` in L2 of a flat slave plate: the
    square root of the smallest eigenvalue of ``B M^-1 B^T x = beta^2 W x``."""
    s = grid(n, (0.0, 0.0), (1.0, 1.0), lambda x, y: np.full_like(x, 0.01), degree,
             [0.5, 0.5, 1.0])
    lay = SurfaceLayout(s, None, degree, 4, multiplier, patch, 3 * s.points.shape[0])
    op = contact_operators_3d(lay, np.array([0.0]))
    cols = np.flatnonzero(abs(op.Un).sum(axis=0).A.ravel())  # the normal (z) dofs
    Un = op.Un[:, cols].toarray()
    M = Un.T @ (op.weights[:, None] * Un)
    B = op.B()[:, cols].toarray()
    ev = sl.eigh(B @ np.linalg.solve(M, B.T), op.W().toarray(), eigvals_only=True)
    return float(np.sqrt(max(ev.min(), 0.0)))


@pytest.mark.parametrize(("degree", "patch", "floor"), [(1, 2, 0.75), (1, 6, 0.75),
                                                        (2, 2, 0.85), (2, 6, 0.85)])
def test_lac_is_inf_sup_stable_under_refinement(degree, patch, floor):
    """LAC (P0 on vertex-star patches) with P1 or P2 displacements: the L2 inf-sup constant
    stays put under refinement (P1: 0.80, 0.79, 0.78; P2: 0.91 at n = 4, 8, 16), where P0
    per triangle loses it (below)."""
    b = [_l2_inf_sup(n, degree, "lac", patch) for n in (4, 8, 16)]
    assert min(b) > floor, b
    assert b[2] > 0.97 * b[1], b


def test_p1_multipliers_in_the_trace_space_have_inf_sup_one():
    """P1 hats lie in the P1 and P2 traces (a flat plate): the constant is exactly 1."""
    assert _l2_inf_sup(4, 1, "p1", 1) == pytest.approx(1.0, rel=1e-10)
    assert _l2_inf_sup(4, 2, "p1", 1) == pytest.approx(1.0, rel=1e-10)


def test_p0_per_triangle_is_unstable_with_p1_and_degrades_with_p2():
    """P0 per triangle: with P1 displacements more multipliers than normal trace dofs
    (2 n^2 > (n + 1)^2), so the constant is 0; with P2 it halves when h halves on this
    mesh (the alternating sign on the triangles is orthogonal to every interior P2 trace),
    the reason for LAC patches."""
    assert _l2_inf_sup(4, 1, "p0", 1) < 1e-6
    b = [_l2_inf_sup(n, 2, "p0", 1) for n in (4, 8)]
    assert b[1] == pytest.approx(0.5 * b[0], rel=0.15), b

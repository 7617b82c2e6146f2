"""3D contact geometry on triangulated surfaces (Gauss-point-to-triangle pairing), against
flat-on-flat and sphere-on-plane facts, rigid motions and linear displacement fields."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import dblquad
from scipy.spatial.transform import Rotation
from support.surface_meshes import grid, sphere_cap

from rbbench.hf.geometry.chains import AffineMap
from rbbench.hf.geometry.pairing import PairingError
from rbbench.hf.geometry.surface import (
    SurfaceLayout,
    TriSurface,
    contact_operators_3d,
    pair_surfaces,
    ray_cast_triangles,
    surface_rows,
)

MU = np.array([1.0])


def _flat(value: float):
    return lambda x, y: np.full_like(x, value)


def _plates(gap: float, degree: int, ns: int = 5, nm: int = 7) -> tuple[TriSurface, TriSurface]:
    """Slave plate [0.1, 0.9]^2 at z = gap (body above), master [0, 1]^2 at z = 0 (below);
    non-matching meshes."""
    s = grid(ns, (0.1, 0.1), (0.9, 0.9), _flat(gap), degree, [0.5, 0.5, gap + 1.0])
    m = grid(nm, (0.0, 0.0), (1.0, 1.0), _flat(0.0), degree, [0.5, 0.5, -1.0],
             first_node=s.points.shape[0])
    return s, m


def _layout(s, m, degree, multiplier="p0", patch=1, quad_order=4) -> SurfaceLayout:
    n = s.points.shape[0] + (0 if m is None else m.points.shape[0])
    return SurfaceLayout(s, m, degree, quad_order, multiplier, patch, 3 * n)


def _field(surfaces, f) -> np.ndarray:
    """The global dof vector of the displacement ``f(x)`` (n, 3) at every node."""
    u = np.zeros(3 * sum(s.points.shape[0] for s in surfaces))
    for s in surfaces:
        u[s.dofs] = f(s.points)
    return u


@pytest.mark.parametrize("degree", [1, 2])
@pytest.mark.parametrize("multiplier", ["p1", "p0", "lac"])
def test_flat_on_flat_gap_translation_jump_and_area(degree, multiplier):
    g = 0.0137
    s, m = _plates(g, degree)
    lay = _layout(s, m, degree, multiplier, patch=4)
    op = contact_operators_3d(lay, MU)
    assert np.allclose(op.gap, g, rtol=1e-13, atol=0)
    assert np.allclose(op.normals, [0.0, 0.0, -1.0], atol=1e-15)
    assert op.weights.sum() == pytest.approx(0.8**2, rel=1e-13)
    vs, vm = np.array([0.3, -0.7, 0.2]), np.array([-0.1, 0.4, 0.9])
    u = np.zeros(lay.n_dofs)
    u[s.dofs] = vs
    u[m.dofs] = vm
    assert np.allclose(op.Un @ u, (vs - vm) @ [0.0, 0.0, -1.0], rtol=1e-13, atol=1e-15)
    # multipliers: p1 hats and P0 indicators sum to one at every point
    assert np.allclose(np.asarray(op.Mlam.sum(axis=1)).ravel(), 1.0)
    assert np.allclose(op.W().sum(), 0.8**2)


def test_p0_multiplier_weights_are_the_triangle_areas_and_extent_brackets_the_support():
    s, m = _plates(0.01, 1, ns=4)
    op = contact_operators_3d(_layout(s, m, 1, "p0"), MU)
    assert np.allclose(np.asarray(op.Mlam.T @ op.weights).ravel(), 0.5 * 0.2**2)
    # brute force: r over a dense sample of each triangle
    bary = np.random.default_rng(3).dirichlet(np.ones(3), 4000)
    bary = np.vstack([bary, np.eye(3)])
    for k in range(s.n_tri):
        v = s.points[s.triangles[k]]
        r = np.hypot(*(bary @ v)[:, :2].T)
        assert op.mult_extent[k, 0] <= r.min() + 1e-12
        assert r.min() - op.mult_extent[k, 0] < 5e-3
        assert op.mult_extent[k, 1] == pytest.approx(r.max(), rel=1e-12)


def test_radial_extent_is_zero_for_a_support_around_the_axis():
    s = grid(4, (-1.0, -1.0), (1.0, 1.0), _flat(0.01), 1, [0.0, 0.0, 1.0])
    op = contact_operators_3d(_layout(s, None, 1, "p1"), MU)
    centre = int(np.argmin(np.linalg.norm(op.mult_points[:, :2], axis=1)))
    assert op.mult_extent[centre, 0] == 0.0
    assert op.mult_extent[centre, 1] == pytest.approx(np.hypot(0.5, 0.5))


def _rigid(surf: TriSurface, rot: Rotation, shift: np.ndarray) -> TriSurface:
    return TriSurface(points=rot.apply(surf.points) + shift, triangles=surf.triangles,
                      dofs=surf.dofs, inside=rot.apply(surf.inside) + shift, map=surf.map)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3),
       st.floats(0.0, np.pi), st.lists(st.floats(-5.0, 5.0), min_size=3, max_size=3),
       st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6), st.sampled_from([1, 2]))
def test_a_rigid_motion_of_both_bodies_keeps_gaps_and_weights(axis, angle, shift, v, degree):
    """Gap and weights are invariant under a rigid motion of the whole scene, normals and
    points move with it, and a translation field ``v_s`` / ``v_m`` jumps by
    ``(v_s - v_m) . n``."""
    axis = np.asarray(axis)
    if np.linalg.norm(axis) < 1e-3:
        axis = np.array([0.0, 0.0, 1.0])
    rot = Rotation.from_rotvec(angle * axis / np.linalg.norm(axis))
    s, m = sphere_cap(4, 1.0, 1.02, 0.4, degree), sphere_cap(6, 1.5, -1.5, 0.6, degree,
                                                              lower=False, first_node=10**3)
    m = TriSurface(m.points, m.triangles, m.dofs - 3 * 10**3 + 3 * s.points.shape[0],
                   m.inside, m.map)
    ref = contact_operators_3d(_layout(s, m, degree), MU)
    shift = np.asarray(shift)
    sr, mr = _rigid(s, rot, shift), _rigid(m, rot, shift)
    lay = _layout(sr, mr, degree)
    op = contact_operators_3d(lay, MU)
    assert np.allclose(op.gap, ref.gap, rtol=0, atol=1e-11)
    assert np.allclose(op.weights, ref.weights, rtol=1e-11)
    assert np.allclose(op.normals, rot.apply(ref.normals), atol=1e-12)
    assert np.allclose(op.points, rot.apply(ref.points) + shift, atol=1e-11)
    vs, vm = np.asarray(v[:3]), np.asarray(v[3:])
    u = np.zeros(lay.n_dofs)
    u[sr.dofs] = vs
    u[mr.dofs] = vm
    assert np.allclose(op.Un @ u, op.normals @ (vs - vm), atol=1e-12)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.floats(-0.15, 0.15), min_size=3, max_size=3), st.floats(0.01, 0.3))
def test_a_slightly_rotated_plate_over_a_rigid_plane_has_the_ray_distance_as_gap(rotvec,
                                                                                   lift):
    """Slave plate rotated by a small rotation about its centre, lifted by ``lift``; the
    gap of point x along the plate normal n to the plane z = 0 is ``-x_z / n_z``, and to
    a triangulated master plate on z = 0 it is the same."""
    rot = Rotation.from_rotvec(rotvec)
    c = np.array([0.5, 0.5, lift])
    base = grid(4, (0.3, 0.3), (0.7, 0.7), _flat(0.0), 1, [0.5, 0.5, 1.0])
    s = TriSurface(rot.apply(base.points - [0.5, 0.5, 0.0]) + c, base.triangles, base.dofs,
                   rot.apply([0.0, 0.0, 1.0]) + c, base.map)
    n = rot.apply([0.0, 0.0, -1.0])
    op = contact_operators_3d(_layout(s, None, 1), MU)
    assert np.allclose(op.normals, n, atol=1e-14)
    assert np.allclose(op.gap, -op.points[:, 2] / n[2], rtol=1e-12)
    m = grid(9, (-0.5, -0.5), (1.5, 1.5), _flat(0.0), 1, [0.5, 0.5, -1.0],
             first_node=s.points.shape[0])
    op_m = contact_operators_3d(_layout(s, m, 1), MU)
    assert np.allclose(op_m.gap, op.gap, rtol=1e-12)


def _sphere_gap(points: np.ndarray, radius: float, centre_z: float) -> np.ndarray:
    """Exact gap to z = 0 along the sphere normal at the radial projection of ``points``."""
    d = points - [0.0, 0.0, centre_z]
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return (centre_z + radius * d[:, 2]) / (-d[:, 2])


def test_sphere_above_a_plane_gap_converges_at_first_order_and_its_integral_at_second():
    """A sphere cap (radius 1, 0.01 above z = 0, over |x|, |y| <= 0.5) on faceted meshes:
    the pointwise gap against the sphere's (the facet normal is O(h) off the sphere
    normal: first order), and the integral of the gap against its exact value
    ``int (c - s) R^2 / s^2 dx dy``, ``s = sqrt(R^2 - r^2)`` (second order)."""
    R, g0, L = 1.0, 0.01, 0.5
    c = R + g0
    exact, _ = dblquad(lambda y, x: (c - np.sqrt(R * R - x * x - y * y)) * R * R
                       / (R * R - x * x - y * y), -L, L, -L, L, epsabs=1e-13, epsrel=1e-13)
    err_max, err_int = [], []
    for n in (8, 16, 32):
        op = contact_operators_3d(_layout(sphere_cap(n, R, c, L, 1), None, 1), MU)
        err_max.append(np.abs(op.gap - _sphere_gap(op.points, R, c)).max())
        err_int.append(abs(op.weights @ op.gap - exact))
    rate_max = np.log2(np.array(err_max[:-1]) / err_max[1:])
    rate_int = np.log2(np.array(err_int[:-1]) / err_int[1:])
    assert np.all(rate_max > 0.6) and rate_max[-1] > 0.8, rate_max
    assert np.all(rate_int > 1.8), rate_int


def test_sphere_on_sphere_gap_matches_the_rigid_plane_limit_of_a_flat_master():
    """A triangulated flat master on z = 0 gives the gaps of the rigid plane."""
    s = sphere_cap(6, 1.0, 1.01, 0.4, 2)
    m = grid(5, (-0.8, -0.8), (0.8, 0.8), _flat(0.0), 2, [0.0, 0.0, -1.0],
             first_node=s.points.shape[0])
    a = contact_operators_3d(_layout(s, None, 2), MU)
    b = contact_operators_3d(_layout(s, m, 2), MU)
    assert np.allclose(a.gap, b.gap, rtol=1e-12)


@pytest.mark.parametrize("degree", [1, 2])
def test_p1_p2_reproduce_linear_displacement_fields(degree):
    """``Un u = (u(x_q) - u(y_q)) . n_q`` for ``u(x) = A x + b`` on both bodies,
    ``y_q = x_q + gap_q n_q`` the hit point (P2 midpoints at the chord midpoints, so the
    interpolant of a linear field on the flat triangles is the field)."""
    rng = np.random.default_rng(36)
    s = sphere_cap(5, 1.0, 1.03, 0.4, degree)
    m = sphere_cap(7, 1.2, -1.2, 0.7, degree, lower=False, first_node=s.points.shape[0])
    lay = _layout(s, m, degree, quad_order=5)
    op = contact_operators_3d(lay, MU)
    for _ in range(3):
        A, b = rng.normal(size=(3, 3)), rng.normal(size=3)

        def f(x, A=A, b=b):
            return x @ A.T + b

        u = _field([s, m], f)
        y = op.points + op.gap[:, None] * op.normals
        expect = np.einsum("qd,qd->q", f(op.points) - f(y), op.normals)
        assert np.allclose(op.Un @ u, expect, rtol=0, atol=1e-12)


def test_mapping_by_mu_scales_weights_by_s_squared_and_moves_the_gap():
    """Slave map ``x = mu x_hat + (0.1 mu, 0, 0.02 - 0.01 mu)``; slave plate at
    z_hat = 0.05: gap ``0.05 mu + 0.02 - 0.01 mu``, weights ``mu^2`` times the reference."""
    amap = AffineMap(scale=np.array([0.0, 1.0]),
                     shift=np.array([[0.0, 0.1], [0.0, 0.0], [0.02, -0.01]]))
    s = grid(4, (0.2, 0.2), (0.6, 0.6), _flat(0.05), 2, [0.4, 0.4, 1.0], map=amap)
    m = grid(6, (0.0, 0.0), (1.5, 1.5), _flat(0.0), 2, [0.5, 0.5, -1.0],
             first_node=s.points.shape[0])
    lay = _layout(s, m, 2, "lac", patch=4)
    ref = contact_operators_3d(lay, np.array([1.0]))
    for mu in (0.7, 1.3):
        op = contact_operators_3d(lay, np.array([mu]))
        assert np.allclose(op.weights, mu**2 * ref.weights, rtol=1e-13)
        assert np.allclose(op.gap, 0.05 * mu + 0.02 - 0.01 * mu, rtol=1e-12)
        assert np.allclose(op.points[:, 0], mu * (ref.points[:, 0] - 0.1) + 0.1 * mu)
        assert op.Mlam.shape == ref.Mlam.shape  # the multiplier numbering is mu-independent


def test_a_miss_raises_pairing_error_naming_a_point():
    s = grid(4, (-0.2, 0.1), (0.9, 0.9), _flat(0.01), 1, [0.5, 0.5, 1.0])  # overhangs x < 0
    m = grid(6, (0.0, 0.0), (1.0, 1.0), _flat(0.0), 1, [0.5, 0.5, -1.0],
             first_node=s.points.shape[0])
    lay = _layout(s, m, 1)
    with pytest.raises(PairingError, match=r"slave quadrature point\(s\) \(e.g. x = ") as err:
        contact_operators_3d(lay, MU)
    x = pair_surfaces(_layout(s, None, 1), MU).x
    assert err.value.n_missed == int(np.sum(x[:, 0] < 0))
    assert err.value.example[0] < 0.0


def test_rows_evaluate_like_the_full_operators():
    s = sphere_cap(6, 1.0, 1.01, 0.4, 2)
    m = sphere_cap(8, 1.5, -1.5, 0.8, 2, lower=False, first_node=s.points.shape[0])
    lay = _layout(s, m, 2, "p1")
    full = contact_operators_3d(lay, MU)
    rows = np.random.default_rng(0).choice(lay.n_quad, 25, replace=False)
    Un, gap = surface_rows(lay, MU, rows)
    assert np.array_equal(gap, full.gap[rows])
    assert (Un - full.Un[rows]).count_nonzero() == 0
    with pytest.raises(ValueError, match="rows must lie in"):
        surface_rows(lay, MU, np.array([lay.n_quad]))


@settings(max_examples=30, deadline=None)
@given(st.integers(0, 10**6), st.integers(1, 8))
def test_ray_cast_widening_finds_the_nearest_hit_of_a_brute_force_search(seed, k0):
    """On a random wavy surface (several hits per line), the k-d tree candidates with
    widening give the nearest hit that trying every triangle gives."""
    rng = np.random.default_rng(seed)
    m = grid(10, (0.0, 0.0), (1.0, 1.0), lambda x, y: 0.15 * np.sin(9 * x) * np.cos(7 * y),
             1, [0.5, 0.5, -1.0])
    v0, v1, v2 = m.vertices(MU)
    x = np.column_stack([rng.uniform(0.1, 0.9, (40, 2)), rng.uniform(-0.3, 0.5, 40)])
    d = rng.normal(size=(40, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    tri, bary, t = ray_cast_triangles(x, d, v0, v1, v2, k0=k0)
    tri_b, bary_b, t_b = ray_cast_triangles(x, d, v0, v1, v2, k0=v0.shape[0])
    assert np.array_equal(tri >= 0, tri_b >= 0)
    hit = tri >= 0
    assert np.allclose(np.abs(t[hit]), np.abs(t_b[hit]), rtol=0, atol=1e-12)
    y = bary[hit, :1] * v0[tri[hit]] + bary[hit, 1:2] * v1[tri[hit]] \
        + bary[hit, 2:] * v2[tri[hit]]
    assert np.allclose(y, x[hit] + t[hit, None] * d[hit], atol=1e-9)


@pytest.mark.parametrize(("field", "value", "match"), [
    ("degree", 3, "degree = 3; valid: 1, 2"),
    ("quad_order", 0, r"quad_order = 0; valid: \[1, 2"),
    ("multiplier", "p2", "multiplier = 'p2'; valid: 'p1', 'p0', 'lac'"),
    ("patch", 0, "patch = 0; valid: an integer >= 1"),
    ("symmetry", ("z",), r"symmetry plane\(s\) \['z'\]; valid: 'x', 'y'"),
])
def test_bad_layout_options_name_the_valid_values(field, value, match):
    s, m = _plates(0.01, 1)
    kw = dict(slave=s, master=m, degree=1, quad_order=4, multiplier="p0", patch=1, n_dofs=10)
    kw[field] = value
    with pytest.raises(ValueError, match=match):
        SurfaceLayout(**kw)


def test_ray_cast_finds_far_hits_beyond_the_nearest_centroids_and_reports_misses():
    """Lines whose hit lies far beyond the nearest centroids (oblique lines over a plate
    of 3200 triangles) get it from the widening search along the line, as trying every triangle
    does; a line parallel to the plate hits nothing."""
    m = grid(40, (0.0, 0.0), (1.0, 1.0), _flat(0.0), 1, [0.5, 0.5, -1.0])
    v0, v1, v2 = m.vertices(MU)
    rng = np.random.default_rng(7)
    x = np.column_stack([rng.uniform(0.02, 0.1, (20, 2)), rng.uniform(0.05, 0.2, 20)])
    target = np.column_stack([rng.uniform(0.8, 0.98, (20, 2)), np.zeros(20)])
    d = target - x
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    x, d = np.vstack([x, [[0.5, 0.5, 0.1]]]), np.vstack([d, [[1.0, 0.0, 0.0]]])
    tri, bary, t = ray_cast_triangles(x, d, v0, v1, v2)
    tri_b, _, t_b = ray_cast_triangles(x, d, v0, v1, v2, k0=v0.shape[0])
    assert np.array_equal(tri, tri_b) and tri[-1] == -1 and np.isnan(t[-1])
    y = x[:-1] + t[:-1, None] * d[:-1]
    assert np.allclose(y, target, atol=1e-12)
    assert np.allclose(t[:-1], t_b[:-1], rtol=1e-13)

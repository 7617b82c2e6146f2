"""Smooth slave normals and segment-to-segment contact integration
(:mod:`rbbench.hf.geometry.operators`; README "Nitsche", the e_AC table)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rbbench.hf.geometry.chains import AffineMap, FacetChain, with_vertex_normals
from rbbench.hf.geometry.facets import facet_shape, gauss_legendre_01
from rbbench.hf.geometry.pairing import ContactLayout, master_vertex_hits, pair, segmented_rule

IDENTITY = AffineMap(scale=np.array([1.0, 0.0]), shift=np.zeros((2, 2)))
MU = np.array([0.0])


def _chain(vertices: np.ndarray, inner: np.ndarray, first_dof: int = 0) -> FacetChain:
    """A P1 chain through ``vertices`` (n + 1, 2); vertex k has dofs 2 (first + k) + (0, 1)."""
    n = vertices.shape[0] - 1
    k = np.arange(n)
    dofs = np.stack([np.stack([2 * (first_dof + k), 2 * (first_dof + k) + 1], axis=1),
                     np.stack([2 * (first_dof + k + 1), 2 * (first_dof + k + 1) + 1], axis=1)],
                    axis=1)
    return FacetChain(a=vertices[:-1], b=vertices[1:], inner=np.broadcast_to(inner, (n, 2)),
                      dofs=dofs, map=IDENTITY, ids=k)


def _arc(radius: float, angles: np.ndarray, centre=(0.0, 0.0)) -> np.ndarray:
    return np.asarray(centre) + radius * np.stack([np.cos(angles), np.sin(angles)], axis=1)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(0.01, 0.2), min_size=2, max_size=12), st.floats(0.3, 3.0))
def test_vertex_normals_are_continuous_unit_and_radial_on_a_regular_arc(steps, radius):
    """On a polygon inscribed in a circle with equal facets the averaged vertex normal is
    the circle's radial normal; in general it is continuous along the chain."""
    th = -np.pi / 2 + np.concatenate([[0.0], np.cumsum(steps)]) - 0.5 * np.sum(steps)
    chain = with_vertex_normals(_chain(_arc(radius, th), np.zeros(2)))
    n = chain.n
    assert np.allclose(np.linalg.norm(chain.na, axis=1), 1.0)
    assert np.allclose(chain.nb[:-1], chain.na[1:])  # continuous at inner vertices
    ends = chain.normals_at(MU, np.arange(n), np.ones(n))
    starts = chain.normals_at(MU, np.arange(n), np.zeros(n))
    assert np.allclose(ends[:-1], starts[1:])
    radial = _arc(1.0, th)  # outward normals of the disk at the vertices
    equal = np.isclose(steps[:-1], steps[1:])
    assert np.allclose(chain.nb[:-1][equal], radial[1:-1][equal])
    # subsets keep the full chain's vertex normals
    sub = chain.subset(np.arange(1, n))
    assert np.array_equal(sub.na, chain.na[1:])


def _flat_pair(slave_x: np.ndarray, master_x: np.ndarray, gap: float, integration: str,
               n_gauss: int) -> ContactLayout:
    """Slave on y = gap (body above), master on y = 0 (body below), both P1 flat chains."""
    slave = _chain(np.stack([slave_x, np.full(slave_x.size, gap)], axis=1),
                   np.array([0.0, gap + 1.0]))
    master = _chain(np.stack([master_x, np.zeros(master_x.size)], axis=1),
                    np.array([0.0, -1.0]), first_dof=slave_x.size)
    return ContactLayout(slave=slave, master=master, degree=1, n_gauss=n_gauss,
                         multiplier="p0", patch=1, n_facets=slave.n,
                         n_dofs=2 * (slave_x.size + master_x.size), integration=integration)


def _sorted_points(ticks: list[int], lo: float, hi: float) -> np.ndarray:
    """Chain abscissae: ``lo``, the ``ticks`` (thousandths), ``hi``; at least 1e-3 apart."""
    return np.unique(np.concatenate([[lo], np.asarray(ticks, dtype=float) / 1000.0, [hi]]))


@settings(max_examples=100, deadline=None)
@given(st.lists(st.integers(1, 999), min_size=1, max_size=8),
       st.lists(st.integers(-300, 1300), min_size=1, max_size=10),
       st.floats(0.001, 0.1))
def test_segmented_rule_transfers_a_uniform_pressure_exactly(slave_in, master_in, gap):
    """Contact patch test of the force transfer: a uniform pressure on the slave gives
    the master nodal forces ``int phi_k`` of its own mesh (on the overlap) when the
    pieces are cut at the master vertices, for any pair of non-matching meshes."""
    xs = _sorted_points(slave_in, 0.0, 1.0)
    xm = _sorted_points(master_in, -0.5, 1.5)
    lay = _flat_pair(xs, xm, gap, "segmented", 1)
    p = pair(lay, MU)
    # the normal jump's master part, weighted: nodal y-forces of a unit pressure
    # (the slave normal is -y, so the master's y-coefficients are +phi_k)
    Un = p.jump(p.nrm, lay.n_dofs)
    f = np.asarray(Un.T @ p.w).ravel()[2 * xs.size + 1::2]
    # exact: int_0^1 phi_k(x) dx of the master hat functions
    fine = np.linspace(0.0, 1.0, 20001)
    hats = np.stack([np.interp(fine, xm, np.eye(xm.size)[k]) for k in range(xm.size)])
    exact = np.trapezoid(hats, fine, axis=1)
    assert np.allclose(f, exact, atol=1e-7)
    assert np.isclose(p.w.sum(), 1.0)


def test_gauss_point_to_segment_fails_that_patch_test_on_non_matching_meshes():
    """The reason for ``segmented``: one Gauss point per slave facet (GPTS) loads the
    master nodes of non-matching meshes unevenly (from -8 % to +29 % here)."""
    xs, xm = np.linspace(0.0, 1.0, 8), np.linspace(-0.5, 1.5, 19)
    fine = np.linspace(0.0, 1.0, 20001)
    exact = np.trapezoid(np.stack([np.interp(fine, xm, np.eye(xm.size)[k])
                                   for k in range(xm.size)]), fine, axis=1)
    forces = {}
    for rule in ("gauss", "segmented"):
        lay = _flat_pair(xs, xm, 0.01, rule, 1)
        p = pair(lay, MU)
        forces[rule] = np.asarray(p.jump(p.nrm, lay.n_dofs).T @ p.w).ravel()[2 * xs.size + 1::2]
    inner = (xm > 0.2) & (xm < 0.8)
    assert np.allclose(forces["segmented"], exact, atol=1e-9)
    assert np.max(np.abs(forces["gauss"][inner] / exact[inner] - 1.0)) > 0.1


def test_master_vertex_hits_lie_on_the_rays_through_the_vertices():
    """On curved chains with smooth normals each cut point's ray passes through a master
    vertex (cross product 0) and the pieces tile every facet."""
    th_s = np.linspace(-0.6, -0.4, 9) * np.pi
    th_m = np.linspace(0.3, 0.7, 23) * np.pi
    slave = with_vertex_normals(_chain(_arc(1.0, th_s, (0.0, 1.001)), np.array([0.0, 1.001])))
    master = _chain(_arc(1.0, th_m, (0.0, -1.0)), np.array([0.0, -1.0]), first_dof=9)
    fi, s = master_vertex_hits(slave, master, MU)
    assert fi.size > 0
    x = slave.a[fi] + s[:, None] * (slave.b[fi] - slave.a[fi])
    n = slave.normals_at(MU, fi, s)
    mv = np.vstack([master.a, master.b[-1:]])
    d = mv[None, :, :] - x[:, None, :]
    cross = np.abs(n[:, None, 0] * d[..., 1] - n[:, None, 1] * d[..., 0])
    assert np.all(cross.min(axis=1) < 1e-12)
    sg, wg = gauss_legendre_01(2)
    fq, sq, wq = segmented_rule(slave, master, MU, sg, wg)
    assert np.allclose(np.bincount(fq, weights=wq, minlength=slave.n), 1.0)
    assert np.all((sq > 0) & (sq < 1))
    # exact on a master P1 hat evaluated along the rays: compare a fine rule
    lay = ContactLayout(slave=slave, master=master, degree=1, n_gauss=2, multiplier="p0",
                        patch=1, n_facets=slave.n, n_dofs=2 * (9 + 23),
                        integration="segmented")
    p = pair(lay, MU)
    fine = pair(ContactLayout(**{**lay.__dict__, "n_gauss": 1}), MU,
                local=(np.linspace(0.5 / 4000, 1 - 0.5 / 4000, 4000), np.full(4000, 1 / 4000)))
    for q, ref in ((p, fine),):
        f = np.asarray(q.jump(q.nrm, lay.n_dofs).T @ q.w).ravel()
        g = np.asarray(ref.jump(ref.nrm, lay.n_dofs).T @ ref.w).ravel()
        assert np.allclose(f, g, atol=1e-6 * np.abs(g).max())


@settings(max_examples=100, deadline=None)
@given(st.lists(st.integers(1, 999), min_size=1, max_size=8),
       st.lists(st.integers(-300, 1300), min_size=1, max_size=10), st.integers(1, 4))
def test_segmented_rule_cuts_flat_facets_exactly_at_the_master_vertices(slave_in, master_in,
                                                                         ng):
    """Flat parallel chains: the cuts are the master abscissae inside each slave facet,
    the pieces tile every facet (weights sum to 1), each holds the ``ng`` Gauss points."""
    xs, xm = _sorted_points(slave_in, 0.0, 1.0), _sorted_points(master_in, -0.5, 1.5)
    lay = _flat_pair(xs, xm, 0.01, "segmented", ng)
    fi, s = master_vertex_hits(lay.slave, lay.master, MU)
    a, b = xs[:-1], xs[1:]
    expected = sorted((i, (m - a[i]) / (b[i] - a[i])) for i in range(a.size) for m in xm
                      if a[i] < m < b[i])
    got = sorted(zip(fi.tolist(), s.tolist(), strict=True))
    assert len(got) == len(expected)
    assert np.allclose(np.array(got).reshape(-1, 2), np.array(expected).reshape(-1, 2))
    sg, wg = gauss_legendre_01(ng)
    fq, sq, wq = segmented_rule(lay.slave, lay.master, MU, sg, wg)
    assert np.allclose(np.bincount(fq, weights=wq, minlength=a.size), 1.0)
    assert fq.size == ng * (a.size + len(expected))
    p = pair(lay, MU)
    assert np.allclose(facet_shape(p.sq, 1).sum(axis=1), 1.0) and np.allclose(p.gap, 0.01)


def test_master_vertex_hits_across_a_gap_in_the_master_chain():
    """Both ends of a gap are cuts (each vertex is tested with its own facet)."""
    slave = _chain(np.array([[0.2, 0.01], [0.6, 0.01]]), np.array([0.0, 1.0]))
    master = _chain(np.array([[0.0, 0.0], [0.3, 0.0]]), np.array([0.0, -1.0]), first_dof=2)
    second = _chain(np.array([[0.5, 0.0], [1.0, 0.0]]), np.array([0.0, -1.0]), first_dof=4)
    gapped = FacetChain(a=np.vstack([master.a, second.a]), b=np.vstack([master.b, second.b]),
                        inner=np.vstack([master.inner, second.inner]),
                        dofs=np.concatenate([master.dofs, second.dofs]), map=IDENTITY,
                        ids=np.arange(2))
    fi, s = master_vertex_hits(slave, gapped, MU)
    assert np.allclose(np.sort(0.2 + 0.4 * s), [0.3, 0.5]) and np.all(fi == 0)


def test_key_neutral_defaults_keep_cache_keys():
    """The options at their defaults leave scene fingerprints and snapshot keys as they
    were before the options existed; other values change them."""
    from rbbench.hf.snapshots.key import snapshot_key
    from rbbench.scene.loading import load_scene

    base = load_scene("hertz_halfdisks")
    same = load_scene("hertz_halfdisks", ['discretization.normals="facet"',
                                          'discretization.contact_integration="gauss"'])
    assert base.fingerprint() == same.fingerprint()
    assert snapshot_key(base) == snapshot_key(same)
    for change in ('discretization.normals="smooth"',
                   'discretization.contact_integration="segmented"'):
        other = load_scene("hertz_halfdisks", [change])
        assert other.fingerprint() != base.fingerprint()
        assert snapshot_key(other) != snapshot_key(base)


def test_rigid_or_obstacle_scenes_keep_fixed_points_with_segmented():
    from rbbench.rb.offline import fixed_contact_points
    from rbbench.scene.loading import load_scene

    rigid = load_scene("hertz_halfdisks", ['geometry.lower="rigid_flat"',
                                           'discretization.contact_integration="segmented"'])
    assert fixed_contact_points(rigid, "eim", plain_ok=False)
    assert fixed_contact_points(load_scene("hertz_halfdisks"), "eim", plain_ok=False)


def test_hyper_reduction_refuses_segmented_integration():
    from rbbench.rb.hyper.contact_eim import restrict_layout

    lay = _flat_pair(np.linspace(0, 1, 5), np.linspace(-0.2, 1.2, 8), 0.01, "segmented", 2)
    with pytest.raises(ValueError, match="contact_integration"):
        restrict_layout(lay, np.arange(2), np.zeros((1, 1)))


# ---------------------------------------------------------------------------
# segmented integration in the pipeline: HF yes, fixed-point hyper-reduction no
# ---------------------------------------------------------------------------
SEGMENTED = ["discretization.h_contact=0.02", "discretization.h_max=0.2",
             "discretization.normals=smooth", "discretization.contact_integration=segmented"]


def test_reduce_with_segmented_points_falls_back_to_plain_or_refuses(tmp_path):
    from rbbench.rb.config import make_config
    from rbbench.rb.offline import reduce
    from rbbench.scene.loading import SceneError, load_scene

    sc = load_scene("hertz_halfdisks", SEGMENTED)
    common = dict(N=4, n_train=4, n_valid=2, n_jobs=1, cache_dir=str(tmp_path),
                  online_repeats=1)
    mixed = dict(dual="mcpg", stabilizer="none", R=4, **common)
    for config in (make_config(hyper="eim", **mixed),
                   make_config(formulation="nitsche", solver="newton", hyper="auto",
                               **common)):
        with pytest.raises(SceneError, match="contact_integration = 'segmented'"):
            reduce(sc, config)
    r = reduce(sc, make_config(hyper="auto", **mixed))  # B(mu) not affine, no EIM: plain
    assert r.hyper == "none" and np.all(np.isfinite(r.err_u)) and max(r.err_u) < 0.1

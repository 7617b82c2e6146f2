"""The numba 3D pairing and magic entries (rbbench.rb.kernels.surface_pairing) against the
Python reference on hertz_sphere level 0 (two hemispheres, and the rigid plane): the rows of
``Un`` and ``gap`` of :func:`~rbbench.hf.geometry.surface.surface_rows` (the full HF
pairing, every master triangle), the weights, and the magic entries of
:meth:`~rbbench.rb.hyper.surface_eim.SurfaceRowEvaluator.entries`, raw values to 1e-12, at
random mu off the sample the windows were built on."""

from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("numba")

from rbbench.hf.components import make_components  # noqa: E402
from rbbench.hf.geometry.chains import AffineMap  # noqa: E402
from rbbench.hf.geometry.surface import pair_surfaces, surface_rows  # noqa: E402
from rbbench.hf.geometry.surface_rules import triangle_rule  # noqa: E402
from rbbench.rb.hyper.surface_eim import (  # noqa: E402
    _row_triangles,
    build_surface_row_evaluator,
)
from rbbench.rb.kernels import layout as L  # noqa: E402
from rbbench.rb.kernels import surface_pairing as SP  # noqa: E402
from rbbench.rb.kernels.plan import pack  # noqa: E402
from rbbench.rb.kernels.surface_plan import (  # noqa: E402
    no_table,
    pairing_table,
    reference_surface_points,
    surface_eim_arrays,
)
from rbbench.scene.loading import load_scene  # noqa: E402

SAMPLE = np.linspace(0.7, 1.3, 9)[:, None]


#: a master map moving with mu (the scene's lower hemisphere is fixed): scale 0.9 + 0.1 mu,
#: a lateral shift, and the cap's top kept at z = 1 (the scene's gap unchanged)
MOVING_MASTER = AffineMap(scale=np.array([0.9, 0.1]),
                          shift=np.array([[0.003, -0.002], [-0.001, 0.002], [0.1, -0.1]]))


@pytest.fixture(scope="module", params=["hemisphere", "rigid_flat", "moving_master"])
def case(request):
    """A layout, an evaluator of 7 rows spread over the cap, a random local basis and
    magic entries (fixed seed), and the packed plan of the kernels. ``moving_master``: the
    hemispheres with the master mapped by :data:`MOVING_MASTER` (the lines are cast in the
    master's reference frame: this exercises it)."""
    lower = "hemisphere" if request.param == "moving_master" else request.param
    sc = load_scene("hertz_sphere", ["discretization.level=0", f"geometry.lower={lower}"])
    lay = make_components(sc)[0].contact_layout()
    if request.param == "moving_master":
        lay = replace(lay, master=replace(lay.master, map=MOVING_MASTER))
    rows = np.unique(np.linspace(0, lay.n_mult - 1, 7).astype(int))
    ev = build_surface_row_evaluator(lay, rows, SAMPLE)
    rng = np.random.default_rng(3)
    N, E = 5, 12
    ceim = SimpleNamespace(evaluator=ev, Z_loc=rng.standard_normal((ev.n_local, N)),
                           pos_B=np.arange(rows.size), entry_row=rng.integers(0, rows.size, E),
                           entry_col=rng.integers(0, N, E), pos_G=np.array([0, 3, 6]))
    return lay, rows, ceim, _pack(surface_eim_arrays(ceim))


def _pack(arrays: dict) -> tuple[np.ndarray, ...]:
    one_f, one_i = np.zeros((1, 1)), np.zeros((1, 1), dtype=np.int64)
    full = {**dict.fromkeys(L.FLOATS, one_f), **dict.fromkeys(L.INTS, one_i),
            "mu_lo": np.array([0.7]), "mu_hi": np.array([1.3]), **arrays}
    return pack(full)


def _pair(plan, mu: float, nq: int, k: int):
    w, gap, mphi = np.empty(nq), np.empty(nq), np.zeros((nq, k))
    mtri = np.zeros(nq, dtype=np.int64)
    status, s = SP.pair_surface_points(np.array([1.0, mu]), *plan, w, gap, mphi, mtri)
    return status, s, w, gap, mphi, mtri


def _mus() -> np.ndarray:
    return np.random.default_rng(11).uniform(0.7, 1.3, 4)


@pytest.mark.netgen
def test_pairing_equals_the_full_hf_rows(case):
    """The kernel's points against ``surface_rows`` (all master triangles): ``Un`` rows
    rebuilt from its hits and ``gap`` to 1e-12 of their largest entry, weights to 1e-12."""
    lay, rows, ceim, plan = case
    ev = ceim.evaluator
    small = ev.layout
    ng = triangle_rule(lay.quad_order)[1].size
    nq = ev.Mrows.shape[1]
    q = np.arange(nq)
    glob = _row_triangles(lay, rows)[q // ng] * ng + q % ng  # the same points, HF numbering
    _, n_hat, _, sphi = reference_surface_points(small)
    k = sphi.shape[1]
    for mu in _mus():
        status, s, w, gap, mphi, mtri = _pair(plan, mu, nq, k)
        assert status == L.OK
        Un, g = surface_rows(lay, np.array([mu]), glob)
        Un = Un.toarray()
        nrm = np.sign(s) * n_hat
        sd = small.slave.dofs[small.slave.triangles[q // ng]].reshape(nq, -1)
        vals = [(sphi[:, :, None] * nrm[:, None, :]).reshape(nq, -1)]
        dofs = [sd]
        if small.master is not None:
            md = small.master.dofs[small.master.triangles[mtri]].reshape(nq, -1)
            vals.append(-(mphi[:, :, None] * nrm[:, None, :]).reshape(nq, -1))
            dofs.append(md)
        mine = sp.csr_matrix((np.concatenate([v.ravel() for v in vals]),
                              (np.tile(np.repeat(q, vals[0].shape[1]), len(vals)),
                               ev.local_dofs[np.concatenate([d.ravel() for d in dofs])])),
                             shape=Un.shape).toarray()
        assert np.abs(mine - Un).max() <= 1e-12 * np.abs(Un).max()
        assert np.abs(gap - g).max() <= 1e-12 * np.abs(g).max()
        ref_w = pair_surfaces(lay, np.array([mu]), rows=glob).w
        np.testing.assert_allclose(w, ref_w, rtol=1e-12, atol=0)


@pytest.mark.netgen
def test_magic_entries_equal_the_python_evaluator(case):
    """``B(mu) Z`` entries and ``G(mu)`` rows: the kernel against
    :meth:`SurfaceRowEvaluator.entries`, 1e-12 relative."""
    _, _, ceim, plan = case
    ev = ceim.evaluator
    for mu in _mus():
        c, g = np.empty(ceim.entry_col.size), np.empty(ceim.pos_G.size)
        assert SP.surface_magic_values(np.array([1.0, mu]), *plan, c, g) == L.OK
        c_py, g_py = ev.entries(np.array([mu]), ceim.Z_loc,
                                *ev.support(ceim.pos_B[ceim.entry_row]), ceim.entry_col,
                                ceim.pos_G)
        assert np.abs(c - c_py).max() <= 1e-12 * np.abs(c_py).max()
        assert np.abs(g - g_py).max() <= 1e-12 * np.abs(g_py).max()


@pytest.mark.netgen
def test_the_key_range_search_equals_the_whole_window(case):
    """The bisection on the sorted keys keeps every hit: the same outputs, bit for bit, as
    a plan whose key range covers each point's whole window (radius column huge)."""
    lay, _, ceim, _ = case
    if lay.master is None:
        pytest.skip("no master surface")
    arrays = surface_eim_arrays(ceim)
    plan = _pack(arrays)
    wide = dict(arrays, w_axis=np.column_stack([arrays["w_axis"][:, :3],
                                                np.full(arrays["w_axis"].shape[0], 1e3)]))
    nq, k = arrays["x_hat"].shape[0], 3 * lay.degree
    for mu in _mus():
        a, b = _pair(plan, mu, nq, k), _pair(_pack(wide), mu, nq, k)
        for x, y in zip(a[2:], b[2:], strict=True):
            np.testing.assert_array_equal(x, y)


def _windows_at_one_mu() -> dict:
    """The plan arrays of every row of hertz_sphere level 0 with master windows sampled at
    mu = 0.7 only, no margin (points leave them over part of D)."""
    sc = load_scene("hertz_sphere", ["discretization.level=0"])
    lay = make_components(sc)[0].contact_layout()
    ev = build_surface_row_evaluator(lay, np.arange(lay.n_mult), np.array([[0.7]]), margin=0)
    ceim = SimpleNamespace(evaluator=ev, Z_loc=np.zeros((ev.n_local, 1)),
                           pos_B=np.arange(1), entry_row=np.zeros(1, int),
                           entry_col=np.zeros(1, int), pos_G=np.arange(1))
    return surface_eim_arrays(ceim)


@pytest.mark.netgen
def test_a_point_outside_its_window_is_no_hit():
    """Windows sampled at mu = 0.7 only, no margin: at mu = 1.3 a point misses them and
    the kernel says so (the caller then runs the reference, which raises)."""
    arrays = _windows_at_one_mu()
    plan = _pack(arrays)
    nq = arrays["x_hat"].shape[0]
    assert _pair(plan, 0.7, nq, 3)[0] == L.OK
    assert _pair(plan, 1.3, nq, 3)[0] == L.NO_HIT


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3), max_size=40), st.floats(-2e3, 2e3),
       st.integers(0, 40), st.integers(0, 40))
def test_first_at_least_is_a_left_bisection(keys, value, a, b):
    """The kernel's bisection on a sorted segment ``first .. last`` equals numpy's
    left ``searchsorted`` there."""
    key = np.sort(np.asarray(keys, dtype=float))
    first, last = sorted((min(a, key.size), min(b, key.size)))
    want = first + int(np.searchsorted(key[first:last], value, side="left"))
    assert SP._first_at_least(key, first, last, value) == want


def _table_plans(case) -> tuple[dict, dict]:
    """The case's arrays with the pairing table and without (every point searched)."""
    lay, _, ceim, _ = case
    arrays = {"mu_lo": np.array([0.7]), "mu_hi": np.array([1.3]), **surface_eim_arrays(ceim)}
    nq = arrays["x_hat"].shape[0]
    return {**arrays, **pairing_table(arrays, n_grid=257)}, {**arrays, **no_table(nq)}


@pytest.mark.netgen
def test_table_gives_the_search_bit_for_bit(case):
    """The table's triangle, kept only when hit well inside, leaves every output of the
    pairing as the search alone gives it, bit for bit: at random mu, at the run starts
    (where the triangle changes) and one ulp either side of them. The rigid plane has no
    table."""
    lay = case[0]
    with_table, searched = _table_plans(case)
    nq, k = with_table["x_hat"].shape[0], 3 * lay.degree
    runs = with_table["t_ptr"][-1]
    if lay.master is None:
        assert runs == 0
        return
    assert runs > nq  # every point has a run, and some change triangle over D
    starts = with_table["t_mu"][(with_table["t_mu"] > 0.7) & (with_table["t_mu"] < 1.3)]
    mus = np.concatenate([np.random.default_rng(5).uniform(0.7, 1.3, 300), starts,
                          np.nextafter(starts, 0.0), np.nextafter(starts, 2.0)])
    a_plan, b_plan = _pack(with_table), _pack(searched)
    for mu in mus:
        a, b = _pair(a_plan, mu, nq, k), _pair(b_plan, mu, nq, k)
        assert a[0] == b[0] == L.OK
        for x, y in zip(a[1:], b[1:], strict=True):
            np.testing.assert_array_equal(x, y)


@pytest.mark.netgen
def test_table_needs_one_bounded_parameter(case):
    """Several parameters or an unbounded D: no table (the search pairs every point)."""
    _, _, ceim, _ = case
    arrays = surface_eim_arrays(ceim)
    for lo, hi in (([0.7, 0.0], [1.3, 1.0]), ([-np.inf], [1.3])):
        table = pairing_table({**arrays, "mu_lo": np.array(lo), "mu_hi": np.array(hi)})
        assert not table["t_ptr"].any()


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(-1e3, 1e3), min_size=1, max_size=40), st.floats(-2e3, 2e3),
       st.integers(0, 39), st.integers(1, 40))
def test_run_is_the_last_start_at_most_mu(starts, value, a, b):
    """The kernel's run lookup on a sorted segment ``first .. last - 1``: the last start
    ``<= value`` (numpy's right ``searchsorted`` less one), the first run when none."""
    key = np.sort(np.asarray(starts, dtype=float))
    first, last = sorted((min(a, key.size - 1), min(b, key.size)))
    if last <= first:
        last = first + 1
    want = first + max(int(np.searchsorted(key[first + 1:last], value, side="right")), 0)
    assert SP._run(key, first, last, value) == want


@pytest.mark.netgen
def test_table_leaves_out_grid_points_outside_the_windows():
    """Windows sampled at mu = 0.7 only, no margin: the search fails over part of D. The
    table keeps the grid points where it succeeds (it is not dropped), and the pairing
    stays the search's, bit for bit, where the search succeeds."""
    arrays = {"mu_lo": np.array([0.7]), "mu_hi": np.array([1.3]), **_windows_at_one_mu()}
    nq = arrays["x_hat"].shape[0]
    table = pairing_table(arrays, n_grid=129)
    assert table["t_ptr"][-1] >= nq and table["t_mu"].max() < 1.3
    a_plan, b_plan = _pack({**arrays, **table}), _pack({**arrays, **no_table(nq)})
    for mu in np.linspace(0.7, 1.3, 61):
        a, b = _pair(a_plan, mu, nq, 3), _pair(b_plan, mu, nq, 3)
        assert a[0] == b[0]
        if a[0] == L.OK:
            for x, y in zip(a[1:], b[1:], strict=True):
                np.testing.assert_array_equal(x, y)

"""3D magic rows of the contact constraint (hertz_sphere, level 0): the restricted,
windowed evaluation equals the rows of the full HF operators."""

from __future__ import annotations

import numpy as np
import pytest

from rbbench.hf.components import make_components
from rbbench.hf.geometry.surface import contact_operators_3d
from rbbench.rb.hyper.contact_eim import HyperReductionError
from rbbench.rb.hyper.surface_eim import build_surface_row_evaluator
from rbbench.scene.loading import load_scene

pytestmark = pytest.mark.netgen


@pytest.fixture(scope="module", params=["hemisphere", "rigid_flat"])
def layout(request):
    sc = load_scene("hertz_sphere", ["discretization.level=0",
                                     f"geometry.lower={request.param}"])
    return make_components(sc)[0].contact_layout()


def test_rows_equal_the_full_operators_off_the_sample(layout):
    """Rows spread over the contact cap, windows sampled on 9 mus; at mus between the
    sample points the rows equal those of B(mu) = Mlam^T W Un, G(mu) assembled whole."""
    n = layout.n_mult
    rows = np.unique(np.linspace(0, n - 1, 7).astype(int))
    ev = build_surface_row_evaluator(layout, rows, np.linspace(0.7, 1.3, 9)[:, None])
    for mu in (np.array([0.73]), np.array([1.01]), np.array([1.27])):
        c = contact_operators_3d(layout, mu)
        B, G = c.B().toarray(), c.G()
        Brows, Grows = ev(mu)
        scale = np.abs(B[rows]).max()
        assert np.abs(Brows - B[rows][:, ev.local_dofs]).max() <= 1e-12 * scale
        # the rows have no entry outside the local dofs
        assert np.abs(np.delete(B[rows], ev.local_dofs, axis=1)).max(initial=0.0) == 0.0
        assert np.allclose(Grows, G[rows], rtol=1e-12, atol=1e-14 * np.abs(G).max())


def test_a_point_outside_its_window_is_refused():
    """Windows sampled on one mu only, evaluated far from it: a clear error, no wrong rows."""
    sc = load_scene("hertz_sphere", ["discretization.level=0"])
    lay = make_components(sc)[0].contact_layout()
    ev = build_surface_row_evaluator(lay, np.arange(lay.n_mult), np.array([[0.7]]), margin=0)
    with pytest.raises(HyperReductionError, match="left the master window"):
        ev(np.array([1.3]))


def test_row_aware_contact_eim_is_exact_at_its_magic_entries_with_fewer_rows():
    """The row-aware selection (3D default) on the two-body level-0 layout: reproduces
    ``Vg^T B(mu) Z`` and ``Vg^T G(mu)`` on its training set to rounding, interpolates
    ``C(mu) = B(mu) Z`` exactly at its magic entries off the training set (the entries the
    restricted evaluator computes equal the full operator's), and pairs fewer rows than the
    plain greedy EIM for the same tolerance."""
    from rbbench.rb.hyper.contact_eim import column_eim, contact_eim

    sc = load_scene("hertz_sphere", ["discretization.level=0"])
    lay = make_components(sc)[0].contact_layout()
    mus = np.linspace(0.7, 1.3, 9)[:, None]
    ops = [contact_operators_3d(lay, mu) for mu in mus]
    B_train, G_train = [c.B() for c in ops], np.stack([c.G() for c in ops], axis=1)
    rng = np.random.default_rng(5)
    Z = np.linalg.qr(rng.standard_normal((lay.n_dofs, 6)))[0]
    Vg = np.abs(rng.standard_normal((lay.n_mult, 3)))
    free = np.arange(lay.n_dofs)
    built = {th: contact_eim(lay, B_train, G_train, Z, Vg, free, mus, tol=1e-12,
                             row_evaluator=build_surface_row_evaluator, row_threshold=th)
             for th in (1.0, 0.25)}
    ce = built[0.25]
    for c, mu in zip(ops, mus, strict=True):
        Bn, Gn = ce(mu)
        np.testing.assert_allclose(Bn, Vg.T @ (c.B() @ Z), atol=1e-9 * np.abs(Bn).max())
        np.testing.assert_allclose(Gn, Vg.T @ c.G(), atol=1e-9 * np.abs(Gn).max())
    res, e_row, e_col, _ = column_eim(B_train, Z, Vg, 1e-12, None, 0.25)
    mu = np.array([0.93])
    C = np.asarray(contact_operators_3d(lay, mu).B() @ Z)
    vals = C[e_row, e_col]
    np.testing.assert_allclose(res.interpolate(vals)[res.magic], vals,
                               atol=1e-12 * np.abs(C).max())
    ev = ce.evaluator
    Cp, _ = ev.entries(mu, ce.Z_loc, *ce._support, ce.entry_col, ce.pos_G)
    np.testing.assert_allclose(Cp, C[ev.rows[ce.pos_B[ce.entry_row]], ce.entry_col],
                               atol=1e-12 * np.abs(C).max())
    assert ce.info["M_B"] == built[1.0].info["M_B"]
    assert ce.info["rows"] < built[1.0].info["rows"]

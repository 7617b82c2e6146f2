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

"""The combined inf-sup rows of the friction validation and the contact profiles of the figure
"RB solutions" of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods:
parametric variational inequalities" (talk): each against an independent computation."""

from __future__ import annotations

import numpy as np
import pytest

import rbbench.rb.friction.infsup as fi
from rbbench.hf.components import make_components
from rbbench.hf.model import build_problem
from rbbench.rb.algorithms import infsup as inf
from rbbench.rb.friction.profiles import lam_t_profiles, profile_parameters
from rbbench.scene.loading import load_scene

#: n_free = 4090, m = 65 friction nodes (as tests/rb/friction/test_eim.py TINY)
TINY = ["discretization.degree=1", "discretization.h_contact=0.04", "discretization.h_max=0.4"]


@pytest.fixture(scope="module")
def tiny():
    sc = load_scene("hertz_friction", TINY)
    b, f, _ = make_components(sc, "skfem", "mixed", "friction-ssn")
    p = build_problem(b, f, sc, np.array([1.1]))
    X = p.X[p.free][:, p.free].tocsr()
    m = p.Bn.shape[0]
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 1.0, m)
    Vn = np.column_stack([np.exp(-((t - c) / 0.2) ** 2) for c in (0.3, 0.5, 0.7)])
    Vt = np.column_stack([np.sin((k + 1) * np.pi * t) for k in range(3)])
    Z = np.linalg.qr(rng.standard_normal((p.free.size, 6)))[0]
    return p, X, inf.make_solver(X), Vn, Vt, Z


def test_lanczos_continuity_equals_the_dense_hf_constant(tiny):
    """c_HF by Lanczos (one solve per iteration) = c_HF from the 2m-solve dense path."""
    p, X, xs, *_ = tiny
    dense = fi.hf_constants(p.Bn, p.Bt, p.W, xs)
    c = fi.hf_continuity(fi.combined_b(p.Bn, p.Bt), fi.combined_w(p.W), xs)
    assert c == pytest.approx(dense.c, rel=1e-7)


def test_validation_rows_equal_the_whole_v_and_projection_paths(tiny, monkeypatch):
    """dec (R + S solves, factor of C^T C) equals reduced_constants over whole V (the 2m-solve
    supremizer operator); off equals reduced_constants over span Z; the relative values
    use the same c_HF with or without the hf row (Lanczos against dense)."""
    p, X, xs, Vn, Vt, Z = tiny
    Vg, R = fi.combined_generators(Vn, Vt), Vn.shape[1]
    rows = fi.validation_constants(p.Bn, p.Bt, p.W, xs, X, Vg, R, Z, exact_max_r=3)
    assert set(rows) == {"hf", "dec", "off"}  # 2m = 130 <= HF_ROWS_MAX
    hf = rows["hf"]
    ref_dec = fi.reduced_constants(p.Bn, p.Bt, p.W, xs, Vn, Vt, None, hf.c, exact_max_r=3)
    ref_off = fi.reduced_constants(p.Bn, p.Bt, p.W, X, Vn, Vt, Z, hf.c, exact_max_r=3)
    for got, ref in ((rows["dec"], ref_dec), (rows["off"], ref_off)):
        assert got.kind == ref.kind == "cone-exact"
        assert got.value == pytest.approx(ref.value, rel=1e-6)
        assert got.span == pytest.approx(ref.span, rel=1e-6)
        assert got.c == pytest.approx(ref.c, rel=1e-9)
        assert got.is_zero == ref.is_zero is False
    # inf over a smaller set is larger: hf <= dec (dual subset), off <= dec (primal subset)
    assert hf.span <= rows["dec"].span * (1 + 1e-9)
    assert rows["off"].value <= rows["dec"].value * (1 + 1e-9)
    monkeypatch.setattr(fi, "HF_ROWS_MAX", 0)
    lean = fi.validation_constants(p.Bn, p.Bt, p.W, xs, X, Vg, R, Z, exact_max_r=3)
    assert set(lean) == {"dec", "off"}
    assert lean["dec"].value_rel == pytest.approx(rows["dec"].value_rel, rel=1e-6)
    assert 0 < lean["off"].value_rel <= lean["dec"].value_rel * (1 + 1e-9)


def test_profile_parameters_pick_the_ends_and_the_centre():
    mus = np.linspace(0.7, 1.3, 41)[:, None]
    j = profile_parameters(mus[::-1], np.array([[0.7, 1.3]]))
    assert mus[::-1][j, 0].tolist() == pytest.approx([0.7, 1.0, 1.3])
    assert profile_parameters(mus[:2], np.array([[0.7, 1.3]])) == [0, 1]


def test_lam_t_profiles_sort_by_x_and_keep_the_columns():
    """The profiles keep the HF columns of the picked mu and the reduced ones given, in the
    order of increasing x; bound_hf = F lam_n."""
    rng = np.random.default_rng(0)
    mus = np.array([[0.7], [1.0], [1.3]])
    LAM, LAM_T = rng.random((5, 3)), rng.standard_normal((5, 3))
    x = rng.permutation(5).astype(float)
    out = lam_t_profiles(mus, np.array([[0.7, 1.3]]), LAM, LAM_T,
                         lambda mu: (2 * LAM[:, 0], -LAM_T[:, 0]), lambda mu: x,
                         lambda mu: 0.2)
    assert out["mu"] == [[0.7], [1.0], [1.3]]
    order = np.argsort(x)
    for k in range(3):
        assert out["x"][k] == sorted(x.tolist())
        np.testing.assert_array_equal(out["lam_t_hf"][k], LAM_T[order, k])
        np.testing.assert_array_equal(out["bound_hf"][k], 0.2 * LAM[order, k])
    np.testing.assert_array_equal(out["lam_t_rb"][1], -LAM_T[order, 0])

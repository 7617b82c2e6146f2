"""The ``mindlin_cylinders`` scene and the ``mindlin`` block of a friction solve."""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp

from rbbench.hf.model import solve_hf
from rbbench.hf.references.hertz import mindlin_2d
from rbbench.hf.references.mindlin import (
    mindlin_metrics,
    odd_fraction,
    stick_zone_ends,
    traction_l2_error,
)
from rbbench.scene.loading import PROBLEMS_DIR, SceneError, key_data, load_scene

#: a coarse contact mesh (33 friction nodes, a few seconds)
COARSE = ("discretization.h_contact=0.002",)


def test_scene_loads_and_declares_the_reference():
    sc = load_scene("mindlin_cylinders")
    assert sc.param_names == ["ut"]
    assert sc.get("reference", "mindlin") is True
    assert sc.get("reference", "hertz") is False
    assert sc.get("friction", "law") == "coulomb"
    assert sc.get("friction", "coefficient") == 0.2
    assert sc.get("material", "upper") == sc.get("material", "lower")  # elastically similar
    assert sc.get("geometry", "upper_radius") == sc.get("geometry", "lower_radius")
    assert [s["tangential"] for s in sc.get("load", "load_steps")] == [0.0, 1.0]
    sc.check_mu(sc.default_mu)


def test_mindlin_key_is_cache_neutral_at_its_default():
    sc = load_scene("hertz_halfdisks")
    assert sc.get("reference", "mindlin") is False
    assert "mindlin" not in key_data(sc.data)["reference"]
    assert "mindlin" in key_data(load_scene("mindlin_cylinders").data)["reference"]


def test_mindlin_reference_needs_coulomb_friction(tmp_path):
    text = (PROBLEMS_DIR / "hertz_halfdisks.toml").read_text() + "mindlin = true\n"
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert str(path) in msg and "[reference] mindlin" in msg and "coulomb" in msg


def test_stick_zone_ends_are_midpoints():
    x = np.array([0.3, -0.2, -0.1, 0.0, 0.1, 0.2, -0.3])
    st = np.array(["open", "slip", "stick", "stick", "stick", "slip", "open"], dtype=object)
    assert stick_zone_ends(x, st) == pytest.approx((-0.15, 0.15))
    assert stick_zone_ends(x, np.full(7, "slip", dtype=object)) is None
    assert stick_zone_ends(x[2:5], st[2:5]) == pytest.approx((-0.1, 0.1))  # ends at nodes


def test_odd_fraction_of_even_and_odd_profiles():
    x = np.linspace(-1.0, 1.0, 41)
    assert odd_fraction(x, 1.0 - x**2, 1.0) == pytest.approx(0.0, abs=1e-14)
    assert odd_fraction(x, 1.0 - x**2 + 0.1 * x, 1.0) > 0.05


def _fake_contact(n: int, a: float) -> SimpleNamespace:
    """P1 nodes on [-1.5 a, 1.5 a], two-point Gauss rule per facet, flat bottom (t_x = 1)."""
    nodes = np.linspace(-1.5 * a, 1.5 * a, n)
    g = np.array([-1.0, 1.0]) / math.sqrt(3.0)
    rows, cols, vals, xq, wq = [], [], [], [], []
    for e in range(n - 1):
        x0, x1 = nodes[e], nodes[e + 1]
        for gp in g:
            s = 0.5 * (gp + 1.0)
            k = len(xq)
            xq.append(x0 + s * (x1 - x0))
            wq.append(0.5 * (x1 - x0))
            rows += [k, k]
            cols += [e, e + 1]
            vals += [1.0 - s, s]
    Mt = sp.csr_matrix((vals, (rows, cols)), shape=(len(xq), n))
    pts = np.stack([xq, np.zeros(len(xq))], 1)
    normals = np.tile([0.0, -1.0], (len(xq), 1))
    colloc = np.stack([nodes, np.zeros(n)], 1)
    return SimpleNamespace(points=pts, normals=normals, weights=np.array(wq), Mt=Mt,
                           colloc_points=colloc)


def test_traction_error_of_the_interpolated_theory_falls_with_h():
    """The P1 interpolant of q itself: a few % at 40 nodes per 2a (q has infinite slopes
    at +-a and +-c), falling with h: the floor of the nodal comparison."""
    m = mindlin_2d(P=1.0, Q=0.5 * 0.2, F=0.2, a=1.0, p0=2.0 / math.pi)
    errs = []
    for n in (61, 241, 481):
        c = _fake_contact(n, m.a)
        lam_t = m.shear_traction(c.colloc_points[:, 0])
        errs.append(traction_l2_error(c, lam_t, m.shear_traction, 1.0, m.a))
        assert traction_l2_error(c, -lam_t, m.shear_traction, -1.0, m.a) == errs[-1]
    assert errs[2] < errs[1] < errs[0] < 0.05 and errs[2] < 0.01


def test_mindlin_metrics_on_the_theory_itself():
    """Nodal theory values and states: c and the traction agree to the mesh size."""
    P, F, a = 1.0, 0.2, 1.0
    m = mindlin_2d(P=P, Q=0.5 * F * P, F=F, a=a, p0=2.0 * P / (math.pi * a))
    c = _fake_contact(241, a)
    x = c.colloc_points[:, 0]
    states = np.where(np.abs(x) < m.c, "stick", np.where(np.abs(x) < a, "slip", "open"))
    geometry = {"R1": 1.0, "R2": 1.0}
    E_star = 4.0 * P * 0.5 / (math.pi * a**2)  # Hertz a = 1 at P = 1, R* = 0.5
    body = SimpleNamespace(E=2.0 * E_star * (1 - 0.09), nu=0.3)
    out = mindlin_metrics(c, m.shear_traction(x), states.astype(object), P, m.Q, F, geometry,
                          [body, body])
    assert out["a"] == pytest.approx(a) and out["c_theory"] == pytest.approx(m.c)
    assert abs(out["c_rel_error"]) < 0.02 and out["traction_l2_rel_error"] < 0.01
    assert out["traction_l2_rel_error_even"] == pytest.approx(out["traction_l2_rel_error"])
    full = mindlin_metrics(c, m.shear_traction(x), states.astype(object), P, F * P, F,
                           geometry, [body, body])
    assert full["c_theory"] is None and "full sliding" in full["reason"]


@pytest.fixture(scope="module")
def coarse_solution():
    return solve_hf(load_scene("mindlin_cylinders", COARSE))


def test_coarse_solve_has_a_finite_mindlin_block(coarse_solution):
    m = coarse_solution.metrics
    assert m["converged"]
    b = m["mindlin"]
    assert b["P"] == m["contact_force"] and b["Q"] == m["tangential_force"]
    for key in ("a", "p0", "c", "c_theory", "c_rel_error", "traction_l2_rel_error",
                "traction_l2_rel_error_even", "lam_t_odd_fraction"):
        assert math.isfinite(b[key]), key
    assert b["a_over_R_star"] <= 0.02
    assert 0.3 < b["Q_over_FP"] < 0.7  # partial slip: the stick zone is inside
    assert 0 < b["c"] < b["a"]
    assert "mindlin" in m["definitions"]


@pytest.mark.slow
def test_errors_fall_under_refinement():
    """h_contact 1e-3 -> 5e-4 (the default): c and the L2 error both fall (about 30 s)."""
    blocks = [solve_hf(load_scene("mindlin_cylinders", (f"discretization.h_contact={h}",)))
              .metrics["mindlin"] for h in (0.001, 0.0005)]
    assert abs(blocks[1]["c_rel_error"]) < abs(blocks[0]["c_rel_error"])
    assert blocks[1]["traction_l2_rel_error"] < blocks[0]["traction_l2_rel_error"]
    assert abs(blocks[1]["c_rel_error"]) < 0.05 and blocks[1]["traction_l2_rel_error"] < 0.10

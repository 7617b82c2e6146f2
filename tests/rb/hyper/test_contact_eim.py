"""Hyper-reduction of the contact rows (rbbench.rb.hyper.contact_eim) against the HF operators."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from rbbench.hf.components import make_components
from rbbench.hf.geometry.facets import ray_cast, ray_cast_window
from rbbench.rb.config import make_config
from rbbench.rb.hyper.contact_eim import HyperReductionError, build_row_evaluator, contact_eim
from rbbench.rb.offline import reduce
from rbbench.scene.loading import load_scene

COARSE = ["discretization.h_contact=0.02", "discretization.h_max=0.2"]


def _components(extra=()):
    sc = load_scene("hertz_halfdisks", COARSE + list(extra))
    return sc, make_components(sc, "skfem", "mixed", "ssn")


@pytest.mark.parametrize("extra", [(), ('geometry.lower="rigid_flat"',),
                                   ("discretization.degree=2", 'discretization.multiplier="p1"')])
def test_row_evaluator_reproduces_hf_rows(extra):
    sc, (b, f, _) = _components(extra)
    layout = b.contact_layout()
    rng = np.random.default_rng(1)
    rows = np.sort(rng.choice(layout.n_mult, min(7, layout.n_mult), replace=False))
    ev = build_row_evaluator(layout, rows, np.linspace(0.7, 1.3, 13)[:, None])
    for mu in [0.7, 1.3, *rng.uniform(0.7, 1.3, 3)]:
        c = b.discretize(mu).contact
        B, G = c.B(), c.G()
        Br, Gr = ev(mu)
        # every nonzero of those rows lives on the local dofs, and the values match
        assert abs(B[ev.rows]).sum() == pytest.approx(np.abs(Br).sum(), rel=1e-12)
        np.testing.assert_allclose(Br, B[ev.rows][:, ev.local_dofs].toarray(),
                                   atol=1e-14 * abs(B).max())
        np.testing.assert_allclose(Gr, G[ev.rows], atol=1e-14 * np.abs(G).max())
        Z = rng.standard_normal((ev.n_local, 3))
        e_row, e_col = np.divmod(np.arange(ev.rows.size * 3), 3)  # every entry of B_r Z
        C, g = ev.entries(mu, Z, *ev.support(e_row), e_col, np.arange(ev.rows.size))
        np.testing.assert_allclose(C, (Br @ Z).ravel(), atol=1e-13 * np.abs(Br @ Z).max())
        np.testing.assert_allclose(g, Gr, atol=1e-14 * np.abs(G).max())


def test_row_evaluator_refuses_a_point_outside_its_window():
    sc, (b, _, _) = _components()
    layout = b.contact_layout()
    ev = build_row_evaluator(layout, [0], np.array([[0.99], [1.0]]), margin=0)
    with pytest.raises(HyperReductionError, match="window"):
        ev(0.7)


@st.composite
def chains(draw):
    n = draw(st.integers(3, 40))
    theta = np.sort(draw(st.lists(st.floats(0.3, 2.8), min_size=n + 1, max_size=n + 1,
                                  unique=True)))
    r = 1.0 + draw(st.floats(0.0, 0.2)) * np.sin(draw(st.integers(1, 9)) * theta)
    verts = np.stack([r * np.cos(theta), r * np.sin(theta)], axis=1)
    k = draw(st.integers(1, 8))
    x = np.stack([np.array(draw(st.lists(st.floats(-1.0, 1.0), min_size=k, max_size=k))),
                  np.full(k, 1.6)], axis=1)
    ang = np.array(draw(st.lists(st.floats(-0.6, 0.6), min_size=k, max_size=k)))
    nrm = np.stack([np.sin(ang), -np.cos(ang)], axis=1)
    lo = np.array(draw(st.lists(st.integers(0, n - 1), min_size=k, max_size=k)))
    hi = np.minimum(lo + np.array(draw(st.lists(st.integers(0, n), min_size=k,
                                                max_size=k))), n - 1)
    return verts[:-1], verts[1:], x, nrm, lo, hi


def _two_crossings():
    """A chain that a ray crosses twice within one window (found by hypothesis in CI):
    a sign change of the side function exists, but a closer crossing hides behind it."""
    th = np.array([0.3125, 0.5, 0.625, 1.0])
    verts = np.stack([np.cos(th), np.sin(th)], axis=1)
    x = np.array([[0.25, 1.6]])
    nrm = np.array([[0.47942554, -0.87758256]])
    return verts[:-1], verts[1:], x, nrm, np.array([0]), np.array([2])


@settings(max_examples=300, deadline=None)
@given(chains())
@example(_two_crossings())
def test_windowed_ray_cast_equals_brute_force_on_the_window(data):
    """Bisection + local check equals the brute-force cast, also on wavy (non-monotone) chains."""
    a, b, x, nrm, lo, hi = data
    width = int((hi - lo).max()) + 1
    cand = lo[:, None] + np.arange(width)[None, :]
    cand = np.where(cand <= hi[:, None], cand, -1)
    seg0, s0, t0 = ray_cast(x, nrm, a, b, candidates=cand)
    seg1, s1, t1 = ray_cast_window(x, nrm, a, b, lo, hi)
    hit = seg0 >= 0
    np.testing.assert_array_equal(seg1 >= 0, hit)
    # the same distance |t| (ties between facets sharing a vertex may pick either)
    np.testing.assert_allclose(np.abs(t1[hit]), np.abs(t0[hit]), rtol=1e-9, atol=1e-12)


@settings(max_examples=100, deadline=None)
@given(chains(), st.integers(1, 50))
def test_ray_cast_in_blocks_equals_one_block(data, block):
    """The blocked brute force (``RAY_CAST_BLOCK`` pairs per block) gives exactly the
    result of all points at once, with and without candidate windows."""
    from rbbench.hf.geometry import facets

    a, b, x, nrm, lo, hi = data
    width = int((hi - lo).max()) + 1
    cand = lo[:, None] + np.arange(width)[None, :]
    cand = np.where(cand <= hi[:, None], cand, -1)
    for candidates in (None, cand):
        whole = facets._ray_cast_block(x, nrm, a, b, 1e-10, candidates)
        with pytest.MonkeyPatch.context() as m:
            m.setattr(facets, "RAY_CAST_BLOCK", block)
            blocked = facets.ray_cast(x, nrm, a, b, candidates=candidates)
        for u, v in zip(whole, blocked, strict=True):
            np.testing.assert_array_equal(u, v)


@pytest.fixture(scope="module")
def hertz_train():
    sc, (b, f, _) = _components()
    mus = np.linspace(0.7, 1.3, 7)[:, None]
    probs = [f.build(b.discretize(mu)) for mu in mus]
    return sc, b, f, mus, probs


def test_contact_eim_is_exact_at_its_magic_rows_and_on_training(hertz_train):
    sc, b, f, mus, probs = hertz_train
    rng = np.random.default_rng(2)
    n = probs[0].A.shape[0]
    Z = np.linalg.qr(rng.standard_normal((n, 4)))[0]
    Vg = np.abs(rng.standard_normal((probs[0].B.shape[0], 3)))
    deim = contact_eim(b.contact_layout(), [p.B for p in probs],
                        np.stack([p.G for p in probs], axis=1), Z, Vg, probs[0].free,
                        mus, tol=1e-12)
    for p, mu in zip(probs, mus, strict=True):  # training: reproduced to rounding
        Bn, Gn = deim(mu)
        np.testing.assert_allclose(Bn, Vg.T @ (p.B @ Z), atol=1e-9 * np.abs(Bn).max())
        np.testing.assert_allclose(Gn, Vg.T @ p.G, atol=1e-9 * np.abs(Gn).max())
    # off training: the interpolant matches C(mu) = B(mu) Z exactly at the magic rows
    ev = deim.evaluator
    p = f.build(b.discretize(0.93))
    C = p.B @ Z
    rows_B = ev.rows[deim.pos_B]
    e_row, e_col = np.divmod(np.arange(rows_B.size * Z.shape[1]), Z.shape[1])
    Cp, _ = ev.entries(0.93, deim.Z_loc, *ev.support(deim.pos_B[e_row]), e_col, deim.pos_G)
    np.testing.assert_allclose(Cp, C[rows_B].ravel(), atol=1e-13 * np.abs(C).max())
    assert pickle.loads(pickle.dumps(deim)).R == 3


def test_pipeline_with_eim_matches_the_plain_reduced_model(tmp_path):
    """On the training parameters (validation = training grid) the EIM reproduces B_N and
    G_N, so hyper 'eim' and hyper 'none' solve the same reduced problems."""
    sc = load_scene("hertz_halfdisks", COARSE + ['sampling.valid="uniform"'])
    common = dict(dual="mcpg", stabilizer="none", N=6, R=5, n_train=7, n_valid=7, n_jobs=1,
                  cache_dir=str(tmp_path), online_repeats=2)
    r_eim = reduce(sc, make_config(hyper="eim", tol_eim=0.0, **common))
    r_none = reduce(sc, make_config(hyper="none", **common))
    assert r_eim.hyper == "eim" and r_none.hyper == "none"
    np.testing.assert_allclose(r_eim.err_u, r_none.err_u, rtol=1e-6)
    np.testing.assert_allclose(r_eim.err_lam, r_none.err_lam, rtol=1e-6)
    h = r_eim.histories
    assert h["eim"]["e_eim_valid_BN"] < 1e-10
    assert h["eim_error"] and all(e >= 0 for e in h["eim_error"])
    assert "eim_entrywise" in h
    # auto picks eim on Hertz (B(mu) is not affine) when the backend has a layout
    r_auto = reduce(sc, make_config(hyper="auto", tol_eim=1e-6, **common))
    assert r_auto.hyper == "eim" and "affine_refused" in r_auto.histories


def test_online_scaling_study_runs_on_two_levels(tmp_path, monkeypatch):
    from rbbench.runtime.timing import ONLINE_PROTOCOL
    from rbbench.studies.scaling import online_scaling, scaling_markdown

    monkeypatch.chdir(tmp_path)
    cfg = make_config(dual="mcpg", stabilizer="none", hyper="eim", N=4, R=4, n_train=5,
                       n_valid=2, n_jobs=1, cache_dir=str(tmp_path), online_repeats=1)
    rows = online_scaling("hertz_halfdisks", cfg, levels=(0, 1), overrides=COARSE, repeats=2,
                          progress=lambda _m: None)
    assert [r["level"] for r in rows] == [0, 1]
    assert rows[1]["n_hf_dofs"] > rows[0]["n_hf_dofs"]
    assert rows[0]["ratio_to_first"] == 1.0 and rows[1]["t_online_median_s"] > 0
    from rbbench.rb.mixed.compiled import NUMBA_VERSION

    assert {r["online_path"] for r in rows} == {"compiled" if NUMBA_VERSION else "python"}
    assert {r["online_protocol"] for r in rows} == {ONLINE_PROTOCOL}
    assert all(r["floor_s"] > 0 for r in rows)
    assert {r["pairing_table_share"] for r in rows} == {None}  # 2D chains: no table
    text = scaling_markdown(rows)
    assert "| 1 |" in text and ONLINE_PROTOCOL in text


def test_online_scaling_times_a_baseline_scene_in_the_same_loop(tmp_path, monkeypatch):
    from rbbench.studies.scaling import online_scaling, scaling_markdown

    monkeypatch.chdir(tmp_path)
    cfg = make_config(dual="mcpg", stabilizer="none", hyper="eim", N=4, R=4, n_train=5,
                       n_valid=2, n_jobs=1, cache_dir=str(tmp_path), online_repeats=1)
    rows = online_scaling("hertz_halfdisks", cfg, levels=(1,), overrides=COARSE, repeats=2,
                          progress=lambda _m: None, baseline="hertz_halfdisks",
                          baseline_overrides=(*COARSE, "discretization.level=0"))
    assert [r["level"] for r in rows] == [None, 1]
    assert rows[0]["n_hf_dofs"] < rows[1]["n_hf_dofs"]
    assert rows[0]["ratio_to_baseline"] == 1.0 and rows[1]["ratio_to_first"] == 1.0
    assert rows[1]["ratio_to_baseline"] == (rows[1]["t_online_median_s"]
                                            / rows[0]["t_online_median_s"])
    text = scaling_markdown(rows)
    assert "ratio to baseline" in text and "| baseline |" in text


def test_online_scaling_caps_later_levels_at_the_first_levels_sizes(tmp_path, monkeypatch):
    from rbbench.studies.scaling import online_scaling, scaling_markdown

    monkeypatch.chdir(tmp_path)
    cfg = make_config(dual="mcpg", stabilizer="none", hyper="eim", N=12, R=12, n_train=5,
                       n_valid=2, n_jobs=1, cache_dir=str(tmp_path), online_repeats=1)
    rows = online_scaling("hertz_halfdisks", cfg, levels=(0, 1), overrides=COARSE, repeats=2,
                          progress=lambda _m: None, match_sizes=True)
    first, later = rows
    assert first["sizes_from"] is None and later["sizes_from"] == 0
    assert later["N"] <= first["N"] and later["R"] <= first["R"]
    assert "capped at level 0's" in scaling_markdown(rows)


def test_capped_config_takes_every_size_the_first_reduction_reached():
    from types import SimpleNamespace

    from rbbench.studies.scaling import capped_config

    cfg = make_config(dual="mcpg", N=20, R=20, k_pga_max=40, tol_eim=1e-6)
    built = SimpleNamespace(summary=lambda: {"N": 11, "R": 7, "K_pga": 8, "S": None},
                            histories={"eim": {"M_B": 13, "M_G": 5, "rows": 20}})
    capped = capped_config(cfg, built)
    assert capped.N == 11
    assert capped.options == {"dual": "mcpg", "R": 7, "k_pga_max": 8, "m_eim": 13,
                              "tol_eim": 1e-6}
    assert cfg.N == 20 and cfg.options["R"] == 20  # the given config is left as it was


def test_online_scaling_refuses_to_match_sizes_of_another_formulation():
    from rbbench.studies.scaling import online_scaling

    with pytest.raises(ValueError, match="match_sizes.*nitsche"):
        online_scaling("hertz_halfdisks", make_config(formulation="nitsche"), levels=(0, 1),
                       match_sizes=True, progress=lambda _m: None)
    with pytest.raises(ValueError, match="match_sizes.*'linear'"):  # a linear scene's default
        online_scaling("thermal_block", make_config(), levels=(0, 1), match_sizes=True,
                       progress=lambda _m: None)

"""The claims of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods:
parametric variational inequalities" (talk), measured on Hertz data, and the beta_dec study.

* mCPG vs CPG (slides "mCPG algorithm (3/4)", "(4/4)": "Accuracy ↗", "Cone aperture ↗",
  "avoid ill-conditioning issues"): at every equal ``R``, ``e_proj`` of mCPG is at most
  that of CPG, its new generators are at least as open (``e_orth``), its Gram matrix at
  most as ill-conditioned. Empirical claims, not theorems: they are checked on data.
* PGA (slide "Some details"): ``max_train sigma_{S^n}`` is non-increasing and reaches 0
  after at most ``P x R`` additions ("Finite termination"); with ``delta < 1`` the
  offline space is inf-sup stable on the training set ("Main result", Riesz form).
* :func:`rbbench.studies.beta_dec.beta_dec_study` on the membrane: the relations between
  the constants that must hold whatever the data.

Hertz runs on a coarse mesh (``HERTZ_COARSE``, 9 training parameters) by default; the same
claims on the scene's own mesh and 21 parameters are marked slow (``--runslow``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from rbbench.hf.components import make_components
from rbbench.hf.snapshots.compute import compute_snapshots
from rbbench.rb.algorithms import infsup as inf
from rbbench.rb.algorithms.pga import supremizers
from rbbench.rb.compressors import pga_default_delta
from rbbench.registry import default_registry
from rbbench.scene.loading import load_scene
from rbbench.scene.sampling import parameter_set
from rbbench.studies.beta_dec import beta_dec_study
from rbbench.testing import HERTZ_COARSE

pytestmark = pytest.mark.timeout(900)

#: e_proj is relative to max_q ||theta_q||_W: 1e-12 absolute is 1e-12 of the largest snapshot.
E_PROJ_SLACK = 1e-12


@dataclass
class HertzData:
    """Training snapshots of the Hertz scene and the operators the claims need."""

    LAM: np.ndarray
    U: np.ndarray
    X: Any
    x_solve: Any
    W_ref: Any
    B_train: list
    W_train: list


@pytest.fixture(scope="module", params=[
    pytest.param(("coarse", HERTZ_COARSE, 9), id="coarse"),
    pytest.param(("default", (), 21), id="default-mesh", marks=pytest.mark.slow),
])
def hertz(request, tmp_path_factory) -> HertzData:
    _, overrides, n_train = request.param
    scene = load_scene("hertz_halfdisks", overrides)
    mus = parameter_set(scene, "train", n_train)
    snaps = compute_snapshots(scene, mus, cache_dir=tmp_path_factory.mktemp("cache"),
                              n_jobs=1, progress=False)
    b, f, _ = make_components(scene)
    probs = [f.build(b.discretize(mu)) for mu in mus]
    p0 = f.build(b.discretize(scene.default_mu))
    X = p0.X[p0.free][:, p0.free].tocsr()
    return HertzData(LAM=snaps.LAM, U=snaps.U, X=X, x_solve=inf.make_solver(X), W_ref=p0.W,
                     B_train=[p.B for p in probs], W_train=[p.W for p in probs])


def _duals(d: HertzData):
    reg = default_registry()
    Q = d.LAM.shape[1]
    return [reg.create("dual", name)(d.LAM, d.W_ref, tol=0.0, r_max=Q)
            for name in ("cpg", "mcpg")]


def test_mcpg_projection_error_at_most_cpg_at_every_R(hertz):
    cpg, mcpg = _duals(hertz)
    R = min(cpg.R, mcpg.R)
    assert R >= hertz.LAM.shape[1] - 1  # both run (almost) to exhaustion
    ec, em = np.asarray(cpg.e_proj[:R]), np.asarray(mcpg.e_proj[:R])
    worse = np.nonzero(em > ec + E_PROJ_SLACK)[0]
    assert worse.size == 0, f"mCPG e_proj > CPG e_proj at R = {(worse + 1).tolist()}"
    assert np.any(em < ec - 1e-6)  # and strictly better somewhere (not the same cones)


def test_mcpg_wider_aperture_and_better_conditioned_than_cpg(hertz):
    cpg, mcpg = _duals(hertz)
    R = min(cpg.R, mcpg.R)
    assert np.all(np.asarray(mcpg.e_orth[:R]) >= np.asarray(cpg.e_orth[:R]) - 1e-12)
    assert np.all(np.asarray(mcpg.info["cond_G"][:R])
                  <= np.asarray(cpg.info["cond_G"][:R]) * (1 + 1e-8))


def test_pga_sigma_max_non_increasing_and_finite_termination(hertz):
    reg = default_registry()
    P = len(hertz.B_train)
    Vg = reg.create("dual", "mcpg")(hertz.LAM, hertz.W_ref, tol=0.0, r_max=6).generators
    Z = reg.create("primal", "pod")(hertz.U, hertz.X, n=4).Z
    stab = reg.create("stabilizer", "pga")
    Z_off, hist = stab.offline(Z, Vg, hertz.X, hertz.x_solve, hertz.B_train, 0.0)
    sig = np.asarray(hist["sigma_max"])
    assert 0 < sig[0] <= 1 + 1e-12
    assert np.all(np.diff(sig) <= 1e-12), np.diff(sig).max()
    assert hist["pga_stop"] == "exhausted" and hist["K"] <= P * Vg.shape[1]


def test_pga_offline_space_is_stable_on_the_training_set(hertz):
    reg = default_registry()
    Vg = reg.create("dual", "mcpg")(hertz.LAM, hertz.W_ref, tol=0.0, r_max=8).generators
    Z = reg.create("primal", "pod")(hertz.U, hertz.X, n=3).Z  # N < R: beta_dec span = 0
    delta = pga_default_delta(hertz.B_train[::4], hertz.W_train[::4], hertz.x_solve, Vg)
    Z_off, hist = reg.create("stabilizer", "pga").offline(
        Z, Vg, hertz.X, hertz.x_solve, hertz.B_train, delta)
    assert hist["sigma_max"][-1] <= delta
    for B, W in zip(hertz.B_train, hertz.W_train, strict=True):
        b_dec = inf.infsup_span(*inf.quotient_matrices(B, hertz.X, Vg, W, Z=Z))
        b_off = inf.infsup_span(*inf.quotient_matrices(B, hertz.X, Vg, W, Z=Z_off))
        BtV = np.asarray(B.T @ Vg)  # whole V: S = (B^T Vg)^T X^-1 (B^T Vg), R solves
        S_on, M_on = BtV.T @ supremizers(B, hertz.x_solve, Vg), Vg.T @ (W @ Vg)
        b_on, c = inf.infsup_span(S_on, M_on), inf.boundedness_constant(S_on, M_on)
        assert b_dec <= 1e-6 * c  # 0 up to the square root of a rounded eigenvalue
        assert b_off >= np.sqrt(1.0 - delta**2) * b_on * (1 - 1e-9) > 0


# ---------------------------------------------------------------------------
# the beta_dec study
# ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def membrane_study(tmp_path_factory):
    scene = load_scene("membrane_obstacle", ["discretization.n_cells=8"])
    return beta_dec_study(scene, dual="mcpg", R=[4, 6], n_train=9, n_valid=4,
                          cache_dir=tmp_path_factory.mktemp("cache"), n_jobs=1)


def _rel_le(a: np.ndarray, b: np.ndarray, rtol: float = 1e-9) -> bool:
    """``a <= b`` up to ``rtol`` of the larger magnitude (elementwise, all)."""
    return bool(np.all(a <= b + rtol * np.maximum(np.abs(a), np.abs(b))))


def test_study_constants_are_ordered(membrane_study):
    """Per mu: span <= cone; dec <= off <= on (nested primal spaces); dec grows with N."""
    for (R, s), d in membrane_study.per_mu.items():
        assert all(r["dec_kind"] == "cone-exact" for r in membrane_study.rows)
        for tag in ("dec", "off"):
            assert _rel_le(d[f"{tag}_span"], d[f"{tag}_cone"]), (R, s, tag)
        assert _rel_le(d["on_span"], d["on_cone"])
        for kind in ("span", "cone"):
            assert _rel_le(d[f"dec_{kind}"], d[f"off_{kind}"]), (R, s, kind)
            assert _rel_le(d[f"off_{kind}"], d["on_" + kind][None, :]), (R, s, kind)
            assert _rel_le(d[f"dec_{kind}"][:-1], d[f"dec_{kind}"][1:]), (R, s, kind)
        # N < R: Z^T B^T Vg has a null space, the span value is 0 up to the square root of a
        # rounded eigenvalue, ~sqrt(eps) times the continuity constant c
        N = np.array([r["N"] for r in membrane_study.rows if (r["R"], r["set"]) == (R, s)])
        assert np.all(d["dec_span"][N < R] <= 1e-6 * d["c"][None, :])
        assert np.all(d["on_cone"] <= d["c"] * (1 + 1e-9))


def test_study_lp_zero_test_agrees_with_the_exact_cone_value(membrane_study):
    for d in membrane_study.per_mu.values():
        for tag in ("dec", "off"):  # "zero": rounding level, ~sqrt(eps) c
            assert np.array_equal(d[f"{tag}_zero"], d[f"{tag}_cone"] <= 1e-6 * d["c"]), tag


def test_study_decorrelated_model_fails_and_pga_restores(membrane_study):
    """Measured on the membrane: the LP certifies beta_dec = 0 at N = 1 < R; after PGA the
    offline constant is positive on the training set, above the Riesz bound."""
    rows = membrane_study.rows
    assert any(r["N"] < r["R"] and r["dec_zero_count"] > 0 for r in rows)
    for (R, s), d in membrane_study.per_mu.items():
        if s != "train":
            continue
        assert not d["off_zero"].any()
        Ns = [r["N"] for r in rows if (r["R"], r["set"]) == (R, s)]
        for i, N in enumerate(Ns):
            delta = membrane_study.pga[(R, N)]["delta"]
            assert np.all(d["off_span"][i] >= np.sqrt(1 - delta**2) * d["on_span"] * (1 - 1e-9))
    text = membrane_study.table()
    assert text.count("\n") == len(rows) + 1 and "dec_cone_min" in text

"""The compiled online path of the hyper-reduced wedge model
(rbbench.rb.friction.wedge.compiled, numba) against the Python reference on the same model.

The model is built from the real friction EIM of coarse P1 hertz_friction (its pairing,
windows, magic rows and slip rows) with random bases (fixed seed), a mu-dependent SPD
``A_N`` and a slip coupling ``P`` scaled so that De Saxce's fixed point contracts: the
two paths must give the same primal and wedge coefficients to 1e-10 (relative, max norm),
the same iterations and stop reason."""

from __future__ import annotations

import pickle

import numpy as np
import pytest

pytest.importorskip("numba")

from rbbench.hf.components import make_components  # noqa: E402
from rbbench.hf.model import build_problem  # noqa: E402
from rbbench.rb.algorithms.affine import AffineOperator, LinearInMu  # noqa: E402
from rbbench.rb.friction.eim import friction_eim, friction_training_operators  # noqa: E402
from rbbench.rb.friction.wedge import compiled  # noqa: E402
from rbbench.rb.friction.wedge.hyper import WedgeHyperModel  # noqa: E402
from rbbench.rb.friction.wedge.model import WedgeBasis, condense_wedge  # noqa: E402
from rbbench.scene.loading import load_scene  # noqa: E402
from rbbench.scene.parameters import SceneError  # noqa: E402

TINY = ["discretization.degree=1", "discretization.h_contact=0.04", "discretization.h_max=0.4"]
_CACHE: dict = {}


def _model() -> WedgeHyperModel:
    """The wedge hyper model of the module docstring (cached per session)."""
    if "model" in _CACHE:
        return _CACHE["model"]
    sc = load_scene("hertz_friction", TINY)
    b, f, _ = make_components(sc, "skfem", "mixed", "friction-ssn")
    free = build_problem(b, f, sc, np.array([1.0])).free
    mus = np.linspace(0.7, 1.3, 7)[:, None]
    layout = b.contact_layout()
    Bn, Bt, Gn = friction_training_operators(layout, mus, free)
    rng = np.random.default_rng(3)
    m, N, R = Gn.shape[0], 6, 3
    Z = np.linalg.qr(rng.standard_normal((free.size, N)))[0]
    wedge = WedgeBasis(np.abs(rng.standard_normal((m, R))), np.abs(rng.standard_normal((m, R))),
                       np.full(m, 0.2))
    slip_nodes = np.sort(rng.choice(m, 5, replace=False))
    feim = friction_eim(layout, Bn, Bt, Gn, Z, wedge.Ln, wedge.Lt, free, mus, tol=1e-12,
                        slip_rows=slip_nodes)
    X = rng.standard_normal((2, N, N))
    A = np.stack([X[0] @ X[0].T + N * np.eye(N), 0.1 * (X[1] + X[1].T)])
    BnN, GnN, BtN = feim(np.array([1.0]))
    c_star = rng.standard_normal(N)  # a load that presses some generators into contact
    scale = np.abs(BnN).max() / np.abs(GnN).max()
    F = np.stack([A[0] @ c_star + (BnN + BtN).T @ np.abs(rng.standard_normal(2 * R)),
                  A[1] @ c_star]) / scale
    model = WedgeHyperModel(P=np.zeros((2 * R, slip_nodes.size)), mus_train=mus[::3],
                            x_train=np.abs(rng.standard_normal((3, 2 * R))),
                            parameters=sc.parameter_space, A=AffineOperator(A),
                            F=AffineOperator(F), coefficients=LinearInMu(1), eim=feim)
    # P: non-negative, scaled so that the slip term moves the QP's solution by at most a
    # third of the change of c (a contraction of factor <= 1/3)
    cond = condense_wedge(model.arrays(np.array([1.0])), model.P)
    P = np.abs(rng.standard_normal(model.P.shape))
    lip = (np.linalg.norm(np.linalg.inv(cond.D), 2) * np.linalg.norm(P, 2)
           * np.linalg.norm(cond.T, 2))
    model.P = P / (3.0 * lip)
    _CACHE["model"] = model
    return model


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


def test_compiled_equals_python_path():
    """Over 8 random mu in D: the same a (relative max norm, per mu) and c (max norm
    relative to the largest wedge coefficient over the 8 mu: at a mu where every generator
    is released daqp's c is round-off, ~1e-24) to 1e-10 (measured <= 1e-13), the same
    iterations and stop reason, the cone held exactly (c >= 0), and the path each result
    reports; the compiled path by default."""
    model = _model()
    assert model.online_path().startswith("compiled (numba ")
    rng = np.random.default_rng(11)
    pairs = [(model.solve(mu), model.solve(mu, path="python"))
             for mu in rng.uniform(0.7, 1.3, (8, 1))]
    c_top = max(float(np.abs(ref.c).max()) for _, ref in pairs)
    for fast, ref in pairs:
        assert (fast.path, ref.path) == ("compiled", "python")
        assert fast.stop_reason == ref.stop_reason == "converged"
        assert fast.iterations == ref.iterations > 1
        assert _rel(fast.a, ref.a) <= 1e-10
        assert np.abs(fast.c - ref.c).max() <= 1e-10 * c_top
        assert fast.c.min() >= 0.0
        np.testing.assert_allclose(fast.history, ref.history, rtol=1e-6, atol=1e-14)
    # real QPs: some bound active and some generator in contact at most mu
    n_pos = [int((ref.c > 1e-8 * c_top).sum()) for _, ref in pairs]
    assert max(n_pos) < model.R and sum(n > 0 for n in n_pos) >= 6, n_pos


def test_given_warm_start_and_cold_start_match_python():
    """An explicit warm start ``x0`` is used by both paths alike (same iterations)."""
    model = _model()
    mu = np.array([0.91])
    x0 = np.full(model.R, 0.5 * float(model.x_train.max()))
    fast, ref = model.solve(mu, x0), model.solve(mu, x0, path="python")
    assert fast.path == "compiled" and fast.iterations == ref.iterations
    assert _rel(fast.c, ref.c) <= 1e-10


def test_outside_d_falls_back_to_the_reference_error_and_pickles():
    """mu outside D: the kernel declines and the Python path raises the scene's error; the
    model pickles without its compiled state and rebuilds it on use."""
    model = _model()
    with pytest.raises(SceneError):
        model.solve(np.array([2.0]))
    with pytest.raises(ValueError, match="online path"):
        model.solve(np.array([1.0]), path="fast")
    again = pickle.loads(pickle.dumps(model))
    assert "_online_state" not in again.__dict__
    mu = np.array([1.1])
    np.testing.assert_array_equal(again.solve(mu).c, model.solve(mu).c)
    assert compiled.COMPILE["first_call_s"] > 0
    assert compiled.is_cached()  # the kernel ran: numba's disk cache holds its current source


def test_without_numba_the_python_path_runs_and_says_why(monkeypatch):
    """Without numba the reason is reported and ``path = "compiled"`` refuses."""
    model = pickle.loads(pickle.dumps(_model()))
    monkeypatch.setattr(compiled, "NUMBA_VERSION", None)
    assert model.online_path() == "python (numba is not installed)"
    assert model.solve(np.array([1.0])).path == "python"
    with pytest.raises(RuntimeError, match="numba is not installed"):
        model.solve(np.array([1.0]), path="compiled")


def test_compressed_eim_map_gives_the_same_solution(monkeypatch):
    """The kernel's compressed map ``B = (c^T U) W_k`` (here the full SVD, exact to
    round-off, forced on a model too small to need it) solves as the Python path does."""
    model = _model()

    def full_svd(W, values):
        U, s, Vt = np.linalg.svd(W, full_matrices=False)
        return np.ascontiguousarray(U), np.ascontiguousarray(s[:, None] * Vt)

    monkeypatch.setattr(compiled, "compress_map", full_svd)
    online = compiled.CompiledWedge(model)
    assert online.mw[compiled_kernels().W_U, 2] > 0
    for mu in (np.array([0.75]), np.array([1.22])):
        fast, ref = online.solve(mu), model.solve(mu, path="python")
        assert fast.iterations == ref.iterations
        assert _rel(fast.a, ref.a) <= 1e-10
        assert np.abs(fast.c - ref.c).max() <= 1e-10 * max(np.abs(ref.c).max(), 1e-300)


def test_compress_map_keeps_the_map_to_its_tolerance():
    """A map of numerical rank 5 (plus 1e-17 noise) is compressed to rank 5 and reproduces
    ``c^T W`` to 1e-14 relative on the sampled and on new values; a full-rank map is kept."""
    rng = np.random.default_rng(5)
    W = rng.standard_normal((60, 5)) @ rng.standard_normal((5, 400))
    W += 1e-17 * rng.standard_normal(W.shape)
    values = rng.standard_normal((20, 60))
    U, Wk = compiled.compress_map(W, values)
    assert U.shape == (60, 5) and Wk.shape == (5, 400)
    for c in (values, rng.standard_normal((5, 60))):
        exact = c @ W
        assert np.abs((c @ U) @ Wk - exact).max() <= 1e-13 * np.abs(exact).max()
    full = rng.standard_normal((60, 80))
    U, Wk = compiled.compress_map(full, values)
    assert U.shape == (60, 0) and Wk is full
    from rbbench.rb.friction.wedge import kernels

    assert kernels.drop_stale_cache() is False  # just imported: nothing stale


def compiled_kernels():
    from rbbench.rb.friction.wedge import kernels

    return kernels


def _jump_rows_reference(s, dh, wh, zs, m_dofs, has_master, slave, vals, pts, mphi, seg):
    """The slip rows point by point in numpy: ``sum_p vals w s (slave_p - sum_a phi_a
    (dh . Z[master node a]))``."""
    out = np.zeros((pts.shape[0], zs.shape[1]))
    for r in range(pts.shape[0]):
        for p in range(pts.shape[1]):
            if vals[r, p] == 0.0:
                continue
            q = pts[r, p]
            term = slave[r, p].copy()
            if has_master:
                for a in range(mphi.shape[1]):
                    f = seg[q]
                    term -= mphi[q, a] * (dh[q, 0] * zs[m_dofs[f, 2 * a]]
                                          + dh[q, 1] * zs[m_dofs[f, 2 * a + 1]])
            out[r] += vals[r, p] * s * wh[q] * term
    return out


@pytest.mark.parametrize("n_facets", [2, 9])
@pytest.mark.parametrize("nodes", [2, 3, 4])
@pytest.mark.parametrize("has_master", [True, False])
def test_jump_rows_equal_the_pointwise_sum(nodes, has_master, n_facets):
    """The kernel's slip rows (slave terms summed offline, consecutive points on one master
    facet merged, a three-node facet unrolled) equal the point-by-point sum to round-off,
    padding points (zero weight) left out, for linear, quadratic and cubic master facets,
    with few facets (points often share one) or many, and without a master (rigid)."""
    kernels = compiled_kernels()
    rng = np.random.default_rng(nodes + 10 * n_facets)
    n_pts, n_rows, per_row, n_cols, n_dofs = 40, 7, 5, 11, 30
    dh = rng.standard_normal((n_pts, 2))
    wh, zs = rng.random(n_pts), rng.standard_normal((n_dofs, n_cols))
    m_dofs = rng.integers(0, n_dofs, (n_facets, 2 * nodes))
    slave = rng.standard_normal((n_rows, per_row, n_cols))
    vals = rng.standard_normal((n_rows, per_row))
    vals[rng.random(vals.shape) < 0.2] = 0.0  # padding
    pts = rng.integers(0, n_pts, (n_rows, per_row))
    mphi, seg = rng.standard_normal((n_pts, nodes)), rng.integers(0, n_facets, n_pts)
    out = np.zeros((n_rows, n_cols))
    kernels.jump_rows(0.7, dh, wh, zs, m_dofs, has_master,
                      compiled.slave_row_sums(slave, vals, pts, wh), vals, pts, mphi, seg, out)
    ref = _jump_rows_reference(0.7, dh, wh, zs, m_dofs, has_master, slave, vals, pts, mphi,
                               seg)
    assert np.abs(out - ref).max() <= 1e-13 * np.abs(ref).max()

"""The compiled online path (rbbench.rb.mixed.compiled, numba) against the Python reference.

Raw values (the magic entries of ``C(mu) = B(mu) Z``, the magic rows of ``G(mu)``, the EIM
coefficients and the scaled QP data handed to daqp) agree to 1e-12 relative, before any
clipping; the reduced solutions of both compiled methods (``nnls``, ``daqp``) to the
solvers' round-off. Variants: a deformable master
(facet and smooth normals), the rigid plane, P2 facets with P1 multipliers.
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import scipy.linalg as sla

pytest.importorskip("numba")

from rbbench.hf.components import make_components  # noqa: E402
from rbbench.rb.algorithms.affine import AffineOperator, LinearInMu  # noqa: E402
from rbbench.rb.hyper.contact_eim import HyperReductionError, contact_eim  # noqa: E402
from rbbench.rb.kernels import layout, pairing  # noqa: E402
from rbbench.rb.kernels.plan import coefficient_map, eigenbasis  # noqa: E402
from rbbench.rb.mixed import compiled as compiled_online
from rbbench.rb.mixed import kernels as _kernels  # noqa: E402
from rbbench.rb.mixed.model import ReducedModel  # noqa: E402
from rbbench.scene.loading import load_scene  # noqa: E402
from rbbench.scene.parameters import SceneError  # noqa: E402
from rbbench.testing import HERTZ_COARSE  # noqa: E402

VARIANTS = {"facet": (), "smooth": ('discretization.normals="smooth"',),
            "rigid": ('geometry.lower="rigid_flat"',),
            "p2": ("discretization.degree=2", 'discretization.multiplier="p1"')}  # slow: ~20 s
MUS = (0.7, 0.83, 1.0, 1.17, 1.3)


def _model(extra: tuple[str, ...]) -> ReducedModel:
    """A reduced model on coarse Hertz: the contact EIM of random bases (fixed seed) with a
    mu-dependent SPD ``A_N`` and a load ``F_N`` (affine in mu)."""
    sc = load_scene("hertz_halfdisks", [*HERTZ_COARSE, *extra])
    b, f, _ = make_components(sc, "skfem", "mixed", "ssn")
    mus = np.linspace(0.7, 1.3, 5)[:, None]
    probs = [f.build(b.discretize(mu)) for mu in mus]
    rng = np.random.default_rng(7)
    n, N, R = probs[0].A.shape[0], 6, 5
    Z = np.linalg.qr(rng.standard_normal((n, N)))[0]
    Vg = np.abs(rng.standard_normal((probs[0].B.shape[0], R)))
    ceim = contact_eim(b.contact_layout(), [p.B for p in probs],
                       np.stack([p.G for p in probs], axis=1), Z, Vg, probs[0].free,
                       mus, tol=1e-12)
    X = rng.standard_normal((2, N, N))
    A = np.stack([X[0] @ X[0].T + N * np.eye(N), 0.1 * (X[1] + X[1].T)])
    Bn, Gn = ceim(np.array([1.0]))
    c_star = rng.standard_normal(N)  # loads that make some constraints active
    F = np.stack([A[0] @ c_star + Bn.T @ np.abs(rng.standard_normal(R)), A[1] @ c_star])
    return ReducedModel(AffineOperator(A), AffineOperator(F), LinearInMu(1), ceim,
                        parameters=sc.parameter_space)


@pytest.fixture(scope="module", params=[
    pytest.param(v, marks=pytest.mark.slow) if v == "p2" else v for v in VARIANTS])
def model(request) -> ReducedModel:
    return _model(VARIANTS[request.param])


def _python_qp(model: ReducedModel, mu: float) -> np.ndarray:
    """The scaled QP data of :func:`rbbench.rb.mixed.model._solve_daqp`, as the kernel lays
    them out (``[H, f, A, b_upper, rows, |F|]``), from the Python path."""
    A, F, B, G = model.arrays(np.array([mu]))
    rows = np.linalg.norm(B, axis=1)
    rows[rows == 0.0] = 1.0
    fs = float(np.linalg.norm(F)) or 1.0
    return np.concatenate([A.ravel(), -F / fs, (B / rows[:, None]).ravel(), G / rows / fs,
                           rows, [fs]])


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


def test_raw_values_equal_the_python_path(model):
    """Magic entries, G rows, EIM coefficients and the QP data: 1e-12 relative."""
    ceim = model.constraint
    ev = ceim.evaluator
    online = compiled_online.CompiledOnline(model)
    fb, ib, meta = online.fb, online.ib, online.meta
    k = ev.layout.degree + 1
    nq = ev.Mrows.shape[1]
    n_hat = layout.float_rows(fb, meta, layout.N_HAT)
    for mu in MUS:
        th = np.array([1.0, mu])
        w, gap, mphi = np.empty(nq), np.empty(nq), np.zeros((nq, k))
        seg = np.zeros(nq, dtype=np.int64)
        status, s = pairing.pair_points(th, fb, ib, meta, w, gap, mphi, seg)
        assert status == layout.OK
        p = ev.pairing(np.array([mu]))
        # the online normals sign(s) n_hat and weights |s| w_hat, tabulated on the reference
        # chain; the reference maps the facet ends first and subtracts them, which costs it
        # eps |x| / h of cancellation (measured <= 7e-14 in the normals, 2e-14 in w)
        np.testing.assert_allclose(np.sign(s) * n_hat, p.nrm, rtol=0, atol=1e-12)
        np.testing.assert_allclose(w, p.w, rtol=1e-12, atol=0)
        np.testing.assert_allclose(gap, p.gap, rtol=0, atol=1e-12 * np.abs(p.gap).max())
        if ev.layout.master is not None:
            np.testing.assert_array_equal(seg, p.master_seg)
        c, g = np.empty(len(ceim.entry_col)), np.empty(len(ceim.pos_G))
        _kernels.magic_values(fb, ib, meta, s, w, gap, mphi, seg, c, g)
        c_py, g_py = ev.entries(np.array([mu]), ceim.Z_loc, *ceim._support, ceim.entry_col,
                                ceim.pos_G)
        assert _rel(c, c_py) <= 1e-12 and _rel(g, g_py) <= 1e-12
        theta = sla.lu_solve(ceim.lu_B, c_py)  # the folded map = the coefficient solve
        w_b = coefficient_map(ceim.lu_B, ceim.T_B)
        assert _rel(np.tensordot(c, w_b, 1), np.tensordot(theta, ceim.T_B, 1)) <= 1e-12
        assert _kernels.online_qp(np.array([mu]), fb, ib, meta, online.qp) == layout.OK
        ref = _python_qp(model, mu)
        n = model.N
        assert _rel(online.qp[:n * n], ref[:n * n]) <= 1e-12  # H = A_N
        for part in np.split(np.arange(n * n, ref.size), np.cumsum(
                [n, model.R * n, model.R, model.R])):  # f, A, b_upper, rows, |F|
            assert _rel(online.qp[part], ref[part]) <= 1e-12


@pytest.mark.parametrize("method", compiled_online.METHODS)
def test_reduced_solution_equals_the_python_path(model, method):
    """Each compiled method against the Python path of the same method, and ``nnls``
    (condensed through the eigenbasis of A_N) against the Python daqp QP too."""
    for mu in MUS:
        py = model.solve(mu, path="python", method=method)
        co = model.solve(mu, path="compiled", method=method)
        assert py.path == "python" and co.path == "compiled"
        assert co.stop_reason == py.stop_reason == "converged"
        if method == "daqp":
            assert co.iterations == py.iterations
        assert _rel(co.c, py.c) <= 1e-12
        # the multipliers: the solvers' round-off on D = B_N A_N^-1 B_N^T (cond ~5e5 on
        # Hertz level 0 with N + K = 60, R = 20: measured <= 3e-11 relative there)
        np.testing.assert_allclose(co.alpha, py.alpha, rtol=0, atol=1e-10 * py.alpha.max())
        assert co.alpha_raw_min >= -1e-10 and co.time_s > 0
        if method == "nnls":
            qp = model.solve(mu, path="python", method="daqp")
            assert _rel(co.c, qp.c) <= 1e-12
            np.testing.assert_allclose(co.alpha, qp.alpha, rtol=0, atol=1e-10 * qp.alpha.max())


def test_nnls_without_a_common_eigenbasis_takes_the_python_path():
    """Two parameters with non-commuting stiffness terms: no V with V^T A_k V diagonal for
    every k, so ``nnls`` says why and solves on the Python path (same answer as daqp)."""
    model = _model(())
    rng = np.random.default_rng(3)
    X = rng.standard_normal(model.A.terms.shape[1:])
    extra = 0.05 * (X + X.T)
    terms = model.A.terms
    reason = eigenbasis(np.stack([terms[0], terms[1], extra]),
                                        np.array([1.0, 1.0, 0.0]))
    assert isinstance(reason, str) and "no common eigenbasis" in reason
    basis = eigenbasis(terms, np.array([1.0, 1.0]))
    V, lam = basis
    for mu in MUS:  # A_N(mu)^-1 = V diag(1 / lam^T theta) V^T
        th = np.array([1.0, mu])
        inv = V @ np.diag(1.0 / (th @ lam)) @ V.T
        A = np.tensordot(th, terms, 1)
        assert np.abs(inv @ A - np.eye(A.shape[0])).max() <= 1e-12


def test_deviations_take_the_python_path_and_its_errors():
    """Outside D: the reference's SceneError; a point leaving its master window: the
    reference's HyperReductionError (both from the Python path the compiled one defers to)."""
    model = _model(())
    ev = model.constraint.evaluator
    lo, _, ranges = ev.windows
    ev.windows = (lo, lo.copy(), ranges)  # one-facet windows: points leave them
    with pytest.raises(HyperReductionError, match="window"):
        model.solve(0.7, path="python")
    with pytest.raises(HyperReductionError, match="window"):
        model.solve(0.7, path="compiled")
    with pytest.raises(SceneError, match="outside its domain"):
        model.solve(1.5, path="compiled")
    with pytest.raises(SceneError, match="value"):
        model.solve([1.0, 1.0], path="compiled")


def test_without_numba_the_python_path_is_used_and_reported(monkeypatch):
    model = _model(())
    monkeypatch.setattr(compiled_online, "NUMBA_VERSION", None)
    assert model.online_path() == "python (numba is not installed)"
    assert model.solve(1.0).path == "python"
    with pytest.raises(RuntimeError, match="numba is not installed"):
        model.solve(1.0, path="compiled")


def test_pickle_drops_the_compiled_state_and_rebuilds_it(model):
    assert model.online_path().startswith("compiled (numba ")
    assert model.online_path("pdas").startswith("python (online method 'pdas'")
    assert model.online_path("daqp").startswith("compiled (numba ")
    clone = pickle.loads(pickle.dumps(model))
    assert "_online_state" not in clone.__dict__
    a, b = model.solve(1.1), clone.solve(1.1)
    assert a.path == b.path == "compiled"
    np.testing.assert_array_equal(a.c, b.c)
    assert compiled_online.COMPILE["nnls"]["first_call_s"] > 0


def _affine_model(R: int, N: int = 6, seed: int = 11) -> ReducedModel:
    """An exact-affine reduced model (no EIM): ``B_N = B_0 + mu B_1``, ``G_N`` likewise, an
    SPD ``A_N(mu)``, a load that makes some constraints active."""
    from rbbench.rb.mixed.model import AffineConstraint
    from rbbench.scene.parameters import ParameterSpace

    rng = np.random.default_rng(seed)
    X = rng.standard_normal((2, N, N))
    A = np.stack([X[0] @ X[0].T + N * np.eye(N), 0.1 * (X[1] + X[1].T)])
    B = rng.standard_normal((2, R, N)) * np.array([1.0, 0.1])[:, None, None]
    c_star = rng.standard_normal(N)
    G = np.stack([B[0] @ c_star - 0.5 * rng.random(R), 0.1 * rng.standard_normal(R)])
    F = np.stack([A[0] @ c_star + B[0].T @ np.abs(rng.standard_normal(R)), A[1] @ c_star])
    return ReducedModel(AffineOperator(A), AffineOperator(F), LinearInMu(1),
                        AffineConstraint(AffineOperator(B), AffineOperator(G), LinearInMu(1)),
                        parameters=ParameterSpace(["mu"], [0.7], [1.3]))


@pytest.mark.parametrize("method", compiled_online.METHODS)
def test_exact_affine_constraint_compiled_equals_python(method):
    model = _affine_model(R=4)
    for mu in MUS:
        py = model.solve(mu, path="python", method=method)
        co = model.solve(mu, path="compiled", method=method)
        assert co.path == "compiled" and co.stop_reason == py.stop_reason == "converged"
        assert _rel(co.c, py.c) <= 1e-12
        np.testing.assert_allclose(co.alpha, py.alpha, rtol=0,
                                   atol=1e-10 * max(py.alpha.max(), 1e-300))


def test_auto_takes_the_compiled_nnls_and_falls_back_to_the_compiled_daqp(monkeypatch):
    """``auto``: the compiled nnls, also with R > N (D = B_N A_N^-1 B_N^T singular, the
    active set only needs its passive blocks regular), equal to the pdas solution; a failed
    nnls solve is retried by the compiled daqp, and the result says so."""
    for R in (4, 9):
        model = _affine_model(R=R)
        assert model.resolve_method() == "nnls"
        res = model.solve(1.0)
        assert res.method == "nnls" and res.path == "compiled"
        assert res.stop_reason == "converged"
        ref = model.solve(1.0, method="pdas")
        assert ref.method == "pdas" and _rel(res.c, ref.c) <= 1e-10
    assert model.resolve_method(path="python") == "daqp"
    assert model.resolve_method("pdas") == "pdas"
    monkeypatch.setattr(model._online_state["nnls"], "solve", lambda mu: None)
    res = model.solve(1.0)
    assert (res.method, res.path, res.stop_reason) == ("daqp", "compiled",
                                                       "converged (daqp fallback)")
    assert _rel(res.c, ref.c) <= 1e-10
    assert model.solve(1.0, method="nnls").path == "python"  # asked for: its own fallback

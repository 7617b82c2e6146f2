"""The linear scenes without contact: scenes, HF solves on two backends, the
reduced models, the exact affine decomposition and the a posteriori error bound, each
against something independent (an analytic value, a second backend, a conservation law,
dense residual norms computed from the HF operators)."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
import scipy.linalg as sla

from rbbench.hf.linear.model import LinearHF, solve_linear
from rbbench.rb.algorithms.pod import pod
from rbbench.rb.config import make_config
from rbbench.rb.linear.offline import LinearData, pod_greedy, reduce_linear
from rbbench.scene.loading import SceneError, load_scene

pytestmark = pytest.mark.timeout(120)
HAS_NGSOLVE = importlib.util.find_spec("ngsolve") is not None
SMALL = ["discretization.n_cells=8"]


def _config(tmp_path, **kw):
    base = dict(formulation="linear", primal="pod", dual="", stabilizer="",
                cache_dir=str(tmp_path / "cache"), online_repeats=2)
    return make_config(**{**base, **kw})


def test_scenes_load_and_refuse_bad_data():
    tb, heat = load_scene("thermal_block"), load_scene("heat_robin")
    assert tb.param_names == ["mu_1", "mu_2", "mu_3", "mu_4"]
    assert heat.data["time"] == {"final": 1.0, "steps": 50}
    with pytest.raises(SceneError, match="multiple of the blocks"):
        load_scene("thermal_block", ["discretization.n_cells=9"])
    with pytest.raises(SceneError, match="one parameter per block"):
        load_scene("thermal_block", ["geometry.blocks=[3, 3]", "discretization.n_cells=9"])
    with pytest.raises(SceneError, match="Robin"):
        load_scene("thermal_block", ["thermal.robin=1.0"])
    with pytest.raises(SceneError, match="unknown key"):
        load_scene("heat_robin", ["load.source=1.0"])


def test_unit_conductivity_matches_the_poisson_series():
    """-Laplace u = 1 on the unit square, u = 0: u(1/2, 1/2) = 0.0736713... (Fourier
    series), P2 on 16 x 16 squares."""
    k = np.arange(1, 400, 2)
    i, j = np.meshgrid(k, k)
    series = np.sum(16 / (np.pi ** 4 * i * j * (i ** 2 + j ** 2))
                    * np.sin(i * np.pi / 2) * np.sin(j * np.pi / 2))
    sc = load_scene("thermal_block", ["discretization.n_cells=16", "discretization.degree=2"])
    hf = LinearHF(sc)
    u = hf.solve(np.ones(4)).u
    pts = hf.backend.pieces.points
    centre = int(np.argmin(np.linalg.norm(pts - 0.5, axis=1)))
    dof = hf.backend.pieces.vertex_dofs[centre, 0]
    assert u[dof] == pytest.approx(series, rel=2e-4)
    # kappa = c everywhere: u_c = u_1 / c (the scaling of the operator)
    assert np.allclose(hf.solve(np.full(4, 0.25)).u, 4 * u, rtol=1e-10, atol=1e-14)


def test_heat_trajectory_conserves_energy_balance():
    """Implicit Euler of the Robin heat problem: 1^T M (u^k - u^{k-1}) / dt
    = int f - h0 int_boundary u^k at every step (K 1 = 0), on the raw trajectory."""
    sc = load_scene("heat_robin", SMALL)
    hf = LinearHF(sc)
    p = hf.problem([0.3])
    traj = solve_linear(p)
    prev = np.vstack([p.u0, traj[:-1]])
    one = np.ones(p.F.size)
    Mb = hf.backend.pieces.boundary_mass
    lhs = (one @ p.M @ (traj - prev).T) / p.dt
    rhs = one @ p.F - 1.0 * (one @ Mb @ traj.T)
    assert np.allclose(lhs, rhs, rtol=0, atol=1e-12 * abs(one @ p.F))
    assert traj[-1].max() > 0.3  # it heats up: int f = 1 over T = 1, less the exchange


@pytest.mark.skipif(not HAS_NGSOLVE, reason="ngsolve not installed")
@pytest.mark.parametrize("name", ["thermal_block", "heat_robin"])
def test_skfem_and_ngsolve_give_the_same_solution(name):
    sc = load_scene(name, SMALL)
    a, b = LinearHF(sc, "skfem"), LinearHF(sc, "ngsolve")
    mu = sc.bounds[:, 0] + 0.3 * (sc.bounds[:, 1] - sc.bounds[:, 0])
    ua, ub = a.solve(mu).u, b.solve(mu).u
    assert np.linalg.norm(ua - ub) <= 1e-10 * np.linalg.norm(ua)


def test_reduced_operators_are_the_exact_affine_projection(tmp_path):
    sc = load_scene("thermal_block", SMALL)
    lin = LinearData(LinearHF(sc), sc)
    Z = pod(np.column_stack([solve_linear(lin(m)) for m in np.random.default_rng(0).uniform(
        0.1, 1.0, (12, 4))]), lin.X, n=6).Z
    rom = lin.build(Z)
    for mu in np.random.default_rng(1).uniform(0.1, 1.0, (3, 4)):
        p = lin(mu)
        th = rom.theta(mu)
        A_N = np.tensordot(th, rom.A, axes=1)
        assert np.allclose(A_N, Z.T @ (p.A @ Z), rtol=0, atol=1e-12 * np.abs(A_N).max())
        assert np.allclose(th @ rom.F, Z.T @ p.F, rtol=1e-12)


def _dual_norm(lin, r):
    return float(np.sqrt(r @ lin.x_solve(r)))


def test_thermal_bound_equals_the_dense_residual_bound_and_is_rigorous(tmp_path):
    sc = load_scene("thermal_block", SMALL)
    lin = LinearData(LinearHF(sc), sc)
    assert lin.alpha_ref == pytest.approx(1.0, rel=1e-8)  # X = A(1, 1, 1, 1)
    U = np.column_stack([solve_linear(lin(m)) for m in np.random.default_rng(0).uniform(
        0.1, 1.0, (15, 4))])
    rom = lin.build(pod(U, lin.X, n=4).Z)
    Z = pod(U, lin.X, n=4).Z
    for mu in np.random.default_rng(2).uniform(0.1, 1.0, (4, 4)):
        p = lin(mu)
        c = rom.solve(mu).u
        r = p.F - p.A @ (Z @ c)
        alpha_true = sla.eigh(p.A.toarray(), lin.X.toarray(), eigvals_only=True)[0]
        assert rom.alpha_lb(mu) == pytest.approx(min(mu), rel=1e-8)
        assert rom.alpha_lb(mu) <= alpha_true * (1 + 1e-10)
        bound = rom.estimate(mu, c)
        assert bound == pytest.approx(_dual_norm(lin, r) / min(mu), rel=1e-6)
        e = solve_linear(p) - Z @ c
        assert bound >= np.sqrt(e @ (lin.X @ e))  # raw values, no clipping


@pytest.mark.parametrize("u0", [0.0, 0.5])
def test_heat_bound_equals_the_dense_residual_bound_and_is_rigorous(tmp_path, u0):
    """u0 = 0.5 is not in the basis: the bound's ||e0||_M term is exercised."""
    sc = load_scene("heat_robin", SMALL + ["time.steps=10", f"thermal.initial={u0}"])
    lin = LinearData(LinearHF(sc), sc)
    mus = np.linspace(0.05, 1.0, 6)[:, None]
    U = np.column_stack([solve_linear(lin(m)).ravel() for m in mus])
    basis = pod_greedy(lin, U, mus, 3, None)
    rom = lin.build(basis.Z)
    Z = basis.Z
    for mu in ([0.07], [0.6]):
        p = lin(mu)
        C = rom.solve(mu).u
        W = C @ Z.T  # (K, n)
        prev = np.vstack([Z @ rom.u0, W[:-1]])
        res = [p.F - p.M @ (w - v) / p.dt - p.A @ w for w, v in zip(W, prev, strict=True)]
        alpha = rom.alpha_lb(mu)
        e0 = p.u0 - Z @ rom.u0
        dense = np.sqrt((e0 @ p.M @ e0 + p.dt / alpha * sum(_dual_norm(lin, r) ** 2
                                                            for r in res)) / alpha)
        assert rom.estimate(mu, C) == pytest.approx(dense, rel=1e-6)
        E = solve_linear(p) - W
        err = np.sqrt(p.dt * np.einsum("ki,ij,kj->", E, lin.X.toarray(), E))
        assert rom.estimate(mu, C) >= err
    assert (rom.e0_m > 0) == (u0 != 0)


def test_reduce_linear_errors_fall_with_n_and_bound_the_error(tmp_path):
    sc = load_scene("thermal_block", SMALL)
    s4 = reduce_linear(sc, _config(tmp_path, N=4, n_train=30, n_valid=6)).summary()
    s8 = reduce_linear(sc, _config(tmp_path, N=8, n_train=30, n_valid=6)).summary()
    assert s8["err_u_max"] < s4["err_u_max"] < 1.0
    for s in (s4, s8):
        assert min(s["per_mu"]["effectivity"]) >= 1.0
        assert s["n_contact"] is None and s["R"] is None and s["beta_kind"] == {}
        assert s["err_lam_max"] is None and "no contact" in s["reason"]


def test_heat_pod_greedy_reaches_one_percent_at_small_n(tmp_path):
    sc = load_scene("heat_robin", SMALL + ["time.steps=20"])
    s = reduce_linear(sc, _config(tmp_path, N=6, n_train=9, n_valid=4)).summary()
    assert s["N"] == 6 and s["err_u_max"] < 1e-2
    assert min(s["per_mu"]["effectivity"]) >= 1.0
    assert s["energy_err_max"] is None  # no energy functional of a trajectory


def test_no_contact_operator_is_assembled(tmp_path, monkeypatch):
    """Nothing of the contact pipeline runs for a linear scene (the reduction and the HF
    solves): the contact operators, their pairing and the obstacle operators raise if
    called."""
    from rbbench_plugins.backends import common

    import rbbench.hf.geometry.operators as cg
    import rbbench.interfaces as itf

    def boom(*a, **k):
        raise AssertionError("a contact operator was assembled")

    monkeypatch.setattr(itf.ContactOperators, "__init__", boom)
    monkeypatch.setattr(cg, "contact_operators", boom)
    monkeypatch.setattr(common, "obstacle_contact", boom)
    monkeypatch.setattr(common, "halfdisk_contact", boom)
    from rbbench.registry import default_registry

    membrane = load_scene("membrane_obstacle", SMALL)  # the spies catch a contact scene
    with pytest.raises(AssertionError, match="contact operator was assembled"):
        default_registry().create("backend", "skfem", scene=membrane).discretize(
            membrane.default_mu)
    for name, N in (("thermal_block", 3), ("heat_robin", 2)):
        sc = load_scene(name, SMALL + (["time.steps=5"] if name == "heat_robin" else []))
        hf = LinearHF(sc)
        assert hf.backend.discretize(sc.default_mu).contact is None
        res = reduce_linear(sc, _config(tmp_path, N=N, n_train=4, n_valid=2))
        assert res.n_contact is None and res.R is None and res.K_pga is None
        assert res.err_lam == [] and res.beta == {}


def test_coercivity_reference_is_the_dense_pencils_smallest_eigenvalue_every_time():
    """ARPACK from its fixed start vector: the smallest eigenvalue of (A(mu_ref), X) equal to
    the dense generalised eigensolver's, and the same float on every call (without a start
    vector ARPACK draws its own, and an unlucky draw stopped it on this small pencil)."""
    from rbbench.rb.linear.model import coercivity_reference

    sc = load_scene("thermal_block", SMALL)
    lin = LinearData(LinearHF(sc), sc)
    p = lin(lin.mu_ref)
    A, X = p.A, lin.X
    dense = sla.eigh(A.toarray(), X.toarray(), eigvals_only=True)[0]
    values = {coercivity_reference(A, X) for _ in range(5)}
    assert len(values) == 1
    assert abs(values.pop() - dense) <= 1e-10 * abs(dense)

"""HF contact solves checked against independent references.

2D Hertz theory (external), KKT conditions recomputed from (u, lam) and the
operators, SSN vs Uzawa (two algorithms), and a brute-force bounded
least-squares QP (scipy BVLS) for the membrane obstacle problem.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.optimize import lsq_linear

from rbbench.hf.model import solve_hf
from rbbench.scene.loading import SceneError, load_scene

COARSE = ["discretization.h_contact=0.02", "discretization.h_max=0.2"]


def _hertz(overrides, mu=1.0, **kw):
    return solve_hf(load_scene("hertz_halfdisks", overrides), mu, **kw)


def test_hertz_default_mesh_within_five_percent():
    """The acceptance check against Hertz: default scene and mesh, mu = 1.0."""
    sol = _hertz([])
    h = sol.metrics["hertz"]
    assert sol.result.converged
    assert abs(h["a_rel_error"]) < 0.05
    assert abs(h["p0_rel_error"]) < 0.05
    assert not sol.metrics["zone_saturated"]


def test_hertz_errors_fall_under_refinement_at_light_load():
    """Light load (a/R* ~ 0.1): a and p0 converge toward 2D Hertz as h -> 0."""
    a_err, p0_err = [], []
    for level in (0, 1, 2):
        sol = _hertz(COARSE + ["load.displacement=0.01", f"discretization.level={level}"])
        assert sol.result.converged
        a_err.append(abs(sol.metrics["hertz"]["a_rel_error"]))
        p0_err.append(abs(sol.metrics["hertz"]["p0_rel_error"]))
    assert a_err[0] > a_err[1] > a_err[2]
    assert p0_err[0] > p0_err[1] > p0_err[2]
    assert a_err[2] < 0.01 and p0_err[2] < 0.025


def test_hertz_lighter_load_is_closer_to_theory():
    """Hertz assumes a << R: the half-width error shrinks with the load."""
    errs = [abs(_hertz(COARSE + ["discretization.level=1", f"load.displacement={d}"])
                .metrics["hertz"]["a_rel_error"]) for d in (0.09, 0.01)]
    assert errs[1] < errs[0]


@pytest.mark.parametrize("mu", [0.7, 1.3])
def test_patch_inside_potential_zone_at_bounds(mu):
    sol = _hertz(COARSE + ["load.displacement=0.09"], mu)
    assert sol.result.converged
    assert not sol.metrics["zone_saturated"]
    lam = sol.result.lam
    assert lam[0] == 0.0 and lam[-1] == 0.0


def _kkt(sol):
    """KKT residuals recomputed from the operators, not from the solver."""
    p, u, lam = sol.problem, sol.result.u, sol.result.lam
    uf = u[p.free]
    eq = np.linalg.norm(p.A @ uf + p.B.T @ lam - p.F) / np.linalg.norm(p.B.T @ lam)
    gap = p.G - p.B @ uf
    scale_g = np.abs(p.G).max()
    return eq, lam.min() / lam.max(), gap.min() / scale_g, abs(lam @ gap) / (lam.max() * scale_g)


@pytest.mark.parametrize("overrides", [
    [],
    ["discretization.degree=2"],
    ["discretization.multiplier='p1'"],
    ["discretization.multiplier='p0'"],
    ["geometry.lower='rigid_flat'"],
], ids=["p1-lac", "p2-lac", "p1-p1mult", "p1-p0", "rigid-flat"])
def test_complementarity_and_non_penetration(overrides):
    sol = _hertz(COARSE + overrides, 0.85)
    assert sol.result.converged, sol.result.stop_reason
    eq, lam_min, gap_min, compl = _kkt(sol)
    assert eq < 1e-8
    assert lam_min >= -1e-12
    assert gap_min >= -1e-10
    assert compl < 1e-10
    assert sol.metrics["penetration_max"] < 1e-10 * sol.disc.info["geometry"]["R1"]
    assert sol.metrics["n_active"] > 0


def test_ssn_and_uzawa_agree():
    s1 = _hertz(COARSE, 1.1, solver="ssn")
    s2 = _hertz(COARSE, 1.1, solver="uzawa", solver_options={"tol": 1e-11})
    assert s1.result.converged and s2.result.converged
    assert s2.result.iterations > s1.result.iterations
    rel = np.linalg.norm(s1.result.lam - s2.result.lam) / np.linalg.norm(s1.result.lam)
    assert rel < 1e-7
    du = np.linalg.norm(s1.result.u - s2.result.u) / np.linalg.norm(s1.result.u)
    assert du < 1e-8
    f1, f2 = s1.metrics["contact_force"], s2.metrics["contact_force"]
    assert abs(f1 - f2) / f1 < 1e-8


def test_dof_count_independent_of_mu():
    sc = load_scene("hertz_halfdisks", COARSE)
    from rbbench.registry import default_registry

    backend = default_registry().create("backend", "skfem", scene=sc)
    d0, d1 = backend.discretize(0.7), backend.discretize(1.3)
    assert d0.n_dofs == d1.n_dofs
    assert d0.contact.n_mult == d1.contact.n_mult
    # ... while the contact operators do depend on mu (the geometry is mapped)
    assert not np.allclose(d0.contact.gap, d1.contact.gap)
    with pytest.raises(SceneError, match=r"outside its domain \[0.7, 1.3\]"):
        backend.discretize(1.5)


def _membrane_brute_force(sol):
    """min 1/2 u^T A u - F^T u  s.t.  u >= psi, by dense BVLS (independent of
    rbbench.hf.solvers.lcp)."""
    p = sol.problem
    A = p.A.toarray()
    L = np.linalg.cholesky(A)
    rhs = sla.solve_triangular(L, p.F, lower=True)  # 1/2|L^T u - rhs|^2 = J(u) + const
    lower = np.full(A.shape[0], -np.inf)
    c = sol.disc.contact
    # B = Mlam^T diag(w) Un with Un = -I on the free nodes: B u <= G  <=>  u >= psi
    node = np.asarray(c.Un.tocoo().col)
    pos = np.searchsorted(p.free, node)
    lower[pos] = -c.gap
    res = lsq_linear(L.T, rhs, bounds=(lower, np.inf), method="bvls", tol=1e-14,
                     lsmr_tol=None, max_iter=10_000)
    return res.x


@pytest.mark.parametrize("mu", [(0.1, 2.0), (0.25, 4.0), (0.4, 6.0)])
def test_membrane_matches_brute_force_qp(mu):
    sc = load_scene("membrane_obstacle", ["discretization.n_cells=8"])
    sol = solve_hf(sc, mu)
    assert sol.result.converged
    u_ref = _membrane_brute_force(sol)
    uf = sol.result.u[sol.problem.free]
    assert np.linalg.norm(uf - u_ref) <= 1e-9 * np.linalg.norm(u_ref)
    assert sol.metrics["n_active"] > 0  # the obstacle is touched: the test is not vacuous

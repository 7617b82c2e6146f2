"""The online bound of the mixed reduced model on the membrane: equal to the HF-evaluated one,
above the true error at random mu, zero where the reduced spaces hold the HF solution."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rbbench.hf.components import make_components
from rbbench.hf.model import solve_hf
from rbbench.rb.algorithms.infsup import make_solver
from rbbench.rb.mixed.bounds import BoundUnsupported, build_mixed_bound, hf_bound
from rbbench.rb.mixed.model import build_affine_model, projector
from rbbench.scene.loading import load_scene


def _x_orthonormal(U, X):
    w, V = np.linalg.eigh(U.T @ (X @ U))
    keep = w > 1e-12 * w.max()
    return U @ (V[:, keep] / np.sqrt(w[keep]))


@pytest.fixture(scope="module")
def membrane():
    sc = load_scene("membrane_obstacle", ["discretization.n_cells=8"])
    comps = make_components(sc)
    b, f, _ = comps
    at = lambda mu: f.build(b.discretize(mu))  # noqa: E731
    mus = np.array([[h, c] for h in (0.1, 0.4) for c in (2.0, 6.0)])
    sols = [solve_hf(sc, mu, components=comps) for mu in mus]
    p0 = sols[0].problem
    X = p0.X[p0.free][:, p0.free].tocsr()
    U = np.stack([s.result.u[p0.free] for s in sols], axis=1)
    LAM = np.stack([s.result.lam for s in sols], axis=1)
    Z = _x_orthonormal(U, X)
    Vg = LAM / np.linalg.norm(LAM, axis=0)
    model = build_affine_model(projector(at, Z, Vg), sc.bounds)
    xs = make_solver(X)
    bound = build_mixed_bound(at, Z, Vg, X, xs, sc.bounds)
    return sc, comps, mus, sols, Z, Vg, model, X, xs, bound, at


def _point(sc, x):
    lo, hi = sc.bounds[:, 0], sc.bounds[:, 1]
    return lo + np.asarray(x) * (hi - lo)


@settings(max_examples=6, deadline=None)
@given(x=st.tuples(st.floats(0, 1), st.floats(0, 1)))
def test_online_bound_holds_and_equals_hf_evaluation(membrane, x):
    sc, comps, _, _, Z, Vg, model, X, xs, bound, at = membrane
    mu = _point(sc, x)
    hf = solve_hf(sc, mu, components=comps)
    u = hf.result.u[hf.problem.free]
    res = model.solve(mu, path="python")
    u_N, lam_N = Z @ res.c, Vg @ res.alpha
    err = float(np.sqrt((u - u_N) @ (X @ (u - u_N))))
    online = bound(mu, res.c, res.alpha)
    ref = hf_bound(at(mu), X, xs, u_N, lam_N, bound.alpha, bound.gamma)
    floor = 1e-6 * np.sqrt(u @ (X @ u))  # sqrt(round-off): where the spaces hold u(mu)
    assert online.delta_u == pytest.approx(ref.delta_u, rel=1e-8, abs=floor)
    assert bound(mu, res.c, res.alpha, compiled=False).delta_u == pytest.approx(
        online.delta_u, rel=1e-10, abs=floor)
    assert online.delta_u >= err
    err_lam = hf.problem.B.T @ (hf.result.lam - lam_N)
    assert online.delta_lam >= np.sqrt(err_lam @ xs(err_lam))


def test_bound_vanishes_where_the_spaces_hold_the_solution(membrane):
    sc, _, mus, sols, Z, Vg, model, X, _, bound, _ = membrane
    for mu, s in zip(mus, sols, strict=True):
        res = model.solve(mu, path="python")
        u = s.result.u[s.problem.free]
        b = bound(mu, res.c, res.alpha)
        # zero in exact arithmetic: the floor is sqrt(round-off) (sigma l_N / alpha)
        assert b.delta_u <= 1e-6 * np.sqrt(u @ (X @ u))
        assert b.terms.rho <= 1e-9 * b.terms.lam_norm


def test_bound_pickles_and_refuses_a_mu_dependent_b(membrane):
    sc, _, _, _, Z, Vg, model, X, xs, bound, at = membrane
    mu = sc.default_mu
    res = model.solve(mu)
    again = pickle.loads(pickle.dumps(bound))
    assert again(mu, res.c, res.alpha).delta_u == bound(mu, res.c, res.alpha).delta_u

    def moving(mu):
        p = at(mu)
        p.B = p.B * float(mu[0])  # a constraint matrix that depends on mu
        return p

    with pytest.raises(BoundUnsupported, match="B depends on mu"):
        build_mixed_bound(moving, Z, Vg, X, xs, sc.bounds)

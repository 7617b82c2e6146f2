"""The compiled online path of the 3D reduced model against the Python reference: the
contact EIM on triangulated surfaces (hertz_sphere level 0, two hemispheres) and an exact
affine constraint with the cubic coefficient map of a 3D similarity (the rigid-plane
variant's). Reduced solutions of both compiled methods equal the Python path's to the
solvers' round-off."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

from rbbench.hf.components import make_components  # noqa: E402
from rbbench.hf.geometry.surface import contact_operators_3d  # noqa: E402
from rbbench.rb.algorithms.affine import (  # noqa: E402
    AffineOperator,
    LinearInMu,
    PolynomialInMu,
)
from rbbench.rb.hyper.contact_eim import contact_eim  # noqa: E402
from rbbench.rb.mixed import compiled as compiled_online  # noqa: E402
from rbbench.rb.mixed.model import AffineConstraint, ReducedModel  # noqa: E402
from rbbench.scene.loading import load_scene  # noqa: E402
from rbbench.scene.parameters import ParameterSpace  # noqa: E402

MUS = np.random.default_rng(5).uniform(0.7, 1.3, 5)


def _rel(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a - b).max() / np.abs(b).max())


@pytest.fixture(scope="module")
def model() -> ReducedModel:
    """The contact EIM of random bases (fixed seed) on the HF contact operators of
    hertz_sphere level 0 (all dofs free), a mu-dependent SPD ``A_N`` and a load whose
    unconstrained solution violates the constraints."""
    sc = load_scene("hertz_sphere", ["discretization.level=0"])
    lay = make_components(sc)[0].contact_layout()
    mus = np.linspace(0.7, 1.3, 7)[:, None]
    ops = [contact_operators_3d(lay, mu) for mu in mus]
    rng = np.random.default_rng(7)
    n, N, R = lay.n_dofs, 6, 5
    Z = np.linalg.qr(rng.standard_normal((n, N)))[0]
    Vg = np.abs(rng.standard_normal((lay.n_mult, R)))
    ceim = contact_eim(lay, [o.B() for o in ops], np.stack([o.G() for o in ops], axis=1), Z,
                       Vg, np.arange(n), mus, tol=1e-10, row_evaluator=_surface_rows)
    X = rng.standard_normal((2, N, N))
    A = np.stack([X[0] @ X[0].T + N * np.eye(N), 0.1 * (X[1] + X[1].T)])
    Bn, Gn = ceim(np.array([1.0]))
    # the unconstrained solution at mu = 1 violates every row: B_N c* = G_N + |G_N|_max
    c_star = np.linalg.lstsq(Bn, Gn + np.abs(Gn).max(), rcond=None)[0]
    F = np.stack([A[0] @ c_star, A[1] @ c_star])
    return ReducedModel(AffineOperator(A), AffineOperator(F), LinearInMu(1), ceim,
                        parameters=sc.parameter_space)


def _surface_rows(layout, rows, mus):
    from rbbench.rb.hyper.surface_eim import build_surface_row_evaluator

    return build_surface_row_evaluator(layout, rows, np.linspace(0.7, 1.3, 13)[:, None])


@pytest.mark.netgen
def test_the_3d_contact_eim_takes_the_compiled_path(model):
    assert compiled_online.path_reason(model, "nnls") is None
    assert model.online_path().startswith("compiled")


@pytest.mark.netgen
@pytest.mark.parametrize("method", compiled_online.METHODS)
def test_every_slave_point_of_the_3d_plan_is_paired_through_its_table(model, method):
    """Each magic point hits some window triangle over D, so each gets a table."""
    assert model.pairing_table_share(method) == 1.0


@pytest.mark.netgen
@pytest.mark.parametrize("method", compiled_online.METHODS)
def test_reduced_solution_equals_the_python_path(model, method):
    """Each compiled method against the Python path of the same method; some constraints
    active (alpha > 0) so the comparison covers the contact rows."""
    active = 0
    for mu in MUS:
        py = model.solve(mu, path="python", method=method)
        co = model.solve(mu, path="compiled", method=method)
        assert co.path == "compiled" and co.stop_reason == py.stop_reason == "converged"
        assert _rel(co.c, py.c) <= 1e-12
        np.testing.assert_allclose(co.alpha, py.alpha, rtol=0, atol=1e-10 * py.alpha.max())
        active += int(np.sum(py.alpha > 0))
    assert active > 0


def _cubic_model(R: int) -> ReducedModel:
    """An exact affine model with ``theta = [1, mu, mu^2, mu^3]`` (a 3D similarity: A_N
    linear, B_N quadratic, G_N cubic in mu) whose A_N terms share an eigenbasis."""
    rng = np.random.default_rng(4)
    N = 6
    Q = np.linalg.qr(rng.standard_normal((N, N)))[0]
    d = np.vstack([N + rng.random(N), rng.random((3, N))])
    A = np.einsum("ia,ka,ja->kij", Q, d, Q)
    B = np.zeros((4, R, N))
    B[2] = rng.standard_normal((R, N))
    B[0] = 0.1 * rng.standard_normal((R, N))
    G = np.zeros((4, R))
    G[3] = rng.random(R)
    G[0] = 0.01 * rng.random(R)
    c_star = rng.standard_normal(N)
    F = np.stack([A[0] @ c_star + B[2].T @ np.abs(rng.standard_normal(R)), A[1] @ c_star,
                  np.zeros(N), np.zeros(N)])
    theta = PolynomialInMu(3)
    return ReducedModel(AffineOperator(A), AffineOperator(F), theta,
                        AffineConstraint(AffineOperator(B), AffineOperator(G), theta),
                        parameters=ParameterSpace(["mu"], [0.7], [1.3]))


@pytest.mark.parametrize("method", compiled_online.METHODS)
def test_cubic_affine_constraint_compiled_equals_python(method):
    model = _cubic_model(R=4)
    assert compiled_online.path_reason(model, method) is None
    for mu in MUS:
        py = model.solve(mu, path="python", method=method)
        co = model.solve(mu, path="compiled", method=method)
        assert co.path == "compiled" and co.stop_reason == py.stop_reason == "converged"
        assert _rel(co.c, py.c) <= 1e-12
        np.testing.assert_allclose(co.alpha, py.alpha, rtol=0,
                                   atol=1e-10 * max(py.alpha.max(), 1e-300))


def test_a_coefficient_map_of_another_size_takes_the_python_path():
    """A polynomial map with fewer coefficients than the model's terms: the reason names
    the map; the Python path answers."""
    model = _cubic_model(R=4)
    model.coefficients = PolynomialInMu(2)
    assert "PolynomialInMu" in compiled_online.path_reason(model, "nnls")

"""Model B (the talk "On coupling of complementarity with friction in contact shape
optimization", ``F = f(|u_t|)``) by a semismooth Newton with ``f'``:
:func:`rbbench.hf.solvers.friction.model_b_newton` against the fixed point on the
coefficient (:func:`rbbench.hf.solvers.friction.coulomb_model_b`), an independent iteration
with the same solution.
"""

from __future__ import annotations

import numpy as np
import pytest
from rbbench_plugins.solvers.friction import FrictionSSNSolver

from rbbench.hf.algebra.friction import MODEL_B, CoefficientLaw, friction_residuals, slip
from rbbench.hf.components import make_components
from rbbench.hf.solvers import friction as fs
from rbbench.interfaces import FrictionLaw
from rbbench.scene.loading import load_scene


def _model_b_case(seed: int, m: int = 12) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A condensed model-B step where the slip is of order one, so that ``F = 0.25 /
    (t^2 + 1)`` really varies (on the scenes t ~ 1e-5 m and F stays within 1e-4 of 0.25)."""
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((2 * m, 2 * m))
    D = M @ M.T / (2 * m) + 0.1 * np.eye(2 * m)
    q = np.r_[-rng.uniform(0.5, 2.0, m), 2.0 * rng.standard_normal(m)]
    return D, q, 0.5 * rng.standard_normal(m)


def _model_b_residual(D, q, ut_prev, x) -> float:
    m = ut_prev.size
    F = MODEL_B.f(np.abs(ut_prev + slip(D, q, x[:m], x[m:])))
    return friction_residuals(D, q, x[:m], x[m:], F * x[:m])["max"]


@pytest.mark.parametrize("seed", range(8))
def test_newton_equals_the_fixed_point_in_fewer_iterations(seed):
    """Same solution (1e-9 of max|x|, both satisfying model B with F = f(|u_t(x)|) to
    1e-9); Newton converges without its fallback, in fewer iterations than the fixed point
    has outer iterations (each a Coulomb solve). Measured on seeds 0-7: Newton 5, 6, 5, 5,
    11, 5, 6, 5 iterations (residual 0.1-0.5 -> 1e-12..1e-16, quadratic at the end); the
    fixed point 11, 23, 23, 17, 25, 47, 22, 48 outer and 13-50 inner iterations, contraction
    0.10-0.64."""
    D, q, ut_prev = _model_b_case(seed)
    fp = fs.coulomb_model_b(D, q, MODEL_B, ut_prev=ut_prev)
    nt = fs.model_b_newton(D, q, MODEL_B, ut_prev=ut_prev)
    assert fp.stop_reason == nt.stop_reason == "converged"
    assert nt.info["method"] == "newton" and "fallback" not in nt.info
    assert np.abs(nt.x - fp.x).max() <= 1e-9 * np.abs(fp.x).max()
    assert _model_b_residual(D, q, ut_prev, nt.x) <= 1e-10
    assert _model_b_residual(D, q, ut_prev, fp.x) <= 1e-9
    assert nt.iterations == nt.info["newton_iterations"] < fp.iterations
    assert nt.iterations < fp.info["inner_iterations"]
    assert 0 < fp.info["contraction"] < 1


@pytest.mark.parametrize("seed", [0, 1])
def test_failed_newton_falls_back_to_the_fixed_point(seed):
    """A wrong derivative (-50 f'): Newton's residual stops decreasing, the fixed point
    runs instead, says so, and gives the fixed point's solution."""
    D, q, ut_prev = _model_b_case(seed)
    wrong = CoefficientLaw("wrong", MODEL_B.f, lambda t: -50.0 * MODEL_B.df(t))
    r = fs.model_b_newton(D, q, wrong, ut_prev=ut_prev)
    assert r.stop_reason == "converged" and r.info["method"] == "fixed_point"
    assert "did not decrease" in r.info["fallback"] and r.info["newton_iterations"] > 0
    fp = fs.coulomb_model_b(D, q, MODEL_B, ut_prev=ut_prev)
    assert np.array_equal(r.x, fp.x)
    stopped = fs.model_b_newton(D, q, wrong, ut_prev=ut_prev, fallback=False)
    assert stopped.stop_reason == "stagnation" and stopped.info["method"] == "newton"


def test_law_without_derivative_is_refused():
    D, q, ut_prev = _model_b_case(0, 3)
    with pytest.raises(ValueError, match="no derivative"):
        fs.model_b_newton(D, q, CoefficientLaw("flat", MODEL_B.f), ut_prev=ut_prev)


def test_friction_ssn_newton_on_the_sheared_scene():
    """friction-ssn ``method="newton"`` on the sheared hertz_halfdisks model-B case of
    tests/hf/solvers/test_friction.py equals the fixed point (``method="direct"``) to 1e-8 of max
    lam_n: both stop on a residual of 1e-10 relative to a force scale (max|q| / mean diag D
    = 3.7e11 Pa) 20 times max lam_n; measured 2.1e-9 apart. Measured: there ``F`` varies by
    7e-5 only, the fixed point needs 2 outer iterations per step (contraction 7e-8; 11
    active-set iterations in all) and Newton 11 + 6 (the active-set search; one more step
    takes its residual from 3e-11 to 1e-16): on a nearly constant coefficient Newton buys
    nothing."""
    mesh = ["discretization.level=0", "discretization.h_contact=0.04",
            "discretization.h_max=0.25", 'discretization.multiplier="p1"',
            'friction.law="coulomb"', "friction.coefficient=0.2",
            "load.tangential_displacement=0.002",
            "load.load_steps=[{normal = 1.0}, {normal = 1.0, tangential = 1.0}]"]
    sc = load_scene("hertz_halfdisks", mesh)
    b, f, _ = make_components(sc)
    prob = f.build(b.discretize(sc.default_mu),
                   friction=FrictionLaw("coulomb", coefficient_law="model_b"))
    fp = FrictionSSNSolver(method="direct").solve(prob)
    nt = FrictionSSNSolver(method="newton").solve(prob)
    assert fp.converged and nt.converged and nt.info["method"] == "newton"
    assert [s["stop_reason"] for s in nt.info["load_steps"]] == ["converged"] * 2
    scale = fp.lam.max()
    assert np.abs(nt.lam - fp.lam).max() <= 1e-8 * scale
    assert np.abs(nt.info["lam_t"] - fp.info["lam_t"]).max() <= 1e-8 * scale
    assert np.abs(nt.info["coefficient"] - fp.info["coefficient"]).max() <= 1e-9
    assert nt.info["friction_residuals"]["max"] <= 1e-10
    with pytest.raises(ValueError, match="'newton'"):
        FrictionSSNSolver(method="nope")

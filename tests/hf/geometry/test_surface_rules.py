"""Triangle quadrature rules and P1/P2 shape functions of the 3D contact geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rbbench.hf.geometry.surface_rules import RULE_DEGREES, triangle_rule, triangle_shape


def _monomial_mean(a: int, b: int) -> float:
    """Mean of ``x^a y^b`` over the triangle (0,0), (1,0), (0,1) (area 1/2):
    ``2 a! b! / (a + b + 2)!``."""
    return 2.0 * math.factorial(a) * math.factorial(b) / math.factorial(a + b + 2)


@pytest.mark.parametrize("degree", RULE_DEGREES)
def test_rules_integrate_every_monomial_of_their_degree_exactly(degree):
    bary, w = triangle_rule(degree)
    assert np.all(w > 0) and np.all(bary > 0)
    assert np.allclose(bary.sum(axis=1), 1.0, rtol=0, atol=1e-15)
    x, y = bary[:, 1], bary[:, 2]
    for a in range(degree + 1):
        for b in range(degree + 1 - a):
            assert np.sum(w * x**a * y**b) == pytest.approx(_monomial_mean(a, b),
                                                           rel=1e-13), (a, b)


@pytest.mark.parametrize("degree", [1, 2, 4, 5, 6, 8])
def test_rules_are_not_exact_one_degree_beyond_their_table_entry(degree):
    """The table claims no more than it has: some monomial of degree + 1 is missed."""
    bary, w = triangle_rule(degree)
    x, y = bary[:, 1], bary[:, 2]
    errs = [abs(np.sum(w * x**a * y**(degree + 1 - a)) - _monomial_mean(a, degree + 1 - a))
            for a in range(degree + 2)]
    assert max(errs) > 1e-6


@pytest.mark.parametrize("bad", [0, 9, 2.5, "4"])
def test_unknown_degree_names_the_valid_ones(bad):
    with pytest.raises(ValueError, match=r"triangle quadrature degree .* \[1, 2, 3"):
        triangle_rule(bad)


def _nodes(degree: int) -> np.ndarray:
    v = np.eye(3)
    if degree == 1:
        return v
    return np.vstack([v, (v[0] + v[1]) / 2, (v[1] + v[2]) / 2, (v[0] + v[2]) / 2])


@pytest.mark.parametrize("degree", [1, 2])
def test_shape_functions_are_nodal_in_the_contract_order(degree):
    assert np.allclose(triangle_shape(_nodes(degree), degree), np.eye(3 * degree), atol=1e-15)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(0.0, 1.0), min_size=6, max_size=6),
       st.lists(st.floats(-2.0, 2.0), min_size=6, max_size=6))
def test_shape_functions_reproduce_polynomials_of_their_degree(raw, c):
    """Interpolating ``p`` at the nodes and evaluating gives ``p`` back: linear ``p`` for
    P1 and P2, quadratic ``p`` for P2 (points: random barycentric coordinates)."""
    lam = np.array(raw).reshape(2, 3) + 1e-3
    lam /= lam.sum(axis=1, keepdims=True)

    def p(b, quadratic):
        x, y = b[:, 1], b[:, 2]
        val = c[0] + c[1] * x + c[2] * y
        return val + (c[3] * x * x + c[4] * x * y + c[5] * y * y if quadratic else 0.0)

    for degree, quadratic in ((1, False), (2, False), (2, True)):
        phi = triangle_shape(lam, degree)
        assert np.allclose(phi @ p(_nodes(degree), quadratic), p(lam, quadratic),
                           rtol=0, atol=1e-12)


def test_unknown_shape_degree_names_the_valid_ones():
    with pytest.raises(ValueError, match="degree 3 is not one of 1, 2"):
        triangle_shape(np.eye(3), 3)

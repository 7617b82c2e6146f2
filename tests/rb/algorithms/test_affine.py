"""Affine and polynomial decompositions in mu, verified by probing."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rbbench.rb.algorithms.affine import (
    LinearInMu,
    NotAffineError,
    PolynomialInMu,
    affine_decomposition,
    coefficient_map,
)

BOUNDS = np.array([[0.7, 1.3]])


@settings(max_examples=25, deadline=None)
@given(degree=st.integers(1, 4), seed=st.integers(0, 2**31 - 1))
def test_polynomial_terms_are_recovered(degree, seed):
    """O(mu) = sum_k mu^k T_k with random T_k: the decomposition returns the T_k."""
    terms = np.random.default_rng(seed).standard_normal((degree + 1, 3, 2))
    got = affine_decomposition(lambda mu: np.tensordot(PolynomialInMu(degree)(mu), terms, 1),
                               BOUNDS, degree=degree)
    assert np.allclose(got, terms, rtol=0, atol=1e-8 * np.abs(terms).max())


def test_a_scaled_surface_weight_is_cubic_not_affine():
    """mu^2 (a + b mu): a 3D area weight times an affine gap; degree 3 exact, 1 and 2 refused."""
    def op(mu):
        return mu[0] ** 2 * (np.array([1.0, -2.0]) + mu[0] * np.array([0.5, 3.0]))

    for degree in (1, 2):
        with pytest.raises(NotAffineError):
            affine_decomposition(op, BOUNDS, degree=degree)
    terms = affine_decomposition(op, BOUNDS, degree=3)
    assert np.allclose(terms, [[0, 0], [0, 0], [1.0, -2.0], [0.5, 3.0]], atol=1e-10)


def test_non_polynomial_is_refused_and_several_parameters_need_degree_one():
    with pytest.raises(NotAffineError, match="not affine in mu"):
        affine_decomposition(lambda mu: np.exp(mu), BOUNDS, degree=3)
    with pytest.raises(ValueError, match="one parameter"):
        affine_decomposition(lambda mu: mu, np.array([[0.0, 1.0], [0.0, 1.0]]), degree=2)
    assert isinstance(coefficient_map(2), LinearInMu)
    assert np.allclose(coefficient_map(1, 3)(np.array([2.0])), [1, 2, 4, 8])

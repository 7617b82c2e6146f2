"""Exact affine decompositions in mu, verified by probing (the "exact-affine" hyper-reducer).

``O(mu) = sum_k theta_k(mu) O_k`` with ``theta = [1, mu_1, ..., mu_p]``: Benaceur, Drouet,
Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric variational inequalities"
(talk), slide "Affine parametric decomposition". Shared by the mixed and the Nitsche reduced
models.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np


class NotAffineError(ValueError):
    """An operator is not affine in mu (the exact-affine hyper-reducer does not apply)."""


@dataclass
class LinearInMu:
    """Coefficient map ``theta(mu) = [1, mu_1, ..., mu_p]`` (exact affine in mu)."""

    p: int

    def __call__(self, mu: np.ndarray) -> np.ndarray:
        return np.concatenate([[1.0], np.atleast_1d(np.asarray(mu, dtype=float))])

    @property
    def n_terms(self) -> int:
        return self.p + 1


@dataclass
class PolynomialInMu:
    """Coefficient map ``theta(mu) = [1, mu, mu^2, ..., mu^degree]`` of one parameter: the
    exact decomposition of a 3D similarity map ``x -> mu x`` (surface weights scale as
    ``mu^2``, gaps times weights as ``mu^3``)."""

    degree: int

    def __call__(self, mu: np.ndarray) -> np.ndarray:
        m = float(np.atleast_1d(np.asarray(mu, dtype=float))[0])
        return m ** np.arange(self.degree + 1)

    @property
    def n_terms(self) -> int:
        return self.degree + 1


def coefficient_map(p: int, degree: int = 1) -> LinearInMu | PolynomialInMu:
    """``theta`` of :func:`affine_decomposition` for ``p`` parameters at ``degree``."""
    return LinearInMu(p) if degree == 1 else PolynomialInMu(degree)


@dataclass
class AffineOperator:
    """``M(theta) = sum_k theta_k terms[k]`` with small dense terms."""

    terms: np.ndarray  # (K, *shape)

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        return np.tensordot(theta, self.terms, axes=1)


def affine_decomposition(op_at: Callable[[np.ndarray], np.ndarray], bounds: np.ndarray,
                         rtol: float = 1e-10, seed: int = 0, degree: int = 1) -> np.ndarray:
    """Exact affine decomposition in mu of ``op_at(mu)``, verified by probing.

    Writes ``O(mu) = O_0 + sum_k mu_k O_k`` from ``O`` at the domain centre and
    at one shifted point per parameter (exact if O is affine), then checks the
    decomposition at a random point of D. Returns the terms (p + 1, ...)
    matching :class:`LinearInMu`. Raises :class:`NotAffineError` with the
    measured relative deviation otherwise. ``degree > 1`` (one parameter only): the
    polynomial ``O(mu) = sum_k mu^k O_k`` (:class:`PolynomialInMu`) interpolated at
    ``degree + 1`` Chebyshev points of D, checked at the same random point.
    """
    bounds = np.asarray(bounds, dtype=float)
    if degree != 1:
        return _polynomial_decomposition(op_at, bounds, rtol, seed, degree)
    centre = bounds.mean(axis=1)
    half = 0.5 * (bounds[:, 1] - bounds[:, 0])
    o_c = np.asarray(op_at(centre), dtype=float)
    derivs = []
    for k in range(bounds.shape[0]):
        mu = centre.copy()
        mu[k] += half[k]
        derivs.append((np.asarray(op_at(mu), dtype=float) - o_c) / half[k])
    terms = np.stack([o_c - sum(c * d for c, d in zip(centre, derivs, strict=True))] + derivs)
    return _probed(op_at, bounds, rtol, seed, terms, LinearInMu(bounds.shape[0]))


def _polynomial_decomposition(op_at: Callable[[np.ndarray], np.ndarray], bounds: np.ndarray,
                              rtol: float, seed: int, degree: int) -> np.ndarray:
    """Terms of :class:`PolynomialInMu` (``degree``) by interpolation, probed."""
    if bounds.shape[0] != 1 or degree < 1:
        raise ValueError(f"a polynomial decomposition of degree {degree} needs one parameter "
                         f"and degree >= 1 (got {bounds.shape[0]} parameters)")
    lo, hi = bounds[0]
    k = np.arange(degree + 1)
    nodes = 0.5 * (lo + hi) + 0.5 * (hi - lo) * np.cos((2 * k + 1) * np.pi / (2 * degree + 2))
    ops = np.stack([np.asarray(op_at(np.array([m])), dtype=float) for m in nodes])
    vander = nodes[:, None] ** k[None, :]
    terms = np.linalg.solve(vander, ops.reshape(degree + 1, -1)).reshape(ops.shape)
    return _probed(op_at, bounds, rtol, seed, terms, PolynomialInMu(degree))


def _probed(op_at: Callable[[np.ndarray], np.ndarray], bounds: np.ndarray, rtol: float,
            seed: int, terms: np.ndarray, theta: Callable[[np.ndarray], np.ndarray]
            ) -> np.ndarray:
    """``terms`` when ``sum_k theta_k(mu) terms[k]`` matches ``op_at`` at a random mu of D
    to ``rtol`` (relative to the largest entry), else :class:`NotAffineError`."""
    rng = np.random.default_rng(seed)
    probe = bounds[:, 0] + rng.random(bounds.shape[0]) * (bounds[:, 1] - bounds[:, 0])
    exact = np.asarray(op_at(probe), dtype=float)
    approx = np.tensordot(theta(probe), terms, axes=1)
    scale = max(np.abs(exact).max(), np.finfo(float).tiny)
    dev = float(np.abs(exact - approx).max() / scale)
    if dev > rtol:
        raise NotAffineError(f"not affine in mu: relative deviation {dev:.2e} at mu = "
                             f"{probe.tolist()} (tolerance {rtol:g})")
    return terms

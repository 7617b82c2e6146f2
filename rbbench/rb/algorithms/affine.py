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
class AffineOperator:
    """``M(theta) = sum_k theta_k terms[k]`` with small dense terms."""

    terms: np.ndarray  # (K, *shape)

    def __call__(self, theta: np.ndarray) -> np.ndarray:
        return np.tensordot(theta, self.terms, axes=1)


def affine_decomposition(op_at: Callable[[np.ndarray], np.ndarray], bounds: np.ndarray,
                         rtol: float = 1e-10, seed: int = 0) -> np.ndarray:
    """Exact affine decomposition in mu of ``op_at(mu)``, verified by probing.

    Writes ``O(mu) = O_0 + sum_k mu_k O_k`` from ``O`` at the domain centre and
    at one shifted point per parameter (exact if O is affine), then checks the
    decomposition at a random point of D. Returns the terms (p + 1, ...)
    matching :class:`LinearInMu`. Raises :class:`NotAffineError` with the
    measured relative deviation otherwise.
    """
    bounds = np.asarray(bounds, dtype=float)
    centre = bounds.mean(axis=1)
    half = 0.5 * (bounds[:, 1] - bounds[:, 0])
    o_c = np.asarray(op_at(centre), dtype=float)
    derivs = []
    for k in range(bounds.shape[0]):
        mu = centre.copy()
        mu[k] += half[k]
        derivs.append((np.asarray(op_at(mu), dtype=float) - o_c) / half[k])
    terms = np.stack([o_c - sum(c * d for c, d in zip(centre, derivs, strict=True))] + derivs)
    rng = np.random.default_rng(seed)
    probe = bounds[:, 0] + rng.random(bounds.shape[0]) * (bounds[:, 1] - bounds[:, 0])
    exact = np.asarray(op_at(probe), dtype=float)
    approx = np.tensordot(LinearInMu(bounds.shape[0])(probe), terms, axes=1)
    scale = max(np.abs(exact).max(), np.finfo(float).tiny)
    dev = float(np.abs(exact - approx).max() / scale)
    if dev > rtol:
        raise NotAffineError(f"not affine in mu: relative deviation {dev:.2e} at mu = "
                             f"{probe.tolist()} (tolerance {rtol:g})")
    return terms

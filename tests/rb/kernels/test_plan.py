"""The offline plan of the compiled online paths (rbbench.rb.kernels.plan) and its packed
layout read back by the compiled accessors (rbbench.rb.kernels.layout)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

from rbbench.rb.kernels.plan import coefficient_map, eigenbasis, pack


def _arrays(rng: np.random.Generator, floats, ints) -> dict[str, np.ndarray]:
    """One array per name, of 0 to 3 axes in turn (sizes 1 to 4 per axis)."""
    out = {}
    for j, name in enumerate(floats):
        out[name] = rng.standard_normal(tuple(rng.integers(1, 5, j % 4)))
    for j, name in enumerate(ints):
        out[name] = rng.integers(-50, 50, tuple(rng.integers(1, 5, j % 4)))
    return out


def test_pack_round_trips_through_the_compiled_accessors():
    """Every array packed is read back exactly, flat and as rows (first axis kept)."""
    layout = pytest.importorskip("rbbench.rb.kernels.layout")
    rng = np.random.default_rng(3)
    arrays = _arrays(rng, layout.FLOATS, layout.INTS)
    fb, ib, meta = pack(arrays)
    assert meta.shape == (len(layout.FLOATS) + len(layout.INTS), 4)
    for k, name in enumerate(layout.FLOATS):
        a = arrays[name]
        np.testing.assert_array_equal(layout.flat_floats(fb, meta, k), a.ravel())
        rows = a.reshape(a.shape[0], -1) if a.ndim else a.reshape(1, 1)
        np.testing.assert_array_equal(layout.float_rows(fb, meta, k), rows)
    for j, name in enumerate(layout.INTS):
        k = len(layout.FLOATS) + j
        a = arrays[name]
        np.testing.assert_array_equal(layout.flat_ints(ib, meta, k), a.ravel())
        rows = a.reshape(a.shape[0], -1) if a.ndim else a.reshape(1, 1)
        np.testing.assert_array_equal(layout.int_rows(ib, meta, k), rows)


def test_pack_takes_another_kernels_names_and_rejects_four_axes():
    arrays = {"a": np.arange(6.0).reshape(2, 3), "b": np.array([7, 8])}
    fb, ib, meta = pack(arrays, ("a",), ("b",))
    np.testing.assert_array_equal(fb, np.arange(6.0))
    np.testing.assert_array_equal(ib, [7, 8])
    np.testing.assert_array_equal(meta, [[0, 2, 3, 1], [0, 2, 1, 1]])
    with pytest.raises(ValueError, match="plan array a: shape"):
        pack({"a": np.zeros((1, 1, 1, 2)), "b": np.zeros(1)}, ("a",), ("b",))


def test_coefficient_map_folds_the_coefficient_solve():
    """``c^T W = (P^-1 c)^T T``: the EIM combination with the solve folded in."""
    rng = np.random.default_rng(4)
    P = rng.standard_normal((6, 6)) + 6 * np.eye(6)
    T = rng.standard_normal((6, 3, 5))
    W = coefficient_map(sla.lu_factor(P), T)
    c = rng.standard_normal(6)
    np.testing.assert_allclose(np.tensordot(c, W, 1),
                               np.tensordot(np.linalg.solve(P, c), T, 1), rtol=1e-12,
                               atol=1e-12)


def test_eigenbasis_one_term_and_commuting_terms():
    """``V^T A_k V = diag(lam[k])`` and ``V^T A(theta_ref) V = I``: one constant term
    (V = L^-T), and three terms that are polynomials of one SPD matrix (they commute, so a
    common eigenbasis exists although there are two parameters)."""
    rng = np.random.default_rng(5)
    X = rng.standard_normal((7, 7))
    S = X @ X.T + 7 * np.eye(7)
    poly = np.stack([S, 0.1 * S @ S / 7, 0.01 * np.eye(7)])
    for terms, th in ((S[None], np.array([1.0])), (poly, np.array([1.0, 0.5, 2.0]))):
        V, lam = eigenbasis(terms, th)
        for k in range(terms.shape[0]):
            np.testing.assert_allclose(V.T @ terms[k] @ V, np.diag(lam[k]), atol=1e-12)
        np.testing.assert_allclose(V.T @ np.tensordot(th, terms, 1) @ V, np.eye(7), atol=1e-12)
    bad = eigenbasis(np.stack([S, -10 * S]), np.array([1.0, 1.0]))  # A(theta_ref) = -9 S
    assert isinstance(bad, str) and "not positive definite" in bad

"""The offline side of the compiled online paths: what a plan tabulates and how it is packed.

A reduced model's compiled online solve reads one packed plan
(:mod:`rbbench.rb.kernels.layout`; :func:`pack`). What does not depend on mu is tabulated
here once, for every formulation that pairs a contact EIM's magic rows in 2D: the
reference slave points (:func:`reference_points`), the slave half of every magic entry
(:func:`slave_terms`), the master chain with its windows and their monotonicity test
(:func:`master_plan`), the EIM maps with the coefficient solve folded in
(:func:`coefficient_map`), the box D (:func:`parameter_bounds`) and a common eigenbasis of
``A_N``'s affine terms for the condensed solve (:func:`eigenbasis`). Importable without
numba (:data:`NUMBA_VERSION` is then None); the functions that call a kernel import it
when called.
"""

from __future__ import annotations

from typing import Any

import numpy as np

try:  # optional: without numba the Python path is the online path
    import numba

    NUMBA_VERSION: str | None = numba.__version__
except ImportError:  # pragma: no cover - exercised where numba is absent
    NUMBA_VERSION = None

__all__ = ["NO_SURFACE", "NUMBA_VERSION", "centre", "centre_theta", "coefficient_map", "eigenbasis",
           "gauss", "master_plan", "pack", "parameter_bounds", "reference_points",
           "slave_terms"]


#: the 3D master window arrays of the plan, as one-entry placeholders in 2D plans
NO_SURFACE = {"m_tri": np.zeros((1, 3), dtype=np.int64), "w_ptr": np.zeros(2, dtype=np.int64),
              "w_tri": np.zeros((1, 2), dtype=np.int64), "w_axis": np.zeros((1, 4)),
              "w_key": np.zeros(1), "m_geo": np.zeros((1, 14)), "t_mu": np.zeros(1),
              "t_ptr": np.zeros(2, dtype=np.int64), "t_tri": np.zeros(1, dtype=np.int64)}


def pack(arrays: dict[str, np.ndarray], floats: tuple[str, ...] | None = None,
         ints: tuple[str, ...] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(fb, ib, meta)``: the float and int arrays of a plan
    (:func:`rbbench.rb.mixed.compiled.plan_arrays`) in the kernels' order (``floats``,
    ``ints``: another kernel's names, default :data:`rbbench.rb.kernels.layout.FLOATS`,
    ``INTS``), one row ``[offset, s0, s1, s2]`` of ``meta`` per array (shape padded with
    1)."""
    from rbbench.rb.kernels import layout

    meta, chunks = [], {"f": [], "i": []}
    offsets = {"f": 0, "i": 0}
    for kind, names in (("f", layout.FLOATS if floats is None else floats),
                        ("i", layout.INTS if ints is None else ints)):
        dtype = np.float64 if kind == "f" else np.int64
        for name in names:
            a = np.ascontiguousarray(arrays[name], dtype=dtype)
            shape = (*a.shape, 1, 1, 1)[:3] if a.ndim else (1, 1, 1)
            if a.ndim > 3 or int(np.prod(shape)) != a.size:
                raise ValueError(f"plan array {name}: shape {a.shape} (at most 3 axes)")
            meta.append([offsets[kind], *shape])
            chunks[kind].append(a.ravel())
            offsets[kind] += a.size
    fb = np.concatenate(chunks["f"])
    ib = np.concatenate(chunks["i"])
    return fb, ib, np.asarray(meta, dtype=np.int64)


def parameter_bounds(model: Any) -> dict[str, np.ndarray]:
    """``mu_lo``, ``mu_hi``: the box D (unbounded without a parameter space)."""
    if model.parameters is not None:
        return {"mu_lo": np.asarray(model.parameters.low, float),
                "mu_hi": np.asarray(model.parameters.high, float)}
    p = _n_parameters(model)
    return {"mu_lo": np.full(p, -np.inf), "mu_hi": np.full(p, np.inf)}


def _n_parameters(model: Any) -> int:
    """The number of parameters of a model without a parameter space: one for a polynomial
    coefficient map, else one less than ``A_N``'s terms (``theta = [1, mu]``)."""
    from rbbench.rb.algorithms.affine import PolynomialInMu

    if isinstance(getattr(model, "coefficients", None), PolynomialInMu):
        return 1
    return int(model.A.terms.shape[0]) - 1


def centre(model: Any) -> np.ndarray:
    """The centre of D (mu = 0 without a parameter space)."""
    if model.parameters is not None:
        return 0.5 * (np.asarray(model.parameters.low) + np.asarray(model.parameters.high))
    return np.zeros(_n_parameters(model))


def centre_theta(model: Any) -> np.ndarray:
    """The coefficients of ``A_N``'s terms at the centre of D (mu = 0 without a parameter
    space): ``model.coefficients`` there (``[1, mu]``, or the powers of mu of a
    polynomial map), ``[1, mu]`` for a model without a coefficient map."""
    mu = centre(model)
    coef = getattr(model, "coefficients", None)
    return np.asarray(coef(mu), dtype=float) if coef is not None else np.concatenate([[1.0], mu])


def coefficient_map(lu_piv: tuple[np.ndarray, np.ndarray], T: np.ndarray) -> np.ndarray:
    """``W = P^-T T`` (``P = lu_piv``, the EIM interpolation matrix at the magic entries,
    ``T`` the EIM terms, first axis the term): online ``sum_j theta_j T[j]`` with
    ``theta = P^-1 c`` is ``sum_i c_i W[i]``, one pass over the terms and no triangular
    solves (the coefficient solve folded offline into the terms; measured 4.6 us of the
    online solve at M = 81)."""
    import scipy.linalg as sla

    flat = sla.lu_solve(lu_piv, T.reshape(T.shape[0], -1), trans=1)
    return flat.reshape(T.shape)


def eigenbasis(terms: np.ndarray, theta_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray] | str:
    """``(V, lam)`` with ``V^T A_k V = diag(lam[k])`` for every affine term ``A_k`` of
    ``A_N`` (``terms``, K x n x n), ``V^T A(theta_ref) V = I``: the generalised eigenvectors
    of a combination of the terms against ``A(theta_ref)`` (scipy ``eigh``). Exists for one
    term or two (one parameter) and for commuting families; otherwise the reason (a string).
    Then ``A_N(mu)^-1 = V diag(1 / lam^T theta) V^T`` (:mod:`rbbench.rb.kernels.nnls`)."""
    import scipy.linalg as sla

    ref = np.tensordot(theta_ref, terms, 1)
    try:
        if terms.shape[0] == 1:
            V = sla.solve_triangular(sla.cholesky(ref, lower=True), np.eye(ref.shape[0]),
                                     lower=True).T
        else:  # fixed weights: a generic member of the span of the mu-dependent terms
            mix = np.tensordot(1.0 / np.arange(1, terms.shape[0]), terms[1:], 1)
            V = sla.eigh(0.5 * (mix + mix.T), ref)[1]
    except (np.linalg.LinAlgError, ValueError) as exc:
        return f"A_N at the centre of D is not positive definite ({exc})"
    proj = np.einsum("ai,kab,bj->kij", V, terms, V)
    lam = np.einsum("kii->ki", proj)
    off = proj - lam[:, :, None] * np.eye(ref.shape[0])
    if np.abs(off).max() > 1e-10 * max(np.abs(lam).max(), 1.0):
        return (f"A_N(mu) has no common eigenbasis (off-diagonal {np.abs(off).max():.1e}); "
                "use online method 'daqp'")
    return V, lam


def gauss(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The layout's Gauss rule on [0, 1] (:func:`rbbench.hf.geometry.facets.gauss_legendre_01`)."""
    from rbbench.hf.geometry.facets import gauss_legendre_01

    return gauss_legendre_01(n)


def reference_points(lay: Any) -> tuple[np.ndarray, ...]:
    """``(x, n, w, phi)`` of the slave Gauss points on the reference chain (the identity
    map), :func:`rbbench.rb.kernels.pairing.slave_points`."""
    from rbbench.rb.kernels import pairing

    sl = lay.slave
    nq = sl.a.shape[0] * lay.n_gauss
    x, n, w = np.empty((nq, 2)), np.empty((nq, 2)), np.empty(nq)
    phi = np.empty((nq, lay.degree + 1))
    none2 = np.zeros((1, 2))
    sg, wg = gauss(lay.n_gauss)
    pairing.slave_points(np.asarray(sl.a, float), np.asarray(sl.b, float),
                          np.asarray(sl.inner, float), none2 if sl.na is None else sl.na,
                          none2 if sl.nb is None else sl.nb, sg, wg, lay.degree,
                          sl.na is not None, x, n, w, phi)
    return x, n, w, phi


def slave_terms(Z_loc: np.ndarray, cols: np.ndarray, dofs: np.ndarray, phi: np.ndarray,
                n: np.ndarray, pts: np.ndarray, n_gauss: int) -> np.ndarray:
    """``S[e, p] = sum_(a, d) phi[q, a] n[q, d] Z[dofs[f, a, d], cols[e]]`` at ``q = pts[e,
    p]`` on slave facet ``f = q // n_gauss``: the slave half of the jump along ``n`` (the
    reference normals, or their tangents) of every magic entry on the reference chain
    (:func:`rbbench.rb.kernels.pairing.jump_values`)."""
    d = np.asarray(dofs).reshape(dofs.shape[0], -1, 2)[pts // n_gauss]  # (E, P, k, 2)
    z = Z_loc[d, np.asarray(cols)[:, None, None, None]]
    return np.einsum("epa,epd,epad->ep", phi[pts], n[pts], z)


def master_plan(ceim: Any, n_hat: np.ndarray) -> dict[str, np.ndarray]:
    """The master chain (facet ends ``m_a``, ``m_b``, vertices ``m_v``), its windows, their
    monotonicity test (the reference's :func:`~rbbench.hf.geometry.facets.ray_cast_window` formula
    for ``sign(s) n_hat``: column 0 for ``s > 0``, 1 for ``s < 0``) and ``Z^T`` on the
    master dofs the windows reach (``m_dofs`` numbered into ``zt_m``; facets outside every
    window point at column 0)."""
    from rbbench.hf.geometry.facets import window_monotone

    ev, ms = ceim.evaluator, ceim.evaluator.layout.master
    N = ceim.Z_loc.shape[1]
    nq = n_hat.shape[0]
    if ms is None:
        none2 = np.zeros((1, 2))
        return {"m_a": none2, "m_b": none2, "m_v": none2, "zt_m": np.zeros((N, 1)),
                "mono": np.zeros((nq, 2), dtype=np.int64),
                "m_dofs": np.zeros((1, 2), int),
                "lo": np.zeros(1, int), "hi": np.zeros(1, int), **NO_SURFACE}
    lo, hi, ranges = ev.windows
    mono = np.stack([window_monotone(n_hat, ranges), window_monotone(-n_hat, ranges)], axis=1)
    dofs = np.asarray(ms.dofs).reshape(ms.dofs.shape[0], -1)
    reached = np.zeros(dofs.shape[0], dtype=bool)
    for a, b in zip(lo, hi, strict=True):
        reached[a:b + 1] = True
    used = np.unique(dofs[reached])
    m_dofs = np.where(reached[:, None], np.searchsorted(used, dofs), 0)
    return {"m_a": ms.a, "m_b": ms.b, "m_v": np.vstack([ms.a, ms.b[-1:]]),
            "zt_m": np.ascontiguousarray(ceim.Z_loc[used].T),
            "mono": mono.astype(np.int64),
            "m_dofs": m_dofs, "lo": lo, "hi": hi, **NO_SURFACE}

"""The compiled online path of the mixed reduced model: contact EIM or
exact affine constraints.

:meth:`rbbench.rb.mixed.model.ReducedModel.solve` spends ~95 % of its ~420 us on the
Python path in about 500 Python calls: the EIM's contact pairing, the magic entries, the
coefficient solves, the reduced assembly and the solver's input. Here one numba kernel does
all of it for one mu, per online method:

* ``nnls`` (what the default ``auto`` takes): :func:`rbbench.rb.mixed.dual_kernels.online_nnls`
  condenses the reduced saddle point on the cone coefficients through a common eigenbasis
  of ``A_N``'s affine terms (:func:`eigenbasis`, offline) and solves ``LCP(q, D)`` by
  Lawson-Hanson's active set inside the same kernel: no factorisation and no Python call
  online;
* ``daqp``: :func:`rbbench.rb.mixed.kernels.online_qp` writes the scaled QP of the Python path,
  daqp solves it (same tolerances), a second kernel unscales its answer.

The Python path stays the reference (``path = "python"``); the tests
compare the two on the same inputs.

Why numba rather than Cython or pythran: the kernels are plain loops over small float arrays
(numba's sweet spot), numba is one ``pip install`` with wheels for every platform the
README's set-up covers (no C compiler at install time, unlike Cython and pythran), the
compiled code is cached on disk (``cache=True``: ~1 s to load in a new process instead of
~10 s to compile), and without numba the package still works: the Python path is used and
reported as such (:func:`path_reason`).

Every deviation (mu outside D, a point leaving its master window, a solver not reporting
optimality, non-finite numbers) returns None and the caller reruns the Python path, which
raises the reference's error or falls back to PDAS as before.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

try:  # optional: without numba the Python path is the online path
    import numba

    NUMBA_VERSION: str | None = numba.__version__
except ImportError:  # pragma: no cover - exercised where numba is absent
    NUMBA_VERSION = None

__all__ = ["COMPILE", "NUMBA_VERSION", "CompiledOnline", "path_reason", "plan_arrays",
           "prepare"]

#: first call of the kernels in this process, per method: ``{method: {"first_call_s": s,
#: "from_disk_cache": bool}}`` (compilation, or loading numba's on-disk cache; never part
#: of an online time)
COMPILE: dict[str, Any] = {}

#: daqp settings of the online QP (:func:`rbbench.rb.mixed.model._solve_daqp`)
DAQP_TOL = 1e-12
#: the online methods with a compiled path
METHODS = ("nnls", "daqp")


def path_reason(model: Any, method: str = "daqp") -> str | None:
    """Why ``model`` cannot take the compiled path (None when it can)."""
    from rbbench.rb.algorithms.affine import AffineOperator, LinearInMu
    from rbbench.rb.hyper.contact_eim import ContactEIM

    if NUMBA_VERSION is None:
        return "numba is not installed"
    if method not in METHODS:
        return f"online method {method!r} (compiled: {', '.join(METHODS)})"
    ceim = model.constraint
    if not isinstance(model.coefficients, LinearInMu):
        return f"coefficient map {type(model.coefficients).__name__} (not theta = [1, mu])"
    if isinstance(getattr(ceim, "B", None), AffineOperator):  # mixed_model.AffineConstraint
        if not isinstance(ceim.coefficients, LinearInMu):
            return (f"constraint coefficient map {type(ceim.coefficients).__name__} "
                    "(not theta = [1, mu])")
        return None
    if not isinstance(ceim, ContactEIM):
        return (f"constraint {type(ceim).__name__} (compiled: the contact EIM and exact "
                "affine constraints)")
    lay = ceim.evaluator.layout
    if not hasattr(lay, "integration"):
        return "3D surface rows (the compiled contact EIM is 2D)"
    if lay.degree not in (1, 2) or lay.integration != "gauss":
        return f"facet degree {lay.degree}, integration {lay.integration!r}"
    if lay.master is not None and ceim.evaluator.windows is None:
        return "a master chain without windows"
    return None


def coefficient_map(lu_piv: tuple[np.ndarray, np.ndarray], T: np.ndarray) -> np.ndarray:
    """``W = P^-T T`` (``P = lu_piv``, the EIM interpolation matrix at the magic entries,
    ``T`` the EIM terms, first axis the term): online ``sum_j theta_j T[j]`` with
    ``theta = P^-1 c`` is ``sum_i c_i W[i]``, one pass over the terms and no triangular
    solves (the coefficient solve folded offline into the terms; measured 4.6 us of the
    online solve at M = 81)."""
    import scipy.linalg as sla

    flat = sla.lu_solve(lu_piv, T.reshape(T.shape[0], -1), trans=1)
    return flat.reshape(T.shape)


def plan_arrays(model: Any, method: str = "daqp") -> dict[str, np.ndarray]:
    """The arrays of the kernels' plan (:data:`rbbench.rb.mixed.kernels.FLOATS`, ``INTS``) from a
    reduced model whose constraint is a :class:`~rbbench.rb.hyper.contact_eim.ContactEIM` or exact
    affine (:func:`_affine_plan`); ``method = "nnls"`` adds the condensed arrays
    (:func:`_condensed_plan`)."""
    out = _eim_plan(model) if hasattr(model.constraint, "evaluator") else _affine_plan(model)
    if method == "nnls":
        out.update(_condensed_plan(model, out["w_b"]))
    return out


def _eim_plan(model: Any) -> dict[str, np.ndarray]:
    """The plan of a :class:`~rbbench.rb.hyper.contact_eim.ContactEIM` constraint
    (:func:`plan_arrays`). What does not depend on mu is tabulated here: the reference slave
    points, normals, weights (:func:`rbbench.rb.mixed.kernels.slave_points`), the monotonicity
    test of each point's master window for both signs of the slave scale, the slave term of
    every magic entry (``slave_b``) and ``Z^T`` on the master dofs of the windows
    (``zt_m``)."""
    ceim = model.constraint
    ev, lay = ceim.evaluator, ceim.evaluator.layout
    sl, ms = lay.slave, lay.master
    x_hat, n_hat, w_hat, sphi = reference_points(lay)
    pts_b, vals_b = ceim._support
    pts_g, vals_g = ev.support(ceim.pos_G)
    out = {**_bounds(model), "s_scale": sl.map.scale, "s_shift": sl.map.shift,
           "m_scale": sl.map.scale if ms is None else ms.map.scale,
           "m_shift": sl.map.shift if ms is None else ms.map.shift,
           "x_hat": x_hat, "n_hat": n_hat, "w_hat": w_hat,
           "slave_b": slave_terms(ceim.Z_loc, ceim.entry_col, sl.dofs, sphi, n_hat, pts_b,
                                   lay.n_gauss),
           "vals_b": vals_b, "vals_g": vals_g, "w_b": coefficient_map(ceim.lu_B, ceim.T_B),
           "w_g": coefficient_map(ceim.lu_G, ceim.T_G), "a_terms": model.A.terms,
           "f_terms": model.F.terms, "dims": np.array([lay.degree, ms is not None, 0]),
           "pts_b": pts_b, "cols_b": ceim.entry_col,
           "order_b": np.argsort(ceim.entry_col, kind="stable"), "pts_g": pts_g,
           "vt": np.zeros((1, 1)), "lam_a": np.zeros((1, 1))}
    out.update(_master_plan(ceim, n_hat))
    return out


def _bounds(model: Any) -> dict[str, np.ndarray]:
    """``mu_lo``, ``mu_hi``: the box D (unbounded without a parameter space)."""
    p = int(model.A.terms.shape[0]) - 1
    if model.parameters is not None:
        return {"mu_lo": np.asarray(model.parameters.low, float),
                "mu_hi": np.asarray(model.parameters.high, float)}
    return {"mu_lo": np.full(p, -np.inf), "mu_hi": np.full(p, np.inf)}


def _affine_plan(model: Any) -> dict[str, np.ndarray]:
    """The plan of an exact affine constraint ``B_N = sum_k theta_k B_k``, ``G_N = sum_k
    theta_k G_k``: its terms take the places of the EIM maps (``w_b``, ``w_g``, combined
    with theta instead of the magic values, ``dims[2] = 1``); no pairing arrays (one-entry
    placeholders)."""
    from rbbench.rb.mixed import kernels as _kernels

    one_f, one_i = np.zeros((1, 1)), np.zeros((1, 1), dtype=np.int64)
    out = {name: one_f for name in _kernels.FLOATS}
    out.update({name: one_i for name in _kernels.INTS})
    out.update(_bounds(model), w_b=model.constraint.B.terms, w_g=model.constraint.G.terms,
               a_terms=model.A.terms, f_terms=model.F.terms, dims=np.array([1, 0, 1]))
    return out


def eigenbasis(terms: np.ndarray, theta_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray] | str:
    """``(V, lam)`` with ``V^T A_k V = diag(lam[k])`` for every affine term ``A_k`` of
    ``A_N`` (``terms``, K x n x n), ``V^T A(theta_ref) V = I``: the generalised eigenvectors
    of a combination of the terms against ``A(theta_ref)`` (scipy ``eigh``). Exists for one
    term or two (one parameter) and for commuting families; otherwise the reason (a string).
    Then ``A_N(mu)^-1 = V diag(1 / lam^T theta) V^T`` (:mod:`rbbench.rb.mixed.dual_kernels`)."""
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


def _condensed_plan(model: Any, w_b: np.ndarray) -> dict[str, np.ndarray]:
    """The arrays of :func:`rbbench.rb.mixed.dual_kernels.online_nnls`: the EIM terms of
    ``B_N V`` transposed (n x R each), ``V^T F_k``, ``V^T`` and ``lam`` of
    :func:`eigenbasis` (raises ValueError with its reason where there is none)."""
    basis = eigenbasis(model.A.terms, _centre_theta(model))
    if isinstance(basis, str):
        raise ValueError(basis)
    V, lam = basis
    return {"w_b": np.ascontiguousarray(np.einsum("era,ak->ekr", w_b, V)),
            "f_terms": model.F.terms @ V, "vt": np.ascontiguousarray(V.T), "lam_a": lam}


def _centre_theta(model: Any) -> np.ndarray:
    """``[1, mu]`` at the centre of D (mu = 0 without a parameter space)."""
    return np.concatenate([[1.0], _centre(model)])


def _centre(model: Any) -> np.ndarray:
    if model.parameters is not None:
        return 0.5 * (np.asarray(model.parameters.low) + np.asarray(model.parameters.high))
    return np.zeros(int(model.A.terms.shape[0]) - 1)


def reference_points(lay: Any) -> tuple[np.ndarray, ...]:
    """``(x, n, w, phi)`` of the slave Gauss points on the reference chain (the identity
    map), :func:`rbbench.rb.mixed.kernels.slave_points`."""
    from rbbench.rb.mixed import kernels as _kernels

    sl = lay.slave
    nq = sl.a.shape[0] * lay.n_gauss
    x, n, w = np.empty((nq, 2)), np.empty((nq, 2)), np.empty(nq)
    phi = np.empty((nq, lay.degree + 1))
    none2 = np.zeros((1, 2))
    sg, wg = gauss(lay.n_gauss)
    _kernels.slave_points(np.asarray(sl.a, float), np.asarray(sl.b, float),
                          np.asarray(sl.inner, float), none2 if sl.na is None else sl.na,
                          none2 if sl.nb is None else sl.nb, sg, wg, lay.degree,
                          sl.na is not None, x, n, w, phi)
    return x, n, w, phi


def slave_terms(Z_loc: np.ndarray, cols: np.ndarray, dofs: np.ndarray, phi: np.ndarray,
                n: np.ndarray, pts: np.ndarray, n_gauss: int) -> np.ndarray:
    """``S[e, p] = sum_(a, d) phi[q, a] n[q, d] Z[dofs[f, a, d], cols[e]]`` at ``q = pts[e,
    p]`` on slave facet ``f = q // n_gauss``: the slave half of the jump along ``n`` (the
    reference normals, or their tangents) of every magic entry on the reference chain
    (:func:`rbbench.rb.mixed.kernels.jump_values`)."""
    d = np.asarray(dofs).reshape(dofs.shape[0], -1, 2)[pts // n_gauss]  # (E, P, k, 2)
    z = Z_loc[d, np.asarray(cols)[:, None, None, None]]
    return np.einsum("epa,epd,epad->ep", phi[pts], n[pts], z)


def _master_plan(ceim: Any, n_hat: np.ndarray) -> dict[str, np.ndarray]:
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
                "lo": np.zeros(1, int), "hi": np.zeros(1, int)}
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
            "m_dofs": m_dofs, "lo": lo, "hi": hi}


def gauss(n: int) -> tuple[np.ndarray, np.ndarray]:
    """The layout's Gauss rule on [0, 1] (:func:`rbbench.hf.geometry.facets.gauss_legendre_01`)."""
    from rbbench.hf.geometry.facets import gauss_legendre_01

    return gauss_legendre_01(n)


def pack(arrays: dict[str, np.ndarray], floats: tuple[str, ...] | None = None,
         ints: tuple[str, ...] | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(fb, ib, meta)``: the float and int arrays of :func:`plan_arrays` in the kernels'
    order (``floats``, ``ints``: another kernel's names, default
    :data:`rbbench.rb.mixed.kernels.FLOATS`, ``INTS``), one row ``[offset, s0, s1, s2]`` of
    ``meta`` per array (shape padded with 1)."""
    from rbbench.rb.mixed import kernels as _kernels

    meta, chunks = [], {"f": [], "i": []}
    offsets = {"f": 0, "i": 0}
    for kind, names in (("f", _kernels.FLOATS if floats is None else floats),
                        ("i", _kernels.INTS if ints is None else ints)):
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


class CompiledOnline:
    """One reduced model's compiled online solve (module docstring) by ``method``.

    ``"daqp"``: the packed plan and the preallocated QP buffer ``qp`` (``[H, f, A, b_upper,
    rows, |F|]``, :func:`rbbench.rb.mixed.kernels.online_qp`) with daqp's views of it.
    ``"nnls"``: the condensed plan (:func:`_condensed_plan`) and one kernel,
    :func:`rbbench.rb.mixed.dual_kernels.online_nnls`. Not picklable state:
    :class:`~rbbench.rb.mixed.model.ReducedModel` rebuilds it after unpickling.
    """

    def __init__(self, model: Any, method: str = "daqp") -> None:
        from rbbench.rb.mixed import kernels as _kernels

        self._k = _kernels
        self.method = method
        self.fb, self.ib, self.meta = pack(plan_arrays(model, method))
        self.n = int(model.A.terms.shape[-1])
        self.m = int(model.R)
        n, m = self.n, self.m
        if method == "nnls":
            from rbbench.rb.mixed import dual_kernels as _dual_kernels

            self._kernel = _dual_kernels.online_nnls
            return
        self._kernel = _kernels.online_qp
        self.qp = np.zeros(n * n + n + m * n + 3 * m + 1)
        self.H = self.qp[:n * n].reshape(n, n)
        self.f = self.qp[n * n:n * n + n]
        self.A = self.qp[n * n + n:n * n + n + m * n].reshape(m, n)
        self.bu = self.qp[n * n + n + m * n:n * n + n + m * n + m]
        self.bl = np.full(m, -1e30)
        self.sense = np.zeros(m, dtype=np.int32)

    def warm_up(self, mu: np.ndarray) -> None:
        """First call of every kernel (compile or load the disk cache), timed into
        :data:`COMPILE` once per process and method."""
        if self.method in COMPILE:
            return
        t0 = time.perf_counter()
        self.solve(mu)
        stats = self._kernel.stats
        COMPILE[self.method] = {"first_call_s": time.perf_counter() - t0,
                                "from_disk_cache": bool(stats.cache_hits)
                                and not stats.cache_misses}

    def solve(self, mu: Any) -> tuple[np.ndarray, np.ndarray, int, float] | None:
        """The online solve at ``mu``: ``(c, alpha, iterations, min(raw alpha) /
        max|raw alpha|)``, or None where the Python path must decide."""
        if not (isinstance(mu, np.ndarray) and mu.dtype == np.float64 and mu.ndim == 1):
            mu = np.asarray(mu, dtype=np.float64).reshape(-1)
        if self.method == "nnls":
            status, it, rel, c, alpha = self._kernel(mu, self.fb, self.ib, self.meta)
            return (c, alpha, it, rel) if status == self._k.OK else None
        return self._solve_daqp(mu)

    def _solve_daqp(self, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray, int, float] | None:
        import daqp

        if self._kernel(mu, self.fb, self.ib, self.meta, self.qp) != self._k.OK:
            return None
        y, _, flag, info = daqp.solve(self.H, self.f, self.A, self.bu, self.bl, self.sense,
                                      primal_tol=DAQP_TOL, dual_tol=DAQP_TOL)
        if flag != 1:
            return None
        c, alpha, finite, rel = self._k.unscale(y, info["lam"], self.qp, self.n, self.m)
        if not finite:
            return None
        return c, alpha, info["iterations"], rel


def prepare(model: Any, method: str = "daqp") -> CompiledOnline | str:
    """The compiled solve of ``model`` (kernels compiled or loaded, :data:`COMPILE`), or the
    reason (:func:`path_reason`) it takes the Python path."""
    reason = path_reason(model, method)
    if reason is not None:
        return reason
    try:
        online = CompiledOnline(model, method)
    except ValueError as exc:  # no common eigenbasis of A_N's terms (method "nnls")
        return str(exc)
    online.warm_up(_centre(model))
    return online

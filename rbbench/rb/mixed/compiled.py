"""The compiled online path of the mixed reduced model: contact EIM or
exact affine constraints.

:meth:`rbbench.rb.mixed.model.ReducedModel.solve` spends ~95 % of its ~420 us on the
Python path in about 500 Python calls: the EIM's contact pairing, the magic entries, the
coefficient solves, the reduced assembly and the solver's input. Here one numba kernel does
all of it for one mu, per online method:

* ``nnls`` (what the default ``auto`` takes): :func:`rbbench.rb.mixed.dual_kernels.online_nnls`
  condenses the reduced saddle point on the cone coefficients through a common eigenbasis
  of ``A_N``'s affine terms (:func:`rbbench.rb.kernels.plan.eigenbasis`, offline) and
  solves ``LCP(q, D)`` by Lawson-Hanson's active set inside the same kernel
  (:mod:`rbbench.rb.kernels.nnls`): no factorisation and no Python call online;
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

from rbbench.rb.kernels.plan import (
    NUMBA_VERSION,
    centre,
    centre_theta,
    coefficient_map,
    eigenbasis,
    master_plan,
    pack,
    parameter_bounds,
    reference_points,
    slave_terms,
)

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
    from rbbench.rb.algorithms.affine import AffineOperator
    from rbbench.rb.hyper.contact_eim import ContactEIM
    from rbbench.rb.hyper.surface_eim import SurfaceRowEvaluator

    if NUMBA_VERSION is None:
        return "numba is not installed"
    if method not in METHODS:
        return f"online method {method!r} (compiled: {', '.join(METHODS)})"
    ceim = model.constraint
    n_terms = int(model.A.terms.shape[0])
    why = _coefficients_reason(model.coefficients, n_terms)
    if why is not None:
        return why
    if isinstance(getattr(ceim, "B", None), AffineOperator):  # mixed_model.AffineConstraint
        why = _coefficients_reason(ceim.coefficients, n_terms)
        return None if why is None else f"constraint {why}"
    if not isinstance(ceim, ContactEIM):
        return (f"constraint {type(ceim).__name__} (compiled: the contact EIM and exact "
                "affine constraints)")
    lay = ceim.evaluator.layout
    if isinstance(ceim.evaluator, SurfaceRowEvaluator):  # 3D: triangulated surfaces
        if lay.degree not in (1, 2):
            return f"surface degree {lay.degree}"
        if lay.master is not None and ceim.evaluator.windows is None:
            return "a master surface without windows"
        return None
    if lay.degree not in (1, 2) or lay.integration != "gauss":
        return f"facet degree {lay.degree}, integration {lay.integration!r}"
    if lay.master is not None and ceim.evaluator.windows is None:
        return "a master chain without windows"
    return None




def _coefficients_reason(coef: Any, n_terms: int) -> str | None:
    """Why the kernels cannot evaluate the coefficient map ``coef`` of ``n_terms`` affine
    terms (:func:`rbbench.rb.kernels.layout.coefficients`: ``[1, mu]``, or the powers of
    one parameter), None when they can."""
    from rbbench.rb.algorithms.affine import LinearInMu, PolynomialInMu

    if isinstance(coef, LinearInMu) and coef.n_terms == n_terms:
        return None
    if isinstance(coef, PolynomialInMu) and coef.n_terms == n_terms:
        return None
    return (f"coefficient map {type(coef).__name__} (compiled: theta = [1, mu] or the "
            f"powers of one parameter, as many as the {n_terms} affine terms)")


def plan_arrays(model: Any, method: str = "daqp") -> dict[str, np.ndarray]:
    """The arrays of the kernels' plan (:data:`rbbench.rb.kernels.layout.FLOATS`, ``INTS``)
    from a reduced model whose constraint is a
    :class:`~rbbench.rb.hyper.contact_eim.ContactEIM` or exact affine
    (:func:`_affine_plan`); ``method = "nnls"`` adds the condensed arrays
    (:func:`_condensed_plan`)."""
    out = _eim_plan(model) if hasattr(model.constraint, "evaluator") else _affine_plan(model)
    if method == "nnls":
        out.update(_condensed_plan(model, out["w_b"]))
    return out


def _eim_plan(model: Any) -> dict[str, np.ndarray]:
    """The plan of a :class:`~rbbench.rb.hyper.contact_eim.ContactEIM` constraint
    (:func:`plan_arrays`). What does not depend on mu is tabulated here: the reference slave
    points, normals, weights (:func:`rbbench.rb.kernels.plan.reference_points`), the
    monotonicity test of each point's master window for both signs of the slave scale
    (:func:`rbbench.rb.kernels.plan.master_plan`), the slave term of every magic entry
    (``slave_b``) and ``Z^T`` on the master dofs of the windows (``zt_m``)."""
    ceim = model.constraint
    ev, lay = ceim.evaluator, ceim.evaluator.layout
    if not hasattr(lay, "integration"):  # 3D: triangulated surfaces
        from rbbench.rb.kernels.surface_plan import pairing_table, surface_eim_arrays

        out = {**parameter_bounds(model), **surface_eim_arrays(ceim),
               "w_b": coefficient_map(ceim.lu_B, ceim.T_B),
               "w_g": coefficient_map(ceim.lu_G, ceim.T_G), "a_terms": model.A.terms,
               "f_terms": model.F.terms, "vt": np.zeros((1, 1)), "lam_a": np.zeros((1, 1))}
        out.update(pairing_table(out))
        return out
    sl, ms = lay.slave, lay.master
    x_hat, n_hat, w_hat, sphi = reference_points(lay)
    pts_b, vals_b = ceim._support
    pts_g, vals_g = ev.support(ceim.pos_G)
    out = {**parameter_bounds(model), "s_scale": sl.map.scale, "s_shift": sl.map.shift,
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
    out.update(master_plan(ceim, n_hat))
    return out




def _affine_plan(model: Any) -> dict[str, np.ndarray]:
    """The plan of an exact affine constraint ``B_N = sum_k theta_k B_k``, ``G_N = sum_k
    theta_k G_k``: its terms take the places of the EIM maps (``w_b``, ``w_g``, combined
    with theta instead of the magic values, ``dims[2] = 1``); no pairing arrays (one-entry
    placeholders)."""
    from rbbench.rb.kernels import layout

    one_f, one_i = np.zeros((1, 1)), np.zeros((1, 1), dtype=np.int64)
    out = {name: one_f for name in layout.FLOATS}
    out.update({name: one_i for name in layout.INTS})
    out.update(parameter_bounds(model), w_b=model.constraint.B.terms, w_g=model.constraint.G.terms,
               a_terms=model.A.terms, f_terms=model.F.terms, dims=np.array([1, 0, 1]))
    return out




def _condensed_plan(model: Any, w_b: np.ndarray) -> dict[str, np.ndarray]:
    """The arrays of :func:`rbbench.rb.mixed.dual_kernels.online_nnls`: the EIM terms of
    ``B_N V`` transposed (n x R each), ``V^T F_k``, ``V^T`` and ``lam`` of
    :func:`eigenbasis` (raises ValueError with its reason where there is none)."""
    basis = eigenbasis(model.A.terms, centre_theta(model))
    if isinstance(basis, str):
        raise ValueError(basis)
    V, lam = basis
    return {"w_b": np.ascontiguousarray(np.einsum("era,ak->ekr", w_b, V)),
            "f_terms": model.F.terms @ V, "vt": np.ascontiguousarray(V.T), "lam_a": lam}
















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

    def pairing_table_share(self) -> float | None:
        """Share of the plan's slave points whose pairing starts from the table of their hit
        triangle against mu (:func:`rbbench.rb.kernels.surface_plan.pairing_table`); None
        where the plan pairs no triangulated surface (2D chains, affine constraints)."""
        from rbbench.rb.kernels import layout

        has_master = layout.flat_ints(self.ib, self.meta, layout.DIMS)[1]
        if not layout.is_surface(self.ib, self.meta) or not has_master:
            return None
        ptr = layout.flat_ints(self.ib, self.meta, layout.T_PTR)
        return float(np.mean(np.diff(ptr) > 0)) if ptr.size > 1 else 0.0

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
    online.warm_up(centre(model))
    return online

"""The compiled online path of the hyper-reduced wedge model: one numba kernel per mu.

On the Python path (:meth:`rbbench.rb.friction.wedge.hyper.WedgeHyperModel.solve`) the
friction EIM's pairing and magic entries, the coefficient solves and De Saxce's fixed point
(daqp called from a Python loop) take ~10 ms on hertz_friction P2. Here
:func:`rbbench.rb.friction.wedge.kernels.wedge_online` does all of it in one call, on the
frictionless path's plan layout (:mod:`rbbench.rb.kernels.layout`, tabulated by
:mod:`rbbench.rb.kernels.plan`: the pairing arrays, the normal magic entries, the EIM maps
with the coefficient solves folded in) and a second
buffer of the wedge's own arrays (tangential and slip entries, the slip DEIM's ``P``, the
training solutions of the warm start).

The Python path stays the reference (``path = "python"``); the tests compare the two on
the same model. Without numba, or for a
model the kernel does not cover (:func:`path_reason`), the Python path runs and
:meth:`~rbbench.rb.friction.wedge.hyper.WedgeHyperModel.online_path` says why; any
deviation at one mu (a kernel status other than ``OK``) reruns that mu on the Python path.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from rbbench.rb.kernels import plan
from rbbench.rb.kernels.plan import NUMBA_VERSION

__all__ = ["COMPILE", "COMPILE_ESTIMATE_S", "CompiledWedge", "is_cached", "path_reason",
           "prepare", "slave_row_sums", "wedge_plan"]

#: first call of the kernel in this process: ``{"first_call_s": s, "from_disk_cache":
#: bool}`` (compilation, or loading numba's on-disk cache; never part of an online time)
COMPILE: dict[str, Any] = {}
#: the first call's time without a disk cache (compiling every kernel it inlines),
#: measured on the 2-core development machine shared with other jobs; announced before it
COMPILE_ESTIMATE_S = 60


def path_reason(model: Any) -> str | None:
    """Why ``model`` (a :class:`~rbbench.rb.friction.wedge.hyper.WedgeHyperModel`) cannot
    take the compiled path (None when it can)."""
    from rbbench.rb.algorithms.affine import LinearInMu

    if NUMBA_VERSION is None:
        return "numba is not installed"
    if not isinstance(model.coefficients, LinearInMu):
        return f"coefficient map {type(model.coefficients).__name__} (not theta = [1, mu])"
    feim = model.eim
    if feim is None or feim.slip is None:
        return "no friction EIM with slip rows"
    lay = feim.evaluator.layout
    if lay.degree not in (1, 2) or lay.integration != "gauss":
        return f"facet degree {lay.degree}, integration {lay.integration!r}"
    if lay.master is not None and feim.evaluator.windows is None:
        return "a master chain without windows"
    return None


def wedge_plan(model: Any) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """``(shared, own)``: the kernel's plan. ``shared`` in the frictionless layout
    (:data:`rbbench.rb.kernels.layout.FLOATS`, ``INTS``): the pairing arrays of the friction
    EIM's evaluator, its normal magic entries as the ``b`` entries, Gn's rows as the ``g``
    rows, ``w_b`` the normal then tangential EIM maps
    (:func:`~rbbench.rb.kernels.plan.coefficient_map`) times the eigenbasis ``V`` of
    ``A_N``'s terms, transposed (n x R each); ``own``:
    :data:`rbbench.rb.friction.wedge.kernels.FLOATS`, ``INTS``. Raises ValueError where
    ``A_N``'s terms have no common eigenbasis."""
    feim = model.eim
    ev, lay = feim.evaluator, feim.evaluator.layout
    sl, ms = lay.slave, lay.master
    basis = plan.eigenbasis(model.A.terms, plan.centre_theta(model))
    if isinstance(basis, str):
        raise ValueError(basis)
    V, lam = basis
    x_hat, n_hat, w_hat, sphi = plan.reference_points(lay)
    t_hat = np.stack([-n_hat[:, 1], n_hat[:, 0]], axis=1)
    Z, Zv = feim.Z_loc, feim.Z_loc @ V
    nrm, tan, slip = feim.normal, feim.tangential, feim.slip

    def slave(part, direction, basis_loc):
        return plan.slave_terms(basis_loc, part.col, sl.dofs, sphi, direction,
                                          part.support[0], lay.n_gauss)

    w_b = np.concatenate([plan.coefficient_map(nrm.lu, nrm.T),
                          plan.coefficient_map(tan.lu, tan.T)])
    w_b = np.einsum("era,ak->ekr", w_b, V)
    w_u, w_b = compress_map(w_b.reshape(w_b.shape[0], -1), _sample_values(model))
    pts_g, vals_g = ev.support(feim.pos_G)
    shared = {**plan.parameter_bounds(model), "s_scale": sl.map.scale,
              "s_shift": sl.map.shift,
              "m_scale": sl.map.scale if ms is None else ms.map.scale,
              "m_shift": sl.map.shift if ms is None else ms.map.shift,
              "x_hat": x_hat, "n_hat": n_hat, "w_hat": w_hat,
              "slave_b": slave(nrm, n_hat, Z), "vals_b": nrm.support[1], "vals_g": vals_g,
              "w_b": np.ascontiguousarray(w_b),
              "w_g": plan.coefficient_map(feim.lu_G, feim.T_G),
              "a_terms": model.A.terms, "f_terms": model.F.terms @ V,
              "dims": np.array([lay.degree, ms is not None, 0]),
              "pts_b": nrm.support[0], "cols_b": nrm.col,
              "order_b": np.argsort(nrm.col, kind="stable"), "pts_g": pts_g,
              "vt": np.ascontiguousarray(V.T), "lam_a": lam}
    master = plan.master_plan(feim, n_hat)
    shared.update(master)
    z_s = np.zeros((1, Zv.shape[1]))
    if ms is not None:  # the master dofs of the windows, in Z V (the slip rows' basis)
        z_s = _master_basis(feim, Zv)
    n_basis, n_rows = Zv.shape[1], model.P.shape[1]
    pts_s, vals_s = slip.support[0][::n_basis], slip.support[1][::n_basis]  # one per row
    slave_s = slave_row_sums(
        slave(slip, t_hat, Zv).reshape(n_rows, n_basis, -1).transpose(0, 2, 1), vals_s,
        pts_s, w_hat)
    x_train = np.asarray(model.x_train, float).reshape(-1, model.R)
    own = {"t_hat": t_hat, "slave_t": slave(tan, t_hat, Z), "vals_t": tan.support[1],
           "slave_s": np.ascontiguousarray(slave_s), "vals_s": vals_s, "z_s": z_s,
           "pq_t": np.ascontiguousarray(model.P.T),
           "mus_train": np.asarray(model.mus_train, float).reshape(
               x_train.shape[0], -1) if x_train.size else np.zeros((1, 1)),
           "x_train": x_train if x_train.size else np.zeros((1, model.R)),
           "settings": np.array([model.tol]),
           "pts_t": tan.support[0], "cols_t": tan.col,
           "order_t": np.argsort(tan.col, kind="stable"), "pts_s": pts_s,
           "sizes": np.array([model.P.shape[1], model.max_iter, w_u.shape[1]]), "w_u": w_u}
    return shared, own


def slave_row_sums(slave: np.ndarray, vals: np.ndarray, pts: np.ndarray, w_hat: np.ndarray
                   ) -> np.ndarray:
    """The slave part of the slip rows summed over their points, up to the scaling ``s``
    of the map: ``sum_p vals[r, p] w_hat[pts[r, p]] slave[r, p]`` (``slave``: rows x points
    x basis; padding points have ``vals = 0``)."""
    return np.ascontiguousarray(np.einsum("rp,rpj->rj", vals * w_hat[pts], slave))


def compress_map(W: np.ndarray, values: np.ndarray, rtol: float = 1e-14
                 ) -> tuple[np.ndarray, np.ndarray]:
    """``(U, W_k)`` with ``c^T W = (c^T U) W_k`` to ``rtol``: the map ``c -> c^T W`` from
    the magic values to the reduced ``B`` (``W``: E x n, the EIM terms with the coefficient
    solve folded in) through its truncated SVD ``W ~ U diag(s) Vt`` (``W_k = diag(s) Vt``,
    k rows), when that halves the online work ``E n`` at least; else ``(zeros (E, 0),
    W)``, the map itself.

    ``k`` is the smallest with ``s[k] max_j ||c_j||_2 <= rtol min_j ||c_j^T W||_2`` over
    the magic values ``values`` (rows ``c_j``) sampled on D: the truncation changes ``B``
    by at most ``s[k] ||c||_2`` (2-norm of the flattened ``B``), so by ``rtol`` relative
    wherever ``||c||`` and ``||B||`` stay within their sampled ranges."""
    E, n = W.shape
    U, sv, Vt = np.linalg.svd(W, full_matrices=False)
    top = float(np.linalg.norm(values, axis=1).max(initial=0.0))
    low = float(np.linalg.norm(values @ W, axis=1).min()) if len(values) else 0.0
    k = int(np.searchsorted(-sv * top, -rtol * low, side="left"))  # first s[k] small enough
    if k == 0 or 2 * k * (E + n) > E * n:
        return np.zeros((E, 0)), W
    return np.ascontiguousarray(U[:, :k]), np.ascontiguousarray(sv[:k, None] * Vt[:k])


def _sample_values(model: Any, n: int = 33) -> np.ndarray:
    """The magic values (normal then tangential entries) of the friction EIM at ``n``
    parameters of D (a grid for one parameter, else corners and seeded random points),
    by the Python path (:meth:`rbbench.rb.hyper.contact_eim.RowEvaluator.jump_entries`)."""
    from rbbench.rb.hyper.contact_eim import tangent

    feim = model.eim
    lo, hi = np.asarray(model.parameters.low, float), np.asarray(model.parameters.high, float)
    if lo.size == 1:
        mus = np.linspace(lo, hi, n)
    else:
        rng = np.random.default_rng(0)
        corners = np.array(np.meshgrid(*zip(lo, hi, strict=True))).reshape(lo.size, -1).T
        mus = np.vstack([corners, lo + (hi - lo) * rng.random((n, lo.size))])
    ev, out = feim.evaluator, []
    for mu in mus:
        p = ev.pairing(mu)
        out.append(np.concatenate([
            ev.jump_entries(p, d, feim.Z_loc, *part.support, part.col)
            for part, d in ((feim.normal, p.nrm), (feim.tangential, tangent(p.nrm)))]))
    return np.array(out)


def _master_basis(feim: Any, basis_loc: np.ndarray) -> np.ndarray:
    """``basis_loc`` on the master dofs the windows reach (one row per dof), numbered as
    :func:`rbbench.rb.kernels.plan.master_plan` numbers them (``m_dofs``)."""
    ev, ms = feim.evaluator, feim.evaluator.layout.master
    lo, hi, _ = ev.windows
    dofs = np.asarray(ms.dofs).reshape(ms.dofs.shape[0], -1)
    reached = np.zeros(dofs.shape[0], dtype=bool)
    for a, b in zip(lo, hi, strict=True):
        reached[a:b + 1] = True
    return np.ascontiguousarray(basis_loc[np.unique(dofs[reached])])


def is_cached() -> bool:
    """Whether numba's disk cache holds the kernel for its current source (else its first
    call compiles it): the cache index exists and its source stamp is current (numba's
    own test, ``_load_index``)."""
    from rbbench.rb.friction.wedge import kernels

    try:
        return bool(kernels.wedge_online._cache._cache_file._load_index())
    except Exception:  # noqa: BLE001 - an unreadable index: numba recompiles too
        return False


class CompiledWedge:
    """One wedge model's compiled online solve (module docstring): the packed plans.
    Not picklable state: the model rebuilds it after unpickling."""

    def __init__(self, model: Any) -> None:
        from rbbench.rb.friction.wedge import kernels

        self._k = kernels
        shared, own = wedge_plan(model)
        self.fb, self.ib, self.meta = plan.pack(shared)
        self.fw, self.iw, self.mw = plan.pack(own, kernels.FLOATS, kernels.INTS)
        self.R = int(model.R)
        self.start = kernels.NEAREST if np.asarray(model.x_train).size else kernels.COLD

    def warm_up(self, mu: np.ndarray) -> None:
        """First call of the kernel (compile or load the disk cache), timed into
        :data:`COMPILE` once per process."""
        if COMPILE:
            return
        t0 = time.perf_counter()
        self.solve(mu)
        stats = self._k.wedge_online.stats
        COMPILE.update(first_call_s=time.perf_counter() - t0,
                       from_disk_cache=bool(stats.cache_hits) and not stats.cache_misses)

    def solve(self, mu: Any, x0: np.ndarray | None = None) -> Any:
        """The online solve at ``mu`` (warm start ``x0``, else the nearest training
        solution): a :class:`~rbbench.rb.friction.wedge.model.WedgeOnlineResult` with
        ``path = "compiled"``, or None where the Python path must decide."""
        from rbbench.rb.friction.wedge.model import WedgeOnlineResult

        if not (isinstance(mu, np.ndarray) and mu.dtype == np.float64 and mu.ndim == 1):
            mu = np.asarray(mu, dtype=np.float64).reshape(-1)
        k = self._k
        if x0 is None:
            start, x = self.start, np.zeros(self.R)
        else:
            start, x = k.GIVEN, np.asarray(x0, dtype=np.float64).reshape(-1)
            if x.size != self.R:
                return None
        status, it, stop, inner, a, c, hist = k.wedge_online(
            mu, self.fb, self.ib, self.meta, self.fw, self.iw, self.mw, x, start)
        if status != k.OK:
            return None
        return WedgeOnlineResult(a, c, int(it), int(inner), k.STOPS[stop], 0.0,
                                 hist.tolist(), mu, path="compiled")


def prepare(model: Any) -> CompiledWedge | str:
    """The compiled solve of ``model`` (kernel compiled or loaded, :data:`COMPILE`), or the
    reason (:func:`path_reason`, no eigenbasis of ``A_N``'s terms) it takes the Python path."""
    reason = path_reason(model)
    if reason is not None:
        return reason
    try:
        online = CompiledWedge(model)
    except ValueError as exc:  # no common eigenbasis of A_N's terms
        return str(exc)
    online.warm_up(plan.centre(model))
    return online

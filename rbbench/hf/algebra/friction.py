"""Collocated 2D friction on the condensed contact problem (plain functions on arrays).

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slides "Coulomb contact problem", "HF model", "Tangential
constraints", "Algebraic formulation / Collocation method" (P1 multipliers,
``S = (d-1) R = R`` in 2D, one tangential multiplier per collocation node); model B
(``F(|u_t|)``) of the talk "On coupling of complementarity with friction in contact shape
optimization".

With ``m`` collocation nodes the mixed problem is
``A u + Bn^T lam_n + Bt^T lam_t = F``. As in :mod:`rbbench.hf.solvers.lcp` it is condensed with
one factorisation of ``A``: ``B = [Bn; Bt]``, ``x = [lam_n; lam_t]`` (length ``2m``),
``u = u0 - A^{-1} B^T x``, ``D = B A^{-1} B^T`` and ``w := q + D x`` with::

    q_n = G - Bn u0           w_n = G - Bn u          = s_n  (normal gap, >= 0)
    q_t = ut_prev - Bt u0     w_t = ut_prev - Bt u    = -v   (v: slip of this load step)

``ut_prev`` is the relative tangential displacement at the start of the load step, so
``v = Bt u - ut_prev`` is the slip measured from the previous step (Coulomb friction is
path-dependent).

**Sign convention.** ``lam_t`` is Benaceur et al.'s multiplier: it enters ``A u + Bt^T lam_t = F``
exactly as ``lam_n`` does, so the tangential force on the body is ``-lam_t``. Friction
opposes the slip, hence at every node::

    |lam_t| <= s;   |lam_t| < s  =>  v = 0 (stick);   v != 0  =>  lam_t = +s sign(v) (slip)

i.e. the friction traction on the body ``-lam_t = -s sign(v)``. This is the sign of the
convex problem: Tresca (``s`` given) is the optimality system of the box QP
``min 1/2 x^T D x + q^T x`` s.t. ``lam_n >= 0``, ``|lam_t| <= s``; Coulomb sets
``s = F lam_n`` (the 2D cone is the wedge ``|lam_t| <= F lam_n``, a non-symmetric LCP).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp
from scipy.optimize import lsq_linear

from rbbench.hf.condensation.dense import delassus_scaling
from rbbench.hf.condensation.schur import condense_problem
from rbbench.interfaces import Factorize

#: names of the per-condition residuals reported by every friction solver
RESIDUAL_NAMES = ("non_penetration", "normal_complementarity", "stick", "slip", "cone")


@dataclass
class FrictionResult:
    """Outcome of a friction solve on the condensed problem.

    ``stop_reason`` is one of :data:`rbbench.interfaces.STOP_REASONS`; ``residuals`` holds
    the relative residual of every condition (:func:`friction_residuals`, plus ``"max"``);
    ``states`` the per-node state ``"open" / "stick" / "slip"``; ``history`` the solver's
    own convergence measure per iteration.
    """

    lam_n: np.ndarray
    lam_t: np.ndarray
    iterations: int
    stop_reason: str
    residuals: dict[str, float]
    states: np.ndarray
    history: list[float] = field(default_factory=list)
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def x(self) -> np.ndarray:
        """The stacked multipliers ``[lam_n; lam_t]``."""
        return np.concatenate([self.lam_n, self.lam_t])


@dataclass(frozen=True)
class CoefficientLaw:
    """A slip-dependent friction coefficient ``F(t)``, ``t = |u_t|`` (as in model B of the
    shape-optimisation talk)."""

    name: str
    f: Callable[[np.ndarray], np.ndarray]
    df: Callable[[np.ndarray], np.ndarray] | None = None


def _model_b(t: np.ndarray) -> np.ndarray:
    return 0.25 / (np.asarray(t, float) ** 2 + 1.0)


def _model_b_derivative(t: np.ndarray) -> np.ndarray:
    t = np.asarray(t, float)
    return -0.5 * t / (t**2 + 1.0) ** 2


#: model B of the shape-optimisation talk: ``F(t) = 0.25 / (t^2 + 1)``
MODEL_B = CoefficientLaw("model_b", _model_b, _model_b_derivative)
COEFFICIENT_LAWS: dict[str, CoefficientLaw] = {"model_b": MODEL_B}


def condense_friction(A: sp.spmatrix, F: np.ndarray, Bn: sp.spmatrix, Bt: sp.spmatrix,
                      G: np.ndarray, ut_prev: np.ndarray | None = None,
                      factorize: Factorize | None = None, condensation: str = "columns",
                      linear_solver: str = "auto") -> Any:
    """Condense the friction problem with one factorisation.

    ``B = [Bn; Bt]`` and ``G = [G; ut_prev]`` in
    :func:`rbbench.hf.condensation.schur.condense_problem` (``condensation``, ``linear_solver``;
    default: the dense ``A^{-1} B^T`` of :func:`rbbench.hf.condensation.dense.condense`), so
    ``q_t = ut_prev - Bt u0`` and ``displacement([lam_n; lam_t])`` is ``u``.
    """
    G = np.asarray(G, float).ravel()
    m = G.size
    ut_prev = np.zeros(m) if ut_prev is None else np.asarray(ut_prev, float).ravel()
    if Bn.shape[0] != m or Bt.shape[0] != m or ut_prev.size != m:
        raise ValueError(f"condense_friction: Bn ({Bn.shape[0]} rows), Bt ({Bt.shape[0]} "
                         f"rows), G ({m}) and ut_prev ({ut_prev.size}) must match")
    B = sp.vstack([sp.csr_matrix(Bn), sp.csr_matrix(Bt)]).tocsr()
    return condense_problem(A, F, B, np.concatenate([G, ut_prev]), condensation=condensation,
                            linear_solver=linear_solver, factorize=factorize)


def check_problem(D: np.ndarray, q: np.ndarray) -> int:
    """The number of nodes ``m`` of a condensed friction problem (``D`` is ``2m x 2m``)."""
    n = q.size
    if n % 2 or D.shape != (n, n):
        raise ValueError(f"friction problem: q has {n} entries and D shape {D.shape}; "
                         "expected q of length 2m (normal then tangential) and D 2m x 2m")
    return n // 2


def node_array(value: float | np.ndarray, m: int, name: str) -> np.ndarray:
    """A per-node non-negative finite array from a scalar or an array (ValueError naming it)."""
    arr = np.broadcast_to(np.asarray(value, float), (m,)).copy() if np.ndim(value) == 0 \
        else np.asarray(value, float).ravel()
    if arr.size != m:
        raise ValueError(f"{name} has {arr.size} entries, expected {m} (one per node)")
    if not np.all(np.isfinite(arr)) or np.any(arr < 0):
        raise ValueError(f"{name} must be finite and >= 0, got min {arr.min()!r}")
    return arr


def delassus_scale(D: np.ndarray) -> float:
    """The mean diagonal of ``D`` (1 when it is not finite and > 0): its order of magnitude.

    The physical ``D`` is tiny (m^2 / Pa, ~1e-13); a system or tableau that mixes rows of
    ``D`` with rows of order one (the Coulomb pattern systems, Lemke's tableau) is scaled by
    it, else it looks singular.
    """
    d = float(np.mean(np.diag(D))) if D.size else 1.0
    return d if math.isfinite(d) and d > 0 else 1.0


def scales(D: np.ndarray, q: np.ndarray, x: np.ndarray) -> tuple[float, float]:
    """Displacement and force scales of the relative residuals.

    ``dscale = max|q|``; ``fscale = max(max|x|, dscale / mean diag D)``.
    """
    tiny = np.finfo(float).tiny
    dscale = max(float(np.abs(q).max()) if q.size else 0.0, tiny)
    dm = float(np.mean(np.diag(D))) if q.size else 1.0
    conv = dscale / dm if dm > 0 else dscale
    fscale = max(float(np.abs(x).max()) if x.size else 0.0, conv, tiny)
    return dscale, fscale


def slip(D: np.ndarray, q: np.ndarray, lam_n: np.ndarray, lam_t: np.ndarray) -> np.ndarray:
    """The slip of the load step ``v = -(q_t + D_tn lam_n + D_tt lam_t) = Bt u - ut_prev``."""
    m = lam_n.size
    return -(q[m:] + D[m:] @ np.concatenate([lam_n, lam_t]))


def friction_residuals(D: np.ndarray, q: np.ndarray, lam_n: np.ndarray, lam_t: np.ndarray,
                       s: np.ndarray) -> dict[str, float]:
    """Relative residual of every condition (max over nodes), zero exactly at a solution.

    With ``g = s_n / dscale``, ``v = v / dscale``, forces divided by ``fscale``
    (:func:`scales`): ``non_penetration = max(-g)_+``,
    ``normal_complementarity = max min(|lam_n|, |g|)``, ``stick = max min(|v|, s - |lam_t|)``
    over nodes with ``|lam_t| < s`` (zero iff those nodes do not slip),
    ``slip = max min(|v|, |lam_t - s sign(v)|)`` (zero iff slipping nodes are on the
    bound that opposes the slip), ``cone = max(-lam_n, |lam_t| - s)_+``.
    """
    m = lam_n.size
    x = np.concatenate([lam_n, lam_t])
    dscale, fscale = scales(D, q, x)
    w = q + D @ x
    g, v = w[:m] / dscale, -w[m:] / dscale
    ln, lt, sc = lam_n / fscale, lam_t / fscale, s / fscale
    inner = np.clip(sc - np.abs(lt), 0.0, None)
    out = {
        "non_penetration": np.clip(-g, 0.0, None),
        "normal_complementarity": np.minimum(np.abs(ln), np.abs(g)),
        "stick": np.minimum(np.abs(v), inner),
        "slip": np.minimum(np.abs(v), np.abs(lt - sc * np.sign(v))),
        "cone": np.clip(np.maximum(-ln, np.abs(lt) - sc), 0.0, None),
    }
    res = {k: float(a.max()) if a.size else 0.0 for k, a in out.items()}
    res["max"] = max(res.values()) if res else 0.0
    return res


#: a node of a reconstruction "slips" when its slip exceeds this fraction of the reference
#: slip scale (:func:`law_residuals`)
SLIP_RTOL = 1e-3


def law_residuals(v: np.ndarray, lam_n: np.ndarray, lam_t: np.ndarray, s: np.ndarray,
                  v_scale: float, f_scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Per-node residuals of the friction law for ANY ``(v, lam_n, lam_t)``, e.g. a reduced
    solution reconstructed at the HF nodes (the law of :class:`rbbench.interfaces.FrictionProblem`:
    ``|lam_t| <= s``, ``|lam_t| < s => v = 0``, ``v != 0 => lam_t = s sign(v)``).

    Slips are divided by ``v_scale``, forces by ``f_scale`` (e.g. the HF solution's max
    slip and max ``lam_n``). Returns ``(law, slipping)``:

    * ``law[i] = max(min(|v_i|, |lam_t,i - s_i sign(v_i)|), |lam_t,i| - s_i, -lam_n,i, 0)``,
      zero iff node i satisfies the law (stick or slip opposing ``v``, inside the cone);
    * ``slipping[i] = |lam_t,i - s_i sign(v_i)|`` (forces) at the nodes with
      ``|v_i| > SLIP_RTOL`` (slips), 0 elsewhere: how far a node the reconstruction makes
      slip is from the bound that must oppose its slip.

    For Coulomb ``s = nu_F lam_n`` of the same solution, for Tresca the threshold.
    """
    vs, fs = max(float(v_scale), 1e-300), max(float(f_scale), 1e-300)
    vr = np.asarray(v, float) / vs
    ln, lt, sc = (np.asarray(a, float) / fs for a in (lam_n, lam_t, s))
    off_bound = np.abs(lt - sc * np.sign(vr))
    law = np.maximum.reduce([np.minimum(np.abs(vr), off_bound), np.abs(lt) - sc, -ln,
                             np.zeros_like(vr)])
    slipping = np.where(np.abs(vr) > SLIP_RTOL, off_bound, 0.0)
    return law, slipping


def node_states(lam_n: np.ndarray, lam_t: np.ndarray, s: np.ndarray,
                rtol: float = 1e-9) -> np.ndarray:
    """Per-node state: ``"open"`` (``lam_n = 0``), ``"slip"`` (``|lam_t| = s``), ``"stick"``.

    Equalities are tested to ``rtol`` times the largest multiplier (not ``s``, which may
    be huge).
    """
    scale = max(float(np.abs(np.concatenate([lam_n, lam_t])).max(initial=0.0)),
                np.finfo(float).tiny)
    eps = rtol * scale
    states = np.where(np.abs(lam_t) >= s - eps, "slip", "stick").astype(object)
    states[lam_n <= eps] = "open"
    return states


def finish(D: np.ndarray, q: np.ndarray, x: np.ndarray, s: np.ndarray, iterations: int,
           reason: str, history: list[float], info: dict) -> FrictionResult:
    """Pack a :class:`FrictionResult` with its residuals and node states."""
    m = q.size // 2
    lam_n, lam_t = x[:m].copy(), x[m:].copy()
    if np.all(np.isfinite(x)):
        res = friction_residuals(D, q, lam_n, lam_t, s)
        states = node_states(lam_n, lam_t, s)
    else:
        res = dict.fromkeys((*RESIDUAL_NAMES, "max"), float("nan"))
        states = np.full(m, "nan", dtype=object)
        reason = "nan"
    return FrictionResult(lam_n, lam_t, iterations, reason, res, states, history, info)


def box_bounds(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of ``x = [lam_n; lam_t]`` for Tresca: ``lam_n >= 0``, ``-s <= lam_t <= s``."""
    m = s.size
    return (np.concatenate([np.zeros(m), -s]), np.concatenate([np.full(m, np.inf), s]))


def tresca_bvls(D: np.ndarray, q: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Exact Tresca solution by bounded-variable least squares on the Cholesky factor.

    ``min ||L^T x + L^{-1} q||^2`` over the box (``D = L L^T``) has the minimiser of the
    Tresca QP; like :func:`rbbench.hf.solvers.lcp.nnls_dual`, a singular ``D`` is shifted by
    ``1e-14 trace(D) / 2m``. Used when the active-set iteration cycles.
    """
    n = q.size
    shift = 1e-14 * max(float(np.trace(D)) / max(n, 1), np.finfo(float).tiny)
    L = np.linalg.cholesky(D + shift * np.eye(n))
    rhs = -sla.solve_triangular(L, q, lower=True)
    lb, ub = box_bounds(s)
    fixed = ub - lb <= 0.0  # s = 0: lam_t fixed at 0, BVLS needs lb < ub
    x = np.zeros(n)
    if (~fixed).any():
        Lf = L.T[:, ~fixed]
        x[~fixed] = lsq_linear(Lf, rhs, bounds=(lb[~fixed], ub[~fixed]), method="bvls",
                               tol=1e-15, max_iter=50 * n).x
    return x


def _project(x: np.ndarray, m: int, s: np.ndarray | None, F: np.ndarray | None) -> np.ndarray:
    """Normal projection on R+, then the tangential one on ``[-s, s]`` (``s = F lam_n``)."""
    lam_n = np.maximum(x[:m], 0.0)
    thr = s if s is not None else F * lam_n
    return np.concatenate([lam_n, np.clip(x[m:], -thr, thr)])


def uzawa_friction(D: np.ndarray, q: np.ndarray, s: float | np.ndarray | None = None,
                   F: float | np.ndarray | None = None, lam0: np.ndarray | None = None,
                   omega: float = 1.0, tol: float = 1e-10, max_iter: int = 200_000,
                   stall_window: int = 5000) -> FrictionResult:
    """Benaceur et al.'s Uzawa for friction (slides "HF model" / "Collocation method").

    ``lam_n <- max(0, lam_n - rho w_n)``, then ``lam_t <- clip(lam_t - rho w_t, -s, s)``
    with ``s`` given (Tresca) or ``s = F lam_n`` at the new ``lam_n`` (Coulomb); condensed,
    ``w = q + D x`` is their ``G - B U_{k+1}``. ``rho = omega / lambda_max(D)``:
    projected gradient on the Tresca QP, convergent for ``0 < omega < 2``; no guarantee
    for Coulomb. Stops on the natural residual ``||x - P(x - w / mean diag D)||_inf /
    fscale <= tol``, NaN, growth (``diverged``), ``max_iter`` or no progress over
    ``stall_window`` iterations (``stagnation``). Give exactly one of ``s`` and ``F``.
    """
    m = check_problem(D, q)
    if (s is None) == (F is None):
        raise ValueError("uzawa_friction: give exactly one of s (Tresca) and F (Coulomb)")
    if not 0.0 < omega < 2.0:
        raise ValueError(f"uzawa_friction: omega = {omega!r} must lie in (0, 2)")
    s_arr = None if s is None else node_array(s, m, "s")
    F_arr = None if F is None else node_array(F, m, "F")
    lmax = float(sla.eigvalsh(D, subset_by_index=[2 * m - 1, 2 * m - 1])[0]) if m else 1.0
    rho = omega / lmax if lmax > 0 else 1.0
    c = delassus_scaling(D)
    x = np.zeros(2 * m) if lam0 is None else _project(np.asarray(lam0, float), m, s_arr, F_arr)
    history: list[float] = []
    best, best_it, it, reason = math.inf, 0, 0, "max_iterations"
    dscale = scales(D, q, x)[0]
    for it in range(1, max_iter + 1):
        w = q + D @ x
        fscale = scales(D, q, x)[1]
        res = float(np.abs(x - _project(x - c * w, m, s_arr, F_arr)).max(initial=0.0)) / fscale
        if it == 1 or it % 50 == 0:
            history.append(res)
        if not np.isfinite(res):
            reason = "nan"
            break
        if res <= tol:
            history.append(res)
            reason = "converged"
            break
        if fscale > 1e12 * max(c * dscale, np.finfo(float).tiny):
            reason = "diverged"
            break
        if res < best * (1 - 1e-12):
            best, best_it = res, it
        elif it - best_it > stall_window:
            reason = "stagnation"
            break
        x = _project(x - rho * w, m, s_arr, F_arr)
    thr = s_arr if s_arr is not None else F_arr * x[:m]
    return finish(D, q, x, thr, it, reason, history, {"rho": rho})


from rbbench._compat import deprecated_names  # noqa: E402 - after the module's own names

__getattr__ = deprecated_names(__name__)  # renamed names (rbbench._compat)

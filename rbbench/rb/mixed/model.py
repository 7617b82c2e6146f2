"""The reduced model: small dense arrays only, picklable, timed alone.

Reduced problem (Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods:
parametric variational inequalities" (talk), slide "Decorrelated model reduction", step 3):
with a
primal basis Z (n x N) and a dual cone W_R^+ = Span+(Vg) (Vg: m x R),
``u_N = Z c`` and ``lam_R = Vg alpha``, ``alpha >= 0``::

    A_N c + B_N^T alpha = F_N,   alpha >= 0,   B_N c <= G_N,   alpha . (G_N - B_N c) = 0

with ``A_N = Z^T A Z``, ``B_N = Vg^T B Z``, ``F_N = Z^T F``, ``G_N = Vg^T G``.
``A_N`` and ``F_N`` are :class:`AffineOperator` ``sum_k theta_k(mu) M_k`` with
a picklable coefficient map; the constraint pair ``(B_N, G_N)`` is either
affine too (:class:`AffineConstraint`) or hyper-reduced by DEIM on the
contact rows (:class:`rbbench.rb.hyper.contact_eim.ContactEIM`). Online,
``c = A_N^{-1}(F_N - B_N^T alpha)`` condenses the problem to an R x R LCP
solved by the primal-dual active set of :mod:`rbbench.hf.solvers.lcp` (warm-startable),
or the primal QP is handed to the compiled solver daqp (the default online).
Nothing here depends on the HF size.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg as sla

from rbbench.hf.condensation.dense import delassus_scaling
from rbbench.hf.solvers import lcp
from rbbench.interfaces import HFVectors
from rbbench.rb.algorithms.affine import (
    AffineOperator,
    NotAffineError,
    affine_decomposition,
    coefficient_map,
)
from rbbench.rb.algorithms.saddle import condense_dense
from rbbench.rb.mixed.options import ONLINE_METHODS
from rbbench.rb.online import ONLINE_PATHS, ReducedBasis, require_basis
from rbbench.scene.parameters import ParameterSpace


@dataclass
class OnlineResult:
    """One online solve (a :class:`rbbench.interfaces.Solution`: ``u`` the primal
    coordinates ``c``, ``lam`` the cone coefficients ``alpha``), its stop reason and time."""

    c: np.ndarray  # primal coordinates (N,)
    alpha: np.ndarray  # cone coefficients (R,) >= 0
    iterations: int
    stop_reason: str
    time_s: float
    #: daqp: the smallest multiplier it returned, before the clip at 0, relative to the
    #: largest (round-off only: tests assert it is >= -1e-10); pdas: min(alpha) / max
    alpha_raw_min: float = 0.0
    #: which online path ran: "python" (the reference) or "compiled"
    #: (:mod:`rbbench.rb.mixed.compiled`)
    path: str = "python"
    #: the online method that ran (``auto`` resolved: :meth:`ReducedModel.resolve_method`)
    method: str = ""
    #: the parameter of the solve (as checked against D)
    mu: np.ndarray | None = None
    #: a model without hyper-reduction: the time of the HF assembly and projection at mu
    #: (s), included in ``time_s``
    assembly_s: float = 0.0

    @property
    def u(self) -> np.ndarray:
        return self.c

    @property
    def lam(self) -> np.ndarray:
        return self.alpha

    @property
    def converged(self) -> bool:
        return self.stop_reason.startswith("converged")




def _solve_daqp(A: np.ndarray, F: np.ndarray, B: np.ndarray,
                G: np.ndarray) -> tuple[np.ndarray, np.ndarray, int] | None:
    """The reduced problem as the QP ``min 1/2 c^T A c - F^T c, B c <= G`` by daqp.

    daqp (Arnstrom et al. 2022, a compiled dual active-set solver) uses absolute
    feasibility tolerances, so rows of B are scaled to unit norm and the load
    to unit norm first (contact rows are O(1e-6) against loads O(1e5) on Hertz);
    the tolerances are then tight (1e-12). ``alpha`` = the constraint multipliers
    (>= 0). Returns None unless daqp reports optimality with finite numbers.
    """
    import daqp

    rows = np.linalg.norm(B, axis=1)
    rows[rows == 0.0] = 1.0
    fs = float(np.linalg.norm(F)) or 1.0
    m = G.size
    y, _, flag, info = daqp.solve(np.ascontiguousarray(A), -F / fs,
                                  np.ascontiguousarray(B / rows[:, None]), G / rows / fs,
                                  np.full(m, -1e30), np.zeros(m, dtype=np.int32),
                                  primal_tol=1e-12, dual_tol=1e-12)
    if int(flag) != 1:
        return None
    c = np.asarray(y, dtype=float) * fs
    raw = np.asarray(info["lam"], dtype=float) * fs / rows
    alpha = np.maximum(raw, 0.0)
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(alpha))):
        return None
    return c, alpha, int(info["iterations"]), _rel_min(raw)


def _rel_min(a: np.ndarray) -> float:
    """``min(a) / max|a|`` (0 for an empty or zero ``a``)."""
    top = float(np.abs(a).max()) if a.size else 0.0
    return float(a.min()) / top if top > 0 else 0.0


def _nnls_scaled(D: np.ndarray, q: np.ndarray, tol: float = 1e-10) -> np.ndarray | None:
    """LCP(q, D) by :func:`rbbench.hf.solvers.lcp.nnls_dual` on ``D / max diag D``, ``q / max|q|``
    (the scaling of the compiled kernel, :func:`rbbench.rb.mixed.dual_kernels.online_nnls`);
    None when it fails or its natural residual exceeds ``tol``."""
    dm = float(np.diag(D).max()) if q.size else 0.0
    qm = float(np.abs(q).max()) if q.size else 0.0
    if qm == 0.0:
        return np.zeros(q.size)
    if not dm > 0.0:
        return None
    try:
        x = lcp.nnls_dual(D / dm, q / qm)
    except (np.linalg.LinAlgError, RuntimeError):
        return None
    if not lcp.natural_residual(D / dm, q / qm, x, delassus_scaling(D / dm)) <= tol:
        return None
    return x * (qm / dm)


def solve_reduced(A: np.ndarray, F: np.ndarray, B: np.ndarray, G: np.ndarray,
                  warm_start: np.ndarray | None = None, max_iter: int = 100,
                  cho: tuple | None = None, method: str = "pdas") -> OnlineResult:
    """Solve the reduced saddle point.

    ``method = "nnls"``: dense Cholesky of A_N, the R x R LCP by Lawson-Hanson's NNLS
    (:func:`rbbench.hf.solvers.lcp.nnls_dual`; ``iterations`` is not counted there: 0).
    ``method = "pdas"``: dense Cholesky of A_N, R x R LCP by the primal-dual
    active set of :mod:`rbbench.hf.solvers.lcp` (warm-startable; ``cho``: a Cholesky factor
    of ``A`` computed once when A_N is independent of mu). ``method = "daqp"``:
    the primal QP by :func:`_solve_daqp` (measured 16x faster at N + K = 60,
    R = 30 and equal to 1e-12), falling back to PDAS if daqp does not report
    optimality (the result's ``stop_reason`` then says ``converged (pdas
    fallback)``).
    """
    if method not in ONLINE_METHODS:
        raise ValueError(f"online method {method!r}: valid: {', '.join(ONLINE_METHODS)}")
    if method == "auto":  # the faster of the two on the Python path (measured 77 / 185 us
        method = "daqp"   # on the membrane model: condense + scipy NNLS cost more here)
    t0 = time.perf_counter()
    if method in ("nnls", "daqp"):
        if method == "nnls":
            c0, AinvBt, D, q = condense_dense(A, F, B, G, cho)
            alpha = _nnls_scaled(D, q)
            out = None if alpha is None else (c0 - AinvBt @ alpha, alpha, 0, _rel_min(alpha))
        else:
            out = _solve_daqp(A, F, B, G)
        if out is not None:
            return OnlineResult(out[0], out[1], out[2], "converged",
                                time.perf_counter() - t0, out[3])
        res = solve_reduced(A, F, B, G, warm_start, max_iter, cho, "pdas")
        res.stop_reason += " (pdas fallback)" if res.stop_reason == "converged" else ""
        res.time_s = time.perf_counter() - t0
        return res
    c0, AinvBt, D, q = condense_dense(A, F, B, G, cho)
    alpha, it, reason, _, _ = lcp.pdas(D, q, warm_start, max_iter=max_iter)
    c = c0 - AinvBt @ alpha
    return OnlineResult(c, alpha, it, reason, time.perf_counter() - t0, _rel_min(alpha))


@dataclass
class AffineConstraint:
    """Reduced constraint ``(B_N(mu), G_N(mu))`` from affine terms and a coefficient map."""

    B: AffineOperator  # (K, R, N)
    G: AffineOperator  # (K, R)
    coefficients: Callable[[np.ndarray], np.ndarray]

    def __call__(self, mu: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        th = self.coefficients(mu)
        return self.B(th), self.G(th)

    @property
    def R(self) -> int:
        return int(self.B.terms.shape[1])


@dataclass
class ReducedModel:
    """Small dense arrays and picklable maps: ``solve(mu)`` never touches HF data.

    Attributes
    ----------
    A, F : AffineOperator
        Reduced stiffness (N x N) and load (N).
    coefficients : callable
        ``theta(mu)`` for A and F, picklable (e.g. :class:`LinearInMu`).
    constraint : callable
        ``mu -> (B_N (R x N), G_N (R,))``: :class:`AffineConstraint` (exact affine)
        or a hyper-reduced evaluator (:class:`rbbench.rb.hyper.contact_eim.ContactEIM`).
    is_cone : bool
        True when the dual space is a cone (alpha >= 0 is the right constraint).
    info : dict
        Sizes and provenance (compressor names, tolerances).
    parameters : ParameterSpace or None
        The domain D that :meth:`solve` checks mu against (set by the offline skeleton).
    online_method : str
        The online method :meth:`solve` uses by default
        (:data:`rbbench.rb.mixed.options.ONLINE_METHODS`).
    basis : ReducedBasis or None
        ``Z`` and the cone generators ``V`` (HF size), for :meth:`reconstruct` only.
    bound : MixedBound or None
        The online error bound (:mod:`rbbench.rb.mixed.bounds`), where the offline stage
        could build it: :meth:`error_bound`.
    """

    A: AffineOperator
    F: AffineOperator
    coefficients: Callable[[np.ndarray], np.ndarray]
    constraint: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
    is_cone: bool = True
    info: dict = field(default_factory=dict)
    parameters: ParameterSpace | None = None
    online_method: str = "auto"
    basis: ReducedBasis | None = None
    bound: Any = None

    def __post_init__(self) -> None:
        # A_N independent of mu (e.g. a dilation, which leaves 2D stiffness invariant):
        # factorise it once. The test is on the decomposition's own terms.
        t = self.A.terms
        scale = np.abs(t[0]).max() if t.size else 0.0
        const = t.shape[0] == 1 or np.abs(t[1:]).max() <= 1e-12 * scale
        self._cho = sla.cho_factor(t[0]) if const and scale > 0 else None

    @property
    def N(self) -> int:
        return int(self.A.terms.shape[-1])

    @property
    def R(self) -> int:
        return int(self.constraint.R)

    def arrays(self, mu: np.ndarray) -> tuple[np.ndarray, ...]:
        th = self.coefficients(mu)
        B, G = self.constraint(mu)
        return self.A(th), self.F(th), B, G

    def solve(self, mu: np.ndarray, warm_start: np.ndarray | None = None,
              max_iter: int = 100, method: str | None = None, path: str = "auto"
              ) -> OnlineResult:
        """Online solve: check mu against D (:attr:`parameters`, a
        :class:`~rbbench.scene.parameters.SceneError` outside it, as the HF solve), assemble
        the reduced arrays, then :func:`solve_reduced` with ``method`` (default:
        :attr:`online_method`).

        ``path``: ``"python"`` (the reference), ``"compiled"`` (:mod:`rbbench.rb.mixed.compiled`,
        a RuntimeError saying why when it is unavailable) or ``"auto"`` (compiled where
        available: :meth:`online_path`). The compiled kernels are prepared on the first
        call, outside the timed solve (``compiled.COMPILE`` has that time); they test mu
        against D themselves and leave a parameter outside it to the Python path's error.
        """
        requested = self.online_method if method is None else method
        method = self.resolve_method(requested, path)
        fast = self._compiled(method, path)
        t0 = time.perf_counter()
        if fast is not None:
            out = fast.solve(mu)
            reason = "converged"
            if out is None and requested == "auto":  # e.g. a dependent row of a singular D
                fast = self._compiled("daqp", path)
                out = fast.solve(mu) if fast is not None else None
                method, reason = "daqp", "converged (daqp fallback)"
            if out is not None:
                return OnlineResult(out[0], out[1], out[2], reason,
                                    time.perf_counter() - t0, out[3], "compiled", method, mu)
        if self.parameters is not None:
            mu = self.parameters.check(mu)
        res = solve_reduced(*self.arrays(mu), warm_start=warm_start, max_iter=max_iter,
                            cho=self._cho, method=method)
        res.time_s = time.perf_counter() - t0
        res.method, res.mu = method, mu
        return res

    def error_bound(self, solution: OnlineResult) -> Any:
        """The certified bound of ``||u(mu) - Z c||_X`` (and of the multiplier error) of an
        online ``solution`` (:class:`rbbench.rb.algorithms.bounds.VIBound`); a RuntimeError
        when this model has none (:attr:`bound`)."""
        if self.bound is None:
            raise RuntimeError("this reduced model has no online error bound (its offline "
                               "stage says why: result.json histories.bound)")
        return self.bound(solution.mu, solution.c, solution.alpha)

    def reconstruct(self, solution: OnlineResult) -> HFVectors:
        """``Z c`` on the free dofs and ``V alpha`` in the HF multiplier space."""
        return require_basis(self).vectors(solution.c, solution.alpha)

    def resolve_method(self, method: str = "auto", path: str = "auto") -> str:
        """``auto``: ``nnls`` where its compiled path is available, otherwise ``daqp`` (the
        faster on the Python path). A compiled ``nnls`` that fails (a dependent row when
        ``D = B_N A_N^-1 B_N^T`` is singular, e.g. ``R > N``) is retried by the compiled
        daqp (:meth:`solve`). Any other method is returned as it is."""
        if method != "auto":
            return method
        if path != "python" and self._compiled("nnls", "auto"):
            return "nnls"
        return "daqp"

    def online_path(self, method: str = "auto") -> str:
        """The path :meth:`solve` takes with ``path = "auto"``: ``"compiled (numba X)"`` or
        ``"python (<why>)"``."""
        from rbbench.rb.mixed import compiled as compiled_online

        method = self.resolve_method(method)
        fast = self._compiled(method, "auto")
        if fast is not None:
            return f"compiled (numba {compiled_online.NUMBA_VERSION})"
        return f"python ({self._online_state[method]})"

    def pairing_table_share(self, method: str = "auto") -> float | None:
        """Share of the magic rows' slave points that the compiled 3D pairing finds through
        its table (:meth:`rbbench.rb.mixed.compiled.CompiledOnline.pairing_table_share`);
        None on the Python path or without triangulated contact surfaces."""
        fast = self._compiled(self.resolve_method(method), "auto")
        return None if fast is None else fast.pairing_table_share()

    def _compiled(self, method: str, path: str):
        """The prepared compiled solve for ``method``, or None (the Python path)."""
        if path not in ONLINE_PATHS:
            raise ValueError(f"online path {path!r}: valid: {', '.join(ONLINE_PATHS)}")
        if path == "python":
            return None
        state = self.__dict__.setdefault("_online_state", {})
        if method not in state:
            from rbbench.rb.mixed.compiled import prepare

            state[method] = prepare(self, method)
        if isinstance(state[method], str):
            if path == "compiled":
                raise RuntimeError(f"compiled online path unavailable: {state[method]}")
            return None
        return state[method]

    def __getstate__(self) -> dict:
        """Pickle without the compiled solve (buffers and daqp views: rebuilt on use)."""
        state = dict(self.__dict__)
        state.pop("_online_state", None)
        return state


def build_affine_model(reduced_operators: Callable[[np.ndarray], tuple], bounds: np.ndarray,
                       is_cone: bool = True, rtol: float = 1e-10, info: dict | None = None,
                       constraint: Callable | None = None, max_degree: int = 1
                       ) -> ReducedModel:
    """Reduced model with the exact affine decomposition in mu ("exact-affine" hyper-reducer).

    ``reduced_operators(mu)`` returns the projected ``(A_N, F_N, B_N, G_N)`` at
    mu (one HF assembly each); each is decomposed by
    :func:`affine_decomposition`, which raises :class:`NotAffineError` when the
    scene has no affine decomposition (then EIM is needed). With a given
    ``constraint`` (a hyper-reduced ``mu -> (B_N, G_N)``), only A and F are
    decomposed. ``max_degree > 1`` (one parameter): else the lowest polynomial degree
    in mu that decomposes them all (:class:`PolynomialInMu`; a 3D similarity map is cubic).
    """
    cache: dict[bytes, tuple] = {}

    def at(mu):
        key = np.asarray(mu, dtype=float).tobytes()
        if key not in cache:
            cache[key] = tuple(np.asarray(x, dtype=float) for x in reduced_operators(mu))
        return cache[key]

    names = ("A", "F", "B", "G") if constraint is None else ("A", "F")
    p = np.asarray(bounds).shape[0]
    for degree in range(1, (max_degree if p == 1 else 1) + 1):  # the lowest that decomposes
        try:
            ops = {}
            for k, name in enumerate(names):
                ops[name] = AffineOperator(affine_decomposition(
                    lambda mu, k=k: at(mu)[k], bounds, rtol=rtol, degree=degree))
            break
        except NotAffineError as exc:
            if degree == 1:
                first = f"reduced {name}(mu) is {exc}"
            if degree == (max_degree if p == 1 else 1):
                raise NotAffineError(first + (f" (nor polynomial in mu of degree <= "
                                              f"{max_degree})" if degree > 1 else "")
                                     ) from None
    theta = coefficient_map(p, degree)
    if constraint is None:
        constraint = AffineConstraint(ops.pop("B"), ops.pop("G"), theta)
    return ReducedModel(coefficients=theta, constraint=constraint, is_cone=is_cone,
                        info={**(info or {}), "affine_degree": degree}, **ops)


def projector(problem_at: Callable[[np.ndarray], object], Z: np.ndarray, Vg: np.ndarray
              ) -> Callable[[np.ndarray], tuple]:
    """``mu -> (Z^T A Z, Z^T F, Vg^T B Z, Vg^T G)`` from a ContactProblem factory."""

    def reduced_operators(mu):
        p = problem_at(mu)
        return Z.T @ (p.A @ Z), Z.T @ p.F, Vg.T @ (p.B @ Z), Vg.T @ p.G

    return reduced_operators

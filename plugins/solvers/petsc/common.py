"""What the PETSc solvers share (:mod:`rbbench_plugins.solvers.petsc`): the lazy,
argument-free PETSc initialisation, the mapping of PETSc's converged reasons, the KKT check,
options under a prefix of their own, and the :class:`_PetscSolver` base class.

The underscore names are internals of the PETSc solver modules
(:mod:`rbbench_plugins.solvers.petsc.vi`, :mod:`rbbench_plugins.solvers.petsc.tao`).
"""

from __future__ import annotations

import itertools
import sys
import time
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp

from rbbench.hf.algebra import friction as fa
from rbbench.interfaces import ContactProblem, FrictionProblem, Solver, SolveResult

__all__ = ["kkt_errors", "map_reason", "petsc"]

_PETSC: Any = None
_COUNTER = itertools.count()
_TINY = np.finfo(float).tiny
_SUBNORMAL = float(np.nextafter(0.0, 1.0))  # the smallest positive float


class TrescaSetup(NamedTuple):
    """The start of a PETSc Tresca solve (``_tresca_setup`` of the PETSc solver base)."""

    PETSc: Any
    t0: float
    s: np.ndarray  # threshold per node
    qp: tuple  # scaled_qp(D, q): (c, Ds, sigma, qs, qnorm)
    k: float  # c sigma: x = k mu
    bounds: tuple[np.ndarray, np.ndarray]  # of mu
    x0: np.ndarray  # start, in mu


def petsc() -> Any:
    """The ``petsc4py.PETSc`` module, initialised once without command-line arguments.

    Returns
    -------
    module
        ``petsc4py.PETSc``.

    Raises
    ------
    ImportError
        When petsc4py is not installed (hint: ``pip install "rbbench[petsc]"``).
    """
    global _PETSC
    if _PETSC is None:
        try:
            import petsc4py
        except ImportError as exc:  # pragma: no cover - the registry checks first
            raise ImportError(f"{exc}; install it with: pip install \"rbbench[petsc]\"") from exc
        if "petsc4py.PETSc" not in sys.modules:  # else someone initialised PETSc already
            petsc4py.init([])
        from petsc4py import PETSc

        _PETSC = PETSc
    return _PETSC


# ---------------------------------------------------------------------------
# shared helpers
# ---------------------------------------------------------------------------
def _reason_name(enum: Any, code: int) -> str:
    """Name of a PETSc converged-reason code (``"CONVERGED_FNORM_RELATIVE"``, ...)."""
    names = [k for k, v in vars(enum).items() if k.isupper() and v == code]
    names.sort(key=lambda k: (k in ("ITERATING", "CONTINUE_ITERATING"), len(k)))
    return names[0] if names else f"UNKNOWN_{code}"


def map_reason(name: str) -> str:
    """Map a PETSc SNES / TAO converged-reason name to one of :data:`STOP_REASONS`.

    Parameters
    ----------
    name : str
        Reason name without the ``SNES_`` / ``TAO_`` prefix, e.g.
        ``"CONVERGED_FNORM_RELATIVE"``, ``"DIVERGED_MAX_IT"``.

    Returns
    -------
    str
        ``"converged"`` for PETSc's converged reasons except those below;
        ``"max_iterations"`` for iteration or function-evaluation limits
        (and SNES ``CONVERGED_ITS``, which only means "ran ``max_it`` steps");
        ``"nan"`` for NaN / Inf; ``"stagnation"`` for line-search, trust-region
        and local-minimum failures and for TAO ``CONVERGED_STEPTOL`` (the step
        vanished, optimality not shown); ``"diverged"`` otherwise, including TAO
        ``CONVERGED_MINF`` (objective unbounded below: the dual is unbounded,
        the contact problem infeasible) and a reason of "still iterating".
    """
    if name in ("CONVERGED_ITS", "DIVERGED_MAX_IT", "DIVERGED_MAXITS", "DIVERGED_MAXFCN",
                "DIVERGED_FUNCTION_COUNT"):
        return "max_iterations"
    if "NAN" in name:
        return "nan"
    if name in ("DIVERGED_LINE_SEARCH", "DIVERGED_LOCAL_MIN", "DIVERGED_TR_DELTA",
                "DIVERGED_LS_FAILURE", "DIVERGED_TR_REDUCTION", "CONVERGED_STEPTOL"):
        return "stagnation"
    if name.startswith("CONVERGED_") and name not in ("CONVERGED_ITERATING", "CONVERGED_MINF"):
        return "converged"
    return "diverged"


def kkt_errors(problem: ContactProblem, u: np.ndarray, lam: np.ndarray) -> dict[str, float]:
    """Relative violations of the KKT conditions at ``(u, lam)`` (free-dof ``u``).

    Parameters
    ----------
    problem : ContactProblem
    u : (n_free,) ndarray
    lam : (m,) ndarray

    Returns
    -------
    dict
        ``equilibrium = ||A u + B^T lam - F|| / max(||F||, ||A u||, ||B^T lam||)``,
        ``dual = max(0, -min lam) / max|lam|``,
        ``primal = max(0, max(B u - G)) / (max|G| + max|B u|)``,
        ``complementarity = |lam . (G - B u)| / (||lam|| (||G|| + ||B u||))``,
        and ``max``, the largest of them (NaN if any input is not finite).
    """
    A, B, F, G = problem.A, problem.B, problem.F, problem.G
    with np.errstate(all="ignore"):  # a diverged iterate may overflow: NaN / inf is fine
        Au, Btl, Bu = A @ u, B.T @ lam, B @ u
        s = G - Bu
        eq = np.linalg.norm(Au + Btl - F) / max(np.linalg.norm(F), np.linalg.norm(Au),
                                                np.linalg.norm(Btl), _TINY)
        lmax = np.abs(lam).max(initial=0.0)
        dual = max(0.0, -lam.min(initial=0.0)) / max(lmax, _TINY)
        primal = max(0.0, -s.min(initial=0.0)) / max(np.abs(G).max(initial=0.0)
                                                     + np.abs(Bu).max(initial=0.0), _TINY)
        comp = abs(float(lam @ s)) / max(np.linalg.norm(lam) * (np.linalg.norm(G)
                                                                + np.linalg.norm(Bu)), _TINY)
    out = {"equilibrium": float(eq), "dual": float(dual), "primal": float(primal),
           "complementarity": float(comp)}
    vals = list(out.values())
    out["max"] = float(max(vals)) if np.all(np.isfinite(vals)) else float("nan")
    return out


def _finite_problem(problem: ContactProblem, warm_start: np.ndarray | None) -> bool:
    parts = [problem.A.data, problem.F, problem.B.data, problem.G]
    if warm_start is not None:
        parts.append(np.asarray(warm_start, dtype=float))
    return all(np.all(np.isfinite(p)) for p in parts)


def _nan_result(problem: ContactProblem, why: str) -> SolveResult:
    u = problem.u_lift.copy()
    u[problem.free] = np.nan
    return SolveResult(u=u, lam=np.full(problem.B.shape[0], np.nan), iterations=0,
                       stop_reason="nan", residuals=[float("nan")],
                       info={"petsc_reason": "not run", "why": why})


def _check_warm(warm_start: np.ndarray | None, m: int) -> np.ndarray | None:
    if warm_start is None:
        return None
    lam0 = np.asarray(warm_start, dtype=float).ravel()
    if lam0.shape != (m,):
        raise ValueError(f"warm start has shape {lam0.shape}, expected ({m},)")
    return np.maximum(lam0, 0.0)


def _finish(reason: str, errors: dict[str, float], kkt_tol: float,
            info: dict[str, Any]) -> str:
    """Demote a PETSc "converged" whose KKT check fails (never a false convergence)."""
    info["kkt_errors"] = errors
    if reason == "converged" and not errors["max"] <= kkt_tol:
        info["why"] = (f"PETSc reported {info['petsc_reason']} but the KKT error "
                       f"{errors['max']:.3e} exceeds kkt_tol = {kkt_tol:g}")
        return "stagnation"
    return reason


class _Options:
    """Options-database entries under one prefix, set for one solve and then removed."""

    def __init__(self, prefix: str, options: dict[str, Any]):
        self.prefix, self.options = prefix, options

    def __enter__(self) -> _Options:
        db = petsc().Options(self.prefix)
        for key, value in self.options.items():
            db.setValue(key, value)
        return self

    def __exit__(self, *exc: Any) -> None:
        db = petsc().Options(self.prefix)
        for key in self.options:
            db.delValue(key)


def _petsc_options(options: dict[str, Any] | None) -> dict[str, Any]:
    out = {}
    for key, value in dict(options or {}).items():
        key = str(key).lstrip("-")
        out[key] = "" if value is None else value
    return out


def _unknown(cls: str, unknown: dict[str, Any], valid: tuple[str, ...]) -> None:
    if unknown:
        raise TypeError(f"{cls}: unknown option(s) {sorted(unknown)}; "
                        f"valid options: {', '.join(valid)}")


def _choice(cls: str, what: str, value: str, valid: tuple[str, ...]) -> str:
    if value not in valid:
        raise ValueError(f"{cls}: {what} = {value!r} is not one of {valid}")
    return value


def _aij(PETSc: Any, M: sp.csr_matrix) -> Any:
    M = sp.csr_matrix(M)
    M.sort_indices()
    return PETSc.Mat().createAIJ(size=M.shape, comm=PETSc.COMM_SELF,
                                 csr=(M.indptr.astype(PETSc.IntType),
                                      M.indices.astype(PETSc.IntType),
                                      M.data.astype(PETSc.ScalarType)))


def scaled_qp(D: np.ndarray, q: np.ndarray) -> tuple[float, np.ndarray, float, np.ndarray,
                                                      float]:
    """``(c, c D, sigma, q / sigma, ||q / sigma||)``: the QP ``1/2 x^T D x + q^T x`` in the
    scaled unknowns ``mu = x / (c sigma)``, ``c = 1 / mean(diag D)``, ``sigma = max|q|``.

    Its gradient is ``(D x + q) / sigma``: unit-mean Hessian diagonal, unit data (TAO's
    trust region and SNES VI's "at the bound" test use absolute numbers).
    """
    d = np.diag(D)
    c = 1.0 / float(np.mean(d)) if d.size and np.mean(d) > 0 else 1.0
    Ds = np.ascontiguousarray(c * D)
    sigma = float(np.abs(q).max(initial=0.0))
    sigma = sigma if sigma > 0 else 1.0
    qs = q / sigma
    return c, Ds, sigma, qs, max(float(np.linalg.norm(qs)), _TINY)


def _vec(PETSc: Any, values: np.ndarray) -> Any:
    v = PETSc.Vec().createSeq(len(values), comm=PETSc.COMM_SELF)
    v.setArray(np.asarray(values, dtype=PETSc.ScalarType))
    return v


class _PetscSolver(Solver):
    """What the PETSc solvers share: the option check, ``kkt_tol``, ``petsc_options`` under
    a prefix of their own (``rbbench_<stem><k>_``), the timed run, and its stop reason."""

    OPTIONS: tuple[str, ...] = ()
    _stem = ""

    def __init__(self, kkt_tol: float, petsc_options: dict[str, Any] | None,
                 unknown: dict[str, Any]):
        _unknown(type(self).__name__, unknown, self.OPTIONS)
        self.kkt_tol = float(kkt_tol)
        self.petsc_options = _petsc_options(petsc_options)
        self.prefix = f"rbbench_{self._stem}{next(_COUNTER)}_"

    def _stop_reason(self, code: int | None, finite: bool, problem: ContactProblem,
                     u: np.ndarray, lam: np.ndarray, info: dict[str, Any]) -> str:
        """``"diverged"`` after a PETSc error (``code = None``), ``"nan"`` for a non-finite
        result, else PETSc's reason (:func:`map_reason`); checked by :func:`_finish`."""
        if code is None:
            reason = "diverged"
        elif not finite:
            reason = "nan"
        else:
            reason = map_reason(info["petsc_reason"])
        return _finish(reason, kkt_errors(problem, u, lam), self.kkt_tol, info)

    def _run(self, obj: Any, solve: Callable[[], Any], t0: float,
             defaults: dict[str, Any] | None = None) -> tuple[float, float]:
        """``obj.setFromOptions()`` with ``defaults`` and :attr:`petsc_options` (which win)
        set under :attr:`prefix` (for this run only), then ``solve()``: ``(seconds since t0
        to the solve, solve seconds)``."""
        with _Options(self.prefix, {**(defaults or {}), **self.petsc_options}):
            obj.setFromOptions()
            t_setup = time.perf_counter() - t0
            ts = time.perf_counter()
            solve()
            return t_setup, time.perf_counter() - ts

    def tresca(self, D: np.ndarray, q: np.ndarray, s: float | np.ndarray,
               lam0: np.ndarray | None = None) -> fa.FrictionResult:
        """The condensed Tresca problem (box QP of :mod:`rbbench.hf.algebra.friction`)."""
        raise NotImplementedError  # pragma: no cover - each PETSc solver defines it

    def solve_friction(self, problem: FrictionProblem,
                       warm_start: np.ndarray | None = None) -> SolveResult:
        """A :class:`FrictionProblem` over its load steps
        (:func:`rbbench_plugins.solvers.friction.solve_steps`): Tresca by :meth:`tresca`,
        Coulomb by the fixed point on it (``s = nu_F lam_n`` of the previous iterate), model B
        by the fixed point on the coefficient around that
        (:func:`~rbbench_plugins.solvers.friction.tresca_runner`)."""
        from rbbench_plugins.solvers.friction import solve_steps, tresca_runner

        return solve_steps(problem, tresca_runner(problem, self.tresca), warm_start)

    @staticmethod
    def _tresca_setup(D: np.ndarray, q: np.ndarray, s: float | np.ndarray,
                      lam0: np.ndarray | None) -> tuple[TrescaSetup | None,
                                                       fa.FrictionResult | None]:
        """What both PETSc Tresca solves start from: the checked data, the scaled QP
        (:func:`scaled_qp`), its box ``[0, inf) x [-s, s] / (c sigma)`` and the clipped start;
        ``(None, result)`` with the ``"nan"`` result on non-finite data."""
        m = fa.check_problem(D, q)
        s = fa.node_array(s, m, "s")
        data = [D, q] if lam0 is None else [D, q, np.asarray(lam0, float)]
        if not all(np.all(np.isfinite(a)) for a in data):
            return None, fa.finish(D, q, np.full(2 * m, np.nan), s, 0, "nan", [],
                                   {"petsc_reason": "not run", "why": "non-finite data"})
        PETSc, t0 = petsc(), time.perf_counter()
        qp = scaled_qp(D, q)
        k = qp[0] * qp[2]
        lo, hi = (np.clip(b / k, PETSc.NINFINITY, PETSc.INFINITY) for b in fa.box_bounds(s))
        x0 = np.zeros(2 * m) if lam0 is None else np.clip(lam0 / k, lo, hi)
        return TrescaSetup(PETSc, t0, s, qp, k, (lo, hi), x0), None

    def _tresca_result(self, D: np.ndarray, q: np.ndarray, x: np.ndarray, s: np.ndarray,
                       code: int | None, its: int, history: list[float],
                       info: dict[str, Any]) -> fa.FrictionResult:
        """Pack a PETSc Tresca run (:func:`rbbench.hf.algebra.friction.finish`): the stop
        reason as in :meth:`_stop_reason`, a "converged" whose largest friction residual
        exceeds :attr:`kkt_tol` demoted to ``"stagnation"``."""
        finite = bool(np.all(np.isfinite(x)))
        reason = "diverged" if code is None else "nan" if not finite \
            else map_reason(info["petsc_reason"])
        r = fa.finish(D, q, x, s, its, reason, history, info)
        if r.stop_reason == "converged" and not r.residuals["max"] <= self.kkt_tol:
            r.stop_reason = "stagnation"
            info["why"] = (f"PETSc reported {info['petsc_reason']} but the friction residual "
                           f"{r.residuals['max']:.3e} exceeds kkt_tol = {self.kkt_tol:g}")
        return r

    @staticmethod
    def _failed(exc: Exception, t0: float, info: dict[str, Any]) -> tuple[float, float]:
        """A PETSc error during the run: its reason in ``info``; ``(seconds since t0, 0)``."""
        t_setup = time.perf_counter() - t0
        info["petsc_reason"] = "PETSc.Error"
        info["why"] = f"PETSc error {exc}"
        return t_setup, 0.0

"""PETSc solvers for the mixed contact problem: SNES VI on the KKT system, TAO on the dual.

The problem (seed 000, "Mixed formulation"; :class:`rbbench.interfaces.ContactProblem`)::

    A u + B^T lam = F,  lam >= 0,  G - B u >= 0,  lam . (G - B u) = 0.

* :class:`PetscVISolver` writes it as a mixed complementarity problem in
  ``x = (u, lam)`` and solves it with a PETSc SNES variational-inequality
  Newton method (``vinewtonrsls``, reduced-space active set, by default).
* :class:`PetscTaoSolver` condenses it on the contact unknowns with
  :func:`rbbench.hf.lcp.condense` and solves the bound-constrained dual QP
  ``min_{lam >= 0} 1/2 lam^T D lam + q^T lam`` with PETSc TAO (``tron``).

``petsc4py`` is imported only here, on first use, and PETSc is initialised
once without reading ``sys.argv``. Every PETSc object gets its own options
prefix (``rbbench_<solver><k>_``); options passed through ``petsc_options``
are written under that prefix for one solve and removed afterwards, so
instances never see each other's options.
"""

from __future__ import annotations

import itertools
import sys
import time
from typing import Any

import numpy as np
import scipy.sparse as sp

from rbbench.hf import lcp
from rbbench.interfaces import ContactProblem, Solver, SolveResult

__all__ = ["PetscTaoSolver", "PetscVISolver", "petsc"]

_PETSC: Any = None
_COUNTER = itertools.count()
_TINY = np.finfo(float).tiny
_SUBNORMAL = float(np.nextafter(0.0, 1.0))  # the smallest positive float

#: SNES VI types offered by :class:`PetscVISolver`.
SNES_TYPES = ("vinewtonrsls", "vinewtonssls")
#: TAO types offered by :class:`PetscTaoSolver` (bound-constrained QP solvers).
TAO_TYPES = ("tron", "gpcg")
#: Fill-reducing orderings of the stiffness block (PETSc ``MatOrderingType``).
ORDERINGS = ("qmd", "nd", "rcm", "1wd")


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


def _vec(PETSc: Any, values: np.ndarray) -> Any:
    v = PETSc.Vec().createSeq(len(values), comm=PETSc.COMM_SELF)
    v.setArray(np.asarray(values, dtype=PETSc.ScalarType))
    return v


class _PetscSolver(Solver):
    """What the PETSc solvers share: the option check, ``kkt_tol``, ``petsc_options`` under
    a prefix of their own (``rbbench_<stem><k>_``), and the stop reason of a run."""

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


# ---------------------------------------------------------------------------
# SNES VI on the KKT system
# ---------------------------------------------------------------------------
class PetscVISolver(_PetscSolver):
    """PETSc SNES variational-inequality Newton on the sparse KKT system.

    Unknowns ``x = (u, mu)`` with ``lam = t mu``; bounds ``u`` free,
    ``mu >= 0``; residual and Jacobian::

        R(x) = [A u + t B^T mu - F ;  r (G - B u)],    J = [[A, t B^T], [-r B, 0]].

    SNES VI solves the mixed complementarity problem "``R_i(x) >= 0`` where
    ``x_i`` is at its lower bound, ``R_i(x) <= 0`` at its upper bound,
    ``R_i(x) = 0`` in between": for ``mu_i = 0`` that reads ``G_i - (B u)_i >= 0``,
    for ``mu_i > 0`` it reads ``(B u)_i = G_i``, the contact conditions. The
    scales ``t = 1 / max|B|`` and ``r = max|A| / max|B|`` put ``mu``, the
    equilibrium rows and the constraint rows of ``R`` in the same (force)
    units: one tolerance then serves all rows, and the Fischer-Burmeister
    function of ``vinewtonssls``, which compares ``mu_i`` with ``R_i``, is not
    fooled by a multiplier many orders of magnitude below its residual.
    The right-hand side is then divided by ``sigma = max|(F, r G)| / max|A|``
    (the problem is linear: ``x`` scales with it) so that ``x`` is of order
    one: PETSc decides "``x_i`` at its bound" with an absolute ``1e-8``.

    The inner linear solve is PETSc's native sparse LU (KSP ``preonly``, PC
    ``lu``; the pip PETSc has no MUMPS). It does not pivot, so the unknowns
    are numbered by a fill-reducing ordering of ``A`` with the multipliers
    last, and the LU keeps that numbering (``natural``): every pivot is then
    a pivot of the SPD ``A`` or of the Schur complement ``r t B_I A^{-1} B_I^T``
    of the inactive multipliers ``I``, nonzero when ``B_I`` has full rank
    (see ``pivot_shift`` otherwise). The reduced-space Jacobians that
    ``vinewtonrsls`` extracts keep the relative order, hence the same property.

    Parameters
    ----------
    snes_type : {"vinewtonrsls", "vinewtonssls"}
        Reduced-space active set (default) or semismooth Newton. ``vinewtonssls``
        overwrites the Jacobian matrix: it is refilled at every evaluation.
    rtol : float
        SNES relative tolerance: stop when the VI residual norm (PETSc's norm of
        ``R`` over the inactive set) falls below ``rtol`` times the initial one.
    atol : float
        SNES absolute tolerance, relative to the data: ``atol * ||(F, r G)||``
        (needed when the initial guess is already the solution).
    stol : float
        SNES step tolerance (``||dx|| < stol ||x||``); 0 disables the test.
    max_iter : int
        Maximum number of Newton iterations.
    ordering : {"qmd", "nd", "rcm", "1wd"}
        Fill-reducing ordering of the stiffness block (PETSc ``MatOrderingType``).
        Measured on ``hertz_halfdisks`` (37k dofs, 9 Newton steps): qmd 1.0 s,
        nd 2.0 s, 1wd 27 s, rcm over 300 s.
    linesearch : str or None
        SNES line-search type (``"basic"`` = full Newton steps, default;
        ``None`` keeps PETSc's default for the SNES type).
    pivot_shift : float
        On a zero pivot (dependent active constraints, e.g. a repeated row of
        ``B``), PETSc's LU restarts with ``pivot_shift * max|A|`` added to the
        diagonal (``MAT_SHIFT_NONZERO``): Newton then converges to one of the
        multiplier vectors. Without a zero pivot it has no effect; 0 disables
        it (a zero pivot then stops SNES with ``DIVERGED_LINEAR_SOLVE``).
    degenerate_tol : float
        Rounding guard for degenerate constraints. At a multiplier on its
        bound (``mu_i = 0``) whose gap row is zero up to rounding,
        ``|R_i| <= degenerate_tol * r (|G_i| + (|B| |u|)_i)``, ``R_i`` is
        returned as ``|R_i|`` (at least the smallest positive float), i.e.
        the constraint counts as satisfied with a free gap. ``vinewtonrsls``
        fixes ``mu_i`` at its bound only when ``R_i > 0``; a multiplier that
        the previous Newton step made negative is clipped to 0 with a gap of
        exactly zero up to rounding, so without the guard the sign of rounding
        noise decides whether it re-enters the linear system, and the same
        wrong set is solved again and again (measured on ``hertz_halfdisks``:
        16 to more than 50 iterations instead of 6 to 10, one more than
        ``ssn``, whose active-set rule the guard reproduces). 0 disables it.
        ``R`` changes below the rounding level of its row only.
    kkt_tol : float
        A PETSc "converged" whose relative KKT error (:func:`kkt_errors`)
        exceeds this becomes ``"stagnation"``.
    petsc_options : dict, optional
        Extra PETSc options for this solver only, without the prefix, e.g.
        ``{"snes_linesearch_type": "bt"}``; applied after the settings above.

    Raises
    ------
    TypeError
        On an unknown option (the message lists the valid ones).
    ValueError
        On an invalid ``snes_type`` or ``ordering``.
    """

    name = "petsc-vi"
    _stem = "vi"
    OPTIONS = ("snes_type", "rtol", "atol", "stol", "max_iter", "ordering", "linesearch",
               "pivot_shift", "degenerate_tol", "kkt_tol", "petsc_options")

    def __init__(self, snes_type: str = "vinewtonrsls", rtol: float = 1e-12,
                 atol: float = 1e-13, stol: float = 0.0, max_iter: int = 50,
                 ordering: str = "qmd", linesearch: str | None = "basic",
                 pivot_shift: float = 1e-10, degenerate_tol: float = 1e-12,
                 kkt_tol: float = 1e-8, petsc_options: dict[str, Any] | None = None,
                 **unknown: Any):
        super().__init__(kkt_tol, petsc_options, unknown)
        self.snes_type = _choice(type(self).__name__, "snes_type", snes_type, SNES_TYPES)
        self.ordering = _choice(type(self).__name__, "ordering", ordering, ORDERINGS)
        self.rtol, self.atol, self.stol = float(rtol), float(atol), float(stol)
        self.max_iter = int(max_iter)
        self.linesearch = linesearch
        self.pivot_shift = float(pivot_shift)
        self.degenerate_tol = float(degenerate_tol)

    def solve(self, problem: ContactProblem, warm_start: np.ndarray | None = None) -> SolveResult:
        """Solve the contact problem; see the class docstring.

        Parameters
        ----------
        problem : ContactProblem
        warm_start : (m,) ndarray, optional
            Multipliers to start from (clipped at 0); the initial displacement
            is then ``A^{-1} (F - B^T lam)`` (one extra factorisation of ``A``).

        Returns
        -------
        SolveResult
            ``info["petsc_reason"]`` holds the SNES converged reason.
        """
        if not _finite_problem(problem, warm_start):
            return _nan_result(problem, "non-finite data or warm start")
        PETSc = petsc()
        t0 = time.perf_counter()
        A = sp.csr_matrix(problem.A, dtype=float)
        B = sp.csr_matrix(problem.B, dtype=float)
        n, m = A.shape[0], B.shape[0]
        lam0 = _check_warm(warm_start, m)
        amax = float(abs(A).max()) if A.nnz else 1.0
        bmax = float(abs(B).max()) if B.nnz else 0.0
        t = 1.0 / bmax if bmax > 0 else 1.0
        r = amax * t

        # fill-reducing ordering of the stiffness block; multipliers last
        A_p = _aij(PETSc, A)
        perm = np.asarray(A_p.getOrdering(self.ordering)[0].getIndices(), dtype=np.int64)
        A_p.destroy()
        Ap = A[perm][:, perm]
        Bp = B[:, perm]
        # explicit zero diagonal in the multiplier block: PETSc's LU and vinewtonssls
        # (which adds to the diagonal) need every diagonal entry in the pattern
        zero = sp.coo_matrix((np.zeros(m), (np.arange(m), np.arange(m))), shape=(m, m))
        K = sp.bmat([[Ap, t * Bp.T], [-r * Bp, zero]], format="coo").tocsr()
        K.sort_indices()
        rhs = np.r_[problem.F[perm], -r * problem.G]
        # normalise the data: PETSc's VI codes test "x_i at its bound" with an absolute
        # 1e-8, so x must be O(1); the problem is linear, x scales with the data
        sigma = float(np.abs(rhs).max(initial=0.0)) / amax
        sigma = sigma if sigma > 0 else 1.0
        rhs = rhs / sigma  # R(x) = K x - rhs, solution x = x_true / sigma
        data_norm = float(np.linalg.norm(rhs))

        x0 = np.zeros(n + m)
        t_warm = 0.0
        if lam0 is not None:
            tw = time.perf_counter()
            u0 = lcp.factorize(A).solve(problem.F - B.T @ lam0)
            x0 = np.r_[u0[perm], lam0 / t] / sigma
            t_warm = time.perf_counter() - tw

        indptr = K.indptr.astype(PETSc.IntType)
        indices = K.indices.astype(PETSc.IntType)
        data = K.data.astype(PETSc.ScalarType)
        J = PETSc.Mat().createAIJ(size=K.shape, comm=PETSc.COMM_SELF,
                                  csr=(indptr, indices, data))
        x = _vec(PETSc, x0)
        fvec = x.duplicate()
        lo = _vec(PETSc, np.r_[np.full(n, PETSc.NINFINITY), np.zeros(m)])
        hi = _vec(PETSc, np.full(n + m, PETSc.INFINITY))
        counts = {"function": 0, "jacobian": 0, "degenerate": 0}

        absB, absG, dtol = abs(Bp).tocsr(), np.abs(rhs[n:]), self.degenerate_tol

        def residual(snes: Any, xv: Any, fv: Any) -> None:
            counts["function"] += 1
            xa = xv.getArray(readonly=True)
            f = K @ xa - rhs
            if dtol > 0 and m:
                # degenerate constraints: multiplier at its bound, gap zero up to rounding
                # (relative to the row's own terms): report a nonnegative gap
                row_scale = absG + r * (absB @ np.abs(xa[:n]))
                flat = (xa[n:] <= 0.0) & (np.abs(f[n:]) <= dtol * row_scale)
                counts["degenerate"] += int(flat.sum())
                f[n:][flat] = np.maximum(np.abs(f[n:][flat]), _SUBNORMAL)
            fv.setArray(f)

        def jacobian(snes: Any, xv: Any, Jm: Any, Pm: Any) -> None:
            counts["jacobian"] += 1
            # the Jacobian is constant, but vinewtonssls overwrites the matrix in place
            # with its semismooth Jacobian: refill it at every evaluation
            Pm.zeroEntries()
            Pm.setValuesCSR(indptr, indices, data)
            Pm.assemble()

        snes = PETSc.SNES().create(comm=PETSc.COMM_SELF)
        info: dict[str, Any] = {"snes_type": self.snes_type, "ordering": self.ordering,
                                "scale_lam": t, "scale_rows": r, "scale_data": sigma,
                                "n_kkt": n + m,
                                "n_contact_unknowns": m, "kkt_nnz": int(K.nnz),
                                "options_prefix": self.prefix}
        try:
            snes.setOptionsPrefix(self.prefix)
            snes.setType(self.snes_type)
            snes.setFunction(residual, fvec)
            snes.setJacobian(jacobian, J, J)
            snes.setVariableBounds(lo, hi)
            snes.setTolerances(rtol=self.rtol, atol=max(self.atol * data_norm, _TINY),
                               stol=self.stol, max_it=self.max_iter)
            snes.setConvergenceHistory(length=self.max_iter + 1)
            if self.linesearch is not None:
                snes.getLineSearch().setType(self.linesearch)
            ksp = snes.getKSP()
            ksp.setType("preonly")
            pc = ksp.getPC()
            pc.setType("lu")
            pc.setFactorSolverType("petsc")
            pc.setFactorOrdering("natural")
            if self.pivot_shift > 0:
                pc.setFactorShift(PETSc.Mat.FactorShiftType.NONZERO, self.pivot_shift * amax)
            with _Options(self.prefix, self.petsc_options):
                snes.setFromOptions()
                t_setup = time.perf_counter() - t0
                ts = time.perf_counter()
                snes.solve(None, x)
                t_solve = time.perf_counter() - ts
            code = int(snes.getConvergedReason())
            its = int(snes.getIterationNumber())
            hist = np.asarray(snes.getConvergenceHistory()[0], dtype=float)
            info["linear_iterations"] = int(snes.getLinearSolveIterations())
            info["petsc_reason"] = _reason_name(PETSc.SNES.ConvergedReason, code)
            info["function_evals"] = counts["function"]
            info["jacobian_evals"] = counts["jacobian"]
            info["degenerate_guarded"] = counts["degenerate"]
            xs = x.getArray().copy()
        except PETSc.Error as exc:
            t_setup = time.perf_counter() - t0
            t_solve = 0.0
            info["petsc_reason"] = "PETSc.Error"
            info["why"] = f"PETSc error {exc}"
            code, its, hist, xs = None, 0, np.zeros(0), np.full(n + m, np.nan)
        finally:
            for obj in (snes, J, x, fvec, lo, hi):
                obj.destroy()

        u = np.empty(n)
        u[perm] = sigma * xs[:n]
        lam = (sigma * t) * xs[n:]
        reason = self._stop_reason(code, bool(np.all(np.isfinite(xs))), problem, u, lam, info)
        residuals = (hist[: its + 1] / max(data_norm, _TINY)).tolist() if hist.size else []
        # not "setup_s" / "solve_s": contact_metrics merges these into the HF driver's times
        times = {"kkt_setup_s": t_setup, "warm_start_s": t_warm, "snes_s": t_solve}
        return SolveResult(u=problem.expand(u), lam=lam, iterations=its, stop_reason=reason,
                           residuals=residuals, times=times, info=info)


# ---------------------------------------------------------------------------
# TAO on the condensed dual QP
# ---------------------------------------------------------------------------
class PetscTaoSolver(_PetscSolver):
    """PETSc TAO bound-constrained QP on the condensed dual problem.

    :func:`rbbench.hf.lcp.condense` factorises ``A`` once and forms the Delassus
    operator ``D = B A^{-1} B^T`` and ``q = G - B A^{-1} F``; the multipliers
    solve LCP(q, D), the optimality system of::

        min_{lam >= 0}  1/2 lam^T D lam + q^T lam

    (gradient ``D lam + q = G - B u``, the gap). TAO solves it scaled, in
    ``mu = lam / (c sigma)`` with ``c = 1 / mean(diag D)`` and ``sigma = max|q|``:
    ``1/2 mu^T (c D) mu + (q / sigma)^T mu`` (unit-mean Hessian diagonal, unit
    data; TAO's trust-region and line-search defaults are absolute numbers).
    Then ``u = A^{-1}(F - B^T lam)`` via the condensed object.

    Parameters
    ----------
    tao_type : {"tron", "gpcg"}
        Trust-region Newton (default) or gradient-projection conjugate gradient.
    gatol : float
        Stop when the projected-gradient norm is below ``gatol * ||q||``.
        ``grtol`` and ``gttol`` are set to 0: TAO's defaults stop early.
    max_iter : int
        Maximum number of TAO iterations.
    ksp_rtol : float
        Relative tolerance of the inner (trust-region) Krylov solve.
    pc_type : str
        Preconditioner of the inner Krylov solve on the dense reduced Hessian:
        ``"jacobi"`` (default), ``"none"``, or ``"cholesky"`` (exact, one
        Krylov step, but a singular reduced Hessian, e.g. from repeated
        constraints, raises a PETSc error: stop reason ``"diverged"``).
    kkt_tol : float
        A TAO "converged" whose relative KKT error (:func:`kkt_errors`)
        exceeds this becomes ``"stagnation"``.
    petsc_options : dict, optional
        Extra PETSc options for this solver only, without the prefix.

    Raises
    ------
    TypeError
        On an unknown option (the message lists the valid ones).
    ValueError
        On an invalid ``tao_type``.
    """

    name = "petsc-tao"
    _stem = "tao"
    OPTIONS = ("tao_type", "gatol", "max_iter", "ksp_rtol", "pc_type", "kkt_tol",
               "petsc_options")

    def __init__(self, tao_type: str = "tron", gatol: float = 1e-13, max_iter: int = 200,
                 ksp_rtol: float = 1e-14, pc_type: str = "jacobi", kkt_tol: float = 1e-8,
                 petsc_options: dict[str, Any] | None = None, **unknown: Any):
        super().__init__(kkt_tol, petsc_options, unknown)
        self.tao_type = _choice(type(self).__name__, "tao_type", tao_type, TAO_TYPES)
        self.gatol, self.ksp_rtol = float(gatol), float(ksp_rtol)
        self.max_iter = int(max_iter)
        self.pc_type = str(pc_type)

    def solve(self, problem: ContactProblem, warm_start: np.ndarray | None = None) -> SolveResult:
        """Solve the contact problem; see the class docstring.

        Parameters
        ----------
        problem : ContactProblem
        warm_start : (m,) ndarray, optional
            Initial multipliers (clipped at 0).

        Returns
        -------
        SolveResult
            ``info["petsc_reason"]`` holds the TAO converged reason.
        """
        if not _finite_problem(problem, warm_start):
            return _nan_result(problem, "non-finite data or warm start")
        m = problem.B.shape[0]
        lam0 = _check_warm(warm_start, m)
        cond = lcp.condense(problem.A, problem.F, problem.B, problem.G)
        times = {"factor_s": cond.t_factor, "condense_s": cond.t_condense}
        info: dict[str, Any] = {"tao_type": self.tao_type, "n_contact_unknowns": m,
                                "options_prefix": self.prefix}
        if m == 0:
            info["petsc_reason"] = "not run (no contact unknowns)"
            u = cond.displacement(np.zeros(0))
            reason = _finish("converged", kkt_errors(problem, u, np.zeros(0)), self.kkt_tol,
                             info)
            return SolveResult(u=problem.expand(u), lam=np.zeros(0), iterations=0,
                               stop_reason=reason, residuals=[0.0],
                               times={**times, "tao_s": 0.0}, info=info)
        PETSc = petsc()
        t0 = time.perf_counter()
        d = np.diag(cond.D)
        c = 1.0 / float(np.mean(d)) if np.mean(d) > 0 else 1.0
        Ds = np.ascontiguousarray(c * cond.D)
        # normalise the data too (max|q| = 1): TAO's trust-region radius and line search
        # have absolute defaults; the problem is linear, mu scales with q
        sigma = float(np.abs(cond.q).max(initial=0.0))
        sigma = sigma if sigma > 0 else 1.0
        q = cond.q / sigma
        qnorm = max(float(np.linalg.norm(q)), _TINY)
        H = PETSc.Mat().createDense((m, m), array=Ds.copy(order="F"), comm=PETSc.COMM_SELF)
        H.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        H.assemble()
        x = _vec(PETSc, np.zeros(m) if lam0 is None else lam0 / (c * sigma))
        lo = _vec(PETSc, np.zeros(m))
        hi = _vec(PETSc, np.full(m, PETSc.INFINITY))
        counts = {"objective": 0}
        history: list[float] = []

        def objective_gradient(tao: Any, xv: Any, gv: Any) -> float:
            counts["objective"] += 1
            mu = xv.getArray(readonly=True)
            g = Ds @ mu + q
            gv.setArray(g)
            return float(0.5 * mu @ (g + q))  # 1/2 mu^T Ds mu + q^T mu

        def hessian(tao: Any, xv: Any, Hm: Any, Pm: Any) -> None:
            return None  # constant Hessian, assembled once

        def monitor(tao: Any) -> None:
            history.append(float(tao.getSolutionStatus()[2]) / qnorm)

        tao = PETSc.TAO().create(comm=PETSc.COMM_SELF)
        try:
            tao.setOptionsPrefix(self.prefix)
            tao.setType(self.tao_type)
            tao.setObjectiveGradient(objective_gradient, None)
            tao.setHessian(hessian, H, H)
            tao.setVariableBounds((lo, hi))
            tao.setSolution(x)
            tao.setTolerances(gatol=self.gatol * qnorm, grtol=0.0, gttol=0.0)
            tao.setMaximumIterations(self.max_iter)
            tao.setMonitor(monitor)
            ksp = tao.getKSP()
            if ksp is not None:
                ksp.setTolerances(rtol=self.ksp_rtol, atol=0.0, max_it=max(10 * m, 100))
                ksp.getPC().setType(self.pc_type)
            with _Options(self.prefix, self.petsc_options):
                tao.setFromOptions()
                t_setup = time.perf_counter() - t0
                ts = time.perf_counter()
                tao.solve()
                t_solve = time.perf_counter() - ts
            code = int(tao.getConvergedReason())
            its = int(tao.getIterationNumber())
            info["petsc_reason"] = _reason_name(PETSc.TAO.ConvergedReason, code)
            info["gradient_norm"] = float(tao.getSolutionStatus()[2]) / qnorm
            info["objective_evals"] = counts["objective"]
            ksp = tao.getKSP()
            info["last_ksp_iterations"] = int(ksp.getIterationNumber()) if ksp else None
            mu = x.getArray().copy()
        except PETSc.Error as exc:
            t_setup = time.perf_counter() - t0
            t_solve = 0.0
            info["petsc_reason"] = "PETSc.Error"
            info["why"] = f"PETSc error {exc}"
            code, its, mu = None, 0, np.full(m, np.nan)
        finally:
            for obj in (tao, H, x, lo, hi):
                obj.destroy()

        lam = (c * sigma) * mu
        tr = time.perf_counter()
        u = cond.displacement(lam)
        times.update(tao_setup_s=t_setup, tao_s=t_solve, recover_s=time.perf_counter() - tr)
        finite = bool(np.all(np.isfinite(lam)) and np.all(np.isfinite(u)))
        reason = self._stop_reason(code, finite, problem, u, lam, info)
        info["scale"] = c
        info["scale_data"] = sigma
        return SolveResult(u=problem.expand(u), lam=lam, iterations=its, stop_reason=reason,
                           residuals=history, times=times, info=info)

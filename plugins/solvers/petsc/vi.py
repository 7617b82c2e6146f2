"""PETSc SNES variational-inequality Newton on the sparse KKT system of the mixed contact
problem (:class:`PetscVISolver`; see :mod:`rbbench_plugins.solvers.petsc`)."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp
from rbbench_plugins.solvers.petsc.common import (
    _SUBNORMAL,
    _TINY,
    _aij,
    _check_warm,
    _choice,
    _finite_problem,
    _nan_result,
    _PetscSolver,
    _reason_name,
    _vec,
    petsc,
)

from rbbench.hf.algebra import friction as fa
from rbbench.hf.condensation.dense import factorize
from rbbench.interfaces import ContactProblem, FrictionProblem, SolveResult

__all__ = ["ORDERINGS", "SNES_TYPES", "PetscVISolver"]

#: SNES VI types offered by :class:`PetscVISolver`.
SNES_TYPES = ("vinewtonrsls", "vinewtonssls")
#: Fill-reducing orderings of the stiffness block (PETSc ``MatOrderingType``).
ORDERINGS = ("qmd", "nd", "rcm", "1wd")
#: ``-snes_vi_zero_tolerance`` of the Tresca solve: ``x_i`` counts as at its bound only when
#: it is (PETSc's default 1e-8 left lam_t within 1e-8 of a moving bound: the Coulomb fixed
#: point on Tresca then stalled at a friction residual of 1e-8 on mindlin_cylinders)
VI_ZERO_TOL = 0.0


@dataclass
class _KKT:
    """The scaled KKT system of :class:`PetscVISolver`: ``R(x) = K x - rhs`` in the unknowns
    ``x = (u[perm], lam / t) / sigma`` (class docstring)."""

    n: int
    m: int
    amax: float  # max|A|
    t: float  # lam = t mu
    r: float  # constraint rows scaled by r
    perm: np.ndarray  # fill-reducing ordering of the stiffness block
    Bp: sp.csr_matrix  # B[:, perm]
    K: sp.csr_matrix
    rhs: np.ndarray  # divided by sigma
    sigma: float
    data_norm: float  # ||rhs||


def _kkt_system(PETSc: Any, A: sp.csr_matrix, B: sp.csr_matrix, F: np.ndarray,
                G: np.ndarray, ordering: str) -> _KKT:
    """Scale, order and assemble the KKT system (see :class:`PetscVISolver`)."""
    n, m = A.shape[0], B.shape[0]
    amax = float(abs(A).max()) if A.nnz else 1.0
    bmax = float(abs(B).max()) if B.nnz else 0.0
    t = 1.0 / bmax if bmax > 0 else 1.0
    r = amax * t

    # fill-reducing ordering of the stiffness block; multipliers last
    A_p = _aij(PETSc, A)
    perm = np.asarray(A_p.getOrdering(ordering)[0].getIndices(), dtype=np.int64)
    A_p.destroy()
    Ap = A[perm][:, perm]
    Bp = B[:, perm]
    # explicit zero diagonal in the multiplier block: PETSc's LU and vinewtonssls
    # (which adds to the diagonal) need every diagonal entry in the pattern
    zero = sp.coo_matrix((np.zeros(m), (np.arange(m), np.arange(m))), shape=(m, m))
    K = sp.bmat([[Ap, t * Bp.T], [-r * Bp, zero]], format="coo").tocsr()
    K.sort_indices()
    rhs = np.r_[F[perm], -r * G]
    # normalise the data: PETSc's VI codes test "x_i at its bound" with an absolute
    # 1e-8, so x must be O(1); the problem is linear, x scales with the data
    sigma = float(np.abs(rhs).max(initial=0.0)) / amax
    sigma = sigma if sigma > 0 else 1.0
    rhs = rhs / sigma  # R(x) = K x - rhs, solution x = x_true / sigma
    data_norm = float(np.linalg.norm(rhs))
    return _KKT(n=n, m=m, amax=amax, t=t, r=r, perm=perm, Bp=Bp, K=K, rhs=rhs, sigma=sigma,
                data_norm=data_norm)


def _initial_point(kkt: _KKT, A: sp.csr_matrix, B: sp.csr_matrix, F: np.ndarray,
                   lam0: np.ndarray | None) -> tuple[np.ndarray, float]:
    """``(x0, seconds)``: 0, or ``(A^{-1} (F - B^T lam0), lam0)`` scaled and permuted."""
    x0 = np.zeros(kkt.n + kkt.m)
    t_warm = 0.0
    if lam0 is not None:
        tw = time.perf_counter()
        u0 = factorize(A).solve(F - B.T @ lam0)
        x0 = np.r_[u0[kkt.perm], lam0 / kkt.t] / kkt.sigma
        t_warm = time.perf_counter() - tw
    return x0, t_warm


def _refill(csr: tuple[Any, Any, Any], counts: dict[str, int]) -> Callable[..., None]:
    """SNES Jacobian callback of a constant matrix (PETSc CSR arrays ``csr``)."""
    indptr, indices, data = csr

    def jacobian(snes: Any, xv: Any, Jm: Any, Pm: Any) -> None:
        counts["jacobian"] += 1
        # the Jacobian is constant, but vinewtonssls overwrites the matrix in place
        # with its semismooth Jacobian: refill it at every evaluation
        Pm.zeroEntries()
        Pm.setValuesCSR(indptr, indices, data)
        Pm.assemble()

    return jacobian


def _csr(PETSc: Any, K: sp.csr_matrix) -> tuple[Any, Any, Any]:
    """PETSc CSR arrays of ``K`` (indices sorted)."""
    K = sp.csr_matrix(K)
    K.sort_indices()
    return (K.indptr.astype(PETSc.IntType), K.indices.astype(PETSc.IntType),
            K.data.astype(PETSc.ScalarType))


def _kkt_callbacks(kkt: _KKT, csr: tuple[Any, Any, Any], dtol: float, counts: dict[str, int]
                   ) -> tuple[Callable[..., None], Callable[..., None]]:
    """SNES ``(residual, jacobian)`` of the KKT system; ``csr`` = PETSc arrays of ``K``."""
    K, rhs, n, m, r = kkt.K, kkt.rhs, kkt.n, kkt.m, kkt.r
    absB, absG = abs(kkt.Bp).tocsr(), np.abs(rhs[n:])

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

    return residual, _refill(csr, counts)


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

    def solve(self, problem: ContactProblem | FrictionProblem,
              warm_start: np.ndarray | None = None) -> SolveResult:
        """Solve the contact problem; see the class docstring.

        Parameters
        ----------
        problem : ContactProblem or FrictionProblem
            A friction problem goes to :meth:`solve_friction` (:meth:`tresca` per step).
        warm_start : (m,) ndarray, optional
            Multipliers to start from (clipped at 0); the initial displacement
            is then ``A^{-1} (F - B^T lam)`` (one extra factorisation of ``A``).

        Returns
        -------
        SolveResult
            ``info["petsc_reason"]`` holds the SNES converged reason.
        """
        if isinstance(problem, FrictionProblem):
            return self.solve_friction(problem, warm_start)
        if not _finite_problem(problem, warm_start):
            return _nan_result(problem, "non-finite data or warm start")
        PETSc = petsc()
        t0 = time.perf_counter()
        A = sp.csr_matrix(problem.A, dtype=float)
        B = sp.csr_matrix(problem.B, dtype=float)
        lam0 = _check_warm(warm_start, B.shape[0])
        kkt = _kkt_system(PETSc, A, B, problem.F, problem.G, self.ordering)
        n, m, K = kkt.n, kkt.m, kkt.K
        x0, t_warm = _initial_point(kkt, A, B, problem.F, lam0)

        csr = _csr(PETSc, K)
        counts = {"function": 0, "jacobian": 0, "degenerate": 0}
        callbacks = _kkt_callbacks(kkt, csr, self.degenerate_tol, counts)
        info: dict[str, Any] = {"snes_type": self.snes_type, "ordering": self.ordering,
                                "scale_lam": kkt.t, "scale_rows": kkt.r, "scale_data": kkt.sigma,
                                "n_kkt": n + m,
                                "n_contact_unknowns": m, "kkt_nnz": int(K.nnz),
                                "options_prefix": self.prefix}
        lo = np.r_[np.full(n, PETSc.NINFINITY), np.zeros(m)]
        code, its, hist, xs, t_setup, t_solve = self._snes(
            PETSc, csr, x0, (lo, np.full(n + m, PETSc.INFINITY)), callbacks,
            (kkt.data_norm, kkt.amax), counts, info, t0)
        # not "setup_s" / "solve_s": contact_metrics merges these into the HF driver's times
        times = {"kkt_setup_s": t_setup, "warm_start_s": t_warm, "snes_s": t_solve}
        return self._result(problem, kkt, xs, code, its, hist, info, times)

    def tresca(self, D: np.ndarray, q: np.ndarray, s: float | np.ndarray,
               lam0: np.ndarray | None = None) -> fa.FrictionResult:
        """Condensed Tresca friction by SNES VI: the box QP ``min 1/2 x^T D x + q^T x``,
        ``lam_n >= 0``, ``|lam_t| <= s`` of :mod:`rbbench.hf.algebra.friction` as the mixed
        complementarity problem ``R(mu) = (c D) mu + q / sigma`` (the scaled gradient,
        :func:`~rbbench_plugins.solvers.petsc.common.scaled_qp`; ``x = c sigma mu``) with
        bounds ``[0, inf) x [-s, s] / (c sigma)``. Same SNES type, tolerances, line search
        and LU as the contact solve (no ordering: ``D`` is dense). The stop reason is
        PETSc's (``info["petsc_reason"]``), checked on the friction residuals (``kkt_tol``).
        """
        st, early = self._tresca_setup(D, q, s, lam0)
        if st is None:
            return early
        PETSc, (_, Ds, _, qs, qnorm) = st.PETSc, st.qp
        csr = _csr(PETSc, sp.csr_matrix(Ds))
        counts = {"function": 0, "jacobian": 0, "degenerate": 0}

        def residual(snes: Any, yv: Any, fv: Any) -> None:
            counts["function"] += 1
            fv.setArray(Ds @ yv.getArray(readonly=True) + qs)

        info: dict[str, Any] = {"snes_type": self.snes_type, "scale_data": st.k}
        amax = float(np.abs(Ds).max(initial=0.0)) or 1.0
        code, its, hist, ys, _, t_solve = self._snes(
            PETSc, csr, st.x0, st.bounds, (residual, _refill(csr, counts)), (qnorm, amax),
            counts, info, st.t0, {"snes_vi_zero_tolerance": VI_ZERO_TOL})
        info["snes_s"] = t_solve
        history = (hist[: its + 1] / qnorm).tolist() if hist.size else []
        return self._tresca_result(D, q, st.k * ys, st.s, code, its, history, info)

    def _snes(self, PETSc: Any, csr: tuple[Any, Any, Any], x0: np.ndarray,
              bounds: tuple[np.ndarray, np.ndarray], callbacks: tuple[Callable[..., None], ...],
              scales: tuple[float, float], counts: dict[str, int], info: dict[str, Any],
              t0: float, options: dict[str, Any] | None = None
              ) -> tuple[int | None, int, np.ndarray, np.ndarray, float, float]:
        """Run SNES VI on ``R(x) >=< 0`` with bounds (``R``, Jacobian: ``callbacks``, the
        Jacobian's PETSc CSR arrays ``csr``; ``scales = (||data||, max|J|)``; ``options``:
        PETSc options for this run, under :attr:`petsc_options`).

        Returns ``(reason code or None after a PETSc error, iterations, residual history,
        x, setup seconds, solve seconds)``; every PETSc object is destroyed.
        """
        residual, jacobian = callbacks
        n = x0.size
        J = PETSc.Mat().createAIJ(size=(n, n), comm=PETSc.COMM_SELF, csr=csr)
        x = _vec(PETSc, x0)
        fvec = x.duplicate()
        lo, hi = _vec(PETSc, bounds[0]), _vec(PETSc, bounds[1])
        snes = PETSc.SNES().create(comm=PETSc.COMM_SELF)
        try:
            snes.setOptionsPrefix(self.prefix)
            snes.setType(self.snes_type)
            snes.setFunction(residual, fvec)
            snes.setJacobian(jacobian, J, J)
            snes.setVariableBounds(lo, hi)
            self._configure(PETSc, snes, *scales)
            t_setup, t_solve = self._run(snes, lambda: snes.solve(None, x), t0, options)
            code, its, hist = self._outcome(PETSc, snes, counts, info)
            xs = x.getArray().copy()
        except PETSc.Error as exc:
            t_setup, t_solve = self._failed(exc, t0, info)
            code, its, hist, xs = None, 0, np.zeros(0), np.full(n, np.nan)
        finally:
            for obj in (snes, J, x, fvec, lo, hi):
                obj.destroy()
        return code, its, hist, xs, t_setup, t_solve

    def _configure(self, PETSc: Any, snes: Any, data_norm: float, amax: float) -> None:
        """Tolerances, line search and the inner sparse LU (class docstring)."""
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

    @staticmethod
    def _outcome(PETSc: Any, snes: Any, counts: dict[str, int], info: dict[str, Any]
                 ) -> tuple[int, int, np.ndarray]:
        """``(reason code, iterations, residual history)`` of a finished SNES run; the
        counters and PETSc's reason go to ``info``."""
        code = int(snes.getConvergedReason())
        its = int(snes.getIterationNumber())
        hist = np.asarray(snes.getConvergenceHistory()[0], dtype=float)
        info["linear_iterations"] = int(snes.getLinearSolveIterations())
        info["petsc_reason"] = _reason_name(PETSc.SNES.ConvergedReason, code)
        info["function_evals"] = counts["function"]
        info["jacobian_evals"] = counts["jacobian"]
        info["degenerate_guarded"] = counts["degenerate"]
        return code, its, hist

    def _result(self, problem: ContactProblem, kkt: _KKT, xs: np.ndarray, code: int | None,
                its: int, hist: np.ndarray, info: dict[str, Any], times: dict[str, float]
                ) -> SolveResult:
        """Unscale ``xs`` into ``(u, lam)`` and check the run (:meth:`_stop_reason`)."""
        n, sigma = kkt.n, kkt.sigma
        u = np.empty(n)
        u[kkt.perm] = sigma * xs[:n]
        lam = (sigma * kkt.t) * xs[n:]
        reason = self._stop_reason(code, bool(np.all(np.isfinite(xs))), problem, u, lam, info)
        residuals = (hist[: its + 1] / max(kkt.data_norm, _TINY)).tolist() if hist.size else []
        return SolveResult(u=problem.expand(u), lam=lam, iterations=its, stop_reason=reason,
                           residuals=residuals, times=times, info=info)

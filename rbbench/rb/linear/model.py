"""Reduced linear models with a residual-based a posteriori error estimator.

Galerkin projection on an X-orthonormal basis ``Z`` with the exact affine decomposition
``A(mu) Z = sum_q theta_q(mu) (A_q Z)``, ``F(mu) = sum_q theta_q(mu) F_q``,
``theta = [1, mu_1, ..., mu_p]``, found and verified by probing
(:func:`rbbench.rb.algorithms.affine.affine_decomposition`; Benaceur, Drouet, Ehrlacher, Ern &
Niakh, "Model order reduction methods: parametric variational inequalities" (talk), slide
"Affine parametric decomposition").

Estimator (Patera & Rozza 2007; Grepl & Patera 2005; Haasdonk & Ohlberger 2008): with the
Riesz representers of the residual pieces, ``||r(mu)||_{X'}^2 = c^T G c`` (``G``: their
Gram matrix, offline) and a coercivity lower bound by min-theta,
``alpha_LB(mu) = alpha(mu_ref) min_q theta_q(mu) / theta_q(mu_ref)`` over the nonzero,
positive semi-definite terms ``A_q`` (thermal block: ``min_i mu_i`` for ``mu_ref = 1``):

* elliptic: ``||u - u_N||_X <= ||r(mu)||_{X'} / alpha_LB(mu)``;
* implicit Euler, ``r^k = F - M (u_N^k - u_N^{k-1}) / dt - A u_N^k``::

      dt sum_k ||e^k||_X^2 <= (||e^0||_M^2 + dt / alpha_LB sum_k ||r^k||_{X'}^2) / alpha_LB

  (test the error equation with ``e^k``, Young's inequality, sum over k), the discrete
  ``L2(0, T; X)`` error of :func:`rbbench.hf.linear.model.space_time_norm`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg as sla
import scipy.sparse.linalg as spla

from rbbench.interfaces import HFVectors, ReducedSolution
from rbbench.rb.algorithms.affine import LinearInMu, affine_decomposition
from rbbench.rb.algorithms.bounds import lanczos_start
from rbbench.rb.online import ReducedBasis, require_basis

__all__ = ["ReducedLinear", "build_reduced", "coercivity_reference"]


@dataclass
class ReducedLinear:
    """The reduced linear model: small dense arrays only (picklable, no backend).

    ``A`` (Q, N, N), ``F`` (Q, N) on ``theta = [1, mu]``; parabolic: ``M`` (N, N), ``u0``
    (N,), ``dt``, ``steps``. Estimator: ``G`` (Gram of the residual pieces), ``alpha_ref``,
    ``theta_ref`` and ``active`` (the terms of the min-theta bound), ``e0_m`` (the
    M-norm of the initial projection error). ``basis``: ``Z`` (HF size), for
    :meth:`reconstruct` only.
    """

    A: np.ndarray
    F: np.ndarray
    G: np.ndarray
    alpha_ref: float
    theta_ref: np.ndarray
    active: np.ndarray
    M: np.ndarray | None = None
    u0: np.ndarray | None = None
    dt: float = 0.0
    steps: int = 0
    e0_m: float = 0.0
    parameters: Any = None
    basis: ReducedBasis | None = None

    @property
    def N(self) -> int:
        return int(self.A.shape[1])

    def theta(self, mu: Any) -> np.ndarray:
        mu = self.parameters.check(mu) if self.parameters is not None else mu
        return LinearInMu(self.A.shape[0] - 1)(mu)

    def solve(self, mu: Any) -> ReducedSolution:
        """Online solve (mu checked against D): ``u`` the coefficients of
        :meth:`coefficients`, ``time_s`` their wall time (the estimator is not included:
        :meth:`estimate`)."""
        t0 = time.perf_counter()
        mu = self.parameters.check(mu) if self.parameters is not None else mu
        c = self.coefficients(mu)
        return ReducedSolution(mu=mu, u=c, lam=np.zeros(0), iterations=0,
                               stop_reason="converged", time_s=time.perf_counter() - t0)

    def reconstruct(self, solution: Any) -> HFVectors:
        """``Z c`` on the free dofs (a trajectory: ``Z c^k`` step by step, flattened)."""
        return require_basis(self).vectors(solution.u)

    def coefficients(self, mu: Any) -> np.ndarray:
        """Reduced coefficients: ``(N,)``, or ``(K, N)`` for the trajectory (one LU of
        ``M / dt + A``, then ``u^k = T u^{k-1} + g``)."""
        th = self.theta(mu)
        A = np.tensordot(th, self.A, axes=1)
        f = th @ self.F
        if self.M is None:
            return np.linalg.solve(A, f)
        lu = sla.lu_factor(self.M / self.dt + A, check_finite=False)
        T = sla.lu_solve(lu, self.M / self.dt, check_finite=False)  # u^k = T u^{k-1} + g
        g = sla.lu_solve(lu, f, check_finite=False)
        out = np.empty((self.steps, self.N))
        u = self.u0
        for k in range(self.steps):
            u = T @ u + g
            out[k] = u
        return out

    def alpha_lb(self, mu: Any) -> float:
        """Min-theta coercivity lower bound ``alpha(mu_ref) min_q theta_q / theta_q,ref``."""
        th = self.theta(mu)
        return float(self.alpha_ref * np.min(th[self.active] / self.theta_ref[self.active]))

    def _coefficients(self, th: np.ndarray, u: np.ndarray, du: np.ndarray | None
                      ) -> np.ndarray:
        """Coefficients of the residual pieces ``[F_q, (M Z), (A_q Z)]`` (rows: steps)."""
        u = np.atleast_2d(u)
        parts = [np.broadcast_to(th, (u.shape[0], th.size))]
        if du is not None:
            parts.append(-du)
        parts.append(-(th[None, :, None] * u[:, None, :]).reshape(u.shape[0], -1))
        return np.hstack(parts)

    def estimate(self, mu: Any, u: np.ndarray) -> float:
        """The error bound (module docstring) of the reduced solution ``u`` at mu
        (absolute, in X or in the discrete L2(0, T; X))."""
        th = self.theta(mu)
        alpha = self.alpha_lb(mu)
        if self.M is None:
            c = self._coefficients(th, u, None)[0]
            return float(np.sqrt(max(c @ self.G @ c, 0.0))) / alpha
        prev = np.vstack([self.u0[None, :], u[:-1]])
        C = self._coefficients(th, u, (u - prev) / self.dt)
        r2 = np.maximum(np.einsum("ki,ij,kj->k", C, self.G, C), 0.0)
        return float(np.sqrt((self.e0_m ** 2 + self.dt / alpha * r2.sum()) / alpha))


def coercivity_reference(A_ref: Any, X: Any) -> float:
    """``alpha(mu_ref) = min_v a(v, v; mu_ref) / ||v||_X^2``: the smallest generalised
    eigenvalue of ``(A(mu_ref), X)`` (shift-invert Lanczos at 0, from a fixed start
    vector: :func:`rbbench.rb.algorithms.bounds.lanczos_start`)."""
    vals = spla.eigsh(A_ref, k=1, M=X, sigma=0.0, which="LM", v0=lanczos_start(A_ref.shape[0]),
                      return_eigenvectors=False)
    return float(np.min(vals))


def _active_terms(problem_at: Callable[[np.ndarray], Any], bounds: np.ndarray
                  ) -> np.ndarray:
    """Which ``A_q`` are nonzero (HF, sparse; centre and one shift per parameter)."""
    c = bounds.mean(axis=1)
    A_c = problem_at(c).A
    terms = []
    for k in range(len(c)):
        mu = c.copy()
        mu[k] = bounds[k, 1]
        terms.append((problem_at(mu).A - A_c) / (bounds[k, 1] - c[k]))
    A0 = A_c - sum(ck * t for ck, t in zip(c, terms, strict=True))
    scale = abs(A_c).max()
    return np.array([abs(t).max() > 1e-10 * scale for t in [A0, *terms]])


def build_reduced(problem_at: Callable[[np.ndarray], Any], Z: np.ndarray, bounds: np.ndarray,
                  x_solve: Callable[[np.ndarray], np.ndarray], mu_ref: np.ndarray,
                  alpha_ref: float) -> ReducedLinear:
    """Project on ``Z`` with the probed affine decomposition and the estimator's Gram
    matrix (``x_solve``: ``X^{-1}``; ``mu_ref``, ``alpha_ref``: the min-theta reference)."""
    N = Z.shape[1]
    terms = affine_decomposition(lambda mu: np.column_stack([problem_at(mu).A @ Z,
                                                             problem_at(mu).F]), bounds)
    AZ, Fq = terms[:, :, :N], terms[:, :, N]
    p0 = problem_at(bounds.mean(axis=1))
    pieces = [Fq.T]
    rom_kw: dict[str, Any] = {}
    if p0.parabolic:
        MZ = p0.M @ Z
        u0 = Z.T @ (p0.X @ p0.u0)
        e0 = p0.u0 - Z @ u0
        rom_kw = {"M": Z.T @ MZ, "u0": u0, "dt": p0.dt, "steps": p0.steps,
                  "e0_m": float(np.sqrt(max(e0 @ (p0.M @ e0), 0.0)))}
        pieces.append(MZ)
    pieces.append(AZ.transpose(1, 0, 2).reshape(Z.shape[0], -1))
    V = np.hstack(pieces)
    G = V.T @ x_solve(V)
    theta_ref = LinearInMu(len(mu_ref))(mu_ref)
    return ReducedLinear(A=np.einsum("ni,qnj->qij", Z, AZ), F=Fq @ Z, G=0.5 * (G + G.T),
                         alpha_ref=alpha_ref, theta_ref=theta_ref,
                         active=_active_terms(problem_at, bounds), **rom_kw)

"""The algebraic HF problems a formulation builds (mixed, friction, Nitsche) and the result of
one solve (:class:`SolveResult`, with its stop reason)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

from rbbench.interfaces.operators import Factorize

#: Why an iterative solve stopped. Every solver reports exactly one of these.
STOP_REASONS = ("converged", "max_iterations", "stagnation", "nan", "diverged")


class _FreeDofs:
    """``expand``: free-dof values back to the global displacement (``free``, ``u_lift``
    are fields of the problem dataclasses below)."""

    free: np.ndarray
    u_lift: np.ndarray

    def expand(self, u_free: np.ndarray) -> np.ndarray:
        """Global displacement from free-dof values."""
        u = self.u_lift.copy()
        u[self.free] = u_free
        return u


@dataclass
class ContactProblem(_FreeDofs):
    """The algebraic HF contact problem on the free dofs.

    Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
    variational inequalities" (talk), slide "Mixed formulation".

    Find ``u, lam`` with ``A u + B^T lam = F``, ``lam >= 0``, ``B u <= G``,
    ``lam . (G - B u) = 0``. ``free`` maps free to global dofs; ``u_lift``
    is the global Dirichlet lifting. ``factorize``: the backend's direct solver
    for ``A`` (:data:`Factorize`, from ``Discretization.factorize``), or ``None``.
    """

    A: sp.csr_matrix
    F: np.ndarray
    B: sp.csr_matrix
    G: np.ndarray
    free: np.ndarray
    u_lift: np.ndarray
    X: sp.csr_matrix
    W: sp.csr_matrix
    factorize: Factorize | None = None


@dataclass(frozen=True)
class FrictionLaw:
    """The friction law of a scene at one mu (``[friction]``, ``"mu.NAME"`` resolved).

    ``law``: ``"tresca"`` (``threshold`` s, Pa) or ``"coulomb"`` (``coefficient`` nu_F, a
    number, or ``coefficient_law`` the name of a slip law ``F(|u_t|)``, model B of the talk
    "On coupling of complementarity with friction in contact shape optimization").
    """

    law: str
    threshold: float | None = None
    coefficient: float | None = None
    coefficient_law: str | None = None


@dataclass
class LoadStep:
    """One load step of a :class:`FrictionProblem` (``Discretization.dirichlet_steps``).

    ``F``: load on the free dofs with the step's lifting moved to the right-hand side;
    ``Gn``: the lifted nodal normal gap ``G_nodal - B_nodal u_lift``; ``ut_lift``: the
    tangential jump of the lifting ``Bt_full u_lift`` (so that the full tangential jump is
    ``Bt u_free + ut_lift``); ``u_lift``: the global Dirichlet lifting of the step.
    """

    F: np.ndarray
    Gn: np.ndarray
    ut_lift: np.ndarray
    u_lift: np.ndarray


@dataclass
class FrictionProblem(_FreeDofs):
    """The algebraic HF friction problem on the free dofs (Benaceur et al., slides "Coulomb
    contact problem", "Algebraic formulation / Collocation method").

    Per load step, find ``u, lam_n, lam_t`` (one pair per collocation node) with
    ``A u + Bn^T lam_n + Bt^T lam_t = F``, Signorini on ``(lam_n, Gn - Bn u)`` and, with
    the slip of the step ``v = Bt u + ut_lift - ut_prev``: ``|lam_t| <= s``,
    ``|lam_t| < s => v = 0``, ``v != 0 => lam_t = +s sign(v)`` (the traction on the body
    is ``-lam_t``, :mod:`rbbench.hf.algebra.friction`); ``s = threshold`` (Tresca) or
    ``s = nu_F lam_n`` (Coulomb). ``ut_prev`` is the tangential jump at the end of the
    previous step (0 before the first).

    ``Bn = Mt^T diag(w) Un``, ``Bt = Mt^T diag(w) Ut`` on the free columns (P1 friction
    multipliers, :meth:`ContactOperators.B_nodal`, :meth:`ContactOperators.Bt`): ``lam_n``,
    ``lam_t`` are the nodal values of P1 traction fields (Pa), so the Tresca threshold
    per node is ``s`` itself (Pa) and the Coulomb wedge ``|lam_t| <= nu_F lam_n`` is
    nodal. ``Bt u`` is weighted by the hat functions (m^2); ``node_weights = int phi_i``
    turns it into the mean jump near node i (m), the ``t`` of a slip law ``F(t)``.

    ``F``, ``Gn``, ``u_lift`` are those of the last step (``expand`` gives its ``u``);
    ``steps`` holds every step in order. ``W`` is the Gram matrix of the friction
    multipliers (``Wt``).
    """

    A: sp.csr_matrix
    F: np.ndarray
    Bn: sp.csr_matrix
    Gn: np.ndarray
    Bt: sp.csr_matrix
    free: np.ndarray
    u_lift: np.ndarray
    X: sp.csr_matrix
    W: sp.csr_matrix
    law: str
    steps: list[LoadStep]
    node_weights: np.ndarray
    threshold: np.ndarray | None = None
    coefficient: np.ndarray | None = None
    coefficient_law: str | None = None
    factorize: Factorize | None = None

    @property
    def n_nodes(self) -> int:
        """The number of collocation nodes (friction multiplier pairs)."""
        return int(self.Bn.shape[0])


@dataclass
class NitscheProblem(_FreeDofs):
    """The algebraic Nitsche contact problem on the free dofs (Benaceur et al., slides "Nitsche's
    method").

    Frictionless Signorini conditions in the Alart-Curnier form
    ``sigma_nn(u) = [P_gamma(u)]_-`` with ``P_gamma(u) = sigma_nn(u) - gamma (u_n - d^n)``
    (``[x]_- = min(x, 0)``), imposed weakly (Chouly & Hild 2013; Chouly, Hild & Renard
    2015): find ``u`` with, for every ``v``::

        a(u, v) - theta int 1/gamma sigma_nn(u) sigma_nn(v)
                + int 1/gamma [P_gamma(u)]_- (theta sigma_nn(v) - gamma v_n) = f(v)

    (``theta = 1``: Benaceur et al.'s symmetric variant, the optimality condition of the
    Nitsche energy; ``0``: skew-less; ``-1``: skew-symmetric). Integrals are the
    slave-side quadrature of the contact operators. Algebra: :mod:`rbbench.hf.algebra.nitsche`.

    Attributes
    ----------
    A, F : (n_free, n_free) sparse, (n_free,)
        Stiffness and load on the free dofs, the Dirichlet lifting moved to ``F``.
    Un, Snn : (n_q, n_free) sparse
        Normal jump and slave normal stress at the contact quadrature points (free
        columns).
    gap : (n_q,)
        Lifted gap ``d^n - Un u_lift`` (m): ``u_n - d^n = Un u_free - gap``.
    snn_lift : (n_q,)
        Normal stress of the lifting, ``Snn u_lift`` (Pa).
    weights : (n_q,)
        Quadrature weights on the mu-mapped boundary (m).
    gamma : (n_q,)
        Nitsche parameter per point, ``gamma0 * E / h_q`` (Pa/m).
    theta : float
        1, 0 or -1 (any real value is accepted).
    gamma0 : float
        Dimensionless Nitsche parameter.
    E : float
        Young's modulus (Pa) of the slave body used in the scaling.
    h : (n_q,)
        Slave facet length per point (m) used in the scaling.
    free, u_lift, X
        As in :class:`ContactProblem`.
    Mlam : (n_q, n_mult) sparse
        The mixed multiplier basis: the solver reports the contact pressure
        ``-[P_gamma(u)]_-`` L2-projected on it as ``SolveResult.lam``.
    factorize : Factorize or None
        The backend's direct solver (for ``theta = 1`` tangents), or ``None``.
    """

    A: sp.csr_matrix
    F: np.ndarray
    Un: sp.csr_matrix
    Snn: sp.csr_matrix
    gap: np.ndarray
    snn_lift: np.ndarray
    weights: np.ndarray
    gamma: np.ndarray
    theta: float
    gamma0: float
    E: float
    h: np.ndarray
    free: np.ndarray
    u_lift: np.ndarray
    X: sp.csr_matrix
    Mlam: sp.csr_matrix
    factorize: Factorize | None = None

    @property
    def W(self) -> sp.csr_matrix:
        """Gram matrix of the multiplier space, ``Mlam^T diag(w) Mlam``."""
        return (self.Mlam.T @ sp.diags(self.weights) @ self.Mlam).tocsr()


@dataclass
class NitscheStep:
    """One load step of a :class:`NitscheFrictionProblem` (``Discretization.dirichlet_steps``).

    ``F``: load on the free dofs with the step's lifting moved to the right-hand side;
    ``gap``, ``snn_lift``: as in :class:`NitscheProblem` for the step's lifting ``u_lift``;
    ``snt_lift``: the shear stress of the lifting ``Snt u_lift``; ``ut_lift``: its
    tangential jump ``Ut u_lift`` at the points (m).
    """

    F: np.ndarray
    gap: np.ndarray
    snn_lift: np.ndarray
    snt_lift: np.ndarray
    ut_lift: np.ndarray
    u_lift: np.ndarray


@dataclass
class NitscheFrictionProblem(NitscheProblem):
    """Nitsche contact with Tresca or Coulomb friction (Chouly 2014; Chouly, Hild & Renard
    2015; Renard 2013): :class:`NitscheProblem` plus the tangential term
    ``int 1/gamma [P_t(u)]_S P_theta,t(v) - theta int 1/gamma sigma_nt(u) sigma_nt(v)``
    with ``P_t(u) = sigma_nt(u) - gamma (u_t - ut_prev)`` (the slip of the load step) and
    ``[x]_S`` the projection on ``[-S, S]``, ``S = threshold`` (Tresca) or
    ``S = -F min(P_gamma(u), 0)`` (Coulomb). Algebra: :mod:`rbbench.hf.algebra.nitsche_friction`.

    The inherited fields ``F``, ``gap``, ``snn_lift``, ``u_lift`` and the fields
    ``snt_lift``, ``ut_lift``, ``ut_prev`` are those of the current load step (the last
    one as built; the solver replaces them step by step from ``steps``).

    Attributes
    ----------
    Ut, Snt : (n_q, n_free) sparse
        Tangential jump and slave shear stress ``sigma_nt`` at the points (free columns).
    snt_lift, ut_lift : (n_q,)
        ``Snt u_lift`` (Pa) and ``Ut u_lift`` (m) of the current step.
    ut_prev : (n_q,)
        Full tangential jump at the end of the previous step (0 before the first): the
        slip of the step is ``Ut u_free + ut_lift - ut_prev``.
    law : str
        ``"tresca"`` or ``"coulomb"``.
    steps : list of NitscheStep
        Every load step in order.
    threshold, coefficient : (n_q,) or None
        Tresca ``s`` (Pa) or Coulomb ``nu_F`` per point.
    coefficient_law : str or None
        A slip law ``F(|u_t|)`` (model B of the shape-optimisation talk) of the full
        tangential jump per point.
    """

    Ut: sp.csr_matrix | None = None
    Snt: sp.csr_matrix | None = None
    snt_lift: np.ndarray | None = None
    ut_lift: np.ndarray | None = None
    ut_prev: np.ndarray | None = None
    law: str = "tresca"
    steps: list[NitscheStep] = field(default_factory=list)
    threshold: np.ndarray | None = None
    coefficient: np.ndarray | None = None
    coefficient_law: str | None = None


@dataclass
class SolveResult:
    """Outcome of one HF solve; ``stop_reason`` is one of :data:`STOP_REASONS`."""

    u: np.ndarray
    lam: np.ndarray
    iterations: int
    stop_reason: str
    residuals: list[float] = field(default_factory=list)
    times: dict[str, float] = field(default_factory=dict)
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def converged(self) -> bool:
        return self.stop_reason == "converged"



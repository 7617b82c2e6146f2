"""The HF operators a backend assembles: the contact-boundary evaluation matrices
(:class:`ContactOperators`), the bodies' meshes and the :class:`Discretization` of a scene at
one parameter value."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

#: A direct solver: ``factorize(A)`` factorises a sparse SPD matrix once and returns
#: ``solve(b)`` for right-hand sides ``b`` of shape (n,) or (n, k).
Factorize = Callable[[sp.csr_matrix], Callable[[np.ndarray], np.ndarray]]


@dataclass
class ContactOperators:
    """Contact-boundary operators at contact quadrature points x_q on the slave side.

    Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
    variational inequalities" (talk), slide "HF model": ``b^n(v, eta) = int_{Gamma_c} v_n eta``,
    ``g^n(eta) = int_{Gamma_c} d^n eta``. With the matrices below,
    ``B = Mlam^T diag(weights) Un`` and ``G = Mlam^T diag(weights) gap``.

    Attributes
    ----------
    Un : (n_q, n_dofs) sparse
        Normal displacement jump ``(u_1(x_q) - u_2(pi(x_q))) . n_1(x_q)``, with
        ``n_1`` the outward normal of the slave body and ``pi`` the projection
        along ``n_1`` onto the master (zero master part for a rigid obstacle).
        For a scalar obstacle problem, ``-u(x_q)``.
    gap : (n_q,)
        Initial normal gap ``d^n(x_q)`` (m): the constraint is ``Un u <= gap``.
    weights : (n_q,)
        Quadrature weights on the current (mu-mapped) boundary (m).
    points, normals : (n_q, 2)
        Physical positions and slave normals of the quadrature points.
    Mlam : (n_q, n_mult) sparse
        Multiplier basis functions evaluated at the quadrature points.
    multiplier : str
        Multiplier space: ``"lac"`` (P0 per patch of facets), ``"p0"``, ``"p1"``
        (continuous nodal), or ``"nodal"`` (collocation, obstacle problems).
    mult_points : (n_mult, 2)
        A representative point of each multiplier's support (its centroid).
    mult_extent : (n_mult, 2)
        Horizontal extent ``[x_min, x_max]`` of each multiplier's support.
    Ut : (n_q, n_dofs) sparse or None
        Tangential displacement jump (only built for friction scenes).
    Snn : (n_q, n_dofs) sparse or None
        Normal stress ``sigma_nn(u)(x_q) = n_1 . sigma(u) n_1`` of the slave body at
        the quadrature points (Pa; only when asked: ``needs={"stress"}``, Nitsche).
        P1: constant on the slave element adjacent to the facet; P2: evaluated at x_q.
    facet_length : (n_q,) or None
        Physical length (m) of the slave facet holding each point (built with
        ``Snn``: the ``h`` of the Nitsche parameter ``gamma = gamma0 E / h``).
    Mt : (n_q, n_nodes) sparse or None
        The tangential (friction) multiplier basis at the quadrature points: continuous
        P1 hat functions of the slave contact nodes, whatever ``multiplier`` is (Benaceur et al.,
        slide "Collocation method": P1 multipliers, ``S = (d-1) R``, ``S_0 = R``). Built with
        ``Ut``.
    Snt : (n_q, n_dofs) sparse or None
        Shear stress ``sigma_nt(u)(x_q) = t_1 . sigma(u) n_1`` of the slave body at the
        quadrature points (Pa), ``t_1`` the tangent of ``Ut``; built only when both
        ``"stress"`` and ``"tangential"`` are asked for (Nitsche friction).
    colloc_points : (n_nodes, 2) or None
        The collocation nodes ``C(mu) = h(mu)(C_hat)`` of the tangential constraint: the
        slave contact nodes (the vertices of the slave chain, in its order) mapped by the
        geometry at mu. Built with ``Ut``.

    The tangent is ``t = (-n_y, n_x)`` (``n`` rotated by +90 degrees): on the bottom of
    the upper body (``n = (0, -1)``) it is ``+x``. ``lam_t`` enters
    ``A u + B^T lam_n + Bt^T lam_t = F`` as ``lam_n`` does (:mod:`rbbench.hf.algebra.friction`).
    """

    Un: sp.csr_matrix
    gap: np.ndarray
    weights: np.ndarray
    points: np.ndarray
    normals: np.ndarray
    Mlam: sp.csr_matrix
    multiplier: str
    mult_points: np.ndarray
    mult_extent: np.ndarray
    Ut: sp.csr_matrix | None = None
    Snn: sp.csr_matrix | None = None
    facet_length: np.ndarray | None = None
    Mt: sp.csr_matrix | None = None
    colloc_points: np.ndarray | None = None
    Snt: sp.csr_matrix | None = None

    @property
    def n_quad(self) -> int:
        return int(self.Un.shape[0])

    @property
    def n_mult(self) -> int:
        return int(self.Mlam.shape[1])

    def B(self) -> sp.csr_matrix:
        """``B = Mlam^T diag(w) Un`` (n_mult x n_dofs)."""
        return (self.Mlam.T @ sp.diags(self.weights) @ self.Un).tocsr()

    def G(self) -> np.ndarray:
        """``G = Mlam^T diag(w) gap`` (n_mult,)."""
        return np.asarray(self.Mlam.T @ (self.weights * self.gap)).ravel()

    def W(self) -> sp.csr_matrix:
        """Gram matrix of the multiplier space in L2(Gamma_c): ``Mlam^T diag(w) Mlam``."""
        return (self.Mlam.T @ sp.diags(self.weights) @ self.Mlam).tocsr()

    def _tangential(self) -> sp.csr_matrix:
        if self.Ut is None or self.Mt is None:
            raise ValueError("no tangential contact operators: they are built for friction "
                             "scenes only (Backend.discretize(mu, needs={'tangential'}))")
        return self.Mt

    def Bt(self) -> sp.csr_matrix:
        """``Bt = Mt^T diag(w) Ut`` (n_nodes x n_dofs): the tangential jump tested with the
        P1 friction multipliers (``ValueError`` for a frictionless scene)."""
        return (self._tangential().T @ sp.diags(self.weights) @ self.Ut).tocsr()

    def B_nodal(self) -> sp.csr_matrix:
        """``Mt^T diag(w) Un``: the normal constraint on the friction (P1) multipliers, so
        that ``(lam_n, lam_t)`` pair up per collocation node (equal to :meth:`B` when
        ``multiplier = "p1"``)."""
        return (self._tangential().T @ sp.diags(self.weights) @ self.Un).tocsr()

    def G_nodal(self) -> np.ndarray:
        """``Mt^T diag(w) gap`` (n_nodes,): :meth:`G` on the friction multipliers."""
        return np.asarray(self._tangential().T @ (self.weights * self.gap)).ravel()

    def Wt(self) -> sp.csr_matrix:
        """Gram matrix of the friction multipliers in L2(Gamma_c): ``Mt^T diag(w) Mt``."""
        Mt = self._tangential()
        return (Mt.T @ sp.diags(self.weights) @ Mt).tocsr()


@dataclass
class BodyMesh:
    """One body's mesh in the physical (mu-mapped) configuration, for output.

    ``vertex_dofs[i, c]`` is the global dof of component ``c`` at vertex ``i``
    (one column for a scalar problem).
    """

    name: str
    points: np.ndarray  # (n_vertices, 2)
    triangles: np.ndarray  # (n_triangles, 3)
    vertex_dofs: np.ndarray  # (n_vertices, n_components)
    E: float | None = None
    nu: float | None = None


@dataclass
class Discretization:
    """Sparse HF operators of a scene at one parameter value.

    ``A u = F`` on all dofs; Dirichlet dofs and values are given separately
    (the formulation eliminates them). ``X`` is the V inner product
    (parameter-independent: assembled on the reference configuration).
    ``factorize`` optionally supplies the backend's own direct solver
    (:data:`Factorize`) for stiffness matrices of this discretization, e.g. on
    the free dofs; ``None`` leaves the choice to the solver (scipy).
    ``dirichlet_steps``: for a friction scene, the Dirichlet values at each load step
    (``[load] load_steps``; ``dirichlet_values`` is the full load); ``None`` otherwise.
    """

    mu: np.ndarray
    A: sp.csr_matrix
    F: np.ndarray
    dirichlet_dofs: np.ndarray
    dirichlet_values: np.ndarray
    X: sp.csr_matrix
    contact: ContactOperators
    bodies: list[BodyMesh]
    physics: str
    info: dict[str, Any] = field(default_factory=dict)
    factorize: Factorize | None = None
    dirichlet_steps: list[np.ndarray] | None = None

    @property
    def n_dofs(self) -> int:
        return int(self.A.shape[0])

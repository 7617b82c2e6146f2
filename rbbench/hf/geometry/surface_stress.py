"""The slave normal stress ``sigma_nn`` at the 3D contact points (Nitsche's method): the
3D counterpart of :class:`~rbbench.hf.geometry.chains.SlaveStress`; numpy only."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from rbbench.hf.geometry.chains import _theta, lame_parameters
from rbbench.hf.geometry.surface import (
    SurfaceLayout,
    SurfacePairing,
    operators_from_pairing,
    pair_surfaces,
)
from rbbench.interfaces import ContactOperators

__all__ = ["SlaveSolid", "contact_operators_3d_stress", "normal_stress_3d", "tet_gradients"]

#: The edges of a tetrahedron whose midpoints are the P2 nodes 4 to 9, in this order.
TET_EDGES = ((0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3))


@dataclass
class SlaveSolid:
    """The slave body's tetrahedra next to its contact triangles.

    Nitsche's method (Chouly & Hild 2013; Benaceur et al. (talk), slide "Nitsche's method")
    needs ``sigma_nn(u) = n . sigma(u) n`` of the slave body on the contact surface, here
    from the Lagrange basis of the tetrahedron holding each slave triangle (P1: constant
    per element; P2: at the point), ``sigma = lambda tr(eps) I + 2 mu_L eps``.

    Attributes
    ----------
    tets : (n_tri, 4, 3)
        Reference vertices of the tetrahedron holding each slave triangle (in the order of
        ``SurfaceLayout.slave.triangles``).
    dofs : (n_tri, 4 or 10, 3)
        Global dofs of the tetrahedron's Lagrange basis: vertices 0 to 3, then (P2) the
        midpoints of edges (0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3); x, y, z.
    E, nu : (p + 1,)
        Young's modulus and Poisson's ratio as coefficients on ``theta(mu) = [1, mu]``.
    """

    tets: np.ndarray
    dofs: np.ndarray
    E: np.ndarray
    nu: np.ndarray

    def lame(self, mu: np.ndarray) -> tuple[float, float]:
        th = _theta(mu)
        return lame_parameters(float(self.E @ th), float(self.nu @ th))


def tet_gradients(tets: np.ndarray, x: np.ndarray, degree: int) -> np.ndarray:
    """Gradients (n, 4 or 10, 3) of the Lagrange shape functions of tetrahedra ``tets``
    (n, 4, 3) at points ``x`` (n, 3): ``grad l_i`` (P1); ``(4 l_i - 1) grad l_i`` at the
    vertices and ``4 (l_i grad l_j + l_j grad l_i)`` at the edge midpoints
    (:data:`TET_EDGES`) (P2)."""
    J = np.stack([tets[:, k] - tets[:, 0] for k in (1, 2, 3)], axis=2)  # columns: edges
    Jinv = np.linalg.inv(J)  # rows: grad l_1, grad l_2, grad l_3
    g = np.concatenate([-Jinv.sum(axis=1, keepdims=True), Jinv], axis=1)  # (n, 4, 3)
    if degree == 1:
        return g
    if degree != 2:
        raise ValueError(f"tetrahedron degree {degree!r} is not one of 1, 2")
    l123 = np.einsum("nij,nj->ni", Jinv, x - tets[:, 0])
    lam = np.concatenate([1.0 - l123.sum(axis=1, keepdims=True), l123], axis=1)
    vert = (4.0 * lam - 1.0)[:, :, None] * g
    mid = np.stack([4.0 * (lam[:, i, None] * g[:, j] + lam[:, j, None] * g[:, i])
                    for i, j in TET_EDGES], axis=1)
    return np.concatenate([vert, mid], axis=1)


def normal_stress_3d(layout: SurfaceLayout, solid: SlaveSolid, mu: np.ndarray,
                     pairing: SurfacePairing | None = None) -> sp.csr_matrix:
    """``Snn`` (n_q x n_dofs): ``sigma_nn(u)(x_q)`` of the slave body at the points of
    ``pairing`` (default: all, :func:`pair_surfaces`).

    ``sigma_nn = lambda div u + 2 mu_L (n . grad u n)``: the coefficient of component
    ``d`` of node ``k`` is ``lambda g_d + 2 mu_L n_d (n . g)`` with
    ``g = grad phi_k / s(mu)`` (a similarity map scales gradients by ``1/s``).
    """
    p = pair_surfaces(layout, mu) if pairing is None else pairing
    s, c = layout.slave.map.at(mu)
    x_hat = (p.x - c) / s
    degree = 1 if solid.dofs.shape[1] == 4 else 2
    g = tet_gradients(solid.tets[p.tq], x_hat, degree) / s  # (nq, k, 3)
    lam, mu_l = solid.lame(mu)
    gn = np.einsum("qkd,qd->qk", g, p.nrm)
    coef = lam * g + 2.0 * mu_l * p.nrm[:, None, :] * gn[:, :, None]
    nq = p.w.size
    rows = np.repeat(np.arange(nq), coef.shape[1] * 3)
    return sp.csr_matrix((coef.ravel(), (rows, solid.dofs[p.tq].ravel())),
                         shape=(nq, layout.n_dofs))


def contact_operators_3d_stress(layout: SurfaceLayout, solid: SlaveSolid, mu: np.ndarray
                                ) -> ContactOperators:
    """:func:`~rbbench.hf.geometry.surface.contact_operators_3d` with ``Snn``
    (:func:`normal_stress_3d`) and ``facet_length``: the diameter (longest edge, m) of
    each point's slave triangle, the ``h`` of the Nitsche parameter ``gamma0 E / h``; one
    pairing for both."""
    p = pair_surfaces(layout, mu)
    v0, v1, v2 = layout.slave.vertices(mu)
    diam = np.max([np.linalg.norm(a - b, axis=1) for a, b in ((v0, v1), (v1, v2), (v0, v2))],
                  axis=0)
    return replace(operators_from_pairing(layout, p, mu),
                   Snn=normal_stress_3d(layout, solid, mu, p), facet_length=diam[p.tq])

"""Backend-agnostic contact geometry on polygonal boundaries (numpy only).

Pairing choice (documented): *Gauss-point-to-segment* on the reference
configuration mapped by mu. Quadrature points live on the slave facets; each
is projected along the slave's outward normal onto the master boundary (a ray
cast); the normal gap is the ray parameter. The normal is the facet's own
(``[discretization] normals = "facet"``, piecewise constant) or, with
``"smooth"``, interpolated along each facet between vertex normals averaged
over the two adjacent facets (:func:`with_vertex_normals`): continuous along
the chain, so ``u . n`` has no jump at the vertices where a large displacement
meets a kink of the polygon (README "Nitsche", the e_AC table).

Integration (``[discretization] contact_integration``): ``"gauss"``, the layout's
Gauss rule on every slave facet (fixed points, as hyper-reduction needs), or
``"segmented"``, the same rule on each piece of a slave facet between the points
whose rays hit a master vertex (:func:`segmented_rule`). The integrands are
then polynomial on every piece, so the master's shape functions are integrated
exactly: the mortar-style segment-to-segment integration that passes the contact
patch test on non-matching meshes, which Gauss-point-to-segment does not
(Zavarise & De Lorenzis 2009; Puso & Laursen 2004). The constraint is imposed
weakly against the multiplier space, ``int (u_n - d^n) eta <= 0`` for
``eta >= 0``, which is the Lagrange-multiplier (mortar-like) form of Benaceur, Drouet,
Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric variational inequalities"
(talk), slide "HF model", integrated with slave-side quadrature.

The code lives in :mod:`rbbench.hf.geometry.facets` (Gauss rules, shape functions, normals, ray
casts, multiplier bases), :mod:`rbbench.hf.geometry.chains` (body maps, facet chains, vertex
normals, slave stress), :mod:`rbbench.hf.geometry.pairing` (layout, pairing, segmented rule); this
module assembles the contact operators and re-exports those names.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from rbbench.hf.geometry.chains import (
    AffineMap,
    FacetChain,
    SlaveStress,
    lagrange_gradients,
    lame_parameters,
    normal_stress_terms,
    with_vertex_normals,
)
from rbbench.hf.geometry.facets import (
    facet_shape,
    gauss_legendre_01,
    multiplier_basis,
    outward_normals,
    ray_cast,
    ray_cast_window,
    window_tangent_ranges,
)
from rbbench.hf.geometry.pairing import (
    ContactLayout,
    Pairing,
    PairingError,
    master_vertex_hits,
    pair,
    segmented_rule,
)
from rbbench.interfaces import ContactOperators

__all__ = [
    "AffineMap",
    "ContactLayout",
    "FacetChain",
    "Pairing",
    "PairingError",
    "SlaveStress",
    "collocation_nodes",
    "contact_operators",
    "facet_shape",
    "friction_multipliers",
    "gauss_legendre_01",
    "lagrange_gradients",
    "lame_parameters",
    "master_vertex_hits",
    "multiplier_basis",
    "normal_stress",
    "normal_stress_terms",
    "outward_normals",
    "pair",
    "ray_cast",
    "ray_cast_window",
    "segmented_rule",
    "tangential_stress",
    "window_tangent_ranges",
    "with_vertex_normals",
]


def _stress_terms(layout: ContactLayout, p: Pairing, mu: np.ndarray, slave: FacetChain | None,
                  direction: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`normal_stress_terms` of ``e . sigma(u) e`` along the unit vectors ``direction``
    (n_q, 2) at the points of ``p`` (``ValueError`` without slave stress data)."""
    if layout.stress is None:
        raise ValueError("the contact layout carries no slave stress data (SlaveStress): "
                         "the backend cannot evaluate sigma_nn")
    slave = layout.slave if slave is None else slave
    return normal_stress_terms(layout.stress, slave, layout.degree, p.fq, p.sq, direction, mu)


def _point_matrix(coef: np.ndarray, dofs: np.ndarray, n_cols: int) -> sp.csr_matrix:
    """The (n_q x n_cols) matrix with ``coef[q, j]`` at column ``dofs[q, j]`` of row ``q``."""
    nq = coef.shape[0]
    rows = np.repeat(np.arange(nq), coef.shape[1])
    return sp.csr_matrix((coef.ravel(), (rows, dofs.ravel())), shape=(nq, n_cols))


def normal_stress(layout: ContactLayout, p: Pairing, mu: np.ndarray,
                  slave: FacetChain | None = None, n_dofs: int | None = None
                  ) -> sp.csr_matrix:
    """``Snn`` (n_q x n_dofs): the slave normal stress at the points of pairing ``p``.

    ``slave`` (default ``layout.slave``) is the chain ``p`` was computed on, with
    ``layout.stress`` aligned with it (:func:`normal_stress_terms`).
    """
    coef, dofs = _stress_terms(layout, p, mu, slave, p.nrm)
    return _point_matrix(coef, dofs, layout.n_dofs if n_dofs is None else n_dofs)


def tangential_stress(layout: ContactLayout, p: Pairing, mu: np.ndarray,
                      slave: FacetChain | None = None, n_dofs: int | None = None
                      ) -> sp.csr_matrix:
    """``Snt`` (n_q x n_dofs): the slave shear stress ``sigma_nt(u) = t . sigma(u) n`` at the
    points of pairing ``p``, ``t = (-n_y, n_x)`` (the tangent of ``Ut``).

    By polarisation of the symmetric ``sigma`` with the unit vectors ``e_+- = (n +- t) /
    sqrt(2)``: ``sigma_nt = (e_+ . sigma e_+ - e_- . sigma e_-) / 2``, each term by
    :func:`normal_stress_terms` (the ``lambda div u`` parts cancel; same dofs per point).
    """
    n = p.nrm
    t = np.stack([-n[:, 1], n[:, 0]], axis=1)
    cp, dofs = _stress_terms(layout, p, mu, slave, (n + t) / np.sqrt(2.0))
    cm, _ = _stress_terms(layout, p, mu, slave, (n - t) / np.sqrt(2.0))
    return _point_matrix(0.5 * (cp - cm), dofs, layout.n_dofs if n_dofs is None else n_dofs)


def contact_operators(layout: ContactLayout, mu: np.ndarray,
                      tangential: bool = False, stress: bool = False) -> ContactOperators:
    """The full contact operators at mu (``Un``, gap, weights, multipliers; ``Ut``, ``Snn``
    on request).

    ``Un`` evaluates the normal jump ``(u1 - u2 o pi) . n1``; with
    ``tangential``, ``Ut`` evaluates ``(u1 - u2 o pi) . t1``, ``t1 = (-n_y, n_x)``, and
    ``Mt``, ``colloc_points`` are the P1 friction multipliers and the collocation nodes
    (:func:`friction_multipliers`);
    with ``stress``, ``Snn`` the slave normal stress (:func:`normal_stress`) and
    ``facet_length`` the physical length of each point's slave facet; with both,
    ``Snt`` the slave shear stress ``sigma_nt`` (:func:`tangential_stress`, Nitsche friction).
    """
    p = pair(layout, mu)
    Un = p.jump(p.nrm, layout.n_dofs)
    Ut = (p.jump(np.stack([-p.nrm[:, 1], p.nrm[:, 0]], axis=1), layout.n_dofs)
          if tangential else None)
    Snn = normal_stress(layout, p, mu) if stress else None
    Snt = tangential_stress(layout, p, mu) if stress and tangential else None
    hq = np.linalg.norm(p.b - p.a, axis=1)[p.fq] if stress else None
    Mlam = multiplier_basis(layout.multiplier, layout.n_facets, layout.slave.ids[p.fq], p.sq,
                            layout.patch)
    mw = np.asarray(Mlam.T @ p.w).ravel()
    mpts = np.asarray(Mlam.T @ (p.w[:, None] * p.x)) / mw[:, None]
    # horizontal extent of each multiplier's support
    ext = np.zeros((Mlam.shape[1], 2))
    coo = Mlam.tocoo()
    xs = p.x[coo.row, 0]
    ext[:, 0], ext[:, 1] = np.inf, -np.inf
    fa, fb = p.a[p.fq][coo.row, 0], p.b[p.fq][coo.row, 0]
    np.minimum.at(ext[:, 0], coo.col, np.minimum(np.minimum(fa, fb), xs))
    np.maximum.at(ext[:, 1], coo.col, np.maximum(np.maximum(fa, fb), xs))
    Mt, colloc = (friction_multipliers(layout, p, mu) if tangential else (None, None))
    return ContactOperators(Un=Un, gap=p.gap, weights=p.w, points=p.x, normals=p.nrm,
                            Mlam=Mlam, multiplier=layout.multiplier, mult_points=mpts,
                            mult_extent=ext, Ut=Ut, Snn=Snn, facet_length=hq, Mt=Mt,
                            colloc_points=colloc, Snt=Snt)


def collocation_nodes(layout: ContactLayout) -> np.ndarray:
    """``C_hat`` (n_facets + 1, 2): the slave contact nodes in reference coordinates, in
    the order of the chain (the start of every facet, then the end of the last one)."""
    slave = layout.slave
    if slave.n != layout.n_facets or not np.array_equal(slave.ids, np.arange(slave.n)):
        raise ValueError("collocation nodes need the full slave chain of the layout")
    return np.vstack([slave.a, slave.b[-1:]])


def friction_multipliers(layout: ContactLayout, p: Pairing, mu: np.ndarray
                         ) -> tuple[sp.csr_matrix, np.ndarray]:
    """``(Mt, C(mu))``: the P1 friction multipliers at the points of pairing ``p`` and the
    collocation nodes ``C(mu) = h(mu)(C_hat)`` (:func:`collocation_nodes`).

    Benaceur et al., slides "Algebraic formulation / Collocation method": P1 multipliers, one
    tangential multiplier per slave contact node (``S = (d-1) R = R`` in 2D).
    """
    Mt = multiplier_basis("p1", layout.n_facets, layout.slave.ids[p.fq], p.sq)
    return Mt, layout.slave.map(mu, collocation_nodes(layout))

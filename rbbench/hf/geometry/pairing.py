"""The contact layout of a scene and the pairing of slave quadrature points with the master
at mu: Gauss-point-to-segment, or segment-to-segment on the pieces between master-vertex
rays (:func:`segmented_rule`).

Part of the contact geometry (:mod:`rbbench.hf.geometry.operators`, whose docstring gives
the choices); numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from rbbench.hf.geometry.chains import FacetChain, SlaveStress
from rbbench.hf.geometry.facets import (
    facet_shape,
    gauss_legendre_01,
    multiplier_basis,
    outward_normals,
    ray_cast,
    ray_cast_window,
)

__all__ = ["ContactLayout", "Pairing", "PairingError", "master_vertex_hits", "pair",
           "segmented_rule"]


class PairingError(ValueError):
    """A slave quadrature point found no master facet along its normal."""

    def __init__(self, n_missed: int, example: np.ndarray):
        self.n_missed = n_missed
        self.example = np.asarray(example, dtype=float)
        super().__init__(f"{n_missed} slave quadrature point(s) (e.g. x = "
                         f"{self.example.round(4).tolist()}) hit no master facet")


@dataclass
class ContactLayout:
    """Everything the GPTS pairing needs, in reference coordinates (small arrays only).

    A backend that provides it (``Backend.contact_layout()``) lets the core
    evaluate the contact operators at any mu, or only some of their rows
    (hyper-reduction), without the backend.

    Attributes
    ----------
    slave, master : FacetChain
        ``master = None`` is the rigid plane ``y = 0`` (outward normal ``+y``).
    degree : int
        Displacement degree on the facets (1 or 2).
    n_gauss : int
        Gauss points per slave facet.
    multiplier, patch : str, int
        Multiplier space (see :func:`multiplier_basis`) and LAC patch size.
    n_facets : int
        Number of facets of the full slave chain (fixes the multiplier numbering).
    n_dofs : int
        Global number of displacement dofs.
    stress : SlaveStress or None
        The slave elements next to the chain facets (aligned with ``slave``), for
        the normal stress ``Snn`` (Nitsche); ``None`` if the backend gives none.
    integration : str
        ``"gauss"`` (``n_gauss`` points per slave facet) or ``"segmented"`` (per
        piece between master-vertex rays, :func:`segmented_rule`; the points
        depend on mu).
    """

    slave: FacetChain
    master: FacetChain | None
    degree: int
    n_gauss: int
    multiplier: str
    patch: int
    n_facets: int
    n_dofs: int
    stress: SlaveStress | None = None
    integration: str = "gauss"

    def __post_init__(self):
        if self.integration not in ("gauss", "segmented"):
            raise ValueError(f"ContactLayout: integration = {self.integration!r}; valid: "
                             "'gauss', 'segmented'")

    @property
    def n_mult(self) -> int:
        return int(multiplier_basis(self.multiplier, self.n_facets, np.zeros(1, dtype=int),
                                    np.zeros(1), self.patch).shape[1])

    def facets_of_rows(self, rows: np.ndarray) -> np.ndarray:
        """Slave-chain positions of the facets in the support of multipliers ``rows``."""
        ids = np.arange(self.n_facets)
        s = np.full(ids.size, 0.5)
        M = multiplier_basis(self.multiplier, self.n_facets, ids, s, self.patch).tocsc()
        return np.unique(M[:, np.asarray(rows)].tocoo().row)


@dataclass
class Pairing:
    """Quadrature points of some slave facets at mu and their master projections."""

    x: np.ndarray  # (nq, 2) physical points
    nrm: np.ndarray  # (nq, 2) slave outward normals
    w: np.ndarray  # (nq,) weights
    fq: np.ndarray  # (nq,) local facet of each point
    sq: np.ndarray  # (nq,) local coordinate on the facet
    gap: np.ndarray  # (nq,)
    slave_phi: np.ndarray  # (nq, k)
    slave_dofs: np.ndarray  # (nq, k, 2)
    master_seg: np.ndarray | None  # (nq,) master facet (index into the chain given)
    master_phi: np.ndarray | None  # (nq, k)
    master_dofs: np.ndarray | None  # (nq, k, 2)
    a: np.ndarray  # (nf, 2) mapped slave facet starts
    b: np.ndarray  # (nf, 2) mapped slave facet ends

    def jump_terms(self, direction: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """``(coefficients, dofs)``, each (nq, 2 k), of the jump ``(u1 - u2 o pi) . direction``.

        Row q of the jump is ``sum_j coefficients[q, j] u[dofs[q, j]]`` summed over the
        slave term and (with a master) the master term.
        """
        nq = self.w.size
        terms = [((self.slave_phi[:, :, None] * direction[:, None, :]).reshape(nq, -1),
                  self.slave_dofs.reshape(nq, -1))]
        if self.master_phi is not None:
            terms.append((-(self.master_phi[:, :, None] * direction[:, None, :]).reshape(nq, -1),
                          self.master_dofs.reshape(nq, -1)))
        return terms

    def jump(self, direction: np.ndarray, n_dofs: int) -> sp.csr_matrix:
        """Rows q: ``(u1(x_q) - u2(pi(x_q))) . direction_q`` (nq x n_dofs)."""
        terms = self.jump_terms(direction)
        rows = np.repeat(np.arange(self.w.size), terms[0][0].shape[1])
        return sp.csr_matrix((np.concatenate([c.ravel() for c, _ in terms]),
                              (np.tile(rows, len(terms)),
                               np.concatenate([d.ravel() for _, d in terms]))),
                             shape=(self.w.size, n_dofs))


def pair(layout: ContactLayout, mu: np.ndarray, slave: FacetChain | None = None,
         master: FacetChain | None = None,
         windows: tuple[np.ndarray, ...] | None = None,
         local: tuple[np.ndarray, np.ndarray] | None = None) -> Pairing:
    """Pairing of the slave quadrature points with the master at mu (module docstring):
    Gauss-point-to-segment, or segment-to-segment with ``layout.integration ==
    "segmented"``.

    ``slave`` / ``master`` default to the layout's chains; a subset chain and
    per-point ``windows = (lo, hi)`` of master facets (indices into an ordered
    ``master`` chain, :func:`ray_cast_window`) restrict the work to some rows
    (hyper-reduction). ``local = (s, w)``: points at local coordinates ``s`` of every
    facet with weights ``w`` (times the facet length) instead of the layout's Gauss
    rule. Raises :class:`PairingError` when a point hits no master facet.
    """
    slave = layout.slave if slave is None else slave
    master = layout.master if master is None else master
    a, b = slave.map(mu, slave.a), slave.map(mu, slave.b)
    sg, wg = gauss_legendre_01(layout.n_gauss) if local is None else local
    nf, ng = slave.n, len(sg)
    if layout.integration == "segmented" and local is None and master is not None:
        if windows is not None:
            raise ValueError("contact_integration = 'segmented' has mu-dependent points: "
                             "windowed pairing (hyper-reduction) needs 'gauss'")
        fq, sq, wq = segmented_rule(slave, master, mu, sg, wg)
    else:
        fq = np.repeat(np.arange(nf), ng)
        sq = np.tile(np.asarray(sg, dtype=float), nf)
        wq = np.tile(wg, nf)
    x = a[fq] + sq[:, None] * (b[fq] - a[fq])
    nrm = slave.normals_at(mu, fq, sq)
    w = wq * np.linalg.norm(b - a, axis=1)[fq]
    phi = facet_shape(sq, layout.degree)
    sdofs = slave.dofs[fq]
    if master is None:  # rigid plane y = 0
        return Pairing(x, nrm, w, fq, sq, -x[:, 1] / nrm[:, 1], phi, sdofs, None, None, None,
                       a, b)
    ma, mb = master.map(mu, master.a), master.map(mu, master.b)
    if windows is None:
        seg, s2, gap = ray_cast(x, nrm, ma, mb)
    else:
        seg, s2, gap = ray_cast_window(x, nrm, ma, mb, *windows)  # (lo, hi[, ranges])
    if np.any(seg < 0):
        raise PairingError(int(np.sum(seg < 0)), x[seg < 0][0])
    return Pairing(x, nrm, w, fq, sq, gap, phi, sdofs, seg, facet_shape(s2, layout.degree),
                   master.dofs[seg], a, b)


def _cross(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]


def master_vertex_hits(slave: FacetChain, master: FacetChain, mu: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray]:
    """Where the slave rays hit master vertices: ``(facet, s)`` pairs, s in (0, 1).

    On slave facet ``i``, ``x(s) = a + s (b - a)`` and the (unnormalised) normal
    ``n(s) = n_a + s (n_b - n_a)`` (the facet normal when constant); the ray
    ``x(s) + t n(s)`` passes through the master vertex ``m`` where
    ``cross(n(s), m - x(s)) = 0``, a quadratic in ``s``. A root counts when the ray
    cast from ``x(s)`` along the normal :func:`pair` uses there
    (:meth:`FacetChain.normals_at`; :func:`ray_cast`) hits the master facet that ``m``
    ends (so vertices behind other facets, or out of reach, are ignored). Shared
    vertices are tested once per facet; the duplicates give the same cut.
    """
    a, b = slave.map(mu, slave.a), slave.map(mu, slave.b)
    ma, mb = master.map(mu, master.a), master.map(mu, master.b)
    # every facet's two ends, tagged with their facet (a chain may have gaps)
    mv, owner = np.vstack([ma, mb]), np.tile(np.arange(master.n), 2)
    if slave.na is None:
        na = nb = outward_normals(a, b, slave.map(mu, slave.inner))
    else:
        na, nb = slave.na, slave.nb
    dn, dx = (nb - na)[:, None, :], (b - a)[:, None, :]
    r = mv[None, :, :] - a[:, None, :]  # (nf, nv, 2)
    c0 = _cross(na[:, None, :], r)
    c1 = _cross(dn, r) - _cross(na[:, None, :], dx)
    c2 = np.broadcast_to(-_cross(dn, dx), c0.shape)
    scale = np.abs(c1) + np.abs(c0)
    quad = np.abs(c2) > 1e-12 * np.maximum(scale, 1e-300)
    disc = c1**2 - 4.0 * c2 * c0
    with np.errstate(divide="ignore", invalid="ignore"):
        sq = np.sqrt(np.where(quad & (disc >= 0), disc, np.nan))
        q = -0.5 * (c1 + np.copysign(sq, c1))  # stable roots q / c2, c0 / q
        roots = np.stack([np.where(quad, q / c2, -c0 / c1), np.where(quad, c0 / q, np.nan)])
    ok = np.isfinite(roots) & (roots > 1e-12) & (roots < 1.0 - 1e-12)
    k, fi, vi = np.nonzero(ok)
    s = roots[k, fi, vi]
    if s.size == 0:
        return fi, s
    x = a[fi] + s[:, None] * (b[fi] - a[fi])
    seg, _, _ = ray_cast(x, slave.normals_at(mu, fi, s), ma, mb)
    keep = seg == owner[vi]  # the ray ends on that facet, at that end
    return fi[keep], s[keep]


def segmented_rule(slave: FacetChain, master: FacetChain, mu: np.ndarray, sg: np.ndarray,
                   wg: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Segment-to-segment quadrature: ``(fq, sq, wq)`` (facet, local coordinate, weight
    relative to the facet length) of the rule ``(sg, wg)`` on [0, 1] applied on each
    piece of every slave facet between the points of :func:`master_vertex_hits`."""
    fi, s = master_vertex_hits(slave, master, mu)
    nf = slave.n
    cuts = np.concatenate([np.arange(nf, dtype=float), np.arange(nf) + 1.0, fi + s])
    cuts = np.unique(cuts)  # sorted breakpoints on the chain parameter facet + s
    lo, hi = cuts[:-1], cuts[1:]
    facet = np.floor(lo).astype(np.int64)
    keep = hi - lo > 1e-12
    lo, hi, facet = lo[keep] - facet[keep], hi[keep] - facet[keep], facet[keep]
    sg, wg = np.asarray(sg, dtype=float), np.asarray(wg, dtype=float)
    sq = lo[:, None] + (hi - lo)[:, None] * sg[None, :]
    wq = (hi - lo)[:, None] * wg[None, :]
    return np.repeat(facet, sg.size), sq.ravel(), wq.ravel()

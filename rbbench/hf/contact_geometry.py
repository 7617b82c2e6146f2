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
``eta >= 0``, which is the Lagrange-multiplier (mortar-like) form of seed 000
("HF model"), integrated with slave-side quadrature.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from rbbench.interfaces import ContactOperators


def _theta(mu: np.ndarray) -> np.ndarray:
    """``theta(mu) = [1, mu_1, ..., mu_p]``: the affine-in-mu scene values are
    coefficient vectors on it."""
    return np.concatenate([[1.0], np.atleast_1d(np.asarray(mu, dtype=float))])


@lru_cache(maxsize=16)
def _gauss_legendre_01(n: int) -> tuple[np.ndarray, np.ndarray]:
    x, w = np.polynomial.legendre.leggauss(n)
    x, w = 0.5 * (x + 1.0), 0.5 * w
    x.setflags(write=False)
    w.setflags(write=False)
    return x, w


def gauss_legendre_01(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre points and weights on [0, 1] (cached, read-only arrays)."""
    return _gauss_legendre_01(int(n))


def facet_shape(s: np.ndarray, degree: int) -> np.ndarray:
    """1-D Lagrange shape functions on a facet, local coordinate s in [0, 1].

    Returns (len(s), degree + 1) with the order [start vertex, end vertex, midpoint].
    """
    s = np.asarray(s, dtype=float)
    if degree == 1:
        return np.stack([1.0 - s, s], axis=-1)
    if degree == 2:
        return np.stack([(1 - s) * (1 - 2 * s), s * (2 * s - 1), 4 * s * (1 - s)], axis=-1)
    raise ValueError(f"facet degree {degree} not supported (1 or 2)")


def outward_normals(a: np.ndarray, b: np.ndarray, inner: np.ndarray) -> np.ndarray:
    """Unit normals of segments a->b pointing away from the points ``inner`` (one per segment)."""
    d = b - a
    n = np.stack([d[:, 1], -d[:, 0]], axis=1)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    flip = np.einsum("ij,ij->i", n, inner - 0.5 * (a + b)) > 0
    n[flip] *= -1.0
    return n


def ray_cast(x: np.ndarray, n: np.ndarray, a: np.ndarray, b: np.ndarray,
             tol: float = 1e-10, candidates: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Project points ``x`` along directions ``n`` onto segments ``[a_j, b_j]``.

    Returns ``(segment, s, t)`` with ``x + t n = a + s (b - a)``; among the hits
    the one with the smallest ``|t|`` is kept. ``segment = -1`` where no
    segment is hit. ``candidates`` (n_points, K), padded with -1, restricts the
    segments tried for each point (the hyper-reduced evaluator's windows);
    ``None`` tries every segment.
    """
    nx = x.shape[0]
    if candidates is None:
        idx = np.broadcast_to(np.arange(a.shape[0]), (nx, a.shape[0]))
        valid = np.ones(idx.shape, dtype=bool)
        A, D = a[None, :, :], (b - a)[None, :, :]
    else:
        valid = candidates >= 0
        idx = np.where(valid, candidates, 0)
        A, D = a[idx], (b - a)[idx]
    # Solve [n, -d] [t, s]^T = a - x for every (point, segment) pair.
    det = n[:, None, 0] * (-D[..., 1]) - n[:, None, 1] * (-D[..., 0])
    r = A - x[:, None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (r[..., 0] * (-D[..., 1]) - r[..., 1] * (-D[..., 0])) / det
        s = (n[:, None, 0] * r[..., 1] - n[:, None, 1] * r[..., 0]) / det
    ok = valid & (np.abs(det) > 1e-14) & (s >= -tol) & (s <= 1 + tol)
    score = np.where(ok, np.abs(t), np.inf)
    j = np.argmin(score, axis=1)
    rows = np.arange(nx)
    hit = np.isfinite(score[rows, j])
    seg = np.where(hit, idx[rows, j], -1)
    return seg, np.clip(s[rows, j], 0.0, 1.0), np.where(hit, t[rows, j], np.nan)


def window_tangent_ranges(a: np.ndarray, b: np.ndarray, lo: np.ndarray,
                          hi: np.ndarray) -> np.ndarray:
    """Per window ``lo .. hi`` of chain facets, the range ``[alpha, beta]`` of facet directions.

    Angles of ``b - a`` unwrapped from the window's first facet, (n_windows, 2). A
    similarity map with a scalar scale (:class:`AffineMap`) leaves them unchanged, so
    they can be computed once on the reference chain. O(windows x width).
    """
    phi = np.arctan2(*(b - a).T[::-1])
    width = int((hi - lo).max()) + 1 if lo.size else 1
    idx = lo[:, None] + np.arange(width)[None, :]
    inside = idx <= hi[:, None]
    idx = np.where(inside, idx, lo[:, None])
    rel = np.angle(np.exp(1j * (phi[idx] - phi[lo][:, None])))  # wrapped to (-pi, pi]
    rel = np.where(inside, rel, 0.0)
    return np.stack([phi[lo] + rel.min(axis=1), phi[lo] + rel.max(axis=1)], axis=1)


def ray_cast_window(x: np.ndarray, n: np.ndarray, a: np.ndarray, b: np.ndarray,
                    lo: np.ndarray, hi: np.ndarray, ranges: np.ndarray | None = None,
                    tol: float = 1e-10) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`ray_cast` of each point against its window of chain facets ``lo .. hi``.

    ``a``, ``b`` form an ordered chain (``b[j] == a[j + 1]``). The side of each chain
    vertex relative to the ray line, ``cross(n, P_j - x)``, is monotone along the
    window when ``cross(n, b_j - a_j)`` has one sign for every facet of the window,
    i.e. when no facet direction in ``ranges`` (:func:`window_tangent_ranges`,
    computed here if not given) is parallel to ``n``. Then the line crosses the
    window at most once: its facet is found by bisection in ``O(log(hi - lo))`` and
    confirmed by an exact ray cast on it and its two neighbours. Every other point
    (a direction parallel to ``n`` in its window, e.g. a wavy chain, or no confirmed
    hit) is cast by brute force over its window. So the result equals
    :func:`ray_cast` restricted to the window.
    """
    verts = np.vstack([a, b[-1:]])  # chain vertices 0 .. n_facets
    if ranges is None:
        ranges = window_tangent_ranges(a, b, lo, hi)
    # monotone side function: [alpha - theta_n, beta - theta_n] holds no multiple of pi
    th = np.arctan2(n[:, 1], n[:, 0])
    eps = 1e-9
    lo_k = np.floor((ranges[:, 0] - th - eps) / np.pi)
    hi_k = np.floor((ranges[:, 1] - th + eps) / np.pi)
    monotone = lo_k == hi_k

    def side(j: np.ndarray) -> np.ndarray:
        d = verts[j] - x
        return n[:, 0] * d[:, 1] - n[:, 1] * d[:, 0]

    left, right = lo.astype(np.int64).copy(), hi.astype(np.int64) + 1  # vertex indices
    f_left = np.sign(side(left))
    for _ in range(int(np.ceil(np.log2(max(int((right - left).max()), 1)))) + 1):
        mid = (left + right) // 2
        f_mid = np.sign(side(mid))
        same = f_mid == f_left
        left = np.where(same, mid, left)
        right = np.where(same, right, mid)
    cand = left[:, None] + np.arange(-1, 2)[None, :]
    cand = np.where((cand >= lo[:, None]) & (cand <= hi[:, None]), cand, -1)
    seg, s, t = ray_cast(x, n, a, b, tol, candidates=cand)
    bad = np.flatnonzero((seg < 0) | ~monotone)
    if bad.size:
        width = int((hi[bad] - lo[bad]).max()) + 1
        full = lo[bad, None] + np.arange(width)[None, :]
        full = np.where(full <= hi[bad, None], full, -1)
        seg[bad], s[bad], t[bad] = ray_cast(x[bad], n[bad], a, b, tol, candidates=full)
    return seg, s, t


def multiplier_basis(kind: str, n_facets: int, facet_of_q: np.ndarray, s_q: np.ndarray,
                     patch: int = 2) -> sp.csr_matrix:
    """Multiplier basis at quadrature points for slave facets ordered along the zone.

    * ``"lac"``: P0 per patch of ``patch`` consecutive facets (Local Average
      Contact, Abbas-Drouet-Hild 2018, used by seed 000 with P1 displacements);
      a remainder shorter than a patch joins the last patch.
    * ``"p0"``: P0 per facet.
    * ``"p1"``: continuous P1 along the chain of facets (nodal values).
    """
    nq = facet_of_q.size
    rows = np.arange(nq)
    if kind in ("lac", "p0"):
        size = patch if kind == "lac" else 1
        n_mult = max(n_facets // size, 1)
        col = np.minimum(facet_of_q // size, n_mult - 1)
        return sp.csr_matrix((np.ones(nq), (rows, col)), shape=(nq, n_mult))
    if kind == "p1":
        vals = np.concatenate([1.0 - s_q, s_q])
        cols = np.concatenate([facet_of_q, facet_of_q + 1])
        return sp.csr_matrix((vals, (np.concatenate([rows, rows]), cols)),
                             shape=(nq, n_facets + 1))
    raise ValueError(f"multiplier space {kind!r} is not one of 'lac', 'p0', 'p1'")


# ---------------------------------------------------------------------------
# contact layout: the reference contact data of a scene, mapped by mu
# ---------------------------------------------------------------------------
class PairingError(ValueError):
    """A slave quadrature point found no master facet along its normal."""

    def __init__(self, n_missed: int, example: np.ndarray):
        self.n_missed = n_missed
        self.example = np.asarray(example, dtype=float)
        super().__init__(f"{n_missed} slave quadrature point(s) (e.g. x = "
                         f"{self.example.round(4).tolist()}) hit no master facet")


@dataclass
class AffineMap:
    """Similarity map ``x = s(mu) x_hat + c(mu)`` of a reference body.

    ``s`` and ``c`` are affine in mu (scene values are constants or ``"mu.NAME"``),
    stored as coefficients on ``theta(mu) = [1, mu_1, ..., mu_p]``: ``scale``
    (p + 1,), ``shift`` (2, p + 1).
    """

    scale: np.ndarray
    shift: np.ndarray

    def at(self, mu: np.ndarray) -> tuple[float, np.ndarray]:
        th = _theta(mu)
        return float(self.scale @ th), self.shift @ th

    def __call__(self, mu: np.ndarray, x_hat: np.ndarray) -> np.ndarray:
        """Mapped points (n, 2) from reference points (n, 2)."""
        s, c = self.at(mu)
        return s * x_hat + c


@dataclass
class FacetChain:
    """Facets of one body's potential contact boundary, ordered along it (reference coords).

    Attributes
    ----------
    a, b : (nf, 2)
        Start and end vertices (the order of the chain).
    inner : (nf, 2)
        A point inside the body next to each facet (orients the normals).
    dofs : (nf, degree + 1, 2)
        Global dofs of the facet's trace: [start, end, (midpoint)] x component.
    map : AffineMap
        The body's map from the reference configuration at mu.
    ids : (nf,)
        Position of each facet in the full chain (a subset keeps its ids).
    na, nb : (nf, 2) or None
        Unit outward normals at the start and end vertex of each facet (reference;
        a similarity map leaves them unchanged), for normals interpolated along the
        facets (:func:`with_vertex_normals`); ``None``: the facet normal.
    """

    a: np.ndarray
    b: np.ndarray
    inner: np.ndarray
    dofs: np.ndarray
    map: AffineMap
    ids: np.ndarray
    na: np.ndarray | None = None
    nb: np.ndarray | None = None

    @property
    def n(self) -> int:
        return int(self.a.shape[0])

    def subset(self, idx: np.ndarray) -> FacetChain:
        idx = np.asarray(idx, dtype=np.int64)
        vn = {} if self.na is None else {"na": self.na[idx], "nb": self.nb[idx]}
        return replace(self, a=self.a[idx], b=self.b[idx], inner=self.inner[idx],
                       dofs=self.dofs[idx], ids=self.ids[idx], **vn)

    def normals_at(self, mu: np.ndarray, fq: np.ndarray, sq: np.ndarray) -> np.ndarray:
        """Unit outward normals (nq, 2) at local coordinates ``sq`` of facets ``fq``.

        The facet normal, or (with vertex normals) ``(1 - s) n_a + s n_b`` normalised.
        """
        if self.na is None:
            nrm = outward_normals(self.map(mu, self.a), self.map(mu, self.b),
                                  self.map(mu, self.inner))
            return nrm[fq]
        n = (1.0 - sq)[:, None] * self.na[fq] + sq[:, None] * self.nb[fq]
        sign = np.sign(self.map.at(mu)[0])  # a reflecting map (negative scale) flips them
        return sign * n / np.linalg.norm(n, axis=1, keepdims=True)


def with_vertex_normals(chain: FacetChain) -> FacetChain:
    """``chain`` with vertex normals: the normalised mean of the facet normals of the two
    facets sharing each vertex (one facet at the ends of the chain or of a gap).

    Interpolated along each facet (:meth:`FacetChain.normals_at`) they give a
    continuous normal field, the usual smoothing of node-to-segment contact
    (e.g. Wriggers, *Computational Contact Mechanics*, 2006, sec. 9.1.2). Facets
    must be ordered along the chain (``b[i] == a[i + 1]`` where they touch).
    """
    nf = outward_normals(chain.a, chain.b, chain.inner)
    na, nb = nf.copy(), nf.copy()
    if chain.n > 1:
        scale = np.linalg.norm(chain.b - chain.a, axis=1).min()
        touch = np.linalg.norm(chain.a[1:] - chain.b[:-1], axis=1) <= 1e-9 * scale
        mean = nf[:-1] + nf[1:]
        mean /= np.linalg.norm(mean, axis=1, keepdims=True)
        nb[:-1][touch] = mean[touch]
        na[1:][touch] = mean[touch]
    return replace(chain, na=na, nb=nb)


@dataclass
class SlaveStress:
    """The slave body's elements next to its contact facets: ``sigma_nn`` at contact points.

    Nitsche's method (seed 000, "Nitsche's method (1/2)"; Chouly & Hild 2013) needs
    the normal stress ``sigma_nn(u) = n . sigma(u) n`` of the slave body on the
    contact boundary. It is evaluated in the element adjacent to each slave facet
    from the Lagrange basis on that element (P1: constant per element; P2: at the
    point), plane strain ``sigma = lambda tr(eps) I + 2 mu_L eps``. The body map is a
    similarity ``x = s(mu) x_hat + c(mu)``, so physical gradients are reference
    gradients divided by ``s(mu)`` and the normals are the reference ones.

    Attributes
    ----------
    tri : (nf, 3, 2)
        Reference vertices of the triangle adjacent to each facet of the slave chain
        (chain order).
    dofs : (nf, n_loc, 2)
        Global dofs of the triangle's Lagrange basis: vertices 0, 1, 2, then (P2)
        the midpoints of the edges (0, 1), (1, 2), (2, 0); x component.
    E, nu : (p + 1,)
        Young's modulus and Poisson's ratio of the slave body as coefficients on
        ``theta(mu) = [1, mu_1, ..., mu_p]`` (scene values are affine in mu).
    """

    tri: np.ndarray
    dofs: np.ndarray
    E: np.ndarray
    nu: np.ndarray

    def subset(self, idx: np.ndarray) -> SlaveStress:
        idx = np.asarray(idx, dtype=np.int64)
        return replace(self, tri=self.tri[idx], dofs=self.dofs[idx])

    def material(self, mu: np.ndarray) -> tuple[float, float]:
        """``(E, nu)`` at mu."""
        th = _theta(mu)
        return float(self.E @ th), float(self.nu @ th)

    def lame(self, mu: np.ndarray) -> tuple[float, float]:
        """Plane-strain Lame parameters ``(lambda, mu_L)`` at mu (:func:`lame_parameters`)."""
        return lame_parameters(*self.material(mu))


def lame_parameters(E: float, nu: float) -> tuple[float, float]:
    """Plane-strain Lame parameters ``(lambda, mu)`` from Young's modulus and Poisson's ratio.

    ``lambda = E nu / ((1 + nu)(1 - 2 nu))``, ``mu = E / (2 (1 + nu))``: the same
    expressions, in the same floating-point order, as
    ``skfem.models.elasticity.lame_parameters``.
    """
    return E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu)), E / (2.0 * (1.0 + nu))


def lagrange_gradients(tri: np.ndarray, x: np.ndarray, degree: int) -> np.ndarray:
    """Gradients of the Lagrange shape functions of triangles ``tri`` at points ``x``.

    Parameters
    ----------
    tri : (n, 3, 2)
        Triangle vertices, one triangle per point.
    x : (n, 2)
        Points (in or on their triangle).
    degree : int
        1 (vertices) or 2 (vertices, then midpoints of edges (0,1), (1,2), (2,0)).

    Returns
    -------
    (n, 3 or 6, 2)
        ``grad phi_k(x)`` in the coordinates of ``tri``.
    """
    J = np.stack([tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]], axis=2)  # columns: edges
    Jinv = np.linalg.inv(J)  # rows: grad lambda_1, grad lambda_2
    g = np.stack([-Jinv[:, 0] - Jinv[:, 1], Jinv[:, 0], Jinv[:, 1]], axis=1)  # (n, 3, 2)
    if degree == 1:
        return g
    if degree != 2:
        raise ValueError(f"degree {degree} not supported (1 or 2)")
    l12 = np.einsum("nij,nj->ni", Jinv, x - tri[:, 0])
    lam = np.stack([1.0 - l12[:, 0] - l12[:, 1], l12[:, 0], l12[:, 1]], axis=1)  # (n, 3)
    vert = (4.0 * lam - 1.0)[:, :, None] * g
    edges = [(0, 1), (1, 2), (2, 0)]
    mid = np.stack([4.0 * (lam[:, i, None] * g[:, j] + lam[:, j, None] * g[:, i])
                    for i, j in edges], axis=1)
    return np.concatenate([vert, mid], axis=1)


def normal_stress_terms(stress: SlaveStress, slave: FacetChain, degree: int, fq: np.ndarray,
                        sq: np.ndarray, nrm: np.ndarray, mu: np.ndarray
                        ) -> tuple[np.ndarray, np.ndarray]:
    """``(c, d)``, each (n_q, 2 n_loc): ``sigma_nn(u)(x_q) = sum_j c[q, j] u[d[q, j]]``.

    ``fq``, ``sq``: facet (in ``slave``, aligned with ``stress``) and local coordinate
    of each point; ``nrm`` (n_q, 2) the slave normals. With ``g = grad phi_k / s(mu)``::

        sigma_nn = lambda div u + 2 mu_L (n . grad u n)
        c[k, x] = lambda g_x + 2 mu_L n_x (n_x g_x + n_y g_y)
        c[k, y] = lambda g_y + 2 mu_L n_y (n_x g_x + n_y g_y)
    """
    scale = slave.map.at(mu)[0]
    x_hat = slave.a[fq] + sq[:, None] * (slave.b[fq] - slave.a[fq])
    g = lagrange_gradients(stress.tri[fq], x_hat, degree) / scale  # (nq, k, 2)
    lam, mu_l = stress.lame(mu)
    gn = np.einsum("qkd,qd->qk", g, nrm)  # n . grad phi_k
    cx = lam * g[:, :, 0] + 2.0 * mu_l * nrm[:, 0, None] * gn
    cy = lam * g[:, :, 1] + 2.0 * mu_l * nrm[:, 1, None] * gn
    nq = fq.size
    coef = np.stack([cx, cy], axis=2).reshape(nq, -1)
    return coef, stress.dofs[fq].reshape(nq, -1)


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


def normal_stress(layout: ContactLayout, p: Pairing, mu: np.ndarray,
                  slave: FacetChain | None = None, n_dofs: int | None = None
                  ) -> sp.csr_matrix:
    """``Snn`` (n_q x n_dofs): the slave normal stress at the points of pairing ``p``.

    ``slave`` (default ``layout.slave``) is the chain ``p`` was computed on, with
    ``layout.stress`` aligned with it (:func:`normal_stress_terms`).
    """
    if layout.stress is None:
        raise ValueError("the contact layout carries no slave stress data (SlaveStress): "
                         "the backend cannot evaluate sigma_nn")
    slave = layout.slave if slave is None else slave
    coef, dofs = normal_stress_terms(layout.stress, slave, layout.degree, p.fq, p.sq,
                                     p.nrm, mu)
    nq = p.w.size
    rows = np.repeat(np.arange(nq), coef.shape[1])
    return sp.csr_matrix((coef.ravel(), (rows, dofs.ravel())),
                         shape=(nq, layout.n_dofs if n_dofs is None else n_dofs))


def contact_operators(layout: ContactLayout, mu: np.ndarray,
                      tangential: bool = False, stress: bool = False) -> ContactOperators:
    """The full contact operators at mu (``Un``, gap, weights, multipliers; ``Ut``, ``Snn``
    on request).

    ``Un`` evaluates the normal jump ``(u1 - u2 o pi) . n1``; with
    ``tangential``, ``Ut`` evaluates ``(u1 - u2 o pi) . t1``, ``t1 = (-n_y, n_x)``;
    with ``stress``, ``Snn`` the slave normal stress (:func:`normal_stress`) and
    ``facet_length`` the physical length of each point's slave facet.
    """
    p = pair(layout, mu)
    Un = p.jump(p.nrm, layout.n_dofs)
    Ut = (p.jump(np.stack([-p.nrm[:, 1], p.nrm[:, 0]], axis=1), layout.n_dofs)
          if tangential else None)
    Snn = normal_stress(layout, p, mu) if stress else None
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
    return ContactOperators(Un=Un, gap=p.gap, weights=p.w, points=p.x, normals=p.nrm,
                            Mlam=Mlam, multiplier=layout.multiplier, mult_points=mpts,
                            mult_extent=ext, Ut=Ut, Snn=Snn, facet_length=hq)

"""The reference contact boundaries of the bodies: mu-maps, ordered facet chains with
their (facet or vertex-interpolated) normals, and the slave elements that give the normal
stress ``sigma_nn`` (Nitsche).

Part of the contact geometry (:mod:`rbbench.hf.geometry.operators`); numpy only.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rbbench.hf.geometry.facets import outward_normals

__all__ = ["AffineMap", "FacetChain", "SlaveStress", "lagrange_gradients", "lame_parameters",
           "normal_stress_terms", "with_vertex_normals"]


def _theta(mu: np.ndarray) -> np.ndarray:
    """``theta(mu) = [1, mu_1, ..., mu_p]``: the affine-in-mu scene values are
    coefficient vectors on it."""
    return np.concatenate([[1.0], np.atleast_1d(np.asarray(mu, dtype=float))])


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

    Nitsche's method (Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction
    methods: parametric variational inequalities" (talk), slide "Nitsche's method (1/2)";
    Chouly & Hild 2013) needs the normal stress ``sigma_nn(u) = n . sigma(u) n`` of the slave
    body on the contact boundary. It is evaluated in the element adjacent to each slave facet
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

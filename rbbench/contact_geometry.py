"""Backend-agnostic contact geometry on polygonal boundaries (numpy only).

Pairing choice (documented): *Gauss-point-to-segment* on the reference
configuration mapped by mu. Quadrature points live on the slave facets; each
is projected along the slave's outward facet normal onto the master boundary
(a ray cast); the normal gap is the ray parameter. The constraint is imposed
weakly against the multiplier space, ``int (u_n - d^n) eta <= 0`` for
``eta >= 0``, which is the Lagrange-multiplier (mortar-like) form of seed 000
("HF model"), integrated with slave-side quadrature.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp


def gauss_legendre_01(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre points and weights on [0, 1]."""
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


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
             tol: float = 1e-10) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Project points ``x`` along directions ``n`` onto segments ``[a_j, b_j]``.

    Returns ``(segment, s, t)`` with ``x + t n = a + s (b - a)``; among the hits
    the one with the smallest ``|t|`` is kept. ``segment = -1`` where no
    segment is hit.
    """
    d = b - a  # (m, 2)
    # Solve [n, -d] [t, s]^T = a - x for every (point, segment) pair.
    det = n[:, None, 0] * (-d[None, :, 1]) - n[:, None, 1] * (-d[None, :, 0])
    r = a[None, :, :] - x[:, None, :]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (r[..., 0] * (-d[None, :, 1]) - r[..., 1] * (-d[None, :, 0])) / det
        s = (n[:, None, 0] * r[..., 1] - n[:, None, 1] * r[..., 0]) / det
    ok = (np.abs(det) > 1e-14) & (s >= -tol) & (s <= 1 + tol)
    score = np.where(ok, np.abs(t), np.inf)
    j = np.argmin(score, axis=1)
    rows = np.arange(x.shape[0])
    hit = np.isfinite(score[rows, j])
    seg = np.where(hit, j, -1)
    return seg, np.clip(s[rows, j], 0.0, 1.0), np.where(hit, t[rows, j], np.nan)


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

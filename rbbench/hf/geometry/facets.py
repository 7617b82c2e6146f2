"""Facet primitives of the contact geometry (numpy only): Gauss rules on [0, 1], facet
shape functions, outward normals, ray casts onto master facets, multiplier bases.

The building blocks of :mod:`rbbench.hf.geometry.operators` (see its docstring for the
pairing and the integration choices).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import scipy.sparse as sp

__all__ = ["facet_shape", "gauss_legendre_01", "multiplier_basis", "outward_normals",
           "point_support", "ray_cast", "ray_cast_window", "window_tangent_ranges"]


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


#: (point, segment) pairs per block of :func:`ray_cast`: eight work arrays of this many
#: doubles stay within a core's L2 cache (1 MB here)
RAY_CAST_BLOCK = 8192


def ray_cast(x: np.ndarray, n: np.ndarray, a: np.ndarray, b: np.ndarray,
             tol: float = 1e-10, candidates: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Project points ``x`` along directions ``n`` onto segments ``[a_j, b_j]``.

    Returns ``(segment, s, t)`` with ``x + t n = a + s (b - a)``; among the hits
    the one with the smallest ``|t|`` is kept. ``segment = -1`` where no
    segment is hit. ``candidates`` (n_points, K), padded with -1, restricts the
    segments tried for each point (the hyper-reduced evaluator's windows);
    ``None`` tries every segment.

    The points go in blocks of about :data:`RAY_CAST_BLOCK` pairs (each point's result
    is computed alone, so blocking changes nothing): the work arrays of all points at
    once were O(points x segments), about 3.5 MB each at Hertz level 0, and a forked worker's
    first solve spent 0.12 s in them instead of 0.027 s (page faults).
    """
    nx = x.shape[0]
    width = max(a.shape[0] if candidates is None else candidates.shape[1], 1)
    step = max(1, RAY_CAST_BLOCK // width)
    seg, s, t = np.empty(nx, dtype=np.int64), np.empty(nx), np.empty(nx)
    for i in range(0, nx, step):
        rows = slice(i, i + step)
        seg[rows], s[rows], t[rows] = _ray_cast_block(
            x[rows], n[rows], a, b, tol, None if candidates is None else candidates[rows])
    return seg, s, t


def _ray_cast_block(x: np.ndarray, n: np.ndarray, a: np.ndarray, b: np.ndarray, tol: float,
                    candidates: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`ray_cast` on one block of points."""
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


def window_monotone(n: np.ndarray, ranges: np.ndarray, eps: float = 1e-9) -> np.ndarray:
    """Whether the side function ``cross(n, P_j - x)`` of each point is monotone along
    its window: ``[alpha - theta_n, beta - theta_n]`` (``ranges``,
    :func:`window_tangent_ranges`) holds no multiple of pi (margin ``eps``)."""
    th = np.arctan2(n[:, 1], n[:, 0])
    return np.floor((ranges[:, 0] - th - eps) / np.pi) == np.floor((ranges[:, 1] - th + eps)
                                                                   / np.pi)


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
    monotone = window_monotone(n, ranges)

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
      Contact, Abbas-Drouet-Hild 2018, used with P1 displacements by Benaceur, Drouet,
      Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric variational
      inequalities" (talk));
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


def point_support(Mrows: np.ndarray, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The slave points of the rows ``pos`` of ``Mrows`` (rows x points, the multiplier
    basis at the points), padded: ``(points, values)``, each (len(pos), P), with
    ``values`` the multiplier basis there (0 on padding)."""
    M = Mrows[np.asarray(pos, dtype=np.int64)]
    P = max(int((M != 0).sum(axis=1).max()), 1) if M.size else 1
    pts = np.zeros((M.shape[0], P), dtype=np.int64)
    vals = np.zeros((M.shape[0], P))
    for i, row in enumerate(M):
        nz = np.flatnonzero(row)
        pts[i, :nz.size], vals[i, :nz.size] = nz, row[nz]
    return pts, vals

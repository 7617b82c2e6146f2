"""Quadrature rules and Lagrange shape functions on triangles, for the 3D contact geometry
(:mod:`rbbench.hf.geometry.surface`); numpy only.

Points are barycentric coordinates ``(l0, l1, l2)`` (rows summing to 1) and weights are
relative to the triangle area (they sum to 1).
"""

from __future__ import annotations

from itertools import permutations

import numpy as np

__all__ = ["RULE_DEGREES", "triangle_rule", "triangle_shape"]


def _orbit(*bary: float) -> np.ndarray:
    """The distinct permutations of the barycentric point ``bary`` (its symmetry orbit)."""
    return np.array(sorted(set(permutations(bary))), dtype=float)


def _rule(*groups: tuple[tuple[float, ...], float]) -> tuple[np.ndarray, np.ndarray]:
    """A symmetric rule from ``((a, b, c), weight)`` generators: every point of an orbit
    carries the generator's weight."""
    pts, wts = [], []
    for bary, w in groups:
        orb = _orbit(*bary)
        pts.append(orb)
        wts.append(np.full(orb.shape[0], w))
    return np.vstack(pts), np.concatenate(wts)


def _two_equal(a: float) -> tuple[float, float, float]:
    return (a, a, 1.0 - 2.0 * a)


#: Symmetric Gauss rules on the triangle with positive weights and interior points, keyed by
#: the degree they integrate exactly: Dunavant, "High degree efficient symmetrical Gaussian
#: quadrature rules for the triangle", Int. J. Numer. Meth. Eng. 21 (1985) 1129-1148,
#: rules of degree 1, 2, 4, 5, 6 and 8 (1, 3, 6, 7, 12 and 16 points). Degrees 3 and 7
#: (Dunavant's rules have a negative weight there) use the next rule up.
_RULES: dict[int, tuple[np.ndarray, np.ndarray]] = {
    1: _rule(((1 / 3, 1 / 3, 1 / 3), 1.0)),
    2: _rule((_two_equal(1 / 6), 1 / 3)),
    4: _rule((_two_equal(0.445948490915965), 0.223381589678011),
             (_two_equal(0.091576213509771), 0.109951743655322)),
    5: _rule(((1 / 3, 1 / 3, 1 / 3), 0.225),
             (_two_equal(0.470142064105115), 0.132394152788506),
             (_two_equal(0.101286507323456), 0.125939180544827)),
    6: _rule((_two_equal(0.249286745170910), 0.116786275726379),
             (_two_equal(0.063089014491502), 0.050844906370207),
             ((0.053145049844817, 0.310352451033784, 0.636502499121399), 0.082851075618374)),
    8: _rule(((1 / 3, 1 / 3, 1 / 3), 0.144315607677787),
             (_two_equal(0.459292588292723), 0.095091634267285),
             (_two_equal(0.170569307751760), 0.103217370534718),
             (_two_equal(0.050547228317031), 0.032458497623198),
             ((0.008394777409958, 0.263112829634638, 0.728492392955404), 0.027230314174435)),
}

#: The exact degrees :func:`triangle_rule` accepts.
RULE_DEGREES = tuple(range(1, max(_RULES) + 1))


def triangle_rule(degree: int) -> tuple[np.ndarray, np.ndarray]:
    """``(bary, weights)``: the smallest tabulated symmetric rule exact for polynomials of
    total degree ``degree`` (1 to 8) on a triangle (Dunavant 1985).

    ``bary`` (n, 3) barycentric points, ``weights`` (n,) relative to the area (sum 1).
    """
    if int(degree) != degree or degree not in RULE_DEGREES:
        raise ValueError(f"triangle quadrature degree {degree!r} is not one of "
                         f"{list(RULE_DEGREES)}")
    exact = min(d for d in _RULES if d >= degree)
    bary, w = _RULES[exact]
    return bary.copy(), w.copy()


def triangle_shape(bary: np.ndarray, degree: int) -> np.ndarray:
    """Lagrange shape functions (n, 3) for P1 or (n, 6) for P2 at barycentric points
    ``bary`` (n, 3).

    P1: ``l_i``. P2, nodes in the order of :class:`~rbbench.hf.geometry.surface.TriSurface`
    (the 3 vertices, then the midpoints of edges (0, 1), (1, 2), (0, 2)):
    ``l_i (2 l_i - 1)`` at the vertices and ``4 l_i l_j`` at the midpoints.
    """
    lam = np.asarray(bary, dtype=float)
    if degree == 1:
        return lam.copy()
    if degree != 2:
        raise ValueError(f"surface displacement degree {degree!r} is not one of 1, 2")
    l0, l1, l2 = lam[:, 0], lam[:, 1], lam[:, 2]
    return np.stack([l0 * (2 * l0 - 1), l1 * (2 * l1 - 1), l2 * (2 * l2 - 1),
                     4 * l0 * l1, 4 * l1 * l2, 4 * l0 * l2], axis=1)

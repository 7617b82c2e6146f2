"""Reference meshes: graded unit half-disk and unit square (scikit-fem MeshTri).

The half-disk is meshed once on the reference configuration (unit radius)
and mapped by mu, so the dof count does not depend on mu. Grading: starting
from a coarse Delaunay mesh, elements are refined (scikit-fem's conforming
adaptive refinement) until their diameter is below
``h(d) = h_contact + grading * d``, ``d`` the distance to the contact arc;
new boundary nodes on the arc are projected onto the circle after each pass.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import Delaunay
from skfem import MeshTri


def _coarse_lower_half_disk() -> tuple[np.ndarray, np.ndarray]:
    """Coarse quality mesh of {x^2 + y^2 <= 1, y <= 0} (curved side down)."""
    pts = []
    th = np.linspace(-np.pi, 0.0, 17)
    pts += [(np.cos(a), np.sin(a)) for a in th]
    pts += [(x, 0.0) for x in np.linspace(-1, 1, 9)[1:-1]]
    for r, k in ((0.65, 9), (0.33, 5)):
        th_r = np.linspace(-np.pi, 0.0, k)[1:-1]
        pts += [(r * np.cos(a), r * np.sin(a)) for a in th_r]
    p = np.array(pts)
    p[np.abs(p[:, 1]) < 1e-14, 1] = 0.0
    t = Delaunay(p).simplices
    return p, t


def _on_arc(m: MeshTri) -> np.ndarray:
    b = m.boundary_nodes()
    return b[m.p[1, b] < -1e-12]


def graded_half_disk(zone: tuple[float, float], h_contact: float, h_max: float,
                     grading: float) -> MeshTri:
    """Unit lower half-disk, graded toward the arc theta in ``zone`` (radians)."""
    p, t = _coarse_lower_half_disk()
    m = MeshTri(p.T.copy(), t.T.copy())
    th0, th1 = zone
    for _ in range(60):
        pts = m.p[:, m.t]  # (2, 3, nt)
        c = pts.mean(axis=1)
        ang = np.clip(np.arctan2(c[1], c[0]), th0, th1)
        q = np.vstack([np.cos(ang), np.sin(ang)])
        dist = np.linalg.norm(c - q, axis=0)
        edges = [np.linalg.norm(pts[:, i] - pts[:, (i + 1) % 3], axis=0) for i in range(3)]
        diam = np.max(edges, axis=0)
        target = np.minimum(h_contact + grading * dist, h_max)
        marked = np.nonzero(diam > target * 1.0001)[0]
        if marked.size == 0:
            break
        m = m.refined(marked)
        arc = _on_arc(m)
        pnew = m.p.copy()
        pnew[:, arc] /= np.linalg.norm(pnew[:, arc], axis=0)
        m = MeshTri(pnew, m.t)
    else:  # pragma: no cover - sizes are bounded below, the loop ends
        raise RuntimeError("half-disk grading did not terminate")
    return m


def unit_square(n: int) -> MeshTri:
    """Structured unit-square mesh with ``n`` cells per side (crossed diagonals avoided)."""
    x = np.linspace(0.0, 1.0, n + 1)
    return MeshTri.init_tensor(x, x)


def min_angle_deg(m: MeshTri) -> float:
    """Smallest interior angle of the mesh (degrees): a quality check."""
    pts = m.p[:, m.t]
    angs = []
    for i in range(3):
        a, b, c = pts[:, i], pts[:, (i + 1) % 3], pts[:, (i + 2) % 3]
        u, v = b - a, c - a
        cosv = np.sum(u * v, axis=0) / np.linalg.norm(u, axis=0) / np.linalg.norm(v, axis=0)
        angs.append(np.degrees(np.arccos(np.clip(cosv, -1, 1))))
    return float(np.min(angs))

"""Reference meshes of the NGSolve backend as arrays (Netgen on OCC geometries, the
scikit-fem backend's meshes, or arrays given by the caller: validated) and the NGSolve
mesh built from them (vertex ``i`` = row ``i`` of the arrays).

Part of :mod:`rbbench_plugins.backends.ngsolve.backend` (see its docstring).
"""

from __future__ import annotations

import functools
from typing import Any

import netgen.meshing as ngm
import ngsolve as ngs
import numpy as np
from netgen.occ import ArcOfCircle, Face, OCCGeometry, Pnt, Segment, Wire, WorkPlane
from rbbench_plugins.backends import common

__all__ = ["netgen_half_disk", "netgen_unit_square", "ngsolve_mesh", "skfem_mesh_arrays",
           "validated_arrays"]


# ---------------------------------------------------------------------------
# reference meshes as arrays
# ---------------------------------------------------------------------------
def _netgen_arrays(ngmesh: Any) -> tuple[np.ndarray, np.ndarray]:
    """Points (n, 2) and triangles (m, 3), 0-based, of a 2D Netgen mesh."""
    points = np.array(ngmesh.Coordinates(), dtype=float)[:, :2]
    triangles = np.array(ngmesh.Elements2D().NumPy()["nodes"][:, :3], dtype=np.int64) - 1
    return points, triangles


def _snap(points: np.ndarray, kind: str) -> np.ndarray:
    """Put boundary points exactly on the reference boundary (rounding of the mesher)."""
    p = points.copy()
    if kind == "halfdisks":
        p[np.abs(p[:, 1]) < 1e-12, 1] = 0.0
        r = np.linalg.norm(p, axis=1)
        arc = np.abs(r - 1.0) < 1e-9
        p[arc] /= r[arc, None]
    else:
        for v in (0.0, 1.0):
            p[np.abs(p - v) < 1e-12] = v
    return p


@functools.lru_cache(maxsize=8)
def netgen_half_disk(zone: tuple[float, float], h_contact: float, h_max: float,
                     grading: float) -> tuple[np.ndarray, np.ndarray]:
    """Netgen mesh of the unit lower half-disk ``{|x| <= 1, y <= 0}`` as arrays.

    The arc is split at the angles of ``zone`` (radians); the middle arc, the
    potential contact zone, carries the local mesh size ``h_contact``; elsewhere
    the size grows with Netgen's ``grading`` (in (0, 1]; the scene's value,
    capped at 1) up to ``h_max``. Cached: Netgen meshing is the slow step.
    Returns read-only ``(points (n, 2), triangles (m, 3))``.
    """
    z0, z1 = zone

    def on_circle(a: float) -> Pnt:
        return Pnt(np.cos(a), np.sin(a), 0.0)

    ends = [-np.pi, z0, z1, 0.0]
    edges = [ArcOfCircle(on_circle(a), on_circle(0.5 * (a + b)), on_circle(b))
             for a, b in zip(ends[:-1], ends[1:], strict=True)]
    edges.append(Segment(Pnt(1.0, 0.0, 0.0), Pnt(-1.0, 0.0, 0.0)))
    face = Face(Wire(edges))
    face.edges[1].maxh = h_contact
    ngmesh = OCCGeometry(face, dim=2).GenerateMesh(maxh=h_max, grading=min(grading, 1.0))
    points, triangles = _netgen_arrays(ngmesh)
    points = _snap(points, "halfdisks")
    for a in (points, triangles):
        a.setflags(write=False)
    return points, triangles


@functools.lru_cache(maxsize=8)
def netgen_unit_square(h: float) -> tuple[np.ndarray, np.ndarray]:
    """Netgen mesh of the unit square with element size ``h`` (read-only arrays)."""
    face = WorkPlane().Rectangle(1.0, 1.0).Face()
    points, triangles = _netgen_arrays(OCCGeometry(face, dim=2).GenerateMesh(maxh=h))
    points = _snap(points, "unit_square")
    for a in (points, triangles):
        a.setflags(write=False)
    return points, triangles


def skfem_mesh_arrays(kind: str, zone=None, h_contact=None, h_max=None, grading=None,
                       n=None) -> tuple[np.ndarray, np.ndarray]:
    """The scikit-fem backend's reference mesh (:mod:`rbbench_plugins.backends.skfem.meshes`)."""
    from rbbench_plugins.backends.skfem.meshes import graded_half_disk, unit_square

    m = graded_half_disk(zone, h_contact, h_max, grading) if kind == "halfdisks" \
        else unit_square(n)
    return m.p.T.copy(), m.t.T.copy()


def _signed_areas(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    e1 = points[triangles[:, 1]] - points[triangles[:, 0]]
    e2 = points[triangles[:, 2]] - points[triangles[:, 0]]
    return 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def validated_arrays(points: Any, triangles: Any, domain: str, what: str
               ) -> tuple[np.ndarray, np.ndarray]:
    """Check a reference mesh given as arrays; raise ``ValueError`` naming ``what``.

    ``domain``: ``"lower_half_disk"`` (``y <= 0``), ``"upper_half_disk"`` or
    ``"unit_square"``. Checks shapes, indices, non-degenerate triangles, that
    every boundary vertex lies on the domain's boundary and that the mesh covers
    the domain (area within 2 % of the polygonal domain).
    """
    try:
        p = np.array(points, dtype=float)
        t = np.array(triangles)
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{what}: points and triangles must be numeric arrays ({exc})") from None
    if p.ndim != 2 or p.shape[1] != 2 or p.shape[0] < 3 or not np.all(np.isfinite(p)):
        raise ValueError(f"{what}: points must be a finite (n, 2) array, got shape {p.shape}")
    if t.ndim != 2 or t.shape[1] != 3 or t.shape[0] < 1 or not np.issubdtype(t.dtype, np.integer):
        raise ValueError(f"{what}: triangles must be an integer (m, 3) array, got "
                         f"{t.dtype} of shape {t.shape}")
    t = t.astype(np.int64)
    if t.min() < 0 or t.max() >= p.shape[0]:
        raise ValueError(f"{what}: triangles index outside the {p.shape[0]} points")
    unused = np.setdiff1d(np.arange(p.shape[0]), t)
    if unused.size:
        raise ValueError(f"{what}: {unused.size} point(s) belong to no triangle "
                         f"(e.g. point {int(unused[0])})")
    area = np.abs(_signed_areas(p, t))
    if np.any(area <= 1e-14 * max(area.max(), 1e-300)):
        raise ValueError(f"{what}: degenerate (zero-area) triangles")
    facets, _ = common.boundary_facets(t)
    bv = np.unique(facets)
    x, y = p[bv, 0], p[bv, 1]
    if domain == "unit_square":
        ok = (np.minimum.reduce([np.abs(x), np.abs(x - 1), np.abs(y), np.abs(y - 1)]) < 1e-9)
        expected, name = 1.0, "the unit square [0, 1]^2"
    else:
        ok = (np.abs(y) < 1e-9) | (np.abs(np.hypot(x, y) - 1.0) < 1e-8)
        sign = -1.0 if domain == "lower_half_disk" else 1.0
        ok &= sign * y >= -1e-9
        expected = 0.5 * np.pi
        name = ("the unit lower half-disk {|x| <= 1, y <= 0}" if sign < 0
                else "the unit upper half-disk {|x| <= 1, y >= 0}")
    if not np.all(ok):
        bad = p[bv[~ok][0]]
        raise ValueError(f"{what}: boundary vertex {bad.round(6).tolist()} is not on the "
                         f"boundary of {name} (reference coordinates)")
    if abs(area.sum() - expected) > 0.02 * expected:
        raise ValueError(f"{what}: the triangles cover an area {area.sum():.6g}, not that of "
                         f"{name} ({expected:.6g})")
    return p, t


def ngsolve_mesh(points: np.ndarray, triangles: np.ndarray,
                 labels: dict[str, np.ndarray]) -> ngs.Mesh:
    """An NGSolve mesh from arrays (vertex ``i`` = row ``i`` of ``points``).

    Triangles are added counter-clockwise; ``labels`` maps a boundary name to
    boundary facets (n_f, 2) (vertex indices), added as segments of that name.
    """
    t = np.array(triangles, dtype=np.int64)
    cw = _signed_areas(points, t) < 0
    t[cw] = t[cw][:, [0, 2, 1]]
    m = ngm.Mesh(dim=2)
    m.AddPoints(np.ascontiguousarray(points, dtype=float))
    m.Add(ngm.FaceDescriptor(bc=1, domin=1, surfnr=1))
    m.AddElements(dim=2, index=1, data=np.ascontiguousarray(t, dtype=np.int32), base=0)
    for k, (name, segs) in enumerate(labels.items()):
        if len(segs):
            m.AddElements(dim=1, index=k + 1, data=np.ascontiguousarray(segs, dtype=np.int32),
                          base=0)
        m.SetBCName(k, name)
    return ngs.Mesh(m)

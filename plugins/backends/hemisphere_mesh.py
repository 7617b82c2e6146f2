"""Reference mesh of the unit quarter hemisphere, graded toward its pole (Netgen via OCC).

The body ``{|x| <= 1, z <= 0, x >= 0, y >= 0}`` (pole at ``(0, 0, -1)``, flat face
``z = 0``, symmetry planes ``x = 0`` and ``y = 0``) is meshed once per size set with
Netgen through NGSolve's OCC geometry, and mapped by mu by each backend, so the dof count
does not depend on mu. Netgen grades it: the solid is split (glued, conforming) into the
part within distance ``r_cap`` of the pole, meshed with ``maxh = h_contact``, and the rest,
meshed with ``maxh = h_max``; Netgen's own ``grading`` bounds the growth between them.
Netgen rather than gmsh: it is already a dependency (the NGSolve backend), so both
backends can share one mesh, and its per-solid ``maxh`` grades the mesh as needed.

Arrays only (no FEM library): points (n, 3), tetrahedra (m, 4), positively oriented.
Meshes are also kept on disk (:func:`mesh_cache_dir`, one ``.npz`` per size set and Netgen
version), so a level is meshed once per machine, not once per process.
"""

from __future__ import annotations

import functools
import hashlib
import importlib.util
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

#: Relative tolerance (to the unit radius) of the plane tests.
PLANE_TOL = 1e-9


@dataclass(frozen=True)
class TetMesh:
    """A tetrahedral mesh as arrays (read-only)."""

    points: np.ndarray  # (n, 3)
    tets: np.ndarray  # (m, 4), positive volume

    @property
    def volume(self) -> float:
        """Sum of the tetrahedra's volumes."""
        return float(signed_volumes(self.points, self.tets).sum())


def signed_volumes(points: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volume of each tetrahedron ``det[b - a, c - a, d - a] / 6``."""
    a = points[tets[:, 0]]
    m = np.stack([points[tets[:, k]] - a for k in (1, 2, 3)], axis=1)
    return np.linalg.det(m) / 6.0


def cap_chord(cap: float) -> float:
    """Distance from the pole of the unit sphere to the edge of the cap of polar angle
    ``cap * pi``: ``2 sin(cap pi / 2)``."""
    return 2.0 * float(np.sin(0.5 * np.pi * cap))


#: Bump when the meshing changes: older cached meshes are then ignored.
MESH_FORMAT = 1


def mesh_cache_dir() -> Path | None:
    """``$RBBENCH_MESH_CACHE`` (``"0"``: no disk cache), else
    ``$XDG_CACHE_HOME/rbbench/meshes``, else ``~/.cache/rbbench/meshes``."""
    env = os.environ.get("RBBENCH_MESH_CACHE")
    if env == "0":
        return None
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "rbbench" / "meshes"


def _cache_file(cap: float, h_contact: float, h_max: float, grading: float) -> Path | None:
    root = mesh_cache_dir()
    if root is None:
        return None
    import netgen

    key = repr((MESH_FORMAT, netgen.__version__, float(cap), float(h_contact), float(h_max),
                float(grading)))
    return root / f"quarter_hemisphere_{hashlib.sha256(key.encode()).hexdigest()[:16]}.npz"


def _frozen(points: np.ndarray, tets: np.ndarray) -> TetMesh:
    points.flags.writeable = False
    tets.flags.writeable = False
    return TetMesh(points, tets)


@functools.lru_cache(maxsize=8)
def quarter_hemisphere(cap: float, h_contact: float, h_max: float,
                       grading: float = 0.3) -> TetMesh:
    """The unit quarter lower hemisphere, graded toward its pole.

    Parameters
    ----------
    cap : float
        Polar angle / pi of the cap around the pole meshed at ``h_contact``; the solid
        part within :func:`cap_chord` of the pole gets that size.
    h_contact, h_max : float
        Netgen's ``maxh`` near the pole and elsewhere (unit radius).
    grading : float
        Netgen's ``grading`` in (0, 1] (larger: faster growth of the element size).

    Returns
    -------
    TetMesh
        Cached per argument set, in the process and on disk (:func:`mesh_cache_dir`;
        meshing takes seconds to minutes); the arrays are read-only.
    """
    if importlib.util.find_spec("netgen") is None:
        raise ModuleNotFoundError('the 3D hemisphere meshes are made by Netgen, which comes '
                                  'with NGSolve: pip install "rbbench[ngsolve]"')
    path = _cache_file(cap, h_contact, h_max, grading)
    if path is not None and path.exists():
        try:
            with np.load(path) as f:
                return _frozen(f["points"], f["tets"])
        except (OSError, ValueError, KeyError):
            pass  # unreadable: mesh again and overwrite
    mesh = _netgen_quarter_hemisphere(cap, h_contact, h_max, grading)
    if path is not None:
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            tmp = path.with_suffix(f".{os.getpid()}.tmp.npz")
            np.savez(tmp, points=mesh.points, tets=mesh.tets)
            os.replace(tmp, path)  # atomic: concurrent processes never read half a file
        except OSError:
            pass  # a read-only cache: the mesh stays in this process only
    return mesh


def _netgen_quarter_hemisphere(cap: float, h_contact: float, h_max: float,
                               grading: float) -> TetMesh:
    """Mesh the body with Netgen (see :func:`quarter_hemisphere`)."""
    from netgen.occ import Box, Glue, OCCGeometry, Pnt, Sphere

    body = Sphere(Pnt(0, 0, 0), 1.0) * Box(Pnt(0, 0, -1.5), Pnt(1.5, 1.5, 0))
    near = body * Sphere(Pnt(0, 0, -1), cap_chord(cap))
    far = body - near
    near.solids.maxh = h_contact
    near.faces.maxh = h_contact
    ngmesh = OCCGeometry(Glue([near, far])).GenerateMesh(maxh=h_max, grading=grading)
    points = np.array([p.p for p in ngmesh.Points()], dtype=float)
    tets = np.array([[v.nr - 1 for v in e.vertices] for e in ngmesh.Elements3D()],
                    dtype=np.int64)
    if tets.ndim != 2 or tets.shape[1] != 4:
        raise RuntimeError("netgen: expected linear tetrahedra (4 vertices per element)")
    # exact planes (netgen leaves round-off on the flat and symmetry faces)
    for k in range(3):
        points[np.abs(points[:, k]) < PLANE_TOL, k] = 0.0
    vol = signed_volumes(points, tets)
    if np.any(vol == 0.0):
        raise RuntimeError("netgen: degenerate tetrahedra in the hemisphere mesh")
    neg = vol < 0
    tets[neg] = tets[neg][:, [0, 2, 1, 3]]
    return _frozen(points, tets)


def mirror_z(mesh: TetMesh) -> TetMesh:
    """The mirror image ``z -> -z`` (the upper hemisphere, pole up), reoriented."""
    return TetMesh(mesh.points * np.array([1.0, 1.0, -1.0]), mesh.tets[:, [0, 2, 1, 3]])


def boundary_triangles(tets: np.ndarray) -> np.ndarray:
    """(n_b, 3) the faces of the tetrahedra that belong to one tetrahedron only."""
    faces = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 2, 3]], tets[:, [0, 1, 3]],
                            tets[:, [0, 1, 2]]])
    key = np.sort(faces, axis=1)
    _, index, count = np.unique(key, axis=0, return_index=True, return_counts=True)
    return faces[np.sort(index[count == 1])]


def edge_lookup(edges: np.ndarray, n_vertices: int):
    """``f(a, b)``: the index of the edge with vertices ``a``, ``b`` (either order)."""
    key = np.sort(edges, axis=1) @ np.array([n_vertices, 1])
    order = np.argsort(key)

    def index(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        k = np.minimum(a, b) * n_vertices + np.maximum(a, b)
        pos = np.searchsorted(key, k, sorter=order)
        found = order[np.minimum(pos, key.size - 1)]
        if not np.array_equal(key[found], k):
            raise RuntimeError("hemispheres: a boundary triangle edge is not a mesh edge")
        return found

    return index


def face_groups(points: np.ndarray, triangles: np.ndarray) -> dict[str, np.ndarray]:
    """Boolean masks of boundary triangles: ``"flat"`` (z = 0), ``"sym_x"`` (x = 0),
    ``"sym_y"`` (y = 0), ``"curved"`` (the rest: the sphere)."""
    c = points[triangles]  # (n, 3, 3)
    groups = {name: np.all(np.abs(c[:, :, k]) < PLANE_TOL, axis=1)
              for name, k in (("sym_x", 0), ("sym_y", 1), ("flat", 2))}
    groups["curved"] = ~(groups["flat"] | groups["sym_x"] | groups["sym_y"])
    return groups

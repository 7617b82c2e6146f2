"""NGSolve HF backend: Netgen meshes (or meshes given as arrays), P1/P2, sparse Cholesky.

The same scenes, reference geometry, mu-maps, Dirichlet data, materials and
contact operators as the scikit-fem backend (the backend-neutral parts live in
:mod:`rbbench_plugins.backends.common`); only the meshes, the assembly and the
dof numbering are NGSolve's:

* **Meshes.** Each reference body (unit half-disks, unit square) is meshed once
  in ``__init__``: by default with Netgen on an OCC geometry whose contact arc
  carries the local size ``h_contact`` (``mesh="netgen"``); or the arrays of
  :mod:`rbbench_plugins.backends.meshes` (``mesh="skfem"``: the very meshes of
  the scikit-fem backend); or arrays given by the caller. An NGSolve mesh is
  then built from the arrays (``netgen.meshing.Mesh``: points, counter-clockwise
  triangles, boundary segments labelled ``"flat"`` / ``"arc"``), so vertex ``i``
  of the NGSolve mesh is row ``i`` of the arrays.
* **mu-map.** The stiffness is assembled on the physical body: the reference
  mesh is deformed by the body's similarity map ``x = s(mu) x_hat + c(mu)``
  (``Mesh.SetDeformation`` with a P1 displacement ``x - x_hat``, which is exact
  for an affine map) for the assembly only.
* **Dofs.** ``VectorH1`` numbers dofs blockwise: dof ``c * n_s + k`` is component
  ``c`` of scalar dof ``k``; scalar dofs are the vertices ``0 .. n_v - 1`` then
  one per edge (P2) in NGSolve's edge order; bodies are stacked (upper, lower).
  NGSolve's order-2 ``H1`` basis is hierarchical (an edge bubble); the handed-out
  operators are in the Lagrange P2 basis (nodal values at vertices and edge
  midpoints, which the contact layout and the Dirichlet data assume):
  ``A_lagrange = T^T A_ngsolve T`` with the sparse change of basis ``T``
  (:func:`lagrange_p2_transform`).
* **Operators** are scipy CSR; ``Discretization.factorize`` is NGSolve's
  ``sparsecholesky`` (:func:`sparse_cholesky`) unless ``direct_solver="scipy"``.
"""

from __future__ import annotations

import functools
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import netgen.meshing as ngm
import ngsolve as ngs
import numpy as np
import scipy.sparse as sp
from netgen.occ import ArcOfCircle, Face, OCCGeometry, Pnt, Segment, Wire, WorkPlane
from rbbench_plugins.backends import common

from rbbench.hf.contact_geometry import (
    AffineMap,
    FacetChain,
    SlaveStress,
    lame_parameters,
)
from rbbench.interfaces import (
    Backend,
    BodyMesh,
    Discretization,
    Factorize,
)
from rbbench.scene.loading import Scene

#: Valid values of the ``mesh`` option (besides arrays).
MESH_SOURCES = ("netgen", "skfem")
#: Valid values of the ``direct_solver`` option.
DIRECT_SOLVERS = ("sparsecholesky", "scipy")
#: Columns per NGSolve MultiVector in a multi-right-hand-side solve.
_RHS_CHUNK = 64


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


def _skfem_mesh_arrays(kind: str, zone=None, h_contact=None, h_max=None, grading=None,
                       n=None) -> tuple[np.ndarray, np.ndarray]:
    """The scikit-fem backend's reference mesh (:mod:`rbbench_plugins.backends.meshes`)."""
    from rbbench_plugins.backends.meshes import graded_half_disk, unit_square

    m = graded_half_disk(zone, h_contact, h_max, grading) if kind == "halfdisks" \
        else unit_square(n)
    return m.p.T.copy(), m.t.T.copy()


def _signed_areas(points: np.ndarray, triangles: np.ndarray) -> np.ndarray:
    e1 = points[triangles[:, 1]] - points[triangles[:, 0]]
    e2 = points[triangles[:, 2]] - points[triangles[:, 0]]
    return 0.5 * (e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0])


def _validated(points: Any, triangles: Any, domain: str, what: str
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


# ---------------------------------------------------------------------------
# Lagrange P2 from NGSolve's hierarchical order-2 basis
# ---------------------------------------------------------------------------
@functools.lru_cache(maxsize=1)
def edge_bubble_scale() -> float:
    """The constant ``c`` of NGSolve's order-2 edge shape function ``c lambda_a lambda_b``.

    Measured on one triangle (value at the edge midpoint is ``c / 4``) and checked
    at the quarter point and the centroid, so that a change of NGSolve's basis
    convention fails loudly instead of silently changing the operators.
    """
    mesh = ngsolve_mesh(np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]),
                        np.array([[0, 1, 2]]), {})
    fes = ngs.H1(mesh, order=2)
    gf = ngs.GridFunction(fes)
    edge = next(iter(mesh.edges))
    gf.vec[:] = 0.0
    gf.vec[fes.GetDofNrs(ngs.NodeId(ngs.EDGE, edge.nr))[0]] = 1.0
    a, b = (np.array(mesh[v].point) for v in edge.vertices)
    c = 4.0 * gf(mesh(*(0.5 * (a + b))))
    checks = [(a + 0.25 * (b - a), 3.0 / 16.0), (np.array([1.0, 1.0]) / 3.0, 1.0 / 9.0)]
    for x, lab in checks:
        if not np.isclose(gf(mesh(*x)), c * lab, rtol=1e-12, atol=1e-14):
            raise RuntimeError("ngsolve backend: NGSolve's order-2 H1 edge function is not "
                               "c * lambda_a * lambda_b; the Lagrange P2 change of basis "
                               "does not apply to this NGSolve version")
    return float(c)


def lagrange_p2_transform(n_vertices: int, edges: np.ndarray) -> sp.csr_matrix:
    """``T`` with ``u_ngsolve = T u_lagrange`` for scalar order-2 ``H1`` (vertex, then edge dofs).

    With NGSolve's edge function ``b_e = c lambda_a lambda_b`` (:func:`edge_bubble_scale`)
    the Lagrange value at the midpoint of edge ``e = (a, b)`` is
    ``U_e = (U_a + U_b) / 2 + w_e c / 4``, hence ``w_e = (4 U_e - 2 (U_a + U_b)) / c``.
    """
    c = edge_bubble_scale()
    ne = edges.shape[0]
    ev = n_vertices + np.arange(ne)
    rows = np.concatenate([np.arange(n_vertices), ev, ev, ev])
    cols = np.concatenate([np.arange(n_vertices), ev, edges[:, 0], edges[:, 1]])
    vals = np.concatenate([np.ones(n_vertices), np.full(ne, 4.0 / c), np.full(2 * ne, -2.0 / c)])
    n = n_vertices + ne
    return sp.csr_matrix((vals, (rows, cols)), shape=(n, n))


# ---------------------------------------------------------------------------
# the direct solver hook
# ---------------------------------------------------------------------------
def sparse_cholesky(A: sp.spmatrix) -> Callable[[np.ndarray], np.ndarray]:
    """NGSolve ``sparsecholesky`` of a sparse SPD matrix (``Discretization.factorize``).

    Factorises once; returns ``solve(b)`` for ``b`` of shape (n,) or (n, k) (the
    columns are solved in blocks of NGSolve ``MultiVector``). NGSolve's sparse
    Cholesky reads the lower triangle only, so only ``tril(A)`` is copied into
    NGSolve (the copy goes through Python sequences: half the entries, half the
    time; ``tests/test_backend_ngsolve.py`` checks the solves against SuperLU).
    """
    coo = sp.tril(A, format="coo")
    n = int(coo.shape[0])
    mat = ngs.la.SparseMatrixd.CreateFromCOO(coo.row.astype(np.int64), coo.col.astype(np.int64),
                                            np.asarray(coo.data, dtype=float), n, n)
    inv = mat.Inverse(inverse="sparsecholesky")

    def solve(b: np.ndarray) -> np.ndarray:
        b = np.asarray(b, dtype=float)
        if b.ndim == 1:
            x, y = ngs.BaseVector(n), ngs.BaseVector(n)
            x.FV().NumPy()[:] = b
            y.data = inv * x
            return np.array(y.FV().NumPy())
        out = np.empty_like(b)
        for s in range(0, b.shape[1], _RHS_CHUNK):
            k = min(_RHS_CHUNK, b.shape[1] - s)
            rhs, res = ngs.MultiVector(n, k, False), ngs.MultiVector(n, k, False)
            for j in range(k):
                rhs[j].FV().NumPy()[:] = b[:, s + j]
            res[:] = inv * rhs
            for j in range(k):
                out[:, s + j] = res[j].FV().NumPy()
        return out

    solve.matrix, solve.inverse = mat, inv  # keep NGSolve's objects alive with the closure
    return solve


# ---------------------------------------------------------------------------
# one body
# ---------------------------------------------------------------------------
class _Body:
    """One body: reference arrays, NGSolve mesh and space, dof maps, mu-map.

    Parameters
    ----------
    name : str
        ``"upper"``, ``"lower"`` or ``"membrane"``.
    points, triangles : arrays
        Reference mesh (vertex ``i`` is NGSolve vertex ``i``).
    degree : int
        Lagrange degree (1 or 2).
    ncomp : int
        Components (2: elasticity, ``VectorH1``; 1: scalar ``H1``).
    offset : int
        First global dof of the body.
    chain_zone : (float, float) or None
        Angular zone (radians) of its contact chain (half-disks).
    """

    def __init__(self, name: str, points: np.ndarray, triangles: np.ndarray, degree: int,
                 ncomp: int, offset: int, chain_zone: tuple[float, float] | None = None):
        self.name, self.degree, self.ncomp, self.offset = name, degree, ncomp, offset
        self.points, self.triangles = points, triangles
        self.chain_zone = chain_zone
        self.facets, self.elements = common.boundary_facets(triangles)
        if ncomp == 2:
            flat = common.flat_facets(points, self.facets)
            arc = np.setdiff1d(np.arange(self.facets.shape[0]), flat)
            labels = {"flat": self.facets[flat], "arc": self.facets[arc]}
        else:
            labels = {"boundary": self.facets}
        self.mesh = ngsolve_mesh(points, triangles, labels)
        self.nv = self.mesh.nv
        if ncomp == 2:
            self.fes = ngs.VectorH1(self.mesh, order=degree)
        else:
            self.fes = ngs.H1(self.mesh, order=degree)
        if degree == 2:
            self.edges = np.array([[v.nr for v in e.vertices] for e in self.mesh.edges],
                                  dtype=np.int64).reshape(-1, 2)
            self.edge_of = common.edge_lookup(self.edges, self.nv)
        else:
            self.edges = np.zeros((0, 2), dtype=np.int64)
        self.nscalar = self.nv + self.edges.shape[0]
        self.ndofs = self.ncomp * self.nscalar
        self._check_numbering()
        T = lagrange_p2_transform(self.nv, self.edges) if degree == 2 else None
        self.T = None if T is None else sp.block_diag([T] * ncomp, format="csr")
        self._deformation = ngs.GridFunction(ngs.VectorH1(self.mesh, order=1))

    def _check_numbering(self) -> None:
        """The dof numbering this backend relies on (module docstring), checked on NGSolve."""
        fes = self.fes
        if fes.ndof != self.ndofs:
            raise RuntimeError(f"ngsolve backend: {fes.ndof} dofs, expected {self.ndofs}")
        nodes = [(ngs.VERTEX, 0, 0), (ngs.VERTEX, self.nv - 1, self.nv - 1)]
        if self.degree == 2:
            ne = self.edges.shape[0]
            nodes += [(ngs.EDGE, 0, self.nv), (ngs.EDGE, ne - 1, self.nscalar - 1)]
        for kind, nr, dof in nodes:
            got = tuple(fes.GetDofNrs(ngs.NodeId(kind, nr)))
            want = tuple(dof + c * self.nscalar for c in range(self.ncomp))
            if got != want:
                raise RuntimeError(f"ngsolve backend: dofs of node {kind} {nr} are {got}, "
                                   f"expected {want} (blockwise numbering)")

    # -- dof maps (global numbers) ---------------------------------------------
    def vertex_dofs(self) -> np.ndarray:
        """(n_v, ncomp) global dofs of the vertices."""
        v = np.arange(self.nv)
        return np.stack([v + c * self.nscalar for c in range(self.ncomp)], axis=1) + self.offset

    def dof_locations(self) -> np.ndarray:
        """(n_scalar, 2) reference coordinates of the scalar dofs (vertices, edge midpoints)."""
        mids = self.points[self.edges].mean(axis=1) if self.degree == 2 else np.zeros((0, 2))
        return np.vstack([self.points, mids])

    def scalar_dofs_on(self, facets: np.ndarray) -> np.ndarray:
        """Sorted scalar dofs (body-local) on the given facets (their vertices and edges)."""
        dofs = [np.unique(facets)]
        if self.degree == 2:
            dofs.append(self.nv + self.edge_of(facets))
        return np.unique(np.concatenate(dofs))

    def check_dofs_on(self, boundary: str, dofs: np.ndarray) -> None:
        """Check body-local ``dofs`` against NGSolve's dofs of the named boundary."""
        bits = self.fes.GetDofs(self.mesh.Boundaries(boundary))
        ngs_dofs = np.flatnonzero(np.array(list(bits), dtype=bool))
        if not np.array_equal(ngs_dofs, np.sort(dofs)):
            raise RuntimeError(f"ngsolve backend: the dofs on boundary {boundary!r} of body "
                               f"{self.name!r} disagree with NGSolve's")

    def facet_dofs(self, rows: np.ndarray, flip: np.ndarray) -> np.ndarray:
        """(n, degree + 1, 2) global dofs of boundary facets ``rows``: [start, end, (mid)]."""
        f = self.facets[rows]
        n0 = np.where(flip, f[:, 1], f[:, 0])
        n1 = np.where(flip, f[:, 0], f[:, 1])
        vd = self.vertex_dofs()
        local = [vd[n0], vd[n1]]
        if self.degree == 2:
            e = self.nv + self.edge_of(f)
            local.append(np.stack([e + c * self.nscalar for c in range(self.ncomp)], axis=1)
                         + self.offset)
        return np.stack(local, axis=1)

    # -- assembly --------------------------------------------------------------
    @contextmanager
    def mapped(self, amap: AffineMap | None, mu: np.ndarray) -> Iterator[None]:
        """The NGSolve mesh deformed to the physical body ``amap(mu, x_hat)`` (inside only)."""
        if amap is None:
            yield
            return
        disp = amap(mu, self.points) - self.points
        self._deformation.vec.FV().NumPy()[:] = disp.T.ravel()  # VectorH1: blockwise
        self.mesh.SetDeformation(self._deformation)
        try:
            yield
        finally:
            self.mesh.UnsetDeformation()

    def to_lagrange(self, M: sp.csr_matrix) -> sp.csr_matrix:
        return M if self.T is None else (self.T.T @ M @ self.T).tocsr()

    def matrix(self, integrand: Callable[[Any, Any], Any]) -> sp.csr_matrix:
        """``integrand(u, v) * dx`` assembled, as a Lagrange-basis scipy CSR matrix."""
        u, v = self.fes.TnT()
        a = ngs.BilinearForm(self.fes)
        a += integrand(u, v) * ngs.dx
        a.Assemble()
        vals, cols, ptr = a.mat.CSR()
        M = sp.csr_matrix((np.array(vals, dtype=float), np.array(cols), np.array(ptr)),
                          shape=(self.ndofs, self.ndofs))
        return self.to_lagrange(M)

    def vector(self, integrand: Callable[[Any], Any]) -> np.ndarray:
        """``integrand(v) * dx`` assembled, in the Lagrange basis."""
        f = ngs.LinearForm(self.fes)
        f += integrand(self.fes.TestFunction()) * ngs.dx
        f.Assemble()
        F = np.array(f.vec.FV().NumPy(), dtype=float)
        return F if self.T is None else self.T.T @ F


def _elasticity(E: float, nu: float) -> Callable[[Any, Any], Any]:
    lam, mu = lame_parameters(E, nu)

    def form(u, v):
        eps_u, eps_v = ngs.Sym(ngs.Grad(u)), ngs.Sym(ngs.Grad(v))
        return 2.0 * mu * ngs.InnerProduct(eps_u, eps_v) + lam * ngs.div(u) * ngs.div(v)

    return form


def _vector_h1(u, v):
    return ngs.InnerProduct(u, v) + ngs.InnerProduct(ngs.Grad(u), ngs.Grad(v))


def _laplace(u, v):
    return ngs.grad(u) * ngs.grad(v)


def _mass(u, v):
    return u * v


# ---------------------------------------------------------------------------
# the backend
# ---------------------------------------------------------------------------
class NGSolveBackend(common.HalfDiskContact, Backend):
    """NGSolve backend: Netgen (or given) meshes, P1/P2 Lagrange, GPTS contact pairing.

    Parameters
    ----------
    scene : Scene
        A validated scene (``halfdisks`` or ``unit_square``).
    mesh : str, tuple or dict, optional
        Reference meshes. ``"netgen"`` (default): Netgen meshes of the reference
        bodies (size ``h_contact`` on the contact arc, graded to ``h_max``; unit
        square of size ``1 / n_cells``; both divided by ``2**level``).
        ``"skfem"``: the scikit-fem backend's meshes
        (:mod:`rbbench_plugins.backends.meshes`), so both backends run on one
        identical mesh. Arrays: ``{"upper": (points, triangles), "lower": (points,
        triangles)}`` in reference coordinates (upper: the unit lower half-disk
        ``{|x| <= 1, y <= 0}``; lower: the unit upper half-disk), or one
        ``(points, triangles)`` pair when the scene has one body (``unit_square``:
        the unit square, body ``"membrane"``; ``rigid_flat``: the upper body).
        ``points`` (n, 2), ``triangles`` (m, 3) vertex indices, any orientation;
        boundary vertices must lie on the reference boundary (straight-sided
        triangles: the arc is polygonal, as in the scikit-fem backend).
        CLI: ``rbbench solve ... --backend ngsolve --backend-option mesh=skfem``.
    direct_solver : str, optional
        ``"sparsecholesky"`` (default): ``Discretization.factorize`` is NGSolve's
        sparse Cholesky (:func:`sparse_cholesky`); ``"scipy"``: ``None`` (the
        solver's SuperLU).
    threads : int, optional
        ``ngsolve.SetNumThreads(threads)`` (a process-wide NGSolve setting), 1 by
        default: on a loaded 2-core machine every sparse Cholesky factorisation
        paid 20-50 ms of thread start-up with NGSolve's default, 0.03 ms with one
        thread (measured, n = 10), and the large factorisations were no faster.

    Raises
    ------
    TypeError
        Unknown option.
    ValueError
        Invalid option value (the message names the option and the valid values).
    """

    name = "ngsolve"

    def __init__(self, scene: Scene, mesh: Any = "netgen", direct_solver: str = "sparsecholesky",
                 threads: int = 1, **options: Any):
        if options:
            raise TypeError(f"ngsolve backend: unknown options {sorted(options)}; valid: "
                            "'mesh', 'direct_solver', 'threads'")
        if not (isinstance(direct_solver, str) and direct_solver in DIRECT_SOLVERS):
            raise ValueError(f"ngsolve backend: option direct_solver = {direct_solver!r} is not "
                             f"valid; expected one of {', '.join(map(repr, DIRECT_SOLVERS))}")
        if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
            raise ValueError(f"ngsolve backend: option threads = {threads!r} is not valid; "
                             "expected an integer >= 1")
        ngs.SetNumThreads(threads)
        if isinstance(mesh, str) and mesh not in MESH_SOURCES:
            raise ValueError(f"ngsolve backend: option mesh = {mesh!r} is not valid; expected "
                             f"one of {', '.join(map(repr, MESH_SOURCES))}, or reference "
                             "meshes as arrays (points, triangles)")
        self.scene = scene
        self.direct_solver = direct_solver
        self.mesh_source = mesh if isinstance(mesh, str) else "arrays"
        vars(self).update(common.discretization_settings(scene))  # degree, h_contact, ..., kind
        self._X: sp.csr_matrix | None = None
        t0 = time.perf_counter()
        if self.kind == "halfdisks":
            self._init_halfdisks(mesh)
        else:
            self._init_square(mesh)
        self.t_mesh = time.perf_counter() - t0

    # ------------------------------------------------------------------ setup
    def _given_arrays(self, mesh: Any, names: list[str]) -> dict[str, tuple]:
        """Reference arrays from the ``mesh`` option, keyed by body name."""
        if isinstance(mesh, dict):
            missing = [n for n in names if n not in mesh]
            extra = sorted(set(mesh) - set(names))
            if missing or extra:
                raise ValueError(f"ngsolve backend: option mesh: expected (points, triangles) "
                                 f"for the bodies {names}; missing {missing}, unknown {extra}")
            given = mesh
        elif len(names) == 1 and isinstance(mesh, (tuple, list)) and len(mesh) == 2:
            given = {names[0]: mesh}
        else:
            one = " or one (points, triangles) pair" if len(names) == 1 else ""
            raise ValueError(f"ngsolve backend: option mesh: expected 'netgen', 'skfem', a dict "
                             f"{{body: (points, triangles)}} for the bodies {names}{one}; got "
                             f"{type(mesh).__name__}")
        out = {}
        for name in names:
            pair = given[name]
            if not (isinstance(pair, (tuple, list)) and len(pair) == 2):
                raise ValueError(f"ngsolve backend: option mesh[{name!r}]: expected a pair "
                                 "(points, triangles)")
            out[name] = pair
        return out

    def _init_halfdisks(self, mesh: Any) -> None:
        common.check_multiplier(self.scene)
        self.rigid = common.is_rigid(self.scene)
        specs = common.halfdisk_bodies(self.scene)
        given = None if isinstance(mesh, str) else self._given_arrays(mesh,
                                                                     [s.name for s in specs])
        self.upper: _Body | None = None
        self.lower: _Body | None = None
        offset = 0
        for spec in specs:
            domain = "upper_half_disk" if spec.mirrored else "lower_half_disk"
            if given is not None:
                p, t = given[spec.name]
                what = f"ngsolve backend: option mesh[{spec.name!r}]"
            else:
                zone = (float(spec.mesh_zone[0]), float(spec.mesh_zone[1]))
                if mesh == "netgen":
                    p, t = netgen_half_disk(zone, self.h_contact, self.h_max, self.grading)
                else:
                    p, t = _skfem_mesh_arrays("halfdisks", zone, self.h_contact, self.h_max,
                                              self.grading)
                if spec.mirrored:
                    p, t = common.mirror_y(p, t)
                what = f"ngsolve backend: the {mesh} mesh of body {spec.name!r}"
            p, t = _validated(p, t, domain, what)
            body = _Body(spec.name, p, t, self.degree, 2, offset, spec.chain_zone)
            setattr(self, spec.name, body)
            offset += body.ndofs
        self.ndofs = offset
        # Dirichlet dofs: the flat face of each body (do not depend on mu)
        self._flat_dofs = []
        for body in self._bodies():
            scalar = body.scalar_dofs_on(body.facets[common.flat_facets(body.points,
                                                                        body.facets)])
            dofs = [scalar + c * body.nscalar + body.offset for c in range(2)]
            body.check_dofs_on("flat", np.concatenate(dofs) - body.offset)
            self._flat_dofs.append(dofs)

    def _init_square(self, mesh: Any) -> None:
        disc = self.scene.data["discretization"]
        n = int(disc["n_cells"]) * 2 ** int(disc["level"])
        what = f"ngsolve backend: the {mesh} mesh" if isinstance(mesh, str) else \
            "ngsolve backend: option mesh"
        if mesh == "netgen":
            p, t = netgen_unit_square(1.0 / n)
        elif mesh == "skfem":
            p, t = _skfem_mesh_arrays("unit_square", n=n)
        else:
            p, t = self._given_arrays(mesh, ["membrane"])["membrane"]
        p, t = _validated(p, t, "unit_square", what)
        self.body = _Body("membrane", p, t, self.degree, 1, 0)
        self.ndofs = self.body.ndofs
        self.A_lap = self.body.matrix(_laplace)
        self.M = self.body.matrix(_mass)
        self.load_vec = self.body.vector(lambda v: v)
        self.boundary_dofs = self.body.scalar_dofs_on(self.body.facets)
        self.body.check_dofs_on("boundary", self.boundary_dofs)

    def _bodies(self) -> list[_Body]:
        if self.kind != "halfdisks":
            return [self.body]
        return [b for b in (self.upper, self.lower) if b is not None]

    # -------------------------------------------------------------- operators
    def dof_table(self) -> dict[str, np.ndarray]:
        """What each global dof is: ``body`` (index into the bodies), ``component``,
        ``x_hat`` (reference coordinates of its node) and ``kind`` (0 vertex, 1 edge)."""
        body, comp, xhat, kind = [], [], [], []
        for i, b in enumerate(self._bodies()):
            loc = b.dof_locations()
            k = np.r_[np.zeros(b.nv, dtype=int), np.ones(b.nscalar - b.nv, dtype=int)]
            for c in range(b.ncomp):
                body.append(np.full(b.nscalar, i))
                comp.append(np.full(b.nscalar, c))
                xhat.append(loc)
                kind.append(k)
        return {"body": np.concatenate(body), "component": np.concatenate(comp),
                "x_hat": np.vstack(xhat), "kind": np.concatenate(kind)}

    def inner_product(self) -> sp.csr_matrix:
        """V inner product on the reference configuration (mu = the scene default)."""
        if self._X is None:
            which = self.scene.data["discretization"]["inner_product"]
            if self.kind == "unit_square":
                self._X = (self.A_lap + self.M).tocsr() if which == "h1" else self.A_lap
            elif which == "energy":
                self._X = self._elastic_operator(self.scene.default_mu)
            else:
                self._X = sp.block_diag([b.matrix(_vector_h1) for b in self._bodies()]).tocsr()
        return self._X

    def _elastic_operator(self, mu: np.ndarray) -> sp.csr_matrix:
        """Block-diagonal plane-strain stiffness, each body assembled at its mu-map."""
        blocks = []
        for body in self._bodies():
            E, nu = self.scene.material(body.name, mu)
            with body.mapped(self._body_maps()[body.name], mu):
                blocks.append(body.matrix(_elasticity(E, nu)))
        return sp.block_diag(blocks).tocsr()

    def _factorize(self) -> Factorize | None:
        return sparse_cholesky if self.direct_solver == "sparsecholesky" else None

    def discretize(self, mu, needs: frozenset[str] = frozenset()) -> Discretization:
        """Operators at ``mu``; ``needs`` may ask for ``"tangential"`` (friction) and
        ``"stress"`` (Nitsche: ``Snn``, ``facet_length``) operators."""
        mu = self.scene.check_mu(mu)
        common.check_needs(self.name, self.scene, needs)
        if self.kind == "unit_square":
            return self._discretize_square(mu)
        return self._discretize_halfdisks(mu, needs)

    def _discretize_halfdisks(self, mu: np.ndarray, needs=frozenset()) -> Discretization:
        t0 = time.perf_counter()
        maps = self._body_maps()
        geo = common.halfdisk_geometry(self.scene, maps, mu)
        A = self._elastic_operator(mu)
        t_asm = time.perf_counter() - t0
        d = float(self.scene.value("load", "displacement", mu))
        # Dirichlet: upper flat face moves by (0, -d); lower flat face clamped.
        dofs, vals = [], []
        for body, flat in zip(self._bodies(), self._flat_dofs, strict=True):
            for c in range(2):
                dofs.append(flat[c])
                value = -d if (body.name == "upper" and c == 1) else 0.0
                vals.append(np.full(flat[c].size, value))
        contact = self._contact(mu, needs)
        bodies = []
        for body in self._bodies():
            E, nu = self.scene.material(body.name, mu)
            bodies.append(BodyMesh(body.name, maps[body.name](mu, body.points),
                                   body.triangles.copy(), body.vertex_dofs(), E, nu))
        info = {"geometry": geo, "t_assemble_s": t_asm,
                "n_facets_slave": self.contact_layout().slave.n,
                "h_contact": self.h_contact, "degree": self.degree, "backend": self.name,
                "mesh": self.mesh_source}
        return Discretization(mu=mu, A=A, F=np.zeros(self.ndofs),
                              dirichlet_dofs=np.concatenate(dofs),
                              dirichlet_values=np.concatenate(vals), X=self.inner_product(),
                              contact=contact, bodies=bodies, physics="elasticity", info=info,
                              factorize=self._factorize())

    @staticmethod
    def _chain(body: _Body, amap: AffineMap) -> FacetChain:
        return common.facet_chain(body.points, body.triangles, body.facets, body.elements,
                                  body.chain_zone, body.facet_dofs, amap)

    def _stress(self, body: _Body) -> SlaveStress:
        """The slave elements behind ``Snn`` (:func:`common.slave_stress`)."""
        comps = np.arange(body.ncomp) * body.nscalar + body.offset
        edge_dofs = None
        if body.degree == 2:
            def edge_dofs(pairs):
                return (body.nv + body.edge_of(pairs))[:, None] + comps

        return common.slave_stress(self.scene, body.points, body.triangles, body.facets,
                                   body.elements, body.chain_zone,
                                   lambda v: body.vertex_dofs()[v], edge_dofs)

    def _discretize_square(self, mu: np.ndarray) -> Discretization:
        f = float(self.scene.value("load", "source", mu))
        b = self.body
        bnd = self.boundary_dofs
        free = np.setdiff1d(np.arange(b.ndofs), bnd)
        xy = b.dof_locations()[free]
        lumped = np.asarray(self.M.sum(axis=1)).ravel()[free]
        contact = common.obstacle_contact(self.scene, mu, xy, free, lumped, b.ndofs)
        body = BodyMesh("membrane", b.points.copy(), b.triangles.copy(), b.vertex_dofs())
        return Discretization(mu=mu, A=self.A_lap, F=f * self.load_vec,
                              dirichlet_dofs=bnd, dirichlet_values=np.zeros(bnd.size),
                              X=self.inner_product(), contact=contact, bodies=[body],
                              physics="poisson", factorize=self._factorize(),
                              info={"backend": self.name, "degree": self.degree,
                                    "mesh": self.mesh_source})

"""Finite-element pieces of the NGSolve backend: the Lagrange P2 change of basis from
NGSolve's hierarchical order-2 basis, the ``sparsecholesky`` solver hook, one reference
body (space, dofs, mu-mapped assembly) and the weak forms.

Part of :mod:`rbbench_plugins.backends.ngsolve.backend` (see its docstring).
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import ngsolve as ngs
import numpy as np
import scipy.sparse as sp
from rbbench_plugins.backends import common
from rbbench_plugins.backends.ngsolve.meshes import ngsolve_mesh

from rbbench.hf.geometry.chains import AffineMap, lame_parameters

__all__ = ["Body", "edge_bubble_scale", "elasticity_form", "lagrange_p2_transform",
           "laplace_form", "mass_form", "sparse_cholesky", "vector_h1_form"]

#: Columns per NGSolve MultiVector in a multi-right-hand-side solve.
_RHS_CHUNK = 64


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
    time; ``tests/plugins/backends/test_ngsolve.py`` checks the solves against SuperLU).
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
class Body:
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


def elasticity_form(E: float, nu: float) -> Callable[[Any, Any], Any]:
    lam, mu = lame_parameters(E, nu)

    def form(u, v):
        eps_u, eps_v = ngs.Sym(ngs.Grad(u)), ngs.Sym(ngs.Grad(v))
        return 2.0 * mu * ngs.InnerProduct(eps_u, eps_v) + lam * ngs.div(u) * ngs.div(v)

    return form


def vector_h1_form(u, v):
    return ngs.InnerProduct(u, v) + ngs.InnerProduct(ngs.Grad(u), ngs.Grad(v))


def laplace_form(u, v):
    return ngs.grad(u) * ngs.grad(v)


def mass_form(u, v):
    return u * v

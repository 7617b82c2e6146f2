"""NGSolve assembly of the linear scenes (:mod:`.linear_common`).

The very mesh of the scikit-fem backend (the arrays of
:func:`rbbench_plugins.backends.skfem.meshes.unit_square`, vertex ``i`` = row ``i``), assembled by
NGSolve's own forms (P1: dof ``i`` = vertex ``i``), one stiffness per conductivity block
(``IfPos`` indicators, block edges on mesh lines), NGSolve's sparse Cholesky for the
solves: an independent check of the scikit-fem assembly.
"""

from __future__ import annotations

import ngsolve as ngs
import numpy as np
import scipy.sparse as sp
from rbbench_plugins.backends.linear_common import LinearBackend, LinearPieces
from rbbench_plugins.backends.ngsolve.fe import sparse_cholesky
from rbbench_plugins.backends.ngsolve.meshes import ngsolve_mesh
from rbbench_plugins.backends.skfem.meshes import unit_square


def _scipy(form: ngs.BilinearForm) -> sp.csr_matrix:
    rows, cols, vals = form.mat.COO()
    n = form.mat.height
    return sp.csr_matrix((np.asarray(vals), (np.asarray(rows), np.asarray(cols))),
                         shape=(n, n))


def _interval(x: ngs.CoefficientFunction, lo: float, hi: float) -> ngs.CoefficientFunction:
    return ngs.IfPos(x - lo, ngs.IfPos(hi - x, 1.0, 0.0), 0.0)


class NGSolveLinearBackend(LinearBackend):
    """NGSolve: the scikit-fem mesh as arrays, P1 only, sparse Cholesky."""

    name = "ngsolve"

    def _pieces(self) -> LinearPieces:
        if self.degree != 1:
            raise ValueError("ngsolve linear backend: degree 1 only (P1: dof = vertex)")
        sk = unit_square(self.n)
        p, t = sk.p.T.copy(), sk.t.T.copy()
        bf = sk.facets[:, sk.boundary_facets()].T
        mesh = ngsolve_mesh(p, t, {"boundary": bf})
        fes = ngs.H1(mesh, order=1)
        u, v = fes.TnT()
        bx, by = self.blocks
        blocks = []
        for b in range(bx * by):
            ix, iy = b % bx, b // bx
            ind = (_interval(ngs.x, ix / bx, (ix + 1) / bx)
                   * _interval(ngs.y, iy / by, (iy + 1) / by))
            form = ngs.BilinearForm(fes)
            form += ind * ngs.grad(u) * ngs.grad(v) * ngs.dx
            blocks.append(_scipy(form.Assemble()))
        mass, bmass = ngs.BilinearForm(fes), ngs.BilinearForm(fes)
        mass += u * v * ngs.dx
        bmass += u * v * ngs.ds
        load = ngs.LinearForm(fes)
        load += v * ngs.dx
        load.Assemble()
        bnd = np.unique(bf.ravel()).astype(np.int64)
        return LinearPieces(blocks=blocks, mass=_scipy(mass.Assemble()),
                            boundary_mass=_scipy(bmass.Assemble()),
                            load=np.array(load.vec.FV().NumPy()), boundary_dofs=bnd,
                            points=p, triangles=t, vertex_dofs=np.arange(len(p))[:, None])

    @staticmethod
    def factorize(A: sp.spmatrix):
        """NGSolve's sparse Cholesky (``ngsolve_fe.sparse_cholesky``)."""
        return sparse_cholesky(A)

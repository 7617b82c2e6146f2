"""scikit-fem assembly of the linear scenes (:mod:`.linear_common`).

The unit square of the membrane scene (:func:`rbbench_plugins.backends.skfem.meshes.unit_square`,
``n_cells 2**level`` squares per side, two triangles each), P1 or P2 Lagrange; one stiffness
matrix per conductivity block (elements selected by their centroid).
"""

from __future__ import annotations

import numpy as np
from rbbench_plugins.backends.linear_common import LinearBackend, LinearPieces, block_of
from rbbench_plugins.backends.skfem.backend import _laplace, _mass
from rbbench_plugins.backends.skfem.meshes import unit_square
from skfem import Basis, ElementTriP1, ElementTriP2, FacetBasis, LinearForm, asm


@LinearForm
def _unit(v, w):
    return v


class SkfemLinearBackend(LinearBackend):
    """scikit-fem: structured unit-square mesh, P1 / P2, SuperLU (scipy) solves."""

    name = "skfem"

    def _pieces(self) -> LinearPieces:
        mesh = unit_square(self.n)
        elem = {1: ElementTriP1, 2: ElementTriP2}[self.degree]()
        centroids = mesh.p[:, mesh.t].mean(axis=1)
        which = block_of(centroids[0], centroids[1], self.blocks)
        blocks = []
        for b in range(self.blocks[0] * self.blocks[1]):
            sub = Basis(mesh, elem, elements=np.flatnonzero(which == b))
            blocks.append(asm(_laplace, sub).tocsr())
        basis = Basis(mesh, elem)
        fb = FacetBasis(mesh, elem)
        return LinearPieces(blocks=blocks, mass=asm(_mass, basis).tocsr(),
                            boundary_mass=asm(_mass, fb).tocsr(), load=asm(_unit, basis),
                            boundary_dofs=basis.get_dofs().all(),
                            points=mesh.p.T.copy(), triangles=mesh.t.T.copy(),
                            vertex_dofs=basis.nodal_dofs.T.copy())

"""Moving mesh, Q1 plane-strain stiffness and its design derivative for ``shape_coulomb``.

The body of the talk "On coupling of complementarity with friction in contact shape
optimization", ``Omega(alpha) = {a < x1 < b, alpha(x1) < x2 < gamma}``, is meshed by a
structured grid of ``nx x ny`` bilinear isoparametric quadrilaterals (Q1, 2 x 2 Gauss
points). Node ``(i, j)`` sits at ``x1 = a + i h`` and
``x2 = alpha_i + (gamma - alpha_i) eta_j`` with ``eta_j = j / ny``: the mesh moves with
the design, the dof count does not. Column ``i`` of nodes depends on ``alpha_i`` only, so
``dA / d alpha_i`` touches the two element columns beside it; it is computed exactly by the
complex step (Squire & Trapp 1998) on the element kernel, which is analytic in the nodal
coordinates. The kernel is plain numpy; ``tests/optim/test_shape_mesh.py`` checks it against
scikit-fem's ``ElementQuad1`` assembly on the same nodes.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

_G = 1.0 / np.sqrt(3.0)
_GAUSS = np.array([[-_G, -_G], [_G, -_G], [_G, _G], [-_G, _G]])
_REF = np.array([[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]])


@dataclass(frozen=True)
class Grid:
    """Structured ``nx x ny`` grid on ``[a, b] x [alpha, gamma]``; dofs interleaved (u1, u2)."""

    a: float
    b: float
    gamma: float
    nx: int
    ny: int

    @property
    def h(self) -> float:
        return (self.b - self.a) / self.nx

    @property
    def n_nodes(self) -> int:
        return (self.nx + 1) * (self.ny + 1)

    @property
    def x1(self) -> np.ndarray:
        """Abscissae of the ``nx + 1`` design (= contact) nodes."""
        return self.a + self.h * np.arange(self.nx + 1)

    def node(self, i, j):
        return np.asarray(j) * (self.nx + 1) + np.asarray(i)

    def elements(self) -> np.ndarray:
        """``(nx * ny, 4)`` node indices, counter-clockwise, element ``e = j * nx + i``."""
        i, j = np.meshgrid(np.arange(self.nx), np.arange(self.ny))
        i, j = i.ravel(), j.ravel()
        return np.stack([self.node(i, j), self.node(i + 1, j), self.node(i + 1, j + 1),
                         self.node(i, j + 1)], axis=1)

    def coordinates(self, alpha: np.ndarray) -> np.ndarray:
        """``(n_nodes, 2)`` node coordinates of the body over the design ``alpha``."""
        eta = np.arange(self.ny + 1) / self.ny
        x1 = np.broadcast_to(self.x1, (self.ny + 1, self.nx + 1))
        x2 = alpha[None, :] + (self.gamma - alpha[None, :]) * eta[:, None]
        return np.stack([x1.ravel(), x2.ravel()], axis=1)

    def bottom(self) -> np.ndarray:
        return self.node(np.arange(self.nx + 1), 0)

    def top(self) -> np.ndarray:
        return self.node(np.arange(self.nx + 1), self.ny)

    def left(self) -> np.ndarray:
        return self.node(0, np.arange(self.ny + 1))


def elasticity_matrix(E: float, nu: float) -> np.ndarray:
    """Plane-strain Hooke matrix in Voigt notation (exx, eyy, gxy)."""
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = E / (2 * (1 + nu))
    return np.array([[lam + 2 * mu, lam, 0.0], [lam, lam + 2 * mu, 0.0], [0.0, 0.0, mu]])


def _shape_gradients(xi: np.ndarray) -> np.ndarray:
    """``(4, 2)`` reference gradients of the Q1 shape functions at ``xi``."""
    return 0.25 * np.stack([_REF[:, 0] * (1 + _REF[:, 1] * xi[1]),
                            _REF[:, 1] * (1 + _REF[:, 0] * xi[0])], axis=1)


def _strain_matrix(X: np.ndarray, xi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Strain-displacement matrices ``B`` ``(ne, 3, 8)`` and ``det J`` at reference point xi."""
    dN = _shape_gradients(xi)
    J = np.einsum("eka,kb->eab", X, dN)
    det = J[:, 0, 0] * J[:, 1, 1] - J[:, 0, 1] * J[:, 1, 0]
    inv = np.stack([np.stack([J[:, 1, 1], -J[:, 0, 1]], -1),
                    np.stack([-J[:, 1, 0], J[:, 0, 0]], -1)], -2) / det[:, None, None]
    g = np.einsum("kb,eba->eka", dN, inv)
    B = np.zeros((X.shape[0], 3, 8), dtype=X.dtype)
    B[:, 0, 0::2] = g[:, :, 0]
    B[:, 1, 1::2] = g[:, :, 1]
    B[:, 2, 0::2] = g[:, :, 1]
    B[:, 2, 1::2] = g[:, :, 0]
    return B, det


def element_stress(grid: Grid, alpha: np.ndarray, D: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Stress ``(sigma_11, sigma_22, sigma_12)`` at the element centres ``(ne, 3)``."""
    el = grid.elements()
    B, _ = _strain_matrix(grid.coordinates(alpha)[el], np.zeros(2))
    return np.einsum("ij,ejb,eb->ei", D, B, u[element_dofs(el)])


def element_stiffness(X: np.ndarray, D: np.ndarray) -> np.ndarray:
    """Q1 element stiffness ``(ne, 8, 8)`` for node coordinates ``X`` ``(ne, 4, 2)``.

    Complex ``X`` is allowed (complex-step derivative); no ``abs`` or conjugate is used.
    """
    K = np.zeros((X.shape[0], 8, 8), dtype=X.dtype)
    for xi in _GAUSS:
        B, det = _strain_matrix(X, xi)
        K += np.einsum("eia,ij,ejb->eab", B, D, B) * det[:, None, None]
    return K


def element_dofs(elements: np.ndarray) -> np.ndarray:
    """``(ne, 8)`` interleaved dofs (u1, u2 of node 0, then node 1, ...)."""
    return np.stack([2 * elements, 2 * elements + 1], axis=2).reshape(len(elements), 8)


def assemble_stiffness(grid: Grid, alpha: np.ndarray, D: np.ndarray) -> sp.csr_matrix:
    """Global stiffness ``A(alpha)`` (all dofs, no boundary conditions)."""
    el = grid.elements()
    K = element_stiffness(grid.coordinates(alpha)[el], D)
    dofs = element_dofs(el)
    rows = np.repeat(dofs, 8, axis=1).ravel()
    cols = np.tile(dofs, (1, 8)).ravel()
    n = 2 * grid.n_nodes
    return sp.csr_matrix((K.ravel(), (rows, cols)), shape=(n, n))


def top_load(grid: Grid, pressure: float, traction: float) -> np.ndarray:
    """Consistent nodal load of a uniform traction ``(traction, -pressure)`` on ``x2 = gamma``.

    The top edge does not move with ``alpha``, so ``dL / d alpha = 0``.
    """
    w = trapezoid_weights(grid)
    f = np.zeros(2 * grid.n_nodes)
    top = grid.top()
    f[2 * top] = traction * w
    f[2 * top + 1] = -pressure * w
    return f


def stiffness_design_products(grid: Grid, alpha: np.ndarray, D: np.ndarray, p: np.ndarray,
                              u: np.ndarray, step: float = 1e-30) -> np.ndarray:
    """``g_i = p . (dA / d alpha_i) u`` for every design node ``i`` (complex step, exact).

    Parameters
    ----------
    p, u : full dof vectors (adjoint and state).
    """
    el = grid.elements()
    X = grid.coordinates(alpha)[el]
    eta = np.arange(grid.ny + 1) / grid.ny
    j = np.repeat(np.arange(grid.ny), grid.nx)
    col = np.tile(np.arange(grid.nx), grid.ny)
    dofs = element_dofs(el)
    pe, ue = p[dofs], u[dofs]
    g = np.zeros(grid.nx + 1)
    # local nodes 0, 3 sit on column col (rows j, j+1); nodes 1, 2 on column col + 1
    for local, shift in (((0, 3), 0), ((1, 2), 1)):
        dX = np.zeros_like(X)
        dX[:, local[0], 1] = 1.0 - eta[j]
        dX[:, local[1], 1] = 1.0 - eta[j + 1]
        dK = element_stiffness(X + 1j * step * dX, D).imag / step
        np.add.at(g, col + shift, np.einsum("ea,eab,eb->e", pe, dK, ue))
    return g


def area(grid: Grid, alpha: np.ndarray) -> float:
    """``meas Omega(alpha) = gamma (b - a) - int alpha`` (trapezoidal, exact for P1 alpha)."""
    return grid.gamma * (grid.b - grid.a) - float(trapezoid_weights(grid) @ alpha)


def area_weights(grid: Grid) -> np.ndarray:
    """``d meas Omega / d alpha`` (constant: the area is affine in the design)."""
    return -trapezoid_weights(grid)


def trapezoid_weights(grid: Grid) -> np.ndarray:
    """Weights of the trapezoidal rule on the design nodes (``h``, ends ``h / 2``)."""
    w = np.full(grid.nx + 1, grid.h)
    w[[0, -1]] = grid.h / 2
    return w

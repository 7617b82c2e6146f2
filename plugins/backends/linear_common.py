"""The backend role for the linear scenes: no contact operator, no multiplier.

A linear backend assembles, once, the parameter-independent pieces of
:mod:`rbbench.scene.linear` (stiffness per conductivity block, mass, boundary mass, the
load of ``f = 1``) with its FEM library (:class:`LinearPieces`), and
:meth:`LinearBackend.discretize` combines them at mu::

    A(mu) = sum_b kappa_b(mu) K_b + h0(mu) M_boundary,    F(mu) = f(mu) int v

(``kappa_b``, ``h0``, ``f``: numbers or ``"mu.NAME"`` of the scene). The
:class:`~rbbench.interfaces.Discretization` has ``contact = None``: nothing of the contact
pipeline (pairing, multipliers, gaps) is built. ``info["mass"]`` is the mass matrix (the
time derivative of ``physics = "heat"``), ``info["time"]`` the implicit Euler grid and
``info["initial"]`` the nodal values of ``u0``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from rbbench.interfaces import Backend, BodyMesh, Discretization
from rbbench.scene.linear import block_parameters, check_physics
from rbbench.scene.loading import Scene


@dataclass
class LinearPieces:
    """What a FEM library assembles once on the reference mesh (P1 or P2 Lagrange).

    ``blocks[b]``: ``int_{block b} grad u . grad v``; ``mass``: ``int u v``;
    ``boundary_mass``: ``int_{boundary} u v``; ``load``: ``int v``; ``boundary_dofs``: the
    dofs on the boundary; ``points``, ``triangles``: the mesh (output);
    ``vertex_dofs``: the dof of each vertex.
    """

    blocks: list[sp.csr_matrix]
    mass: sp.csr_matrix
    boundary_mass: sp.csr_matrix
    load: np.ndarray
    boundary_dofs: np.ndarray
    points: np.ndarray
    triangles: np.ndarray
    vertex_dofs: np.ndarray


def block_of(x: np.ndarray, y: np.ndarray, blocks: tuple[int, int]) -> np.ndarray:
    """The block ``ix + bx iy`` of points (element centroids) on the unit square."""
    bx, by = blocks
    ix = np.minimum((np.asarray(x) * bx).astype(int), bx - 1)
    iy = np.minimum((np.asarray(y) * by).astype(int), by - 1)
    return ix + bx * iy


class LinearBackend(Backend):
    """Base of the linear backends: the scene's affine combination of :class:`LinearPieces`.

    Subclasses implement :meth:`_pieces` (the FEM library's assembly) and may set
    :attr:`factorize` (their direct solver, :data:`rbbench.interfaces.Factorize`).
    """

    name = "linear"
    factorize = None

    #: the constructor's options (checked before the mesh is built)
    OPTIONS: tuple[str, ...] = ()

    def __init__(self, scene: Scene, **options) -> None:
        if options:
            raise TypeError(f"{self.name} linear backend: unknown options {sorted(options)}")
        check_physics(scene)
        self.scene = scene
        disc = scene.data["discretization"]
        self.degree = int(disc["degree"])
        self.n = int(disc["n_cells"]) * 2 ** int(disc["level"])
        self.blocks = tuple(int(b) for b in scene.data["geometry"]["blocks"])
        t0 = time.perf_counter()
        self.pieces = self._pieces()
        self.t_mesh = time.perf_counter() - t0
        self.parabolic = scene.data["scene"]["physics"] == "heat"
        self._X: sp.csr_matrix | None = None

    def _pieces(self) -> LinearPieces:  # pragma: no cover - abstract
        raise NotImplementedError

    @property
    def ndofs(self) -> int:
        return int(self.pieces.mass.shape[0])

    def inner_product(self) -> sp.csr_matrix:
        """X: the H1_0 seminorm ``sum_b K_b`` (``h1_semi``) or the H1 norm ``+ M`` (``h1``)."""
        if self._X is None:
            K = sum(self.pieces.blocks[1:], self.pieces.blocks[0])
            which = self.scene.data["discretization"]["inner_product"]
            self._X = (K if which == "h1_semi" else K + self.pieces.mass).tocsr()
        return self._X

    def _value(self, key: str, mu: np.ndarray) -> float:
        return float(self.scene.value("thermal", key, mu))

    def discretize(self, mu, needs: frozenset[str] = frozenset()) -> Discretization:
        """``A(mu)``, ``F(mu)`` (module docstring); ``needs`` must be empty (no contact)."""
        if needs:
            raise ValueError(f"{self.name}: a linear scene has no optional operators "
                             f"({sorted(needs)} asked)")
        mu = self.scene.check_mu(mu)
        pc = self.pieces
        names = self.scene.param_names
        kappa = [float(mu[names.index(p)]) for p in block_parameters(self.scene)]
        A = sum(k * K for k, K in zip(kappa[1:], pc.blocks[1:], strict=True))
        A = (A + kappa[0] * pc.blocks[0]) if len(kappa) > 1 else kappa[0] * pc.blocks[0]
        h0 = self._value("robin", mu)
        if h0:
            A = A + h0 * pc.boundary_mass
        dofs = pc.boundary_dofs if not self.parabolic else np.empty(0, dtype=np.int64)
        body = BodyMesh("domain", pc.points, pc.triangles, pc.vertex_dofs)
        info = {"backend": self.name, "degree": self.degree, "mass": pc.mass,
                "initial": np.full(self.ndofs, float(self.scene.data["thermal"]["initial"]))}
        if self.parabolic:
            t = self.scene.data["time"]
            info["time"] = {"final": float(t["final"]), "steps": int(t["steps"])}
        physics = self.scene.data["scene"]["physics"]
        return Discretization(mu=mu, A=sp.csr_matrix(A), F=self._value("source", mu) * pc.load,
                              dirichlet_dofs=dofs, dirichlet_values=np.zeros(dofs.size),
                              X=self.inner_product(), contact=None, bodies=[body],
                              physics=physics, info=info, factorize=self.factorize)

"""scikit-fem HF backend (the default).

Reference meshes are built once (``__init__``) and mapped by mu in
:meth:`SkfemBackend.discretize`: the upper half-disk is ``x = R1 x_hat + c``,
so dof counts do not depend on mu while ``B(mu)`` and the gap do.

Scenes: ``halfdisks`` (plane-strain elasticity, two half-disks or a half-disk
on a rigid flat) and ``unit_square`` (scalar membrane obstacle problem).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
from rbbench_plugins.backends.meshes import graded_half_disk, unit_square
from skfem import (
    Basis,
    BilinearForm,
    ElementTriP1,
    ElementTriP2,
    ElementVector,
    LinearForm,
    asm,
)
from skfem.helpers import dot, grad
from skfem.models.elasticity import lame_parameters, linear_elasticity

from rbbench.contact_geometry import (
    AffineMap,
    ContactLayout,
    FacetChain,
    PairingError,
    contact_operators,
)
from rbbench.interfaces import Backend, BodyMesh, ContactOperators, Discretization
from rbbench.scene import Scene, SceneError


@BilinearForm
def _laplace(u, v, w):
    return dot(grad(u), grad(v))


@BilinearForm
def _mass(u, v, w):
    return u * v


@BilinearForm
def _vector_h1(u, v, w):
    return dot(u, v) + (grad(u) * grad(v)).sum(axis=(0, 1))


@LinearForm
def _unit_load(v, w):
    return v


def _element(degree: int):
    return {1: ElementTriP1, 2: ElementTriP2}[degree]()


class _Body:
    """One elastic body: reference mesh, basis factory and facet dof maps."""

    def __init__(self, name: str, mesh_hat, degree: int, offset: int):
        self.name = name
        self.mesh_hat = mesh_hat
        self.degree = degree
        self.offset = offset
        self.basis_hat = Basis(mesh_hat, ElementVector(_element(degree)))
        self.ndofs = self.basis_hat.N

    def facet_dofs(self, facets: np.ndarray, flip: np.ndarray) -> np.ndarray:
        """(n_facets, degree + 1, 2) global dofs: [start, end, (mid)] x component."""
        b = self.basis_hat
        n0 = np.where(flip, self.mesh_hat.facets[1, facets], self.mesh_hat.facets[0, facets])
        n1 = np.where(flip, self.mesh_hat.facets[0, facets], self.mesh_hat.facets[1, facets])
        local = [b.nodal_dofs[:, n0].T, b.nodal_dofs[:, n1].T]
        if self.degree == 2:
            local.append(b.facet_dofs[:, facets].T)
        return np.stack(local, axis=1) + self.offset

    def vertex_dofs(self) -> np.ndarray:
        return self.basis_hat.nodal_dofs.T + self.offset


class SkfemBackend(Backend):
    """scikit-fem backend: graded meshes, P1/P2 Lagrange, GPTS contact pairing.

    Parameters
    ----------
    scene : Scene
        A validated scene.
    """

    name = "skfem"

    def __init__(self, scene: Scene, **options):
        if options:
            raise TypeError(f"skfem backend: unknown options {sorted(options)}")
        self.scene = scene
        disc = scene.data["discretization"]
        self.degree = int(disc["degree"])
        scale = 2.0 ** (-int(disc["level"]))
        self.h_contact = float(disc["h_contact"]) * scale
        self.h_max = float(disc["h_max"]) * scale
        self.grading = float(disc["grading"])
        self.n_gauss = int(disc["quadrature"]) or self.degree + 1
        self.multiplier = disc["multiplier"]
        self.kind = scene.data["geometry"]["kind"]
        t0 = time.perf_counter()
        if self.kind == "halfdisks":
            self._init_halfdisks()
        else:
            self._init_square()
        self.t_mesh = time.perf_counter() - t0
        self._X = None

    # ------------------------------------------------------------------ setup
    def _init_halfdisks(self) -> None:
        g = self.scene.data["geometry"]
        if self.multiplier == "nodal":
            raise SceneError(f"{self.scene.path}: [discretization] multiplier: 'nodal' is for "
                             "obstacle problems; use 'lac', 'p0' or 'p1' for two-body contact")
        self.zone = tuple(np.pi * np.asarray(g["contact_zone"]))
        mesh_up = graded_half_disk(self.zone, self.h_contact, self.h_max, self.grading)
        self.upper = _Body("upper", mesh_up, self.degree, 0)
        self.rigid = g["lower"] == "rigid_flat"
        self.lower = None
        if not self.rigid:
            mzone = np.pi * np.asarray(g["master_zone"])
            mesh_lo = graded_half_disk((-mzone[1], -mzone[0]), self.h_contact, self.h_max,
                                       self.grading)
            mesh_lo = type(mesh_lo)(mesh_lo.p * np.array([[1.0], [-1.0]]), mesh_lo.t[[0, 2, 1]])
            self.lower = _Body("lower", mesh_lo, self.degree, self.upper.ndofs)
            self.master_zone = mzone
        self.ndofs = self.upper.ndofs + (self.lower.ndofs if self.lower else 0)
        self._layout = None
        self._maps = None

    @staticmethod
    def _zone_facets(mesh, zone) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Boundary facets whose midpoint angle lies in ``zone``, ordered by angle.

        Returns (facets, flip, inner) where ``flip`` orders each facet's
        vertices by increasing angle and ``inner`` is the adjacent element's centroid
        (reference coordinates).
        """
        bf = mesh.boundary_facets()
        mid = mesh.p[:, mesh.facets[:, bf]].mean(axis=1)
        ang = np.arctan2(mid[1], mid[0])
        on_arc = np.abs(np.linalg.norm(mid, axis=0) - 1.0) < 0.1
        keep = on_arc & (ang >= zone[0]) & (ang <= zone[1])
        facets = bf[keep][np.argsort(ang[keep])]
        a0 = np.arctan2(*mesh.p[::-1, mesh.facets[0, facets]])
        a1 = np.arctan2(*mesh.p[::-1, mesh.facets[1, facets]])
        flip = a0 > a1
        inner = mesh.p[:, mesh.t[:, mesh.f2t[0, facets]]].mean(axis=1).T
        return facets, flip, inner

    def _init_square(self) -> None:
        n = int(self.scene.data["discretization"]["n_cells"]) * 2 ** int(
            self.scene.data["discretization"]["level"])
        self.mesh = unit_square(n)
        self.basis = Basis(self.mesh, _element(self.degree))
        self.ndofs = self.basis.N
        self.A_lap = asm(_laplace, self.basis).tocsr()
        self.M = asm(_mass, self.basis).tocsr()
        self.load_vec = asm(_unit_load, self.basis)

    # -------------------------------------------------------------- operators
    def inner_product(self) -> sp.csr_matrix:
        """V inner product on the reference configuration (mu = the scene default)."""
        if self._X is None:
            which = self.scene.data["discretization"]["inner_product"]
            if self.kind == "unit_square":
                self._X = self.A_lap + self.M if which == "h1" else self.A_lap
            else:
                mu0 = self.scene.default_mu
                if which == "energy":
                    self._X = self._elastic_operators(mu0)[0]
                else:
                    blocks = [asm(_vector_h1, b.basis_hat) for b in self._bodies()]
                    self._X = sp.block_diag(blocks).tocsr()
        return self._X

    def _bodies(self) -> list[_Body]:
        return [self.upper] + ([self.lower] if self.lower is not None else [])

    def _body_maps(self) -> dict[str, AffineMap]:
        """The mu-map of each body, the one source of the geometry: the upper half-disk is
        ``R1 x_hat + (0, top + g0 + R1)``, the lower one ``R2 x_hat``."""
        if self._maps is None:
            coef = self.scene.affine_coefficients
            r1 = coef("geometry", "upper_radius")
            top = np.zeros_like(r1) if self.rigid else coef("geometry", "lower_radius")
            self._maps = {"upper": AffineMap(r1, np.stack([
                np.zeros_like(r1), top + coef("geometry", "initial_gap") + r1]))}
            if not self.rigid:
                r2 = coef("geometry", "lower_radius")
                self._maps["lower"] = AffineMap(r2, np.zeros((2, r2.size)))
        return self._maps

    def _geometry(self, mu) -> dict:
        maps = self._body_maps()
        r1, centre1 = maps["upper"].at(mu)
        r2 = None if self.rigid else maps["lower"].at(mu)[0]
        return {"R1": r1, "R2": r2, "g0": float(self.scene.value("geometry", "initial_gap", mu)),
                "centre1": centre1}

    def _mapped(self, body: _Body, mu) -> np.ndarray:
        return self._body_maps()[body.name](mu, body.mesh_hat.p.T).T

    def _elastic_operators(self, mu) -> tuple[sp.csr_matrix, list]:
        blocks, bases = [], []
        for body in self._bodies():
            E, nu = self.scene.material(body.name, mu)
            mesh = type(body.mesh_hat)(self._mapped(body, mu), body.mesh_hat.t)
            basis = Basis(mesh, ElementVector(_element(self.degree)))
            blocks.append(asm(linear_elasticity(*lame_parameters(E, nu)), basis))
            bases.append(basis)
        return sp.block_diag(blocks).tocsr(), bases

    def discretize(self, mu, needs: frozenset[str] = frozenset()) -> Discretization:
        """Operators at ``mu``; ``needs`` may ask for ``"tangential"`` (friction) operators.

        Only what is asked for is built ("model only what a scene requires").
        """
        mu = self.scene.check_mu(mu)
        unknown = set(needs) - {"tangential"}
        if unknown:
            raise ValueError(f"skfem backend: unknown needs {sorted(unknown)}; "
                             "valid: 'tangential'")
        if self.kind == "unit_square":
            if needs:
                raise ValueError("skfem backend: a scalar obstacle problem has no tangential "
                                 "operators")
            return self._discretize_square(mu)
        return self._discretize_halfdisks(mu, needs)

    def _discretize_halfdisks(self, mu, needs=frozenset()) -> Discretization:
        t0 = time.perf_counter()
        geo = self._geometry(mu)
        A, bases = self._elastic_operators(mu)
        t_asm = time.perf_counter() - t0
        d = float(self.scene.value("load", "displacement", mu))
        # Dirichlet: upper flat face moves by (0, -d); lower flat face clamped.
        b_up = bases[0]
        y_face = geo["centre1"][1]
        up = b_up.get_dofs(lambda x: np.abs(x[1] - y_face) < 1e-9 * geo["R1"])
        dofs = [up.all("u^1"), up.all("u^2")]
        vals = [np.zeros(up.all("u^1").size), np.full(up.all("u^2").size, -d)]
        if self.lower is not None:
            lo = bases[1].get_dofs(lambda x: np.abs(x[1]) < 1e-9 * geo["R2"])
            dofs.append(lo.all() + self.lower.offset)
            vals.append(np.zeros(lo.all().size))
        ddofs = np.concatenate(dofs)
        dvals = np.concatenate(vals)
        contact = self._contact(mu, tangential="tangential" in needs)
        bodies = []
        for body in self._bodies():
            E, nu = self.scene.material(body.name, mu)
            bodies.append(BodyMesh(body.name, self._mapped(body, mu).T.copy(),
                                   body.mesh_hat.t.T.copy(), body.vertex_dofs(), E, nu))
        info = {"geometry": geo, "t_assemble_s": t_asm,
                "n_facets_slave": self.contact_layout().slave.n,
                "h_contact": self.h_contact, "degree": self.degree, "backend": self.name}
        return Discretization(mu=mu, A=A, F=np.zeros(self.ndofs), dirichlet_dofs=ddofs,
                              dirichlet_values=dvals, X=self.inner_product(), contact=contact,
                              bodies=bodies, physics="elasticity", info=info)

    def contact_layout(self) -> ContactLayout:
        """Reference contact data and the mu-maps (see :mod:`rbbench.contact_geometry`)."""
        if self.kind != "halfdisks":
            raise NotImplementedError("skfem backend: a contact layout exists for two-body "
                                      "(halfdisks) scenes only")
        if self._layout is None:
            self._layout = self._build_layout()
        return self._layout

    def _chain(self, body: _Body, zone: tuple, amap: AffineMap) -> FacetChain:
        facets, flip, inner = self._zone_facets(body.mesh_hat, zone)
        f = body.mesh_hat.facets
        n0 = np.where(flip, f[1, facets], f[0, facets])
        n1 = np.where(flip, f[0, facets], f[1, facets])
        p = body.mesh_hat.p
        return FacetChain(a=p[:, n0].T.copy(), b=p[:, n1].T.copy(), inner=inner,
                          dofs=body.facet_dofs(facets, flip), map=amap,
                          ids=np.arange(facets.size))

    def _build_layout(self) -> ContactLayout:
        maps = self._body_maps()
        slave = self._chain(self.upper, self.zone, maps["upper"])
        master = None
        if not self.rigid:
            master = self._chain(self.lower, tuple(self.master_zone), maps["lower"])
        return ContactLayout(slave=slave, master=master, degree=self.degree,
                             n_gauss=self.n_gauss, multiplier=self.multiplier,
                             patch=int(self.scene.data["discretization"]["lac_patch"]),
                             n_facets=slave.n, n_dofs=self.ndofs)

    def _contact(self, mu, tangential: bool = False) -> ContactOperators:
        """GPTS pairing at mu: :func:`rbbench.contact_geometry.contact_operators`."""
        try:
            return contact_operators(self.contact_layout(), mu, tangential)
        except PairingError as exc:
            zone = [float(z) for z in self.scene.data["geometry"]["master_zone"]]
            raise SceneError(
                f"{self.scene.path}: [geometry] master_zone: {exc.n_missed} slave "
                f"quadrature point(s) (e.g. x = {exc.example.round(4).tolist()}) project "
                f"outside the master zone {zone} (theta/pi); widen it") from None

    def _discretize_square(self, mu) -> Discretization:
        s = self.scene
        f = float(s.value("load", "source", mu))
        h = float(s.value("obstacle", "height", mu))
        c = float(s.value("obstacle", "curvature", mu))
        x0 = np.asarray(s.data["obstacle"]["centre"])
        m, b = self.mesh, self.basis
        bnd = self.mesh.boundary_nodes() if self.degree == 1 else b.get_dofs().all()
        free_nodes = np.setdiff1d(np.arange(b.N), bnd)
        xy = b.doflocs[:, free_nodes].T
        psi = h - c * np.sum((xy - x0) ** 2, axis=1)
        lumped = np.asarray(self.M.sum(axis=1)).ravel()[free_nodes]
        nq = free_nodes.size
        Un = sp.csr_matrix((-np.ones(nq), (np.arange(nq), free_nodes)), shape=(nq, b.N))
        contact = ContactOperators(
            Un=Un, gap=-psi, weights=lumped, points=xy, normals=np.tile([0.0, -1.0], (nq, 1)),
            Mlam=sp.identity(nq, format="csr"), multiplier="nodal", mult_points=xy,
            mult_extent=np.stack([xy[:, 0], xy[:, 0]], axis=1))
        body = BodyMesh("membrane", m.p.T.copy(), m.t.T.copy(), np.arange(m.nvertices)[:, None])
        return Discretization(mu=mu, A=self.A_lap, F=f * self.load_vec,
                              dirichlet_dofs=bnd, dirichlet_values=np.zeros(bnd.size),
                              X=self.inner_product(), contact=contact, bodies=[body],
                              physics="poisson", info={"backend": self.name,
                                                       "degree": self.degree})

"""scikit-fem HF backend (the default).

Reference meshes are built once (``__init__``) and mapped by mu in
:meth:`SkfemBackend.discretize`: the upper half-disk is ``x = R1 x_hat + c``,
so dof counts do not depend on mu while ``B(mu)`` and the gap do.

Scenes: ``halfdisks`` (plane-strain elasticity, two half-disks or a half-disk
on a rigid flat), ``hemispheres`` (3D elasticity, handed to
:func:`~rbbench_plugins.backends.skfem.hemispheres.skfem_hemisphere_model`) and ``unit_square``
(scalar membrane obstacle problem).
"""

from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
from rbbench_plugins.backends import common
from rbbench_plugins.backends.skfem.hemispheres import skfem_hemisphere_model
from rbbench_plugins.backends.skfem.meshes import graded_half_disk, unit_square
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

from rbbench.hf.geometry.chains import AffineMap, FacetChain, SlaveStress
from rbbench.interfaces import Backend, BodyMesh, Discretization
from rbbench.scene.loading import Scene


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

    def __init__(self, name: str, mesh_hat, degree: int, offset: int,
                 chain_zone: tuple[float, float] = (0.0, 0.0)):
        self.name = name
        self.mesh_hat = mesh_hat
        self.degree = degree
        self.offset = offset
        self.chain_zone = chain_zone
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

    def flat_facets(self) -> np.ndarray:
        """Boundary facets on the flat face (Dirichlet), sorted."""
        m = self.mesh_hat
        bf = m.boundary_facets()
        return bf[common.flat_facets(m.p.T, m.facets[:, bf].T)]


class SkfemBackend(common.HalfDiskContact, Backend):
    """scikit-fem backend: graded meshes, P1/P2 Lagrange, GPTS contact pairing.

    Parameters
    ----------
    scene : Scene
        A validated scene.
    """

    name = "skfem"

    #: the constructor's options (checked before the mesh is built)
    OPTIONS: tuple[str, ...] = ()

    def __init__(self, scene: Scene, **options):
        if options:
            raise TypeError(f"skfem backend: unknown options {sorted(options)}")
        self.scene = scene
        vars(self).update(common.discretization_settings(scene))  # degree, h_contact, ..., kind
        t0 = time.perf_counter()
        if self.kind == "halfdisks":
            self._init_halfdisks()
        elif self.kind == "hemispheres":
            self._hemi = skfem_hemisphere_model(scene, self.degree, self.h_contact, self.h_max,
                                         self.grading)
            self.ndofs = self._hemi.ndofs
        else:
            self._init_square()
        self.t_mesh = time.perf_counter() - t0
        self._X = None
        self._k_ref = None

    # ------------------------------------------------------------------ setup
    def _init_halfdisks(self) -> None:
        common.check_multiplier(self.scene)
        self.rigid = common.is_rigid(self.scene)
        self.upper, self.lower = None, None
        offset = 0
        for spec in common.halfdisk_bodies(self.scene):
            mesh = graded_half_disk(spec.mesh_zone, self.h_contact, self.h_max, self.grading)
            if spec.mirrored:
                p, t = common.mirror_y(mesh.p.T, mesh.t.T)
                mesh = type(mesh)(p.T, t.T)
            body = _Body(spec.name, mesh, self.degree, offset, spec.chain_zone)
            setattr(self, spec.name, body)
            offset += body.ndofs
        self.zone = self.upper.chain_zone
        if self.lower is not None:
            self.master_zone = np.asarray(self.lower.chain_zone)
        self.ndofs = offset
        # Dirichlet dofs (independent of mu): the flat face of each body; the upper one
        # moves by (t, -d) (``_moving``: its y dofs; ``_sliding``: its x dofs, t = 0
        # without friction), the lower one is clamped
        up = self.upper.basis_hat.get_dofs(facets=self.upper.flat_facets())
        dofs = [up.all("u^1"), up.all("u^2")]
        if self.lower is not None:
            lo = self.lower.basis_hat.get_dofs(facets=self.lower.flat_facets())
            dofs.append(lo.all() + self.lower.offset)
        self._dirichlet = np.concatenate(dofs)
        self._moving = np.zeros(self._dirichlet.size, dtype=bool)
        self._moving[dofs[0].size:dofs[0].size + dofs[1].size] = True
        self._sliding = np.zeros(self._dirichlet.size, dtype=bool)  # its x dofs
        self._sliding[:dofs[0].size] = True

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
            elif self.kind == "hemispheres":
                self._X = self._hemi.inner_product(which)
            else:
                mu0 = self.scene.default_mu
                if which == "energy":
                    self._X = self._elastic_operator(mu0)
                else:
                    blocks = [asm(_vector_h1, b.basis_hat) for b in self._bodies()]
                    self._X = sp.block_diag(blocks).tocsr()
        return self._X

    def warm_up(self) -> None:
        """The inner product and, for half-disks, the reference stiffness terms."""
        super().warm_up()
        if self.kind == "halfdisks":
            self._reference_stiffness()

    def contact_layout(self):
        """The contact layout: a :class:`~rbbench.hf.geometry.surface.SurfaceLayout` for
        ``hemispheres``, else :meth:`common.HalfDiskContact.contact_layout`."""
        if self.kind == "hemispheres":
            return self._hemi.contact_layout()
        return super().contact_layout()

    def _bodies(self) -> list[_Body]:
        return [self.upper] + ([self.lower] if self.lower is not None else [])

    def _geometry(self, mu) -> dict:
        return common.halfdisk_geometry(self.scene, self._body_maps(), mu)

    def _mapped(self, body: _Body, mu) -> np.ndarray:
        return self._body_maps()[body.name](mu, body.mesh_hat.p.T).T

    def _elastic_operator(self, mu) -> sp.csr_matrix:
        """Block-diagonal plane-strain stiffness at mu: ``sum_b lam_b K_div,b + mu_b
        K_eps,b`` with the Lame parameters of each body at mu (:meth:`_reference_stiffness`).

        Each body moves by a similarity ``x = s x_hat + c`` (:class:`AffineMap`): strains
        scale by ``1 / s`` and areas by ``s^2``, so the stiffness on the mapped mesh is the
        one on the reference mesh (2D), and only ``E(mu)``, ``nu(mu)`` enter. Equal to the
        assembly on the mapped mesh up to round-off (``tests/plugins/backends/test_skfem.py``)."""
        pattern, parts = self._reference_stiffness()
        data = np.concatenate([lam * k_div + mu_l * k_eps for (k_div, k_eps), (lam, mu_l) in
                               zip(parts, self._lame(mu), strict=True)])
        return sp.csr_matrix((data, *pattern), shape=(self.ndofs, self.ndofs))

    def _lame(self, mu) -> list[tuple[float, float]]:
        """The plane-strain Lame parameters ``(lambda, mu)`` of each body at mu."""
        return [lame_parameters(*self.scene.material(body.name, mu)) for body in self._bodies()]

    def _reference_stiffness(self) -> tuple[tuple[np.ndarray, np.ndarray], list]:
        """``((indices, indptr), [(K_div data, K_eps data) per body])``: the block-diagonal
        CSR pattern and the data of the two Lame terms of each body on it, assembled once on
        the reference meshes (``linear_elasticity(1, 0)`` and ``(0, 1)``: the same element
        loops, so the same pattern before scipy sums the duplicates; 0.16 s at level 0)."""
        if self._k_ref is None:
            rows, cols, data = [], [], ([], [])
            for body in self._bodies():
                for lame, out in zip(((1.0, 0.0), (0.0, 1.0)), data, strict=True):
                    coo = linear_elasticity(*lame).coo_data(body.basis_hat)
                    out.append(coo.data.ravel())
                rows.append(coo.indices[0].ravel() + body.offset)
                cols.append(coo.indices[1].ravel() + body.offset)
            shape = (self.ndofs, self.ndofs)
            k_div, k_eps = (sp.coo_matrix((np.concatenate(d), (np.concatenate(rows),
                                                               np.concatenate(cols))),
                                          shape=shape).tocsr() for d in data)
            for k in (k_div, k_eps):
                k.sort_indices()
            if not (np.array_equal(k_div.indptr, k_eps.indptr)
                    and np.array_equal(k_div.indices, k_eps.indices)):
                raise RuntimeError("skfem backend: the Lame terms differ in pattern")
            cuts = k_div.indptr[[body.offset for body in self._bodies()] + [self.ndofs]]
            parts = [(k_div.data[a:b], k_eps.data[a:b])
                     for a, b in zip(cuts[:-1], cuts[1:], strict=True)]
            # shared by every matrix of _elastic_operator: read-only (a change raises)
            pattern = (k_div.indices, k_div.indptr)
            for a in pattern:
                a.flags.writeable = False
            self._k_ref = (pattern, parts)
        return self._k_ref

    def discretize(self, mu, needs: frozenset[str] = frozenset()) -> Discretization:
        """Operators at ``mu``; ``needs`` may ask for ``"tangential"`` (friction) and
        ``"stress"`` (Nitsche: ``Snn``, ``facet_length``) operators.

        Only what is asked for, or what the scene requires, is built ("model only what
        a scene requires": the tangential operators of a friction scene).
        """
        mu = self.scene.check_mu(mu)
        common.check_needs(self.name, self.scene, needs)
        if self.kind == "unit_square":
            return self._discretize_square(mu)
        if self.kind == "hemispheres":
            if needs - {"stress"}:
                raise ValueError(f"skfem backend: the 3D hemispheres have no "
                                 f"{sorted(needs - {'stress'})} operators (frictionless: "
                                 "valid needs are 'stress' or none)")
            return self._hemi.discretize(mu, self.name, self.inner_product(),
                                        stress="stress" in needs)
        return self._discretize_halfdisks(mu, common.scene_needs(self.scene, needs))

    def _discretize_halfdisks(self, mu, needs=frozenset()) -> Discretization:
        t0 = time.perf_counter()
        geo = self._geometry(mu)
        A = self._elastic_operator(mu)
        t_asm = time.perf_counter() - t0
        dvals, steps = common.dirichlet_loads(self.scene, mu, self._moving, self._sliding)
        contact = self._contact(mu, needs)
        bodies = []
        for body in self._bodies():
            E, nu = self.scene.material(body.name, mu)
            bodies.append(BodyMesh(body.name, self._mapped(body, mu).T.copy(),
                                   body.mesh_hat.t.T.copy(), body.vertex_dofs(), E, nu))
        info = {"geometry": geo, "t_assemble_s": t_asm,
                "n_facets_slave": self.contact_layout().slave.n,
                "h_contact": self.h_contact, "degree": self.degree, "backend": self.name}
        return Discretization(mu=mu, A=A, F=np.zeros(self.ndofs), dirichlet_dofs=self._dirichlet,
                              dirichlet_values=dvals, X=self.inner_product(), contact=contact,
                              bodies=bodies, physics="elasticity", info=info,
                              dirichlet_steps=steps)

    def _chain(self, body: _Body, amap: AffineMap) -> FacetChain:
        m = body.mesh_hat
        bf = m.boundary_facets()
        return common.facet_chain(m.p.T, m.t.T, m.facets[:, bf].T, m.f2t[0, bf],
                                  body.chain_zone,
                                  lambda rows, flip: body.facet_dofs(bf[rows], flip), amap)

    def _stress(self, body: _Body) -> SlaveStress:
        """The slave elements behind ``Snn`` (:func:`common.slave_stress`)."""
        m, b = body.mesh_hat, body.basis_hat
        bf = m.boundary_facets()
        edge_dofs = None
        if body.degree == 2:
            index = common.edge_lookup(m.facets.T, m.nvertices)

            def edge_dofs(pairs):
                return b.facet_dofs[:, index(pairs)].T + body.offset

        return common.slave_stress(self.scene, m.p.T, m.t.T, m.facets[:, bf].T, m.f2t[0, bf],
                                   body.chain_zone,
                                   lambda v: b.nodal_dofs[:, v].T + body.offset, edge_dofs)

    def _discretize_square(self, mu) -> Discretization:
        f = float(self.scene.value("load", "source", mu))
        m, b = self.mesh, self.basis
        bnd = self.mesh.boundary_nodes() if self.degree == 1 else b.get_dofs().all()
        free_nodes = np.setdiff1d(np.arange(b.N), bnd)
        xy = b.doflocs[:, free_nodes].T
        lumped = np.asarray(self.M.sum(axis=1)).ravel()[free_nodes]
        contact = common.obstacle_contact(self.scene, mu, xy, free_nodes, lumped, b.N)
        body = BodyMesh("membrane", m.p.T.copy(), m.t.T.copy(), np.arange(m.nvertices)[:, None])
        return Discretization(mu=mu, A=self.A_lap, F=f * self.load_vec,
                              dirichlet_dofs=bnd, dirichlet_values=np.zeros(bnd.size),
                              X=self.inner_product(), contact=contact, bodies=[body],
                              physics="poisson", info={"backend": self.name,
                                                       "degree": self.degree})

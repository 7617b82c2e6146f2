"""NGSolve HF backend: Netgen meshes (or meshes given as arrays), P1/P2, sparse Cholesky.

The same scenes, reference geometry, mu-maps, Dirichlet data, materials and
contact operators as the scikit-fem backend (the backend-neutral parts live in
:mod:`rbbench_plugins.backends.common`); only the meshes, the assembly and the
dof numbering are NGSolve's:

* **Meshes.** Each reference body (unit half-disks, unit square) is meshed once
  in ``__init__``: by default with Netgen on an OCC geometry whose contact arc
  carries the local size ``h_contact`` (``mesh="netgen"``); or the arrays of
  :mod:`rbbench_plugins.backends.skfem.meshes` (``mesh="skfem"``: the very meshes of
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

The meshes live in :mod:`rbbench_plugins.backends.ngsolve.meshes`, the change of basis,
the solver hook, one body and the weak forms in :mod:`rbbench_plugins.backends.ngsolve.fe`;
this module holds the backend.
"""

from __future__ import annotations

import time
from typing import Any

import ngsolve as ngs
import numpy as np
import scipy.sparse as sp
from rbbench_plugins.backends import common
from rbbench_plugins.backends.ngsolve.fe import (
    Body,
    elasticity_form,
    laplace_form,
    mass_form,
    sparse_cholesky,
    vector_h1_form,
)
from rbbench_plugins.backends.ngsolve.hemispheres import ngsolve_hemisphere_model
from rbbench_plugins.backends.ngsolve.meshes import (
    netgen_half_disk,
    netgen_unit_square,
    skfem_mesh_arrays,
    validated_arrays,
)

from rbbench.hf.geometry.chains import AffineMap, FacetChain, SlaveStress
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

__all__ = ["DIRECT_SOLVERS", "MESH_SOURCES", "NGSolveBackend"]


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
        (:mod:`rbbench_plugins.backends.skfem.meshes`), so both backends run on one
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

    #: the constructor's options (checked before the mesh is built)
    OPTIONS: tuple[str, ...] = ("mesh", "direct_solver", "threads")

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
        elif self.kind == "hemispheres":
            if mesh != "netgen":
                raise ValueError("ngsolve backend: option mesh: the 3D hemispheres take the "
                                 "shared Netgen reference mesh only; expected 'netgen'")
            self._hemi = ngsolve_hemisphere_model(scene, self.degree, self.h_contact,
                                                  self.h_max, self.grading)
            self.ndofs = self._hemi.ndofs
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
        self.upper: Body | None = None
        self.lower: Body | None = None
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
                    p, t = skfem_mesh_arrays("halfdisks", zone, self.h_contact, self.h_max,
                                              self.grading)
                if spec.mirrored:
                    p, t = common.mirror_y(p, t)
                what = f"ngsolve backend: the {mesh} mesh of body {spec.name!r}"
            p, t = validated_arrays(p, t, domain, what)
            body = Body(spec.name, p, t, self.degree, 2, offset, spec.chain_zone)
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
            p, t = skfem_mesh_arrays("unit_square", n=n)
        else:
            p, t = self._given_arrays(mesh, ["membrane"])["membrane"]
        p, t = validated_arrays(p, t, "unit_square", what)
        self.body = Body("membrane", p, t, self.degree, 1, 0)
        self.ndofs = self.body.ndofs
        self.A_lap = self.body.matrix(laplace_form)
        self.M = self.body.matrix(mass_form)
        self.load_vec = self.body.vector(lambda v: v)
        self.boundary_dofs = self.body.scalar_dofs_on(self.body.facets)
        self.body.check_dofs_on("boundary", self.boundary_dofs)

    def contact_layout(self):
        """The contact layout: a :class:`~rbbench.hf.geometry.surface.SurfaceLayout` for
        ``hemispheres``, else :meth:`common.HalfDiskContact.contact_layout`."""
        if self.kind == "hemispheres":
            return self._hemi.contact_layout()
        return super().contact_layout()

    def _bodies(self) -> list[Body]:
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
            elif self.kind == "hemispheres":
                self._X = self._hemi.inner_product(which)
            elif which == "energy":
                self._X = self._elastic_operator(self.scene.default_mu)
            else:
                self._X = sp.block_diag([b.matrix(vector_h1_form) for b in self._bodies()]).tocsr()
        return self._X

    def _elastic_operator(self, mu: np.ndarray) -> sp.csr_matrix:
        """Block-diagonal plane-strain stiffness, each body assembled at its mu-map."""
        blocks = []
        for body in self._bodies():
            E, nu = self.scene.material(body.name, mu)
            with body.mapped(self._body_maps()[body.name], mu):
                blocks.append(body.matrix(elasticity_form(E, nu)))
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
        if self.kind == "hemispheres":
            if needs - {"stress"}:
                raise ValueError(f"ngsolve backend: the 3D hemispheres have no "
                                 f"{sorted(needs - {'stress'})} operators (frictionless: "
                                 "valid needs are 'stress' or none)")
            disc = self._hemi.discretize(mu, self.name, self.inner_product(),
                                        stress="stress" in needs)
            disc.factorize = self._factorize()
            return disc
        return self._discretize_halfdisks(mu, common.scene_needs(self.scene, needs))

    def _discretize_halfdisks(self, mu: np.ndarray, needs=frozenset()) -> Discretization:
        t0 = time.perf_counter()
        maps = self._body_maps()
        geo = common.halfdisk_geometry(self.scene, maps, mu)
        A = self._elastic_operator(mu)
        t_asm = time.perf_counter() - t0
        # Dirichlet: upper flat face moves by (t, -d) (t = 0 without friction); lower
        # flat face clamped.
        dofs, down, along = [], [], []
        for body, flat in zip(self._bodies(), self._flat_dofs, strict=True):
            for c in range(2):
                dofs.append(flat[c])
                down.append(np.full(flat[c].size, body.name == "upper" and c == 1))
                along.append(np.full(flat[c].size, body.name == "upper" and c == 0))
        vals, steps = common.dirichlet_loads(self.scene, mu, np.concatenate(down),
                                             np.concatenate(along))
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
                              dirichlet_values=vals, X=self.inner_product(),
                              contact=contact, bodies=bodies, physics="elasticity", info=info,
                              factorize=self._factorize(), dirichlet_steps=steps)

    @staticmethod
    def _chain(body: Body, amap: AffineMap) -> FacetChain:
        return common.facet_chain(body.points, body.triangles, body.facets, body.elements,
                                  body.chain_zone, body.facet_dofs, amap)

    def _stress(self, body: Body) -> SlaveStress:
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

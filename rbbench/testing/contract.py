"""Plugin contract test-suite: what every rbbench component must satisfy.

A third-party plugin package runs the same checks as the built-in components::

    import pytest
    from rbbench.testing import check_component, component_params

    @pytest.mark.parametrize("spec", component_params())
    def test_contract(spec):
        check_component(spec)

or calls one role's check on its own class::

    from rbbench.testing import check_solver
    check_solver(MySolver)                      # any callable returning a Solver
    check_backend(MyBackend, load_scene("membrane_obstacle"))

Every check raises :class:`ContractViolation` (an ``AssertionError``) naming the
component and the property that failed. The checks assert mathematical
properties of the role (symmetry, definiteness, KKT conditions, shapes), never
the output of a particular implementation.

Reference scenes: ``membrane_obstacle`` (scalar, cheap) for every backend, and
``hertz_halfdisks`` on a coarse mesh for backends declaring ``"elasticity"`` in
``capabilities["physics"]``.

``pytest`` is imported only by the helpers that need it (:func:`component_params`,
:func:`check_component`), so importing this module stays cheap.
"""

from __future__ import annotations

import copy
import functools
import inspect
import re
import threading
from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from rbbench.interfaces import (
    STOP_REASONS,
    ContactOperators,
    ContactProblem,
    Discretization,
    NitscheProblem,
    SolveResult,
)
from rbbench.registry import ROLES, ComponentSpec, Registry, default_registry
from rbbench.scene.loading import SCHEMA, Scene, SceneError, load_scene

__all__ = [
    "ContractViolation",
    "HERTZ_COARSE",
    "PRIMAL_TOL_KINDS",
    "ROLE_CHECKS",
    "STABILIZER_GUARANTEES",
    "backend_scenes",
    "check_backend",
    "check_component",
    "check_dual",
    "check_formulation",
    "check_nitsche_solver",
    "check_primal",
    "check_solver",
    "check_spec",
    "check_stabilizer",
    "component_params",
    "dual_test_data",
    "infeasible_contact_problem",
    "primal_test_data",
    "random_contact_problem",
    "random_nitsche_problem",
    "redundant_contact_problem",
    "reference_discretization",
    "stabilizer_test_data",
]

#: Overrides making ``hertz_halfdisks`` cheap enough for a contract run.
HERTZ_COARSE = ("discretization.h_contact=0.02", "discretization.h_max=0.2")

#: Roles with a role-specific contract (the others get the declaration check only).
ROLE_CHECKS = ("backend", "formulation", "solver", "primal", "dual", "stabilizer",
               "executor")

_KNOWN_PHYSICS = SCHEMA["scene"]["physics"].choices
_KNOWN_MULTIPLIERS = SCHEMA["discretization"]["multiplier"].choices
_SYM_TOL = 1e-12  # relative asymmetry allowed in A, X, W
_DENSE_LIMIT = 2000  # up to this size definiteness is checked with dense eigvalsh
_DEF_TOL = 1e-13  # lambda_min (or smallest pivot) relative to the largest diagonal entry
_IDENT = r"[A-Za-z_][A-Za-z0-9_]*"
_TARGET_RE = re.compile(rf"^{_IDENT}(\.{_IDENT})*:{_IDENT}(\.{_IDENT})*$")


class ContractViolation(AssertionError):
    """A component breaks its role's contract; the message says which property."""


def _require(cond: Any, what: str) -> None:
    if not cond:
        raise ContractViolation(what)


# ---------------------------------------------------------------------------
# linear-algebra helpers (independent of the code under test)
# ---------------------------------------------------------------------------
def _as_sparse(M: Any, what: str) -> sp.csr_matrix:
    _require(sp.issparse(M) or isinstance(M, np.ndarray), f"{what}: expected a sparse matrix "
             f"or ndarray, got {type(M).__name__}")
    M = sp.csr_matrix(M, dtype=float)
    _require(np.all(np.isfinite(M.data)), f"{what}: has non-finite entries")
    return M


def _check_symmetric(M: sp.csr_matrix, what: str, tol: float = _SYM_TOL) -> None:
    _require(M.shape[0] == M.shape[1], f"{what}: not square, shape {M.shape}")
    scale = abs(M).max() if M.nnz else 0.0
    asym = abs(M - M.T).max() if M.nnz else 0.0
    _require(asym <= tol * max(scale, np.finfo(float).tiny),
             f"{what}: not symmetric: max|M - M^T| = {asym:.3e} > {tol:g} * max|M| "
             f"= {tol * scale:.3e}")


def _check_spd(M: sp.csr_matrix, what: str) -> None:
    """Positive definiteness of a symmetric matrix.

    Dense ``eigvalsh`` for small matrices; otherwise an LDL^T-equivalent sparse LU
    with symmetric permutation and diagonal pivots only: a symmetric matrix is
    positive definite iff all those pivots are positive.
    """
    n = M.shape[0]
    if n == 0:
        return
    dmax = float(np.max(np.abs(M.diagonal())))
    _require(dmax > 0, f"{what}: zero diagonal")
    if n <= _DENSE_LIMIT:
        lam_min = float(np.linalg.eigvalsh(M.toarray())[0])
        _require(lam_min > _DEF_TOL * dmax,
                 f"{what}: not positive definite: smallest eigenvalue {lam_min:.3e} "
                 f"(largest diagonal entry {dmax:.3e})")
        return
    try:
        lu = spla.splu(sp.csc_matrix(M), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
    except RuntimeError as exc:  # "Factor is exactly singular"
        raise ContractViolation(f"{what}: not positive definite ({exc})") from None
    _require(np.array_equal(lu.perm_r, lu.perm_c),
             f"{what}: not positive definite (LU needed an off-diagonal pivot)")
    piv = lu.U.diagonal()
    _require(piv.min() > _DEF_TOL * dmax,
             f"{what}: not positive definite: smallest LDL^T pivot {piv.min():.3e} "
             f"(largest diagonal entry {dmax:.3e})")


def _vector(v: Any, n: int, what: str) -> np.ndarray:
    v = np.asarray(v)
    _require(v.shape == (n,), f"{what}: expected shape ({n},), got {v.shape}")
    _require(np.issubdtype(v.dtype, np.number) and np.all(np.isfinite(v)),
             f"{what}: not a finite numeric vector")
    return v.astype(float)


def _index_set(idx: Any, n: int, what: str) -> np.ndarray:
    idx = np.asarray(idx)
    _require(idx.ndim == 1, f"{what}: expected a 1-d index array, got shape {idx.shape}")
    _require(idx.size == 0 or np.issubdtype(idx.dtype, np.integer),
             f"{what}: expected integer indices, got dtype {idx.dtype}")
    idx = idx.astype(np.int64)
    _require(np.all((idx >= 0) & (idx < n)), f"{what}: indices outside [0, {n})")
    _require(np.unique(idx).size == idx.size, f"{what}: repeated indices")
    return idx


def _shape(M: Any, shape: tuple[int, int], what: str) -> None:
    _require(tuple(M.shape) == shape, f"{what}: expected shape {shape}, got {tuple(M.shape)}")


# ---------------------------------------------------------------------------
# declaration
# ---------------------------------------------------------------------------
_ROLE_METHOD = {"backend": "discretize", "formulation": "build", "solver": "solve",
                "primal": "__call__", "dual": "__call__", "stabilizer": "offline"}


def check_spec(registry: Registry, spec: ComponentSpec) -> Any:
    """Check a component's declaration; return its loaded target, or None if not installed.

    Role valid, ``target`` reads ``"module:attr"`` (and resolves when the
    component is available), ``capabilities`` is a dict, description non-empty,
    the spec is what the registry returns for its (role, name).
    """
    label = f"{spec.role} {spec.name!r} (package {spec.package or '?'})"
    _require(isinstance(spec.name, str) and spec.name.strip(), f"{label}: empty name")
    _require(spec.name == spec.name.strip() and " " not in spec.name,
             f"{label}: the name must not contain spaces")
    _require(spec.role in ROLES, f"{label}: role {spec.role!r} is not one of {ROLES}")
    _require(isinstance(spec.target, str) and _TARGET_RE.match(spec.target),
             f"{label}: target {spec.target!r} must read 'package.module:Attribute'")
    _require(isinstance(spec.capabilities, dict),
             f"{label}: capabilities must be a dict, got {type(spec.capabilities).__name__}")
    _require(isinstance(spec.description, str) and spec.description.strip(),
             f"{label}: empty description (shown by 'rbbench plugins')")
    for field in ("extras", "modules"):
        value = getattr(spec, field)
        _require(isinstance(value, tuple) and all(isinstance(v, str) and v for v in value),
                 f"{label}: {field} must be a tuple of non-empty strings, got {value!r}")
    physics = spec.capabilities.get("physics")
    if physics is not None:
        _require(isinstance(physics, (tuple, list)) and set(physics) <= set(_KNOWN_PHYSICS),
                 f"{label}: capabilities['physics'] = {physics!r}; known physics: "
                 f"{_KNOWN_PHYSICS}")
    _require(registry.get(spec.role, spec.name) == spec,
             f"{label}: the registry returns a different spec for this (role, name)")
    ok, why = registry.availability(spec)
    _require(isinstance(ok, bool) and isinstance(why, str),
             f"{label}: availability() must return (bool, str)")
    if not ok:
        _require(spec.install_hint in why, f"{label}: unavailable, but the reason {why!r} "
                 f"does not give the install hint {spec.install_hint!r}")
        return None
    try:
        obj = registry.load(spec.role, spec.name)
    except (ImportError, AttributeError) as exc:
        raise ContractViolation(
            f"{label}: target {spec.target!r} does not resolve: {exc!r}") from exc
    _require(callable(obj), f"{label}: target {spec.target!r} is not callable")
    method = _ROLE_METHOD.get(spec.role)
    if method and isinstance(obj, type):
        # vars() along the MRO: every class object is callable through its metaclass
        _require(callable(getattr(obj, method, None))
                 and any(method in vars(c) for c in obj.__mro__),
                 f"{label}: class {obj.__name__} has no {method}() method")
    return obj


# ---------------------------------------------------------------------------
# backend
# ---------------------------------------------------------------------------
@functools.cache
def _scene(name: str, overrides: tuple[str, ...] = ()) -> Scene:
    return load_scene(name, overrides)


def backend_scenes(capabilities: dict | None = None) -> list[Scene]:
    """The reference scenes for a component with these capabilities.

    ``membrane_obstacle`` for ``poisson`` (or when ``physics`` is not declared),
    coarse ``hertz_halfdisks`` when ``"elasticity"`` is declared.
    """
    physics = tuple((capabilities or {}).get("physics", ("poisson",)))
    scenes = []
    if "poisson" in physics:
        scenes.append(_scene("membrane_obstacle"))
    if "elasticity" in physics:
        scenes.append(_scene("hertz_halfdisks", HERTZ_COARSE))
    return scenes


def _check_contact(c: ContactOperators, n: int, label: str) -> None:
    _require(isinstance(c, ContactOperators),
             f"{label}: contact is {type(c).__name__}, not a ContactOperators")
    Un = _as_sparse(c.Un, f"{label}: contact.Un")
    nq = Un.shape[0]
    _shape(Un, (nq, n), f"{label}: contact.Un (n_q x n_dofs)")
    _require(nq > 0, f"{label}: no contact quadrature points")
    _vector(c.gap, nq, f"{label}: contact.gap")
    w = _vector(c.weights, nq, f"{label}: contact.weights")
    _require(np.all(w > 0), f"{label}: contact.weights must be > 0 (min {w.min():.3e})")
    _shape(np.asarray(c.points), (nq, 2), f"{label}: contact.points")
    nrm = np.asarray(c.normals, dtype=float)
    _shape(nrm, (nq, 2), f"{label}: contact.normals")
    _require(np.allclose(np.linalg.norm(nrm, axis=1), 1.0, atol=1e-10),
             f"{label}: contact.normals are not unit vectors")
    Mlam = _as_sparse(c.Mlam, f"{label}: contact.Mlam")
    nm = Mlam.shape[1]
    _shape(Mlam, (nq, nm), f"{label}: contact.Mlam (n_q x n_mult)")
    _require(nm > 0, f"{label}: no contact multipliers")
    _require(c.multiplier in _KNOWN_MULTIPLIERS,
             f"{label}: contact.multiplier {c.multiplier!r} not one of {_KNOWN_MULTIPLIERS}")
    _shape(np.asarray(c.mult_points), (nm, 2), f"{label}: contact.mult_points")
    ext = np.asarray(c.mult_extent, dtype=float)
    _shape(ext, (nm, 2), f"{label}: contact.mult_extent")
    _require(np.all(ext[:, 0] <= ext[:, 1]), f"{label}: contact.mult_extent has x_min > x_max")
    for opt in ("Ut", "Snn"):
        M = getattr(c, opt)
        if M is not None:
            _shape(M, (nq, n), f"{label}: contact.{opt}")
    _shape(c.B(), (nm, n), f"{label}: contact.B()")
    _vector(c.G(), nm, f"{label}: contact.G()")
    W = _as_sparse(c.W(), f"{label}: contact.W()")
    _shape(W, (nm, nm), f"{label}: contact.W()")
    _check_symmetric(W, f"{label}: contact.W()")
    _check_spd(W, f"{label}: contact.W() (multiplier Gram matrix)")


def _check_rigid_modes(disc: Discretization, label: str) -> None:
    """``A`` on all dofs is the unconstrained operator: it annihilates the rigid modes.

    Constants for a scalar problem; the two translations and the infinitesimal
    rotation for plane elasticity. Checked when the bodies' vertex dofs cover
    every dof (P1), where these modes are exactly representable.
    """
    n = disc.n_dofs
    vd = [np.asarray(b.vertex_dofs) for b in disc.bodies]
    covered = np.unique(np.concatenate([v.ravel() for v in vd]))
    if covered.size != n:
        return
    modes = []
    ncomp = vd[0].shape[1]
    if ncomp == 1:
        modes.append(("constant", np.ones(n)))
    elif ncomp == 2:
        for k, name in ((0, "x-translation"), (1, "y-translation")):
            t = np.zeros(n)
            for v in vd:
                t[v[:, k]] = 1.0
            modes.append((name, t))
        for b, v in zip(disc.bodies, vd, strict=True):  # rotation of each body on its own
            r = np.zeros(n)
            p = np.asarray(b.points, dtype=float)
            p = p - p.mean(axis=0)
            r[v[:, 0]], r[v[:, 1]] = -p[:, 1], p[:, 0]
            modes.append((f"rotation of body {b.name!r}", r))
    A = disc.A
    scale = abs(A).max()
    for name, m in modes:
        res = np.abs(A @ m).max()
        _require(res <= 1e-10 * scale * np.abs(m).max(),
                 f"{label}: A does not annihilate the {name} (max|A m| = {res:.3e}): "
                 "A must be the unconstrained operator, Dirichlet dofs given separately")


def _check_bodies(disc: Discretization, label: str) -> None:
    _require(isinstance(disc.bodies, list) and disc.bodies, f"{label}: no bodies for output")
    for b in disc.bodies:
        pts = np.asarray(b.points)
        tri = np.asarray(b.triangles)
        vd = np.asarray(b.vertex_dofs)
        nv = pts.shape[0]
        _require(pts.ndim == 2 and pts.shape[1] == 2, f"{label}: body {b.name}: points not (n, 2)")
        _require(tri.ndim == 2 and tri.shape[1] == 3 and np.issubdtype(tri.dtype, np.integer),
                 f"{label}: body {b.name}: triangles not an integer (n, 3) array")
        _require(tri.min() >= 0 and tri.max() < nv,
                 f"{label}: body {b.name}: triangles index outside the vertices")
        _require(vd.ndim == 2 and vd.shape[0] == nv and np.issubdtype(vd.dtype, np.integer),
                 f"{label}: body {b.name}: vertex_dofs not an integer (n_vertices, k) array")
        _require(vd.min() >= 0 and vd.max() < disc.n_dofs,
                 f"{label}: body {b.name}: vertex_dofs outside [0, n_dofs)")


def _check_contact_measure(disc: Discretization, scene: Scene, mu: np.ndarray,
                           label: str) -> None:
    """The quadrature weights measure the potential contact set of the mapped geometry.

    Half-disks: the arc ``R1 * pi * (zone[1] - zone[0])`` (to 1 %, polygonal
    boundary), so the weights follow ``R1(mu)``. Unit square (obstacle
    problem, nodal weights): at most the area 1 and more than half of it.
    """
    total = float(np.sum(disc.contact.weights))
    kind = scene.data["geometry"]["kind"]
    if kind == "halfdisks":
        r1 = float(scene.value("geometry", "upper_radius", mu))
        z0, z1 = scene.data["geometry"]["contact_zone"]
        arc = r1 * np.pi * (z1 - z0)
        _require(abs(total - arc) <= 0.01 * arc,
                 f"{label}: sum of contact weights {total:.6g} is not the length "
                 f"{arc:.6g} of the contact arc of radius R1 = {r1:g}")
    elif kind == "unit_square":
        _require(0.5 < total <= 1.0 + 1e-12,
                 f"{label}: sum of contact weights {total:.6g} is not a part of the unit area")


def _check_discretization(disc: Any, scene: Scene, mu: np.ndarray, label: str) -> None:
    _require(isinstance(disc, Discretization),
             f"{label}: discretize() returned {type(disc).__name__}, not a Discretization")
    _require(np.allclose(np.asarray(disc.mu, dtype=float), mu),
             f"{label}: Discretization.mu = {disc.mu!r}, expected {mu!r}")
    physics = scene.data["scene"]["physics"]
    _require(disc.physics == physics, f"{label}: physics {disc.physics!r}, scene says {physics!r}")
    A = _as_sparse(disc.A, f"{label}: A")
    n = A.shape[0]
    _require(n > 0, f"{label}: no dofs")
    _check_symmetric(A, f"{label}: A")
    _vector(disc.F, n, f"{label}: F")
    dd = _index_set(disc.dirichlet_dofs, n, f"{label}: dirichlet_dofs")
    _vector(disc.dirichlet_values, dd.size, f"{label}: dirichlet_values")
    free = np.setdiff1d(np.arange(n), dd)
    _require(free.size > 0, f"{label}: every dof is a Dirichlet dof")
    _check_spd(A[free][:, free], f"{label}: A on the free dofs")
    X = _as_sparse(disc.X, f"{label}: X")
    _shape(X, (n, n), f"{label}: X")
    _check_symmetric(X, f"{label}: X")
    _check_spd(X[free][:, free], f"{label}: X on the free dofs")
    _check_contact(disc.contact, n, label)
    _check_contact_measure(disc, scene, mu, label)
    _check_bodies(disc, label)
    _check_rigid_modes(disc, label)


def check_backend(factory: Callable[..., Any], scene: Scene, name: str | None = None) -> None:
    """Contract of the backend role on ``scene`` (``factory(scene=scene)`` builds it).

    ``discretize(default mu)`` returns a well-formed :class:`Discretization`:
    ``A`` and ``X`` symmetric, positive definite on the free dofs, ``A`` the
    unconstrained operator; consistent contact operators with positive weights
    and an SPD multiplier Gram matrix ``W``; dof and multiplier counts
    independent of mu; out-of-domain mu raises :class:`~rbbench.scene.loading.SceneError`.
    """
    label = f"backend {name or getattr(factory, '__name__', factory)!r} on {scene.name}"
    backend = factory(scene=scene)
    mu0 = scene.default_mu
    disc = backend.discretize(mu0)
    _check_discretization(disc, scene, mu0, label)
    n, nm, nq = disc.n_dofs, disc.contact.n_mult, disc.contact.n_quad
    lo, hi = scene.bounds[:, 0], scene.bounds[:, 1]
    for tag, mu in (("lower", lo), ("upper", hi)):
        d = backend.discretize(mu)
        where = f"{label} at the {tag} parameter bounds mu = {mu.tolist()}"
        _require(isinstance(d, Discretization), f"{where}: not a Discretization")
        _require((d.n_dofs, d.contact.n_mult, d.contact.n_quad) == (n, nm, nq),
                 f"{where}: (n_dofs, n_mult, n_quad) = "
                 f"{(d.n_dofs, d.contact.n_mult, d.contact.n_quad)} differ from "
                 f"{(n, nm, nq)} at the default mu: counts must not depend on mu")
        _require(np.all(np.isfinite(d.contact.gap)), f"{where}: non-finite gap")
        _check_contact_measure(d, scene, mu, where)
    outside = hi + (hi - lo) + 1.0
    for bad in (outside, np.append(mu0, 0.0)):
        try:
            backend.discretize(bad)
        except SceneError:
            continue
        raise ContractViolation(
            f"{label}: discretize({bad.tolist()}) must raise SceneError (mu outside the "
            f"domain {scene.bounds.tolist()} or of the wrong size)")


# ---------------------------------------------------------------------------
# formulation
# ---------------------------------------------------------------------------
@functools.cache
def _cached_disc(backend: str, scene_name: str, overrides: tuple[str, ...],
                 registry: Registry, needs: frozenset[str] = frozenset()) -> Discretization:
    scene = _scene(scene_name, overrides)
    b = registry.create("backend", backend, scene=scene)
    return b.discretize(scene.default_mu, needs=needs) if needs else \
        b.discretize(scene.default_mu)


def reference_discretization(physics: str, registry: Registry | None = None,
                             needs: frozenset[str] = frozenset()) -> Discretization:
    """A Discretization of the reference scene for ``physics`` from an installed backend.

    Prefers the built-in ``skfem`` backend; the result is a copy of a cached
    discretization, with the optional operators ``needs`` (e.g. ``{"stress"}``).
    Raises ``LookupError`` if no installed backend declares that physics.
    """
    reg = registry or default_registry()
    names = sorted(reg.names("backend"), key=lambda s: (s != "skfem", s))
    scene = "membrane_obstacle" if physics == "poisson" else "hertz_halfdisks"
    overrides = () if physics == "poisson" else HERTZ_COARSE
    for name in names:
        spec = reg.get("backend", name)
        if physics in spec.capabilities.get("physics", ()) and reg.availability(spec)[0]:
            return copy.deepcopy(_cached_disc(name, scene, overrides, reg,
                                              frozenset(needs)))
    raise LookupError(f"no installed backend declares physics {physics!r}")


def _check_free_stiffness(prob: Any, n: int, label: str) -> np.ndarray:
    """The part every formulation's problem shares: free dofs (a non-empty index set of
    ``0 .. n - 1``, returned), ``A`` sparse, n_free square, symmetric, SPD, and ``F`` of
    that size."""
    free = _index_set(prob.free, n, f"{label}: free")
    nf = free.size
    _require(nf > 0, f"{label}: no free dofs")
    A = _as_sparse(prob.A, f"{label}: A")
    _shape(A, (nf, nf), f"{label}: A (n_free x n_free)")
    _check_symmetric(A, f"{label}: A")
    _check_spd(A, f"{label}: A")
    _vector(prob.F, nf, f"{label}: F")
    return free


def check_formulation(factory: Callable[..., Any], disc: Discretization,
                      name: str | None = None) -> ContactProblem | NitscheProblem:
    """Contract of the formulation role on one Discretization (``factory()`` builds it).

    ``build(disc)`` returns a :class:`ContactProblem` with consistent shapes,
    finite data, ``A`` symmetric positive definite, ``W`` symmetric, ``free``
    a set of distinct dofs, and the Dirichlet dofs outside ``free`` carrying
    their values in ``u_lift`` and in ``expand(u_free)``. A :class:`NitscheProblem`
    is checked by the same rules for ``free``, ``A``, ``F`` and the lifting, plus its
    point operators against the backend's. Returns the checked problem.
    """
    label = f"formulation {name or getattr(factory, '__name__', factory)!r} on {disc.physics}"
    prob = factory().build(disc)
    if isinstance(prob, NitscheProblem):
        _check_nitsche_problem(prob, disc, label)
        return prob
    _require(isinstance(prob, ContactProblem),
             f"{label}: build() returned {type(prob).__name__}, not a ContactProblem")
    n = disc.n_dofs
    free = _check_free_stiffness(prob, n, label)
    nf = free.size
    B = _as_sparse(prob.B, f"{label}: B")
    _require(B.shape[1] == nf, f"{label}: B has {B.shape[1]} columns, expected n_free = {nf}")
    m = B.shape[0]
    _vector(prob.G, m, f"{label}: G")
    X = _as_sparse(prob.X, f"{label}: X")
    _require(X.shape[0] == X.shape[1] and X.shape[0] in (n, nf),
             f"{label}: X has shape {X.shape}, expected square of size n_dofs or n_free")
    W = _as_sparse(prob.W, f"{label}: W")
    _shape(W, (m, m), f"{label}: W (n_mult x n_mult)")
    _check_symmetric(W, f"{label}: W")
    _check_lifting(prob, disc, label)
    return prob


def _check_lifting(prob: Any, disc: Discretization, label: str) -> None:
    """The Dirichlet lifting: ``expand(u_free)`` puts ``u_free`` at ``free`` and, like
    ``u_lift``, the Dirichlet values at the constrained dofs (``free`` already checked)."""
    n = disc.n_dofs
    free = np.asarray(prob.free)
    constrained = np.setdiff1d(np.asarray(disc.dirichlet_dofs), free)
    dvals = dict(zip(np.asarray(disc.dirichlet_dofs).tolist(),
                     np.asarray(disc.dirichlet_values, dtype=float).tolist(), strict=True))
    want = np.array([dvals[d] for d in constrained.tolist()])
    lift = _vector(prob.u_lift, n, f"{label}: u_lift")
    v = np.random.default_rng(0).standard_normal(free.size)
    u = np.asarray(prob.expand(v))
    _require(u.shape == (n,), f"{label}: expand(u_free) has shape {u.shape}, expected ({n},)")
    _require(np.array_equal(u[free], v),
             f"{label}: expand() does not place the free values at free dofs")
    _require(np.allclose(u[constrained], want, rtol=1e-12, atol=0)
             and np.allclose(lift[constrained], want, rtol=1e-12, atol=0),
             f"{label}: expand()/u_lift do not carry the Dirichlet values")


def _check_nitsche_problem(prob: NitscheProblem, disc: Discretization, label: str) -> None:
    """A :class:`NitscheProblem`: shapes, finite data, ``A`` SPD, positive weights and
    ``gamma``, the Dirichlet lifting, and its point operators equal to the backend's
    ``Un``, ``Snn`` and gap applied to the lifted displacement (an independent check of the
    elimination: ``Un v - gap = Un_full expand(v) - gap_full``, same for ``Snn``)."""
    free = _check_free_stiffness(prob, disc.n_dofs, label)
    nf = free.size
    w = np.asarray(prob.weights, dtype=float)
    nq = w.size
    _require(nq > 0 and np.all(w > 0), f"{label}: weights must be > 0")
    for what in ("Un", "Snn"):
        M = _as_sparse(getattr(prob, what), f"{label}: {what}")
        _shape(M, (nq, nf), f"{label}: {what} (n_q x n_free)")
    for what in ("gap", "snn_lift", "gamma", "h"):
        _vector(getattr(prob, what), nq, f"{label}: {what}")
    _require(np.all(np.asarray(prob.gamma) > 0) and np.all(np.asarray(prob.h) > 0),
             f"{label}: gamma and h must be > 0")
    _require(np.isfinite(prob.theta), f"{label}: theta must be finite")
    _require(prob.Mlam.shape[0] == nq, f"{label}: Mlam must have n_q = {nq} rows")
    _check_lifting(prob, disc, label)
    c = disc.contact
    _require(c.Snn is not None, f"{label}: the discretization has no Snn")
    v = np.random.default_rng(1).standard_normal(nf)
    u = np.asarray(prob.expand(v))
    for got, want, what in ((prob.Un @ v - prob.gap, c.Un @ u - c.gap, "Un v - gap"),
                            (prob.Snn @ v + prob.snn_lift, c.Snn @ u, "Snn v + snn_lift")):
        scale = max(np.abs(want).max(), np.finfo(float).tiny)
        _require(np.abs(got - want).max() <= 1e-10 * scale,
                 f"{label}: {what} differs from the backend operator on the lifted "
                 "displacement")


# ---------------------------------------------------------------------------
# solver
# ---------------------------------------------------------------------------
def _problem(A, F, B, G, n_fixed: int, rng) -> ContactProblem:
    nf = A.shape[0]
    n = nf + n_fixed
    fixed = np.sort(rng.choice(n, size=n_fixed, replace=False))
    free = np.setdiff1d(np.arange(n), fixed)
    u_lift = np.zeros(n)
    u_lift[fixed] = rng.standard_normal(n_fixed)
    return ContactProblem(A=sp.csr_matrix(A), F=np.asarray(F, float), B=sp.csr_matrix(B),
                          G=np.asarray(G, float), free=free, u_lift=u_lift,
                          X=sp.identity(nf, format="csr"),
                          W=sp.identity(B.shape[0], format="csr"))


def random_contact_problem(seed: int = 0, n: int = 30, m: int = 8,
                           n_fixed: int = 4) -> ContactProblem:
    """A small, well-posed LCP-type problem: SPD ``A`` (n x n), full-rank ``B`` (m x n).

    ``G`` has negative entries so some constraints are active at the solution.
    ``n_fixed`` extra global dofs carry a Dirichlet lifting.
    """
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((n, n))
    A = M @ M.T / n + np.eye(n)
    B = rng.standard_normal((m, n))
    F = rng.standard_normal(n)
    G = rng.standard_normal(m)
    G[: max(1, m // 3)] = -np.abs(G[: max(1, m // 3)])
    return _problem(A, F, B, G, n_fixed, rng)


def redundant_contact_problem(seed: int = 0) -> ContactProblem:
    """:func:`random_contact_problem` with its first three constraints repeated.

    Still solvable (same ``u``), but the Delassus operator ``B A^{-1} B^T`` is
    singular and the multipliers are not unique.
    """
    p = random_contact_problem(seed)
    B = sp.vstack([p.B, p.B[:3]]).tocsr()
    return ContactProblem(A=p.A, F=p.F, B=B, G=np.r_[p.G, p.G[:3]], free=p.free,
                          u_lift=p.u_lift, X=p.X, W=sp.identity(B.shape[0], format="csr"))


def infeasible_contact_problem(seed: int = 0, n: int = 30) -> ContactProblem:
    """Constraints ``b.u <= -1`` and ``-b.u <= -1``: no ``u`` satisfies both, no solution."""
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((n, n))
    A = M @ M.T / n + np.eye(n)
    b = rng.standard_normal(n)
    B = np.vstack([rng.standard_normal((2, n)), b, -b])
    G = np.array([1.0, 1.0, -1.0, -1.0])
    return _problem(A, rng.standard_normal(n), B, G, 0, rng)


def _kkt_violations(prob: ContactProblem, res: SolveResult, tol: float = 1e-8) -> list[str]:
    """KKT conditions of ``A u + B^T lam = F, lam >= 0, B u <= G, lam.(G - B u) = 0``."""
    u = np.asarray(res.u, dtype=float)[prob.free]
    lam = np.asarray(res.lam, dtype=float)
    A, B, F, G = prob.A, prob.B, prob.F, prob.G
    Au, Btl = A @ u, B.T @ lam
    out = []
    eq = np.linalg.norm(Au + Btl - F)
    eq_scale = max(np.linalg.norm(F), np.linalg.norm(Au), np.linalg.norm(Btl),
                   np.finfo(float).tiny)
    if not eq <= tol * eq_scale:
        out.append(f"equilibrium ||A u + B^T lam - F|| = {eq:.3e} > {tol:g} * {eq_scale:.3e}")
    lam_scale = max(np.abs(lam).max(initial=0.0), np.finfo(float).tiny)
    if lam.size and not lam.min() >= -1e-10 * lam_scale:
        out.append(f"dual feasibility: min lam = {lam.min():.3e} < 0")
    Bu = B @ u
    s = G - Bu
    s_scale = np.abs(G).max(initial=0.0) + np.abs(Bu).max(initial=0.0)
    if s.size and not s.min() >= -tol * s_scale:
        out.append(f"primal feasibility: max(B u - G) = {-s.min():.3e} > {tol:g} * {s_scale:.3e}")
    comp = abs(float(lam @ s))
    comp_scale = np.linalg.norm(lam) * (np.linalg.norm(G) + np.linalg.norm(Bu))
    if not comp <= tol * max(comp_scale, np.finfo(float).tiny):
        out.append(f"complementarity |lam.(G - B u)| = {comp:.3e} > {tol:g} * {comp_scale:.3e}")
    return out


def _call_with_timeout(fn: Callable[[], Any], timeout: float, what: str) -> Any:
    """Run ``fn`` in a daemon thread; a hang becomes a ContractViolation, not a stuck run.

    The thread of a hung call is abandoned (it cannot be killed) and keeps running
    until the process exits.
    """
    box: dict[str, Any] = {}

    def target():
        try:
            box["value"] = fn()
        except BaseException as exc:  # noqa: BLE001 - re-raised in the caller
            box["error"] = exc

    th = threading.Thread(target=target, daemon=True, name=f"rbbench-contract: {what}")
    th.start()
    th.join(timeout)
    if th.is_alive():
        raise ContractViolation(f"{what}: did not return within {timeout:g} s "
                                "(solvers must never hang: every return carries a stop reason)")
    if "error" in box:
        raise box["error"]
    return box["value"]


def _check_result(res: Any, prob: Any, n_mult: int, label: str) -> SolveResult:
    """The form of any solver's result: a :class:`SolveResult` with a known stop reason, a
    non-negative iteration count, ``u`` on the global dofs of ``prob`` and ``n_mult``
    multipliers."""
    _require(isinstance(res, SolveResult),
             f"{label}: solve() returned {type(res).__name__}, not a SolveResult")
    _require(res.stop_reason in STOP_REASONS,
             f"{label}: stop_reason {res.stop_reason!r} is not one of {STOP_REASONS}")
    _require(isinstance(res.iterations, (int, np.integer)) and res.iterations >= 0,
             f"{label}: iterations must be a non-negative int, got {res.iterations!r}")
    n = prob.u_lift.size
    _require(np.shape(res.u) == (n,), f"{label}: u has shape {np.shape(res.u)}, expected "
             f"({n},) (global dofs, Dirichlet lifting included)")
    _require(np.shape(res.lam) == (n_mult,), f"{label}: lam has shape {np.shape(res.lam)}, "
             f"expected ({n_mult},)")
    return res


def _accepts(factory: Callable[..., Any], option: str) -> bool:
    """Whether ``factory`` takes the keyword ``option`` (False if it has no signature)."""
    try:
        return option in inspect.signature(factory).parameters
    except (TypeError, ValueError):
        return False


def _solve_checked(factory: Callable[..., Any], opts: dict, prob: Any, warm: Any,
                   where: str, timeout: float) -> Any:
    """``factory(**opts).solve(prob, warm_start=warm)`` within ``timeout``; any exception
    breaks the contract (a solver returns a stop reason instead)."""
    solver = factory(**opts)
    try:
        return _call_with_timeout(lambda: solver.solve(prob, warm_start=warm), timeout, where)
    except ContractViolation:
        raise
    except Exception as exc:  # noqa: BLE001 - any exception breaks the contract
        raise ContractViolation(f"{where}: solve() raised {type(exc).__name__}: {exc} "
                                "instead of returning a stop reason") from exc


def check_solver(factory: Callable[..., Any], options: dict | None = None,
                 name: str | None = None, timeout: float = 20.0, seed: int = 0,
                 n_degenerate: int = 5) -> None:
    """Contract of the solver role (``factory(**options)`` builds it).

    1. On a small random well-posed problem the solver converges, the result
       satisfies the KKT conditions and keeps the Dirichlet lifting.
    2. A warm start from that solution converges to the same ``u``.
    3. Without contact unknowns, ``u = A^{-1} F``.
    4. With ``max_iter=1`` (when the constructor takes ``max_iter``) it returns
       after at most one iteration.
    5. On degenerate problems (``n_degenerate`` seeds each): redundant
       constraints (feasible, singular Delassus operator) and infeasible
       constraints (``b.u <= -1`` and ``-b.u <= -1``), it returns.

    Every solve must return within ``timeout`` seconds, without raising, with a
    stop reason in :data:`~rbbench.interfaces.STOP_REASONS`; a ``"converged"``
    result must satisfy the KKT conditions (so none is possible on the
    infeasible problems).
    """
    options = dict(options or {})
    label = f"solver {name or getattr(factory, '__name__', factory)!r}"

    def run(prob, opts=options, warm=None, what="solve"):
        where = f"{label}: {what}"
        res = _solve_checked(factory, opts, prob, warm, where, timeout)
        _check_result(res, prob, prob.B.shape[0], where)
        _require(isinstance(res.residuals, list), f"{where}: residuals must be a list")
        return res

    def kkt(prob, res, what):
        if not res.converged:
            return
        bad = _kkt_violations(prob, res)
        _require(not bad, f"{label}: {what}: stop_reason 'converged' but KKT fails: "
                 + "; ".join(bad))

    # 1. well-posed random problem: converges, KKT, Dirichlet lifting kept
    prob = random_contact_problem(seed)
    res = run(prob, what="random problem")
    _require(res.converged, f"{label}: did not converge on a small well-posed problem "
             f"(stop_reason {res.stop_reason!r} after {res.iterations} iterations)")
    kkt(prob, res, "random problem")
    fixed = np.setdiff1d(np.arange(prob.u_lift.size), prob.free)
    _require(np.array_equal(np.asarray(res.u)[fixed], prob.u_lift[fixed]),
             f"{label}: u does not keep the Dirichlet values u_lift on the constrained dofs")
    lam = np.asarray(res.lam, dtype=float)
    _require(np.any(lam > 0), f"{label}: no active constraint on a problem built to have some")

    # 2. warm start from the solution
    res2 = run(prob, warm=lam.copy(), what="warm start from the solution")
    _require(res2.converged, f"{label}: warm start from the solution did not converge "
             f"({res2.stop_reason!r})")
    kkt(prob, res2, "warm start")
    du = np.linalg.norm(np.asarray(res2.u) - np.asarray(res.u))
    _require(du <= 1e-6 * np.linalg.norm(res.u),
             f"{label}: warm start changed the solution (||du|| = {du:.3e})")

    # 3. no contact unknowns: the unconstrained solution
    p0 = ContactProblem(A=prob.A, F=prob.F, B=sp.csr_matrix((0, prob.A.shape[0])),
                        G=np.zeros(0), free=prob.free, u_lift=prob.u_lift, X=prob.X,
                        W=sp.csr_matrix((0, 0)))
    r0 = run(p0, what="problem without contact unknowns")
    _require(r0.converged, f"{label}: no contact unknowns: stop_reason {r0.stop_reason!r}")
    u_ref = np.linalg.solve(p0.A.toarray(), p0.F)
    _require(np.allclose(np.asarray(r0.u)[p0.free], u_ref, rtol=1e-8, atol=1e-12),
             f"{label}: without contact unknowns u must solve A u = F")

    # 4. max_iter = 1: returns with a stop reason
    if _accepts(factory, "max_iter"):
        r1 = run(prob, opts={**options, "max_iter": 1}, what="max_iter=1")
        _require(r1.iterations <= 1, f"{label}: max_iter=1 but {r1.iterations} iterations")
        kkt(prob, r1, "max_iter=1")

    # 5. degenerate problems: always return; never a false "converged"
    for k in range(seed, seed + n_degenerate):
        pr = redundant_contact_problem(k)
        rr = run(pr, what=f"redundant constraints (seed {k})")
        kkt(pr, rr, f"redundant constraints (seed {k})")
    for k in range(seed, seed + n_degenerate):
        pinf = infeasible_contact_problem(k)
        rinf = run(pinf, what=f"infeasible problem (seed {k})")
        _require(rinf.stop_reason != "converged",
                 f"{label}: claims 'converged' on a problem without solution "
                 f"(b.u <= -1 and -b.u <= -1; seed {k})")


def random_nitsche_problem(seed: int = 0, n: int = 30, n_q: int = 12, n_fixed: int = 4,
                           theta: float = 1.0, gamma: float = 10.0) -> NitscheProblem:
    """A small Nitsche problem: SPD ``A``, random ``Un`` and a small ``Snn``, some negative
    gaps (so some points are in contact), P0 multipliers on pairs of points.

    ``Snn`` is scaled so that ``A - Snn^T diag(w / gamma) Snn`` stays positive definite
    for ``gamma >= 1`` (``theta = 1`` is then a convex minimisation).
    """
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((n, n))
    A = M @ M.T / n + np.eye(n)
    Un = rng.standard_normal((n_q, n)) / np.sqrt(n)
    Snn = 0.3 * rng.standard_normal((n_q, n)) / np.sqrt(n)
    gap = rng.uniform(0.05, 0.5, n_q)
    gap[: max(1, n_q // 3)] *= -1.0
    fixed = np.sort(rng.choice(n + n_fixed, size=n_fixed, replace=False))
    free = np.setdiff1d(np.arange(n + n_fixed), fixed)
    u_lift = np.zeros(n + n_fixed)
    u_lift[fixed] = rng.standard_normal(n_fixed)
    m = max(n_q // 2, 1)
    Mlam = sp.csr_matrix((np.ones(n_q), (np.arange(n_q), np.minimum(np.arange(n_q) // 2,
                                                                      m - 1))), (n_q, m))
    return NitscheProblem(A=sp.csr_matrix(A), F=rng.standard_normal(n), Un=sp.csr_matrix(Un),
                          Snn=sp.csr_matrix(Snn), gap=gap, snn_lift=0.1 * rng.standard_normal(n_q),
                          weights=rng.uniform(0.5, 1.5, n_q), gamma=np.full(n_q, float(gamma)),
                          theta=float(theta), gamma0=float(gamma), E=1.0, h=np.ones(n_q),
                          free=free, u_lift=u_lift, X=sp.identity(n, format="csr"), Mlam=Mlam)


def _nitsche_residual(prob: NitscheProblem, u: np.ndarray) -> tuple[float, np.ndarray]:
    """Relative residual of the Nitsche equations at ``u`` (free dofs) and the point
    pressures ``-[P]_-``, written out here independently of :mod:`rbbench.hf.nitsche_algebra`."""
    s = prob.Snn @ u + prob.snn_lift
    P = s - prob.gamma * (prob.Un @ u - prob.gap)
    neg = np.minimum(P, 0.0)
    dw = prob.weights / prob.gamma
    Au = prob.A @ u
    boundary = -prob.theta * (prob.Snn.T @ (dw * s)) + (prob.theta * prob.Snn.T @ (dw * neg)
                                                       - prob.Un.T @ (prob.weights * neg))
    R = Au - prob.F + boundary
    scale = max(np.linalg.norm(prob.F), np.linalg.norm(Au), np.linalg.norm(boundary),
                np.finfo(float).tiny)
    return float(np.linalg.norm(R) / scale), -neg


def check_nitsche_solver(factory: Callable[..., Any], options: dict | None = None,
                         name: str | None = None, timeout: float = 20.0, seed: int = 0) -> None:
    """Contract of a solver of the Nitsche formulation (``factory(**options)`` builds it).

    1. For ``theta`` = 1, 0, -1 on :func:`random_nitsche_problem`, a cold start
       converges; the result solves the Nitsche equations (residual recomputed
       here, relative ``1e-8``), keeps the Dirichlet lifting, has some points in
       contact, and ``lam`` has one entry per multiplier.
    2. A warm start from that solution converges in at most one iteration to the
       same ``u``.
    3. NaN in the data: stop reason ``"nan"``.
    4. With ``max_iter=1`` (when the constructor takes it): at most one iteration.
    5. ``theta = 1`` with ``gamma`` far too small (the energy is not convex) and huge
       ``gamma``: it returns, and a ``"converged"`` result solves the equations.

    Every solve must return within ``timeout`` seconds with a stop reason in
    :data:`~rbbench.interfaces.STOP_REASONS`, without raising.
    """
    options = dict(options or {})
    label = f"solver {name or getattr(factory, '__name__', factory)!r}"

    def run(prob, opts=options, warm=None, what="solve"):
        where = f"{label}: {what}"
        res = _solve_checked(factory, opts, prob, warm, where, timeout)
        _check_result(res, prob, prob.Mlam.shape[1], where)
        if res.converged:
            rel, _ = _nitsche_residual(prob, np.asarray(res.u, dtype=float)[prob.free])
            _require(rel <= 1e-8, f"{where}: stop_reason 'converged' but the Nitsche residual "
                     f"is {rel:.3e} (relative)")
        return res

    for theta in (1.0, 0.0, -1.0):
        prob = random_nitsche_problem(seed, theta=theta)
        res = run(prob, what=f"random problem, theta = {theta:g}")
        _require(res.converged, f"{label}: theta = {theta:g}: a cold start did not converge "
                 f"on a small well-posed problem ({res.stop_reason!r})")
        fixed = np.setdiff1d(np.arange(prob.u_lift.size), prob.free)
        _require(np.array_equal(np.asarray(res.u)[fixed], prob.u_lift[fixed]),
                 f"{label}: u does not keep the Dirichlet values u_lift on the constrained dofs")
        _, p = _nitsche_residual(prob, np.asarray(res.u)[prob.free])
        _require(np.any(p > 0), f"{label}: no point in contact on a problem built to have some")
        res2 = run(prob, warm=np.asarray(res.u).copy(), what="warm start from the solution")
        _require(res2.converged and res2.iterations <= 1,
                 f"{label}: a warm start from the solution took {res2.iterations} iterations "
                 f"({res2.stop_reason!r})")
        du = np.linalg.norm(np.asarray(res2.u) - np.asarray(res.u))
        _require(du <= 1e-8 * np.linalg.norm(res.u),
                 f"{label}: warm start changed the solution (||du|| = {du:.3e})")

    bad = random_nitsche_problem(seed)
    bad.F = bad.F.copy()
    bad.F[0] = np.nan
    rn = run(bad, what="NaN in F")
    _require(rn.stop_reason == "nan", f"{label}: NaN in the data gave stop_reason "
             f"{rn.stop_reason!r}, expected 'nan'")

    if _accepts(factory, "max_iter"):
        r1 = run(random_nitsche_problem(seed), opts={**options, "max_iter": 1}, what="max_iter=1")
        _require(r1.iterations <= 1, f"{label}: max_iter=1 but {r1.iterations} iterations")

    for gamma in (1e-4, 1e8):
        run(random_nitsche_problem(seed, theta=1.0, gamma=gamma),
            what=f"theta = 1, gamma = {gamma:g}")


# ---------------------------------------------------------------------------
# primal compressor, dual compressor, stabiliser (rbbench.rb.compressors protocols)
# ---------------------------------------------------------------------------
#: ``capabilities["tol"]`` of a primal compressor: what its ``tol`` bounds.
PRIMAL_TOL_KINDS = ("energy", "max")
#: ``capabilities["inf_sup"]`` of a stabiliser: where its primal space is inf-sup stable.
STABILIZER_GUARANTEES = ("not guaranteed", "every mu", "training set")
_ORTH_TOL = 1e-10  # max |Z^T X Z - I| of an X-orthonormal basis
_EXACT_RTOL = 1e-8  # relative projection error of a vector inside a space


def _tridiag_gram(n: int) -> sp.csr_matrix:
    """SPD, non-diagonal Gram matrix (a 1-D H1-like product): X-orthonormality != orthonormality."""
    return sp.diags([-np.ones(n - 1), 2.5 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1]).tocsr()


def primal_test_data(seed: int = 0, n: int = 40, P: int = 12,
                     rank: int = 6) -> tuple[np.ndarray, sp.csr_matrix, int]:
    """Snapshots ``U`` (n x P) of exact rank ``rank`` (graded 1 .. 1e-4), SPD ``X``."""
    rng = np.random.default_rng(seed)
    U = (rng.standard_normal((n, rank)) * np.logspace(0, -4, rank)) @ rng.standard_normal(
        (rank, P))
    return U, _tridiag_gram(n), rank


def dual_test_data(seed: int = 0, n: int = 40, Q: int = 12) -> tuple[np.ndarray, sp.csr_matrix]:
    """Non-negative bump snapshots ``Theta`` (n x Q), overlapping supports, and a diagonal ``W``."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.0, n)
    c = rng.uniform(0.2, 0.8, Q)
    w = rng.uniform(0.1, 0.3, Q)
    Theta = np.clip(1.0 - ((x[:, None] - c) / w) ** 2, 0.0, None) * rng.uniform(0.5, 2.0, Q)
    return Theta, sp.diags(rng.uniform(0.5, 1.5, n)).tocsr()


def _xorth_errors(Z: np.ndarray, X: Any) -> float:
    G = Z.T @ (X @ Z)
    return float(np.abs(G - np.eye(Z.shape[1])).max(initial=0.0))


def _proj_residual(U: np.ndarray, Z: np.ndarray, X: Any) -> np.ndarray:
    """X-norms of ``(I - Pi_Z) u_p`` for an X-orthonormal ``Z``."""
    R = U - Z @ (Z.T @ (X @ U)) if Z.shape[1] else U
    return np.sqrt(np.clip(np.einsum("ij,ij->j", R, X @ R), 0.0, None))


def _json_ok(obj: Any, what: str) -> None:
    import json

    try:
        json.dumps(obj)
    except (TypeError, ValueError) as exc:
        raise ContractViolation(f"{what}: not JSON-serialisable ({exc}): use lists and "
                                "floats (histories go to result.json)") from None


def _unchanged(before: np.ndarray, after: Any, what: str) -> None:
    _require(np.array_equal(before, np.asarray(after)), f"{what}: the input was modified")


def _bool_capability(caps: dict, key: str, label: str) -> bool:
    _require(isinstance(caps.get(key), bool),
             f"{label}: capabilities[{key!r}] must be declared True or False, got "
             f"{caps.get(key)!r}")
    return caps[key]


def _instantiate(factory: Callable[..., Any], label: str) -> Any:
    try:
        return factory()
    except Exception as exc:  # noqa: BLE001 - any failure to build breaks the contract
        raise ContractViolation(f"{label}: factory() raised {type(exc).__name__}: {exc} (the "
                                "target must build the component without arguments)") from exc


def check_primal(factory: Callable[..., Any], capabilities: dict | None = None,
                 name: str | None = None, seed: int = 0) -> None:
    """Contract of the primal-compressor role (``factory()`` builds it).

    On snapshots of exact rank ``r`` (:func:`primal_test_data`) and a non-diagonal SPD
    ``X``, ``compressor(U, X, tol=..., n=...)`` returns a
    :class:`~rbbench.rb.compressors.PrimalBasis` whose ``Z`` is X-orthonormal, spans a
    subspace of the snapshots, and:

    1. without ``tol`` and ``n``: ``N = r`` and every snapshot is reproduced;
    2. with ``n = k``: ``N = min(k, r)``;
    3. with ``tol``: the declared guarantee ``capabilities["tol"]`` holds (``"energy"``:
       relative Frobenius error of the snapshot set; ``"max"``: largest error relative to
       the largest snapshot) and, if ``capabilities["nested"]``, ``N`` is the first size
       meeting it (``Z[:, :N-1]`` does not);
    4. ``capabilities["nested"]``: the snapshot-set error is non-increasing in ``n``.

    The history is JSON-serialisable and the snapshots are not modified.
    """
    caps = dict(capabilities or {})
    label = f"primal compressor {name or getattr(factory, '__name__', factory)!r}"
    kind = caps.get("tol")
    _require(kind in PRIMAL_TOL_KINDS, f"{label}: capabilities['tol'] = {kind!r}; declare "
             f"what tol bounds, one of {PRIMAL_TOL_KINDS}")
    nested = _bool_capability(caps, "nested", label)
    comp = _instantiate(factory, label)
    _require(callable(comp), f"{label}: factory() returned a non-callable {type(comp).__name__}")
    U, X, rank = primal_test_data(seed)
    U0 = U.copy()
    unorm = _proj_residual(U, np.zeros((U.shape[0], 0)), X)
    span_U = np.linalg.svd(U, full_matrices=False)[0][:, :rank]

    def run(what: str, **kw) -> np.ndarray:
        from rbbench.rb.compressors import PrimalBasis

        res = comp(U, X, **kw)
        where = f"{label}: {what}"
        _unchanged(U0, U, where)
        _require(isinstance(res, PrimalBasis),
                 f"{where}: returned {type(res).__name__}, not a PrimalBasis")
        Z = np.asarray(res.Z)
        _require(Z.ndim == 2 and Z.shape[0] == U.shape[0] and np.all(np.isfinite(Z)),
                 f"{where}: Z must be a finite ({U.shape[0]}, N) array, got shape {Z.shape}")
        err = _xorth_errors(Z, X)
        _require(err <= _ORTH_TOL, f"{where}: Z is not X-orthonormal: max|Z^T X Z - I| = "
                 f"{err:.3e}")
        out = np.abs(Z - span_U @ (span_U.T @ Z)).max(initial=0.0)
        _require(out <= _EXACT_RTOL * max(np.abs(Z).max(initial=0.0), 1e-300),
                 f"{where}: Z leaves the span of the snapshots (max deviation {out:.3e})")
        _require(isinstance(res.history, dict), f"{where}: history must be a dict")
        _json_ok(res.history, f"{where}: history")
        return Z

    Z = run("no tol, no n")
    _require(Z.shape[1] == rank, f"{label}: without tol and n, N = {Z.shape[1]}, expected the "
             f"numerical rank {rank} of the snapshots")
    e = _proj_residual(U, Z, X).max()
    _require(e <= _EXACT_RTOL * unorm.max(), f"{label}: with N = rank the snapshots are not "
             f"reproduced (max relative error {e / unorm.max():.3e})")
    errs = []
    for k in (1, 2, 3, rank, rank + 3):
        Z = run(f"n={k}", n=k)
        _require(Z.shape[1] == min(k, rank), f"{label}: requested n = {k}, got N = "
                 f"{Z.shape[1]} (expected min(n, rank) = {min(k, rank)})")
        errs.append(float(np.linalg.norm(_proj_residual(U, Z, X))))
    if nested:
        _require(bool(np.all(np.diff(errs) <= 1e-12 * np.asarray(errs[:-1]) + 1e-14)),
                 f"{label}: declared nested, but the snapshot-set error is not non-increasing "
                 f"in n: {errs}")

    def measure(Zk: np.ndarray) -> float:
        r = _proj_residual(U, Zk, X)
        if kind == "energy":
            return float(np.linalg.norm(r) / np.linalg.norm(unorm))
        return float(r.max() / unorm.max())

    for tol in (0.3, 1e-2, 1e-3):
        Z = run(f"tol={tol:g}", tol=tol)
        got = measure(Z)
        _require(got <= tol * (1 + 1e-9), f"{label}: tol = {tol:g} ({kind}) not met: "
                 f"error {got:.3e} with N = {Z.shape[1]}")
        if nested and Z.shape[1] > 0:
            prev = measure(Z[:, :-1])
            _require(prev > tol, f"{label}: tol = {tol:g}: N = {Z.shape[1]} is not the first "
                     f"size meeting the tolerance (N - 1 vectors give {prev:.3e})")


def check_dual(factory: Callable[..., Any], capabilities: dict | None = None,
               name: str | None = None, seed: int = 0) -> None:
    """Contract of the dual-compressor role (``factory()`` builds it).

    On non-negative snapshots ``Theta`` and a diagonal SPD ``W`` (:func:`dual_test_data`),
    ``compressor(Theta, W, tol=..., r_max=...)`` returns a
    :class:`~rbbench.rb.cones.DualBasis` with:

    * ``1 <= R <= r_max`` finite generators of unit W-norm, shape ``(n, R)``;
    * ``is_cone == capabilities["cone"]``; a cone's generators are non-negative (the
      reduced cone lies in ``W+``);
    * ``e_proj`` and ``e_orth`` of length ``R`` with values in ``[0, 1]``; ``e_proj[-1]``
      equal to an independent recomputation (NNLS on the cone, least squares on a span) of
      ``max_q ||theta_q - Pi theta_q||_W / max_q ||theta_q||_W`` (seed 000, slide "mCPG
      algorithm (4/4)");
    * ``capabilities["nested"]``: ``e_proj`` non-increasing (to ``1e-12``);
    * with ``tol``: ``R`` is the first size with ``e_proj <= tol`` (``e_proj[:-1] > tol``);
    * the snapshots are not modified.
    """
    from scipy.optimize import nnls

    from rbbench.rb.cones import DualBasis

    caps = dict(capabilities or {})
    label = f"dual compressor {name or getattr(factory, '__name__', factory)!r}"
    cone = _bool_capability(caps, "cone", label)
    nested = _bool_capability(caps, "nested", label)
    comp = _instantiate(factory, label)
    _require(callable(comp), f"{label}: factory() returned a non-callable {type(comp).__name__}")
    Theta, W = dual_test_data(seed)
    T0 = Theta.copy()
    sw = np.sqrt(W.diagonal())
    CT = sw[:, None] * Theta
    scale = float(np.linalg.norm(CT, axis=0).max())

    def proj_error(V: np.ndarray, is_cone: bool) -> float:
        CV = sw[:, None] * V
        if is_cone:
            errs = [nnls(CV, CT[:, q])[1] for q in range(CT.shape[1])]
        else:
            c = np.linalg.lstsq(CV, CT, rcond=None)[0]
            errs = np.linalg.norm(CT - CV @ c, axis=0)
        return float(np.max(errs)) / scale

    def run(what: str, tol: float, r_max: int | None) -> DualBasis:
        b = comp(Theta, W, tol=tol, r_max=r_max)
        where = f"{label}: {what}"
        _unchanged(T0, Theta, where)
        _require(isinstance(b, DualBasis), f"{where}: returned {type(b).__name__}, "
                 "not a DualBasis")
        V = np.asarray(b.generators)
        R = V.shape[1] if V.ndim == 2 else -1
        _require(V.ndim == 2 and V.shape[0] == Theta.shape[0] and np.all(np.isfinite(V)),
                 f"{where}: generators must be a finite ({Theta.shape[0]}, R) array, got "
                 f"shape {V.shape}")
        _require(R >= 1, f"{where}: no generators")
        _require(r_max is None or R <= r_max, f"{where}: R = {R} > r_max = {r_max}")
        nrm = np.linalg.norm(sw[:, None] * V, axis=0)
        _require(np.allclose(nrm, 1.0, rtol=0, atol=1e-8),
                 f"{where}: generators must have unit W-norm, got {nrm.min():.6g} .. "
                 f"{nrm.max():.6g}")
        _require(bool(b.is_cone) == cone,
                 f"{where}: is_cone = {b.is_cone}, but capabilities['cone'] = {cone}")
        if b.is_cone:
            _require(V.min() >= -1e-14 * np.abs(V).max(), f"{where}: a cone generator has a "
                     f"negative entry ({V.min():.3e}): the reduced cone must lie in W+")
        ep, eo = np.asarray(b.e_proj, dtype=float), np.asarray(b.e_orth, dtype=float)
        _require(ep.shape == (R,) and eo.shape == (R,),
                 f"{where}: e_proj and e_orth need one entry per generator (R = {R}), got "
                 f"{ep.shape[0]} and {eo.shape[0]}")
        _require(np.all(np.isfinite(ep)) and ep.min() >= 0 and ep.max() <= 1 + 1e-12,
                 f"{where}: e_proj must be finite and in [0, 1], got {ep.tolist()}")
        _require(np.all(np.isfinite(eo)) and eo.min() >= -1e-12 and eo.max() <= 1 + 1e-12,
                 f"{where}: e_orth must be finite and in [0, 1], got {eo.tolist()}")
        true = proj_error(V, b.is_cone)
        _require(abs(ep[-1] - true) <= 1e-6 * true + 1e-10,
                 f"{where}: e_proj[-1] = {ep[-1]:.6e} does not match the recomputed "
                 f"projection error {true:.6e}")
        if nested:
            _require(np.all(np.diff(ep) <= 1e-12), f"{where}: declared nested, but e_proj "
                     f"increases: {ep.tolist()}")
        return b

    run("tol=0, r_max=6", tol=0.0, r_max=6)
    for tol in (0.3, 0.05):
        b = run(f"tol={tol:g}", tol=tol, r_max=None)
        ep = np.asarray(b.e_proj)
        _require(ep[-1] <= tol, f"{label}: tol = {tol:g} not met: e_proj(R = {b.R}) = "
                 f"{ep[-1]:.3e}")
        _require(np.all(ep[:-1] > tol), f"{label}: tol = {tol:g}: R = {b.R} is not the first "
                 f"size meeting the tolerance (e_proj = {ep.tolist()})")


def stabilizer_test_data(seed: int = 0, n: int = 30, m: int = 6, R: int = 3, N: int = 2,
                         P: int = 4) -> dict[str, Any]:
    """A small saddle-point family with ``N < R``, so that ``beta_dec = 0`` on ``span(Vg)``.

    Keys: ``X`` (sparse SPD), ``x_solve``, ``W`` (identity), ``Vg`` (m x R, non-negative),
    ``Z`` (n x N, X-orthonormal), ``B_train`` (P matrices m x n), ``B_new`` (one more).
    """
    import scipy.linalg as sla

    rng = np.random.default_rng(seed)
    X = _tridiag_gram(n)
    cho = sla.cho_factor(X.toarray())
    Z = rng.standard_normal((n, N))
    L = np.linalg.cholesky(Z.T @ (X @ Z))
    Z = sla.solve_triangular(L, Z.T, lower=True).T
    Bs = [sp.csr_matrix(rng.standard_normal((m, n))) for _ in range(P + 1)]
    return {"X": X, "x_solve": lambda rhs: sla.cho_solve(cho, rhs),
            "W": sp.identity(m, format="csr"), "Vg": rng.uniform(0.0, 1.0, (m, R)),
            "Z": Z, "B_train": Bs[:P], "B_new": Bs[P]}


def _beta_span(Y: np.ndarray | None, B: Any, d: dict) -> float:
    """Inf-sup of ``eta^T B v`` over ``span(Vg) x span(Y)`` (``Y`` X-orthonormal; None: all)."""
    import scipy.linalg as sla

    BtV = np.asarray(B.T @ d["Vg"])
    S = BtV.T @ d["x_solve"](BtV) if Y is None else (Y.T @ BtV).T @ (Y.T @ BtV)
    M = d["Vg"].T @ (d["W"] @ d["Vg"])
    return float(np.sqrt(max(sla.eigh(0.5 * (S + S.T), M, eigvals_only=True)[0], 0.0)))


def check_stabilizer(factory: Callable[..., Any], capabilities: dict | None = None,
                     name: str | None = None, seed: int = 0, delta: float = 0.3) -> None:
    """Contract of the stabiliser role (``factory()`` builds it).

    On :func:`stabilizer_test_data` (``N < R``: the decorrelated model is not inf-sup
    stable), ``offline(Z, Vg, X, x_solve, B_train, delta)`` returns ``(Z_off, history)``:

    * ``Z_off`` finite, X-orthonormal, containing ``span Z``; ``history`` a JSON-serialisable
      dict; the inputs are not modified;
    * ``online`` is a bool equal to ``capabilities["online_hf"]``;
      ``online_basis(Z_off, Vg, X, x_solve, B)`` is X-orthonormal and contains ``Z_off``,
      and spans exactly ``Z_off`` when ``online`` is False;
    * the declared guarantee ``capabilities["inf_sup"]`` holds, with the span inf-sup
      ``beta`` of ``b(mu; v, eta) = eta^T B(mu) v`` (a lower bound of the cone value, and
      what the seed's proofs bound): ``"every mu"``: ``beta = beta_on`` (whole primal
      space) on the training matrices and on a new one (seed 000, "Parameter-dependent
      context"); ``"training set"``: ``beta >= sqrt(1 - delta^2) beta_on > 0`` on the
      training matrices (seed 000 "Main result"; the sharper Riesz form of
      :func:`rbbench.rb.pga.riesz_lower_bound`); ``"not guaranteed"``: nothing.
    """
    caps = dict(capabilities or {})
    label = f"stabilizer {name or getattr(factory, '__name__', factory)!r}"
    online_hf = _bool_capability(caps, "online_hf", label)
    guarantee = caps.get("inf_sup")
    _require(guarantee in STABILIZER_GUARANTEES, f"{label}: capabilities['inf_sup'] = "
             f"{guarantee!r}; declare one of {STABILIZER_GUARANTEES}")
    stab = _instantiate(factory, label)
    online = getattr(stab, "online", None)
    _require(isinstance(online, bool), f"{label}: attribute 'online' must be a bool, got "
             f"{online!r}")
    _require(online == online_hf, f"{label}: online = {online} but capabilities['online_hf'] "
             f"= {online_hf}")
    d = stabilizer_test_data(seed)
    X, Z, Vg = d["X"], d["Z"], d["Vg"]
    Z0, V0 = Z.copy(), Vg.copy()
    out = stab.offline(Z, Vg, X, d["x_solve"], list(d["B_train"]), delta)
    _require(isinstance(out, tuple) and len(out) == 2,
             f"{label}: offline() must return (Z_off, history)")
    Z_off, hist = np.asarray(out[0]), out[1]
    _require(Z_off.ndim == 2 and Z_off.shape[0] == Z.shape[0] and np.all(np.isfinite(Z_off)),
             f"{label}: Z_off must be a finite ({Z.shape[0]}, k) array, got {Z_off.shape}")
    _require(isinstance(hist, dict), f"{label}: the offline history must be a dict")
    _json_ok(hist, f"{label}: offline history")
    _unchanged(Z0, Z, f"{label}: offline() (Z)")
    _unchanged(V0, Vg, f"{label}: offline() (Vg)")

    def check_space(Y: np.ndarray, inner: np.ndarray, what: str) -> None:
        err = _xorth_errors(Y, X)
        _require(err <= _ORTH_TOL, f"{label}: {what} is not X-orthonormal: "
                 f"max|Y^T X Y - I| = {err:.3e}")
        miss = _proj_residual(inner, Y, X).max(initial=0.0)
        _require(miss <= _EXACT_RTOL, f"{label}: {what} does not contain the space it must "
                 f"enrich (relative residual {miss:.3e})")

    check_space(Z_off, Z, "Z_off (offline)")
    n_train = len(d["B_train"])
    for i, B in enumerate(list(d["B_train"]) + [d["B_new"]]):
        Y = np.asarray(stab.online_basis(Z_off, Vg, X, d["x_solve"], B))
        where = f"online_basis at matrix {i}"
        _require(Y.ndim == 2 and Y.shape[0] == Z.shape[0] and np.all(np.isfinite(Y)),
                 f"{label}: {where} must be a finite ({Z.shape[0]}, k) array")
        check_space(Y, Z_off, where)
        if not online:
            _require(Y.shape[1] == Z_off.shape[1], f"{label}: online = False, but {where} "
                     f"has {Y.shape[1]} vectors instead of the {Z_off.shape[1]} of Z_off")
        if guarantee == "not guaranteed" or (guarantee == "training set" and i >= n_train):
            continue
        b_on, b = _beta_span(None, B, d), _beta_span(Y, B, d)
        if guarantee == "every mu":
            _require(abs(b - b_on) <= 1e-8 * b_on, f"{label}: declares 'every mu', but "
                     f"beta = {b:.6e} != beta_on = {b_on:.6e} at matrix {i}")
        else:
            bound = np.sqrt(1.0 - delta**2) * b_on
            _require(b >= bound * (1 - 1e-9), f"{label}: declares 'training set', but the "
                     f"inf-sup {b:.3e} < sqrt(1 - delta^2) beta_on = {bound:.3e} at training "
                     f"matrix {i} (delta = {delta:g})")


# ---------------------------------------------------------------------------
# pytest helpers
# ---------------------------------------------------------------------------
def component_params(registry: Registry | None = None, roles: tuple[str, ...] | None = None):
    """``pytest.param(spec, id="role:name")`` for every registered component.

    Components whose modules are missing carry a skip mark whose reason is the
    install hint from :meth:`Registry.availability`.
    """
    import pytest

    reg = registry or default_registry()
    params = []
    for spec in reg.specs():
        if roles is not None and spec.role not in roles:
            continue
        ok, why = reg.availability(spec)
        marks = () if ok else (pytest.mark.skip(reason=why),)
        params.append(pytest.param(spec, id=f"{spec.role}:{spec.name}", marks=marks))
    return params


def check_component(spec: ComponentSpec, registry: Registry | None = None) -> None:
    """Declaration check plus the role-specific contract of one registered component.

    Calls ``pytest.skip`` when the component is not installed (reason: the
    install hint), when its role has no specific contract yet, or when no
    installed backend can produce the discretizations a formulation needs.
    """
    import pytest

    reg = registry or default_registry()
    ok, why = reg.availability(spec)
    obj = check_spec(reg, spec)
    if not ok:
        pytest.skip(why)
    if spec.role not in ROLE_CHECKS:
        pytest.skip("no role-specific contract yet")
    name = f"{spec.name} ({spec.package or '?'})"
    if spec.role == "backend":
        scenes = backend_scenes(spec.capabilities)
        _require(scenes, f"backend {name}: declares no physics with a reference scene")
        for scene in scenes:
            check_backend(obj, scene, name=name)
    elif spec.role == "formulation":
        physics = tuple(spec.capabilities.get("physics", _KNOWN_PHYSICS))
        needs = frozenset(getattr(obj, "needs", frozenset()))
        ran = 0
        for ph in physics:
            try:
                disc = reference_discretization(ph, reg, needs)
            except LookupError:
                continue
            check_formulation(obj, disc, name=name)
            ran += 1
        if not ran:
            pytest.skip(f"no installed backend provides physics {physics}")
    elif spec.role == "solver":
        # a solver declares the formulations it solves; the mixed contract is the default
        forms = tuple(spec.capabilities.get("formulations", ("mixed",)))
        if "nitsche" in forms:
            check_nitsche_solver(obj, name=name)
        if "mixed" in forms or "nitsche" not in forms:
            check_solver(obj, name=name)
    elif spec.role == "executor":
        check_executor(obj, name=name)
    else:
        check = {"primal": check_primal, "dual": check_dual, "stabilizer": check_stabilizer}
        check[spec.role](obj, spec.capabilities, name=name)


def check_executor(factory: Callable[..., Any], name: str | None = None) -> None:
    """Executor contract: every case reported once, as a valid results row.

    Two tiny membrane cases, one of which uses a dual compressor that raises
    (:mod:`rbbench.testing.faulty`): ``run`` must call ``on_result`` exactly
    once per case, with a row of :mod:`rbbench.bench.schema` whose identity matches
    the case; the good case is ``ok``, the failing one ``error`` with its
    traceback; ``on_stage`` receives strings only.
    """
    import tempfile

    from rbbench.bench import schema
    from rbbench.bench.matrix import Case
    from rbbench.registry import discover
    from rbbench.testing import faulty

    label = f"executor {name or getattr(factory, '__name__', '?')}"
    reg = discover(extra_plugins=(faulty,))
    sc = load_scene("membrane_obstacle", ["discretization.n_cells=6"])
    params = {"n_train": 4, "n_valid": 2, "online_repeats": 1, "exact_max_r": 3}
    cases = [Case("membrane_obstacle", ("discretization.n_cells=6",),
                  {"backend": "skfem", "formulation": "mixed", "solver": "ssn",
                   "primal": "pod", "dual": d, "stabilizer": "none", "hyper": "auto"},
                  2, 2, params, 0, 0, 120.0, sc.fingerprint()) for d in ("cpg", "faulty-raise")]
    got: list[tuple[Any, dict]] = []
    stages: list[Any] = []
    ex = _instantiate(lambda: factory(jobs=2), label)
    with tempfile.TemporaryDirectory() as tmp:
        ex.run(cases, run_id="contract", cache_dir=tmp, registry=reg,
               on_result=lambda c, r: got.append((c, r)), on_stage=stages.append)
    _require(sorted(c.key for c, _ in got) == sorted(c.key for c in cases),
             f"{label}: on_result must be called once per case (got "
             f"{[c.key for c, _ in got]})")
    for case, rec in got:
        _require(isinstance(rec, dict) and "row" in rec, f"{label}: a record is "
                 "{'row': ..., 'details': ...}")
        try:
            row = schema.normalise_row(rec["row"])
        except (KeyError, ValueError) as exc:
            raise ContractViolation(f"{label}: invalid results row: {exc}") from None
        _require(row["case_id"] == case.case_id and row["run_id"] == "contract",
                 f"{label}: the row's identity does not match its case")
        want = "ok" if case.components["dual"] == "cpg" else "error"
        _require(row["status"] == want, f"{label}: case with dual "
                 f"{case.components['dual']!r}: status {row['status']!r}, expected {want!r} "
                 f"({row['reason']})")
        if want == "error":
            _require(bool(row["traceback"]), f"{label}: an error row carries its traceback")
    _require(all(isinstance(m, str) for m in stages), f"{label}: on_stage takes strings")

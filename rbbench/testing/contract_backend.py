"""Contract of the backend role: a well-formed :class:`~rbbench.interfaces.Discretization`.

Reference scenes: ``membrane_obstacle`` (scalar, cheap) for every backend, and
``hertz_halfdisks`` on a coarse mesh for backends declaring ``"elasticity"`` in
``capabilities["physics"]``.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from rbbench.interfaces import ContactOperators, Discretization
from rbbench.registry import ComponentSpec, Registry
from rbbench.scene.loading import Scene, SceneError
from rbbench.testing.contract_base import (
    HERTZ_COARSE,
    KNOWN_MULTIPLIERS,
    ContractViolation,
    RoleContract,
    as_sparse,
    check_shape,
    check_spd,
    check_symmetric,
    component_label,
    index_set,
    reference_scene,
    require,
    vector,
)


def backend_scenes(capabilities: dict | None = None) -> list[Scene]:
    """The reference scenes for a component with these capabilities.

    ``membrane_obstacle`` for ``poisson`` (or when ``physics`` is not declared),
    coarse ``hertz_halfdisks`` when ``"elasticity"`` is declared.
    """
    physics = tuple((capabilities or {}).get("physics", ("poisson",)))
    scenes = []
    if "poisson" in physics:
        scenes.append(reference_scene("membrane_obstacle"))
    if "elasticity" in physics:
        scenes.append(reference_scene("hertz_halfdisks", HERTZ_COARSE))
    return scenes


def _check_quadrature(c: ContactOperators, n: int, label: str) -> int:
    """``Un``, gap, weights, points and unit normals at the ``n_q`` contact points
    (returned); the optional point operators ``Ut``, ``Snn`` of the same shape as ``Un``."""
    Un = as_sparse(c.Un, f"{label}: contact.Un")
    nq = Un.shape[0]
    check_shape(Un, (nq, n), f"{label}: contact.Un (n_q x n_dofs)")
    require(nq > 0, f"{label}: no contact quadrature points")
    vector(c.gap, nq, f"{label}: contact.gap")
    w = vector(c.weights, nq, f"{label}: contact.weights")
    require(np.all(w > 0), f"{label}: contact.weights must be > 0 (min {w.min():.3e})")
    check_shape(np.asarray(c.points), (nq, 2), f"{label}: contact.points")
    nrm = np.asarray(c.normals, dtype=float)
    check_shape(nrm, (nq, 2), f"{label}: contact.normals")
    require(np.allclose(np.linalg.norm(nrm, axis=1), 1.0, atol=1e-10),
            f"{label}: contact.normals are not unit vectors")
    return nq


def _check_multipliers(c: ContactOperators, n: int, nq: int, label: str) -> None:
    """The multiplier space: ``Mlam``, its kind, points and extents, and ``B``, ``G``, and
    the multiplier Gram matrix ``W`` (symmetric positive definite)."""
    Mlam = as_sparse(c.Mlam, f"{label}: contact.Mlam")
    nm = Mlam.shape[1]
    check_shape(Mlam, (nq, nm), f"{label}: contact.Mlam (n_q x n_mult)")
    require(nm > 0, f"{label}: no contact multipliers")
    require(c.multiplier in KNOWN_MULTIPLIERS,
            f"{label}: contact.multiplier {c.multiplier!r} not one of {KNOWN_MULTIPLIERS}")
    check_shape(np.asarray(c.mult_points), (nm, 2), f"{label}: contact.mult_points")
    ext = np.asarray(c.mult_extent, dtype=float)
    check_shape(ext, (nm, 2), f"{label}: contact.mult_extent")
    require(np.all(ext[:, 0] <= ext[:, 1]), f"{label}: contact.mult_extent has x_min > x_max")
    for opt in ("Ut", "Snn"):
        M = getattr(c, opt)
        if M is not None:
            check_shape(M, (nq, n), f"{label}: contact.{opt}")
    check_shape(c.B(), (nm, n), f"{label}: contact.B()")
    vector(c.G(), nm, f"{label}: contact.G()")
    W = as_sparse(c.W(), f"{label}: contact.W()")
    check_shape(W, (nm, nm), f"{label}: contact.W()")
    check_symmetric(W, f"{label}: contact.W()")
    check_spd(W, f"{label}: contact.W() (multiplier Gram matrix)")


def _check_contact(c: ContactOperators, n: int, label: str) -> None:
    require(isinstance(c, ContactOperators),
            f"{label}: contact is {type(c).__name__}, not a ContactOperators")
    nq = _check_quadrature(c, n, label)
    _check_multipliers(c, n, nq, label)


def _rigid_modes(disc: Discretization, vd: list[np.ndarray]) -> list[tuple[str, np.ndarray]]:
    """Constants (scalar) or the two translations and each body's rotation (plane
    elasticity), as vectors on all dofs."""
    n = disc.n_dofs
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
    return modes


def _check_rigid_modes(disc: Discretization, label: str) -> None:
    """``A`` on all dofs is the unconstrained operator: it annihilates the rigid modes.

    Constants for a scalar problem; the two translations and the infinitesimal
    rotation for plane elasticity. Checked when the bodies' vertex dofs cover
    every dof (P1), where these modes are exactly representable.
    """
    vd = [np.asarray(b.vertex_dofs) for b in disc.bodies]
    covered = np.unique(np.concatenate([v.ravel() for v in vd]))
    if covered.size != disc.n_dofs:
        return
    A = disc.A
    scale = abs(A).max()
    for name, m in _rigid_modes(disc, vd):
        res = np.abs(A @ m).max()
        require(res <= 1e-10 * scale * np.abs(m).max(),
                f"{label}: A does not annihilate the {name} (max|A m| = {res:.3e}): "
                "A must be the unconstrained operator, Dirichlet dofs given separately")


def _check_bodies(disc: Discretization, label: str) -> None:
    require(isinstance(disc.bodies, list) and disc.bodies, f"{label}: no bodies for output")
    for b in disc.bodies:
        pts = np.asarray(b.points)
        tri = np.asarray(b.triangles)
        vd = np.asarray(b.vertex_dofs)
        nv = pts.shape[0]
        require(pts.ndim == 2 and pts.shape[1] == 2, f"{label}: body {b.name}: points not (n, 2)")
        require(tri.ndim == 2 and tri.shape[1] == 3 and np.issubdtype(tri.dtype, np.integer),
                f"{label}: body {b.name}: triangles not an integer (n, 3) array")
        require(tri.min() >= 0 and tri.max() < nv,
                f"{label}: body {b.name}: triangles index outside the vertices")
        require(vd.ndim == 2 and vd.shape[0] == nv and np.issubdtype(vd.dtype, np.integer),
                f"{label}: body {b.name}: vertex_dofs not an integer (n_vertices, k) array")
        require(vd.min() >= 0 and vd.max() < disc.n_dofs,
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
        require(abs(total - arc) <= 0.01 * arc,
                f"{label}: sum of contact weights {total:.6g} is not the length "
                f"{arc:.6g} of the contact arc of radius R1 = {r1:g}")
    elif kind == "unit_square":
        require(0.5 < total <= 1.0 + 1e-12,
                f"{label}: sum of contact weights {total:.6g} is not a part of the unit area")


def _check_operators(disc: Discretization, label: str) -> int:
    """``A`` and ``X`` symmetric, SPD on the free dofs; ``F`` and the Dirichlet data.
    Returns the number of dofs."""
    A = as_sparse(disc.A, f"{label}: A")
    n = A.shape[0]
    require(n > 0, f"{label}: no dofs")
    check_symmetric(A, f"{label}: A")
    vector(disc.F, n, f"{label}: F")
    dd = index_set(disc.dirichlet_dofs, n, f"{label}: dirichlet_dofs")
    vector(disc.dirichlet_values, dd.size, f"{label}: dirichlet_values")
    free = np.setdiff1d(np.arange(n), dd)
    require(free.size > 0, f"{label}: every dof is a Dirichlet dof")
    check_spd(A[free][:, free], f"{label}: A on the free dofs")
    X = as_sparse(disc.X, f"{label}: X")
    check_shape(X, (n, n), f"{label}: X")
    check_symmetric(X, f"{label}: X")
    check_spd(X[free][:, free], f"{label}: X on the free dofs")
    return n


def _check_discretization(disc: Any, scene: Scene, mu: np.ndarray, label: str) -> None:
    require(isinstance(disc, Discretization),
            f"{label}: discretize() returned {type(disc).__name__}, not a Discretization")
    require(np.allclose(np.asarray(disc.mu, dtype=float), mu),
            f"{label}: Discretization.mu = {disc.mu!r}, expected {mu!r}")
    physics = scene.data["scene"]["physics"]
    require(disc.physics == physics, f"{label}: physics {disc.physics!r}, scene says {physics!r}")
    n = _check_operators(disc, label)
    _check_contact(disc.contact, n, label)
    _check_contact_measure(disc, scene, mu, label)
    _check_bodies(disc, label)
    _check_rigid_modes(disc, label)


def _check_bounds(backend: Any, disc: Discretization, scene: Scene, label: str) -> None:
    """At the parameter bounds: a Discretization with the counts of the default mu, a
    finite gap and the contact measure of the mapped geometry."""
    n, nm, nq = disc.n_dofs, disc.contact.n_mult, disc.contact.n_quad
    for tag, mu in (("lower", scene.bounds[:, 0]), ("upper", scene.bounds[:, 1])):
        d = backend.discretize(mu)
        where = f"{label} at the {tag} parameter bounds mu = {mu.tolist()}"
        require(isinstance(d, Discretization), f"{where}: not a Discretization")
        require((d.n_dofs, d.contact.n_mult, d.contact.n_quad) == (n, nm, nq),
                f"{where}: (n_dofs, n_mult, n_quad) = "
                f"{(d.n_dofs, d.contact.n_mult, d.contact.n_quad)} differ from "
                f"{(n, nm, nq)} at the default mu: counts must not depend on mu")
        require(np.all(np.isfinite(d.contact.gap)), f"{where}: non-finite gap")
        _check_contact_measure(d, scene, mu, where)


def _check_rejects_bad_mu(backend: Any, scene: Scene, label: str) -> None:
    """A mu outside the domain or of the wrong size raises SceneError."""
    lo, hi = scene.bounds[:, 0], scene.bounds[:, 1]
    outside = hi + (hi - lo) + 1.0
    for bad in (outside, np.append(scene.default_mu, 0.0)):
        try:
            backend.discretize(bad)
        except SceneError:
            continue
        raise ContractViolation(
            f"{label}: discretize({bad.tolist()}) must raise SceneError (mu outside the "
            f"domain {scene.bounds.tolist()} or of the wrong size)")


def check_backend(factory: Callable[..., Any], scene: Scene, name: str | None = None) -> None:
    """Contract of the backend role on ``scene`` (``factory(scene=scene)`` builds it).

    ``discretize(default mu)`` returns a well-formed :class:`Discretization`:
    ``A`` and ``X`` symmetric, positive definite on the free dofs, ``A`` the
    unconstrained operator; consistent contact operators with positive weights
    and an SPD multiplier Gram matrix ``W``; dof and multiplier counts
    independent of mu; out-of-domain mu raises :class:`~rbbench.scene.loading.SceneError`.
    """
    label = f"backend {component_label(factory, name)!r} on {scene.name}"
    backend = factory(scene=scene)
    mu0 = scene.default_mu
    disc = backend.discretize(mu0)
    _check_discretization(disc, scene, mu0, label)
    _check_bounds(backend, disc, scene, label)
    _check_rejects_bad_mu(backend, scene, label)


def _check_registered(obj: Any, spec: ComponentSpec, registry: Registry, name: str) -> None:
    scenes = backend_scenes(spec.capabilities)
    require(scenes, f"backend {name}: declares no physics with a reference scene")
    for scene in scenes:
        check_backend(obj, scene, name=name)


CONTRACT = RoleContract("backend", "discretize", _check_registered)

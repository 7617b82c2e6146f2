"""Contract of the formulation role: a consistent
:class:`~rbbench.interfaces.ContactProblem` or :class:`~rbbench.interfaces.NitscheProblem`
built from a reference discretization."""

from __future__ import annotations

import copy
import functools
from collections.abc import Callable
from typing import Any

import numpy as np

from rbbench.interfaces import ContactProblem, Discretization, NitscheProblem
from rbbench.registry import ComponentSpec, Registry, default_registry
from rbbench.testing.contract_base import (
    HERTZ_COARSE,
    KNOWN_PHYSICS,
    ContractSkipped,
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


@functools.cache
def _cached_disc(backend: str, scene_name: str, overrides: tuple[str, ...],
                 registry: Registry, needs: frozenset[str] = frozenset()) -> Discretization:
    scene = reference_scene(scene_name, overrides)
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
    free = index_set(prob.free, n, f"{label}: free")
    nf = free.size
    require(nf > 0, f"{label}: no free dofs")
    A = as_sparse(prob.A, f"{label}: A")
    check_shape(A, (nf, nf), f"{label}: A (n_free x n_free)")
    check_symmetric(A, f"{label}: A")
    check_spd(A, f"{label}: A")
    vector(prob.F, nf, f"{label}: F")
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
    label = f"formulation {component_label(factory, name)!r} on {disc.physics}"
    prob = factory().build(disc)
    if isinstance(prob, NitscheProblem):
        _check_nitsche_problem(prob, disc, label)
        return prob
    require(isinstance(prob, ContactProblem),
            f"{label}: build() returned {type(prob).__name__}, not a ContactProblem")
    n = disc.n_dofs
    free = _check_free_stiffness(prob, n, label)
    nf = free.size
    B = as_sparse(prob.B, f"{label}: B")
    require(B.shape[1] == nf, f"{label}: B has {B.shape[1]} columns, expected n_free = {nf}")
    m = B.shape[0]
    vector(prob.G, m, f"{label}: G")
    X = as_sparse(prob.X, f"{label}: X")
    require(X.shape[0] == X.shape[1] and X.shape[0] in (n, nf),
            f"{label}: X has shape {X.shape}, expected square of size n_dofs or n_free")
    W = as_sparse(prob.W, f"{label}: W")
    check_shape(W, (m, m), f"{label}: W (n_mult x n_mult)")
    check_symmetric(W, f"{label}: W")
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
    lift = vector(prob.u_lift, n, f"{label}: u_lift")
    v = np.random.default_rng(0).standard_normal(free.size)
    u = np.asarray(prob.expand(v))
    require(u.shape == (n,), f"{label}: expand(u_free) has shape {u.shape}, expected ({n},)")
    require(np.array_equal(u[free], v),
            f"{label}: expand() does not place the free values at free dofs")
    require(np.allclose(u[constrained], want, rtol=1e-12, atol=0)
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
    require(nq > 0 and np.all(w > 0), f"{label}: weights must be > 0")
    for what in ("Un", "Snn"):
        M = as_sparse(getattr(prob, what), f"{label}: {what}")
        check_shape(M, (nq, nf), f"{label}: {what} (n_q x n_free)")
    for what in ("gap", "snn_lift", "gamma", "h"):
        vector(getattr(prob, what), nq, f"{label}: {what}")
    require(np.all(np.asarray(prob.gamma) > 0) and np.all(np.asarray(prob.h) > 0),
            f"{label}: gamma and h must be > 0")
    require(np.isfinite(prob.theta), f"{label}: theta must be finite")
    require(prob.Mlam.shape[0] == nq, f"{label}: Mlam must have n_q = {nq} rows")
    _check_lifting(prob, disc, label)
    _check_nitsche_point_operators(prob, disc, label)


def _check_nitsche_point_operators(prob: NitscheProblem, disc: Discretization,
                                   label: str) -> None:
    """``Un v - gap`` and ``Snn v + snn_lift`` equal the backend's operators on the lifted
    displacement ``expand(v)``."""
    c = disc.contact
    require(c.Snn is not None, f"{label}: the discretization has no Snn")
    v = np.random.default_rng(1).standard_normal(np.asarray(prob.free).size)
    u = np.asarray(prob.expand(v))
    for got, want, what in ((prob.Un @ v - prob.gap, c.Un @ u - c.gap, "Un v - gap"),
                            (prob.Snn @ v + prob.snn_lift, c.Snn @ u, "Snn v + snn_lift")):
        scale = max(np.abs(want).max(), np.finfo(float).tiny)
        require(np.abs(got - want).max() <= 1e-10 * scale,
                f"{label}: {what} differs from the backend operator on the lifted "
                "displacement")


def _check_registered(obj: Any, spec: ComponentSpec, registry: Registry, name: str) -> None:
    """The contract on each declared physics an installed backend provides (skipped when
    none does)."""
    physics = tuple(spec.capabilities.get("physics", KNOWN_PHYSICS))
    needs = frozenset(getattr(obj, "needs", frozenset()))
    ran = 0
    for ph in physics:
        try:
            disc = reference_discretization(ph, registry, needs)
        except LookupError:
            continue
        check_formulation(obj, disc, name=name)
        ran += 1
    if not ran:
        raise ContractSkipped(f"no installed backend provides physics {physics}")


CONTRACT = RoleContract("formulation", "build", _check_registered)

"""What a plugin package imports: the stable path for plugin authors.

Every role's base class or protocol, the data types a role receives and returns, and the
helpers a component of that role needs, under one name that does not move (the modules
that define them may). The built-in components use exactly these names.

``import rbbench.plugin`` is cheap: the registration names (:data:`ROLES`,
``ComponentSpec``, ``hookimpl``, ``Registry``) are imported at once, every other name on
first access, so a plugin's ``rbbench_register`` module may import from here without
loading numpy-heavy code.

Registration (every role)
    ``hookimpl``, ``ComponentSpec``, ``Registry``, ``ROLES``.
backend
    ``Backend``; it returns a ``Discretization`` holding ``ContactOperators`` and one
    ``BodyMesh`` per body, from a ``Scene`` (an out-of-domain ``mu`` raises ``SceneError``).
formulation
    ``Formulation``; it builds a ``ContactProblem`` (or ``NitscheProblem``,
    ``FrictionProblem``) from a ``Discretization``.
solver
    ``Solver``; it returns a ``SolveResult`` whose ``stop_reason`` is one of
    ``STOP_REASONS``.
primal
    ``PrimalCompressor`` (protocol); it returns a ``PrimalBasis``; ``x_orthonormalize``
    makes a basis X-orthonormal.
dual
    ``DualCompressor`` (base class: implement ``compress``); it returns a ``DualBasis``;
    ``as_metric`` / ``WMetric`` (the multiplier metric ``W``), ``cone_projection`` and
    ``span_projection`` (exact W-orthogonal projections, for ``e_proj`` and ``e_orth``).
stabilizer
    ``Stabilizer`` (protocol), ``NoStabilizer`` (a base doing nothing); ``supremizers``
    and ``x_orthonormalize`` build enrichments.
hyper
    ``HyperReducer`` (base class: a name, the formulations, ``check``).
executor
    ``Executor`` (protocol); it runs ``Case`` objects with ``execute_case`` and reports a
    case it could not run with ``failed_row``.

The contract suite each role must pass is :mod:`rbbench.testing` (``rbbench plugins
--check`` runs it without pytest).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from rbbench.hookspecs import hookimpl
from rbbench.registry import ROLES, ComponentSpec, Registry

if TYPE_CHECKING:  # the names below, for type checkers and the import graph
    from rbbench.bench.execution import execute_case, failed_row
    from rbbench.bench.matrix import Case
    from rbbench.interfaces import (
        STOP_REASONS,
        Backend,
        BodyMesh,
        ContactOperators,
        ContactProblem,
        Discretization,
        Executor,
        Formulation,
        FrictionProblem,
        NitscheProblem,
        Solver,
        SolveResult,
    )
    from rbbench.rb.algorithms.cones import (
        DualBasis,
        WMetric,
        as_metric,
        cone_projection,
        span_projection,
    )
    from rbbench.rb.algorithms.pga import supremizers, x_orthonormalize
    from rbbench.rb.compressors import (
        DualCompressor,
        NoStabilizer,
        PrimalBasis,
        PrimalCompressor,
        Stabilizer,
    )
    from rbbench.rb.hyper.reducers import HyperReducer
    from rbbench.scene.loading import Scene, SceneError

_INTERFACES = "rbbench.interfaces"
_CONES = "rbbench.rb.algorithms.cones"
_COMPRESSORS = "rbbench.rb.compressors"

#: public name -> the module that defines it (imported on first access)
_LAZY: dict[str, str] = {
    # backend, formulation, solver, executor
    **{name: _INTERFACES for name in (
        "Backend", "BodyMesh", "ContactOperators", "Discretization", "Formulation",
        "ContactProblem", "NitscheProblem", "FrictionProblem", "Solver", "SolveResult",
        "STOP_REASONS", "Executor")},
    "Scene": "rbbench.scene.loading",
    "SceneError": "rbbench.scene.loading",
    # primal, dual, stabilizer, hyper
    **{name: _COMPRESSORS for name in (
        "PrimalCompressor", "PrimalBasis", "DualCompressor", "Stabilizer", "NoStabilizer")},
    **{name: _CONES for name in (
        "DualBasis", "WMetric", "as_metric", "cone_projection", "span_projection")},
    "supremizers": "rbbench.rb.algorithms.pga",
    "x_orthonormalize": "rbbench.rb.algorithms.pga",
    "HyperReducer": "rbbench.rb.hyper.reducers",
    # executor
    "Case": "rbbench.bench.matrix",
    "execute_case": "rbbench.bench.execution",
    "failed_row": "rbbench.bench.execution",
}

__all__ = [
    "STOP_REASONS", "ROLES", "Backend", "BodyMesh", "Case", "ComponentSpec", "ContactOperators",
    "ContactProblem", "Discretization", "DualBasis", "DualCompressor", "Executor",
    "Formulation", "FrictionProblem", "HyperReducer", "NitscheProblem", "NoStabilizer",
    "PrimalBasis", "PrimalCompressor", "Registry", "Scene", "SceneError", "SolveResult",
    "Solver", "Stabilizer", "WMetric", "as_metric", "cone_projection", "execute_case",
    "failed_row", "hookimpl", "span_projection", "supremizers", "x_orthonormalize",
]


def __getattr__(name: str) -> Any:
    """The names of :data:`_LAZY`, imported from their module on first access."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'rbbench.plugin' has no attribute {name!r}; its names: "
                             f"{', '.join(__all__)}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})

"""The abstract HF roles filled by plugins: backend, formulation, solver."""

from __future__ import annotations

from abc import ABC, abstractmethod
from typing import Any

import numpy as np

from rbbench.interfaces.operators import Discretization
from rbbench.interfaces.problems import (
    ContactProblem,
    FrictionProblem,
    NitscheProblem,
    SolveResult,
)


class Backend(ABC):
    """HF backend role: mesh the reference geometry once, map it by mu, assemble."""

    name: str = ""

    @abstractmethod
    def __init__(self, scene: Any, **options: Any) -> None: ...

    @abstractmethod
    def discretize(self, mu: np.ndarray | float,
                   needs: frozenset[str] = frozenset()) -> Discretization:
        """Operators of the scene at ``mu``; optional operators only when in ``needs``
        (``"tangential"``: ``ContactOperators.Ut``; ``"stress"``: ``ContactOperators.Snn``
        and ``facet_length``)."""

    def warm_up(self) -> None:
        """Build what does not depend on mu now (default: ``inner_product()`` when the
        backend has one), so that no timed ``discretize`` holds that one-off work."""
        inner_product = getattr(self, "inner_product", None)
        if callable(inner_product):
            inner_product()


class Formulation(ABC):
    """Formulation role: turn backend operators into the algebraic contact problem.

    ``needs``: the optional backend operators the formulation uses, passed by the
    HF driver to ``Backend.discretize(mu, needs=...)`` (e.g. ``{"stress"}`` for
    Nitsche); empty by default.
    """

    name: str = ""
    needs: frozenset[str] = frozenset()

    @abstractmethod
    def build(self, disc: Discretization
              ) -> ContactProblem | NitscheProblem | FrictionProblem: ...

    def reduction(self) -> Any:
        """The formulation's steps in the offline skeleton (:mod:`rbbench.rb.offline`):
        an object with ``prepare(scene, config, registry) -> config`` (checks before any HF
        work) and ``reduce(context) -> ReducedStage`` (:mod:`rbbench.rb.validation`).
        Import them lazily here, so that registering the plugin stays cheap."""
        raise NotImplementedError(f"formulation {self.name!r} has no reduced model")


class Solver(ABC):
    """Algebraic VI solver role."""

    name: str = ""

    @abstractmethod
    def solve(self, problem: ContactProblem | NitscheProblem | FrictionProblem,
              warm_start: np.ndarray | None = None) -> SolveResult:
        """Solve; never hang: every return carries a stop reason."""

"""The abstract roles filled by plugins: backend, formulation, solver (HF) and executor.

The RB roles (primal, dual, stabilizer, hyper) are defined beside the pipeline that calls
them: :mod:`rbbench.rb.compressors` and :mod:`rbbench.rb.hyper.reducers`. Every role's base
class or protocol is gathered for plugin authors in :mod:`rbbench.plugin`.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import Any, Protocol, runtime_checkable

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


@runtime_checkable
class Executor(Protocol):
    """Executor role: where the cases of a run matrix run.

    Built by the runner as ``factory(jobs=jobs, **options)`` (``jobs``: concurrent cases,
    ``None`` for the CPUs; ``options``: e.g. the Dask scheduler ``address``), then
    :meth:`run` once per run.
    """

    name: str

    def run(self, cases: list[Any], run_id: str, cache_dir: str, registry: Any,
            on_result: Callable[[Any, dict], None], on_stage: Callable[[str], None]) -> None:
        """Run every case and report each exactly once.

        Parameters
        ----------
        cases : list of rbbench.bench.matrix.Case
            The cases to run (those the matrix decided to run).
        run_id : str
            The run's identifier, written into every row.
        cache_dir : str
            The HF snapshot cache shared by the cases.
        registry : rbbench.registry.Registry
            The registry the cases take their components from.
        on_result : callable
            ``on_result(case, record)`` once per case, whatever happened: the record of
            :func:`rbbench.bench.execution.execute_case`, or a ``timeout`` / ``error`` row
            of :func:`rbbench.bench.execution.failed_row`.
        on_stage : callable
            ``on_stage(message)``: a string saying what a running case does now.
        """

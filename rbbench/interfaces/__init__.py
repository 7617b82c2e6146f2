"""The abstract roles, the data that flow between them, and the model interface.

Data flow (one way)::

    Scene -> Backend.discretize(mu) -> Discretization (sparse operators)
          -> Formulation.build(...)  -> ContactProblem (algebraic VI)
          -> Solver.solve(...)       -> SolveResult (u, lam, stop reason)

and every model, HF or reduced, is called through :class:`Model`: ``solve(mu) ->
Solution``, ``reconstruct(solution) -> HFVectors``.

Everything here is plain numpy / scipy: no backend type crosses a role boundary, so
formulations and solvers are backend-agnostic. The names live in :mod:`.operators` (what a
backend assembles), :mod:`.problems` (the algebraic problems and a solve's result),
:mod:`.roles` (the abstract HF roles and the executor) and :mod:`.model` (the model interface).
"""

from rbbench.interfaces.model import HFVectors, Model, ReducedSolution, Solution
from rbbench.interfaces.operators import BodyMesh, ContactOperators, Discretization, Factorize
from rbbench.interfaces.problems import (
    STOP_REASONS,
    ContactProblem,
    FrictionLaw,
    FrictionProblem,
    LoadStep,
    NitscheFrictionProblem,
    NitscheProblem,
    NitscheStep,
    SolveResult,
)
from rbbench.interfaces.roles import Backend, Executor, Formulation, Solver

__all__ = ["STOP_REASONS", "Backend", "BodyMesh", "ContactOperators", "ContactProblem",
           "Discretization", "Executor", "Factorize", "Formulation", "FrictionLaw",
           "FrictionProblem",
           "HFVectors", "LoadStep", "Model", "NitscheFrictionProblem", "NitscheProblem",
           "NitscheStep", "ReducedSolution", "Solution", "SolveResult", "Solver"]

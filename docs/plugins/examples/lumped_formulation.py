"""A formulation plugin: the mixed contact problem with the multiplier Gram matrix ``W``
lumped (its row sums on the diagonal), so that every ``W``-norm is a weighted sum."""

from __future__ import annotations

import dataclasses
from typing import Any

import scipy.sparse as sp

from rbbench.plugin import ComponentSpec, ContactProblem, Discretization, Formulation, hookimpl


class LumpedMixed(Formulation):
    """``A u + B^T lam = F``, ``0 <= lam _|_ G - B u >= 0`` (the registered ``mixed``
    formulation's problem), with ``W`` replaced by ``diag(W 1)``."""

    name = "mixed-lumped"

    def __init__(self, **options: Any) -> None:
        from rbbench.registry import default_registry

        self.mixed = default_registry().create("formulation", "mixed", **options)

    def build(self, disc: Discretization) -> ContactProblem:
        problem = self.mixed.build(disc)
        lumped = sp.diags(abs(problem.W).sum(axis=1).A1).tocsr()
        return dataclasses.replace(problem, W=lumped)

    def reduction(self, friction: str = "none") -> Any:
        """The offline steps of the mixed formulation's reduced model: its problems are
        ContactProblems too, so the same steps reduce them."""
        return self.mixed.reduction(friction)


@hookimpl
def rbbench_register(registry):
    registry.add(ComponentSpec(
        name="mixed-lumped", role="formulation", target="lumped_formulation:LumpedMixed",
        # its problems are ContactProblems: the built-in mixed solvers take them
        capabilities={"physics": ("elasticity", "poisson"), "solvers": ("ssn", "uzawa")},
        description="mixed contact problem with the multiplier Gram matrix lumped",
    ))

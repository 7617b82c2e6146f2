"""The linear formulation: no constraint, no multiplier, no contact operator.

``build(disc)`` restricts a linear discretization (``disc.contact`` is None) to the free
dofs (:class:`rbbench.hf.linear.model.LinearProblem`: ``A u = F``, or implicit Euler with the mass
matrix); the HF solve is one sparse factorisation (:func:`rbbench.hf.linear.model.solve_linear`).
``reduction()``: POD / POD-greedy, exact affine decomposition, residual-based error bound
(:mod:`rbbench.rb.linear.offline`).
"""

from __future__ import annotations

from typing import Any

from rbbench.interfaces import Discretization, Formulation


class LinearFormulation(Formulation):
    """Linear elliptic / parabolic problems of the ``thermal`` and ``heat`` scenes."""

    name = "linear"

    def build(self, disc: Discretization) -> Any:
        from rbbench.hf.linear.model import build_linear

        return build_linear(disc)

    def reduction(self) -> Any:
        from rbbench.rb.linear.offline import LinearReduction

        return LinearReduction()

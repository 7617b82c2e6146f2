"""The model interface: one way to call the HF model and every reduced model.

As pyMOR's ``Model.solve(mu)``, a model has a parameter domain and solves at a parameter;
the benchmark compares models only through this interface (the shared validation, the
runner and the studies call nothing else):

* ``parameters``: the domain D that ``solve`` checks mu against
  (:class:`rbbench.scene.parameters.ParameterSpace`; a parameter outside it raises a
  :class:`~rbbench.scene.parameters.SceneError` naming it);
* ``solve(mu) -> Solution``: the common fields of :class:`Solution`, the same for every
  model, and the model's own result in ``detail``;
* ``reconstruct(solution) -> HFVectors``: the HF vectors of a solution in the space of the
  HF snapshots (displacement on the free dofs, multipliers in the HF multiplier space), so
  that errors against HF snapshots need nothing else;
* the model pickles (a reduced model holds no backend object; a model whose online stage
  needs HF operators rebuilds them from its recipe after unpickling).

:func:`rbbench.testing.check_reduced_model` checks a model against this contract.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

__all__ = ["HFVectors", "Model", "ReducedSolution", "Solution"]


@dataclass
class HFVectors:
    """HF vectors of a solution, in the space of the HF snapshots.

    Attributes
    ----------
    u : (n_free,) or (K n_free,)
        Displacement (or state) on the free dofs; a trajectory of K time steps is
        flattened step by step, as the snapshots store it.
    lam : (m,)
        Normal contact multipliers in the HF multiplier space; ``(0,)`` for a model without
        multipliers (linear scenes, Nitsche).
    lam_t : (m,) or None
        Tangential (friction) multipliers at the friction nodes; ``None`` without friction.
    """

    u: np.ndarray
    lam: np.ndarray
    lam_t: np.ndarray | None = None


@runtime_checkable
class Solution(Protocol):
    """What every model's ``solve(mu)`` returns (the common fields).

    Attributes
    ----------
    mu : (p,)
        The parameter as checked against D.
    u : ndarray
        Reduced primal coefficients (``(N,)``; ``(K, N)`` for a trajectory), or, for the HF
        model, the displacement on all dofs.
    lam : ndarray
        Reduced multiplier coefficients (``(R,)``; ``(0,)`` without a dual space), or the HF
        multipliers.
    iterations : int
        Iterations of the (online) solver; 0 for a direct solve.
    stop_reason : str
        ``"converged"`` (possibly with the fallback that converged, e.g. ``"converged (pdas
        fallback)"``) or why the solver stopped (:data:`rbbench.interfaces.STOP_REASONS`,
        ``"flagged"``, ``"qp failed (daqp flag k)"``).
    time_s : float
        Wall time of the solve (s): the online solve of a reduced model (with the HF
        assembly it needs, for a model without hyper-reduction), the HF solve's total.
    """

    mu: np.ndarray
    u: np.ndarray
    lam: np.ndarray
    iterations: int
    stop_reason: str
    time_s: float


@dataclass
class ReducedSolution:
    """The :class:`Solution` of a reduced model; ``detail`` is the model's own online result
    (e.g. :class:`rbbench.rb.mixed.model.OnlineResult`, with its solver's extra numbers)."""

    mu: np.ndarray
    u: np.ndarray
    lam: np.ndarray
    iterations: int
    stop_reason: str
    time_s: float
    detail: Any = None

    @property
    def converged(self) -> bool:
        """Whether the online solver converged (possibly through a fallback)."""
        return self.stop_reason.startswith("converged")


@runtime_checkable
class Model(Protocol):
    """The model interface (module docstring): ``parameters``, ``solve``, ``reconstruct``."""

    parameters: Any

    def solve(self, mu: Any) -> Solution:
        """Solve at ``mu`` (checked against :attr:`parameters`)."""

    def reconstruct(self, solution: Any) -> HFVectors:
        """The HF vectors of ``solution`` (snapshot space)."""

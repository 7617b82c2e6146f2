"""What the reduced models share online: the bases that turn a reduced solution into HF
vectors (:class:`ReducedBasis`, used by ``reconstruct`` only), and the online stage of a
model without hyper-reduction (:class:`PlainArrays`: HF assembly at mu, then projection).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from rbbench.interfaces import HFVectors

__all__ = ["PlainArrays", "ReducedBasis", "require_basis"]


@dataclass
class ReducedBasis:
    """The HF-size bases of a reduced model, kept apart from its online arrays.

    ``Z`` (n_free x N): the primal basis on the free dofs; ``V`` (m x R): the generators of
    the normal multipliers; ``Vt`` (m x S): those of the tangential (friction) multipliers.
    A model's ``reconstruct`` maps its coefficients through them (:meth:`vectors`).
    """

    Z: np.ndarray
    V: np.ndarray | None = None
    Vt: np.ndarray | None = None

    def vectors(self, c: np.ndarray, alpha: np.ndarray | None = None,
                theta: np.ndarray | None = None, Z: np.ndarray | None = None) -> HFVectors:
        """``Z c``, ``V alpha`` (empty without ``V``) and ``Vt theta`` (``None`` without
        ``Vt``); ``Z``: a basis to use instead of :attr:`Z` (an online stabiliser's)."""
        Z = self.Z if Z is None else Z
        u = (c @ Z.T).ravel() if np.ndim(c) == 2 else Z @ c  # a trajectory: K rows
        lam = self.V @ alpha if self.V is not None and alpha is not None else np.zeros(0)
        lam_t = self.Vt @ theta if self.Vt is not None and theta is not None else None
        return HFVectors(u=u, lam=lam, lam_t=lam_t)


def require_basis(model: Any) -> ReducedBasis:
    """``model.basis``, or a ValueError saying that the model keeps none."""
    basis = getattr(model, "basis", None)
    if basis is None:
        raise ValueError(f"{type(model).__name__}: no reconstruction basis (basis = None: "
                         "built without one, or dropped to ship the model light)")
    return basis


class PlainArrays:
    """``mu -> (reduced arrays, assembly time)`` of a model without hyper-reduction: the HF
    problem at mu assembled afresh (``problems``, :class:`rbbench.hf.model.ProblemSource`)
    and projected on the bases (``project``, picklable).

    The assembly and projection at a mu are done and timed once; a repeated solve at the
    same mu reuses them and reports the same assembly time, counted in its online time (the
    cost of a solve at a new mu). Pickles with its recipe (no HF problem kept).
    """

    def __init__(self, problems: Callable[[np.ndarray], Any],
                 project: Callable[[Any], Any]) -> None:
        self.problems, self.project = problems, project
        self._last: tuple[bytes, Any, float] | None = None

    def __call__(self, mu: np.ndarray) -> tuple[Any, float]:
        key = np.asarray(mu, float).tobytes()
        if self._last is None or self._last[0] != key:
            t0 = time.perf_counter()
            arrays = self.project(self.problems(mu))
            self._last = (key, arrays, time.perf_counter() - t0)
        return self._last[1], self._last[2]

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        state["_last"] = None
        return state

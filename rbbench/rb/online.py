"""What the reduced models share online: the bases that turn a reduced solution into HF
vectors (:class:`ReducedBasis`, used by ``reconstruct`` only), the online stage of a
model without hyper-reduction (:class:`PlainArrays`: HF assembly at mu, then projection),
and the one protocol of every online time (:func:`timed_online_solves`,
:data:`rbbench.runtime.timing.ONLINE_PROTOCOL`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rbbench.interfaces import HFVectors
from rbbench.runtime.threads import one_blas_thread
from rbbench.runtime.timing import ONLINE_PROTOCOL, gc_paused

__all__ = ["ONLINE_PATHS", "OnlineTimes", "PlainArrays", "ReducedBasis", "require_basis",
           "timed_online_solves"]

#: the online paths of a model's ``solve(mu, path=)``: "auto" (compiled where available),
#: "compiled" (numba kernels), "python" (the reference)
ONLINE_PATHS = ("auto", "compiled", "python")

@dataclass
class OnlineTimes:
    """The timed solutions of :func:`timed_online_solves`: ``per_mu[j]`` the ``repeats``
    solutions at the j-th mu."""

    per_mu: list[list[Any]] = field(default_factory=list)

    @property
    def times(self) -> list[float]:
        """Every timed solve's ``time_s`` (s), mu by mu."""
        return [float(s.time_s) for sols in self.per_mu for s in sols]

    @property
    def paths(self) -> str:
        """The online paths that ran (``compiled`` / ``python``; ``/``-joined when both)."""
        return _joined(str(getattr(s, "path", "python")) for sols in self.per_mu for s in sols)

    @property
    def methods(self) -> str:
        """The online methods that ran (``auto`` resolved; empty for a model that names
        none)."""
        return _joined(str(getattr(s, "method", "") or "") for sols in self.per_mu
                       for s in sols)

    def extend(self, other: OnlineTimes) -> None:
        self.per_mu.extend(other.per_mu)

    def summary(self) -> dict[str, Any]:
        """``t_online_median_s``, ``t_online_iqr_s`` (s), ``online_path``,
        ``online_method`` and ``online_protocol``."""
        t = self.times
        return {"t_online_median_s": float(np.median(t)),
                "t_online_iqr_s": float(np.subtract(*np.percentile(t, [75, 25]))),
                "online_path": self.paths, "online_method": self.methods,
                "online_protocol": ONLINE_PROTOCOL}


def _joined(names: Any) -> str:
    return "/".join(sorted({n for n in names if n}))


def timed_online_solves(model: Any, mus: Sequence[np.ndarray], repeats: int,
                        warm_up: bool = True, **solve_kw: Any) -> OnlineTimes:
    """The online-time protocol :data:`~rbbench.runtime.timing.ONLINE_PROTOCOL`
    (:data:`~rbbench.runtime.timing.ONLINE_PROTOCOL_DEFINITION`):
    ``repeats`` (at least one) timed solves ``model.solve(mu, **solve_kw)`` at each of
    ``mus``, one BLAS thread, garbage collector paused; ``warm_up``: one untimed solve at
    ``mus[0]`` first (give ``False`` for a model already warmed up in this process)."""
    repeats = max(1, int(repeats))
    with one_blas_thread(), gc_paused():
        if warm_up and len(mus):
            model.solve(mus[0], **solve_kw)
        return OnlineTimes([[model.solve(mu, **solve_kw) for _ in range(repeats)]
                            for mu in mus])


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

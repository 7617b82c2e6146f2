"""The hyper-reduced wedge model: online work independent of the HF size.

The plain wedge model (:mod:`rbbench.rb.friction.wedge.model`) projects the HF operators at mu.
Here every online array comes from small dense data:

* ``A_N(mu)``, ``F_N(mu)``: exact affine decomposition
  (:func:`rbbench.rb.friction.eim.friction_operators`);
* ``B = Ln^T Bn(mu) Z + Lt^T Bt(mu) Z`` and ``g = Ln^T Gn(mu)``: the friction EIM
  (:func:`rbbench.rb.friction.eim.friction_eim` with ``Vn = Ln``, ``Vt = Lt``; the
  tangential lifting vanishes, no Dirichlet column in the contact rows);
* De Saxce's modified gap ``P |w_t|`` (``P = [V+, V-]^T / 2``, ``w_t = -Bt(mu) Z a`` the
  tangential gap at all ``m`` HF contact nodes): the only HF-size dependent term. It is a
  componentwise nonlinearity, so DEIM applies (Chaturantabut & Sorensen 2010): the slip
  ``s = |w_t|`` is interpolated from ``M_s`` magic nodes ``I``,
  ``s ~ Q (Q[I])^{-1} s[I]``, ``Q`` the greedy EIM basis of the slips of every De Saxce
  iterate on the training set (:func:`slip_deim`); online ``P |w_t| ~ (P Q Q[I]^{-1})
  |w_t[I]|`` with the rows ``(Bt(mu) Z)[I]`` evaluated exactly by the same
  :class:`~rbbench.rb.hyper.contact_eim.RowEvaluator` pairing as the EIM
  (:meth:`~rbbench.rb.friction.eim.FrictionEIM.with_slip_rows`).

Why interpolate ``|w_t|`` and not ``w_t``: ``w_t`` lies in an ``M_t``-dimensional EIM space
but its absolute value must be taken node by node, so the signed interpolant would still
need all ``m`` nodes; ``|w_t|`` is continuous along the contact zone (0 on the stick
zone, growing with the slip), so its training iterates compress well. The reduced cone
still holds at every HF node (``c >= 0``): the DEIM only perturbs the linear term.

Measured on hertz_friction P1 (41 training, 20 validation mu, N = 30, R = S = 20, PGA
K = 40, tol_eim 1e-4; max over validation, same bases): plain err_u 2.39e-4, err_lam_t
0.1869; EIM with the exact nodal slip 2.39e-4, 0.1797; EIM + slip DEIM 2.39e-4, 0.1798
(``M_s`` = 67 of 513 nodes, ``M_n = M_t`` = 161, ``M_G`` = 4, 225 distinct rows): the slip
DEIM adds < 1e-4 to err_lam_t. Online 6.5 ms median (1 BLAS thread; coarse mesh,
129 nodes: 4.7 ms) against the HF 37 s.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.linalg as sla

from rbbench.rb.algorithms.affine import AffineOperator, LinearInMu
from rbbench.rb.algorithms.eim import deim
from rbbench.rb.friction.eim import (
    FrictionEIM,
    friction_eim,
    friction_operators,
    friction_training_operators,
)
from rbbench.rb.friction.wedge.model import (
    WedgeArrays,
    WedgeBasis,
    WedgeOnlineResult,
    WedgeReducedModel,
)
from rbbench.rb.online import ONLINE_PATHS

__all__ = ["SlipDEIM", "WedgeHyperModel", "slip_deim", "wedge_hyper_model"]


@dataclass
class SlipDEIM:
    """``P |w_t| ~ PQ |w_t[nodes]|`` (module docstring): ``nodes`` (M_s,) the magic HF
    contact nodes, ``PQ = P Q Q[nodes]^{-1}`` (R x M_s); ``info``: ``M_s``, training error
    curve (relative max-norm), number of slip snapshots."""

    nodes: np.ndarray
    PQ: np.ndarray
    info: dict = field(default_factory=dict)


def slip_deim(slips: np.ndarray, P: np.ndarray, tol: float | None = 1e-4,
              m_max: int | None = None) -> SlipDEIM:
    """Greedy EIM (:func:`rbbench.rb.algorithms.eim.deim`) of the slip snapshots ``slips`` (m x K,
    ``|w_t|`` of the training iterates) and the precomputed ``P Q Q[I]^{-1}``."""
    res = deim(np.asarray(slips, float), tol=tol, m_max=m_max)
    if res.m == 0:  # no training slip: the term is 0 (node 0 kept for the shapes)
        return SlipDEIM(np.zeros(1, np.int64), np.zeros((P.shape[0], 1)),
                        {"M_s": 0, "errors_slip": [], "n_slip_snapshots": int(slips.shape[1])})
    PQ = sla.solve(res.Q[res.magic].T, (P @ res.Q).T).T
    order = np.argsort(res.magic)
    return SlipDEIM(res.magic[order], PQ[:, order],
                    {"M_s": int(res.m), "errors_slip": res.errors.tolist(),
                     "n_slip_snapshots": int(np.asarray(slips).shape[1])})


@dataclass
class WedgeHyperModel(WedgeReducedModel):
    """The wedge model with an HF-size independent online stage (module docstring): ``P`` is
    the slip DEIM's ``PQ`` (R x M_s); ``A``, ``F`` affine in ``coefficients(mu)``; ``eim``
    the friction EIM with the slip rows. Small dense arrays and the restricted contact
    layout only; picklable."""

    A: AffineOperator | None = None
    F: AffineOperator | None = None
    coefficients: LinearInMu | None = None
    eim: FrictionEIM | None = None

    def arrays(self, mu: np.ndarray) -> WedgeArrays:
        """The reduced arrays at mu; ``BtZ`` holds the slip rows only."""
        mu = np.atleast_1d(np.asarray(mu, float))
        th = self.coefficients(mu)
        Bn, Gn, Bt, rows = self.eim.with_slip_rows(mu)
        return WedgeArrays(A=self.A(th), F=self.F(th), B=Bn + Bt, g=Gn, BtZ=rows,
                           wt0=np.zeros(rows.shape[0]))

    def timed_arrays(self, mu: np.ndarray) -> tuple[WedgeArrays, float]:
        """:meth:`arrays` and the time of its EIM evaluation (s)."""
        t0 = time.perf_counter()
        arr = self.arrays(mu)
        return arr, time.perf_counter() - t0

    def solve(self, mu: np.ndarray, x0: np.ndarray | None = None,
              path: str = "auto") -> WedgeOnlineResult:
        """Online solve at mu (warm start ``x0``, else the nearest training solution).

        ``path``: ``"python"`` (the reference: :meth:`WedgeReducedModel.solve`),
        ``"compiled"`` (:mod:`rbbench.rb.friction.wedge.compiled`, a RuntimeError saying why
        when it is unavailable) or ``"auto"`` (compiled where available:
        :meth:`online_path`). The kernel is prepared on the first call, outside the timed
        solve (``compiled.COMPILE`` has that time); a mu it does not solve (outside D, a
        point leaving its window, a QP it does not solve to its tolerance) is solved by
        the Python path, which raises the reference's error where there is one."""
        fast = self._compiled(path)
        if fast is not None:
            t0 = time.perf_counter()
            res = fast.solve(mu, x0)
            if res is not None:
                res.time_s = time.perf_counter() - t0
                return res
        return super().solve(mu, x0)

    def online_path(self) -> str:
        """The path :meth:`solve` takes with ``path = "auto"``: ``"compiled (numba X)"`` or
        ``"python (<why>)"``."""
        from rbbench.rb.friction.wedge import compiled

        fast = self._compiled("auto")
        if fast is not None:
            return f"compiled (numba {compiled.NUMBA_VERSION})"
        return f"python ({self.__dict__['_online_state']})"

    def _compiled(self, path: str) -> Any:
        """The prepared compiled solve, or None (the Python path)."""
        if path not in ONLINE_PATHS:
            raise ValueError(f"online path {path!r}: valid: {', '.join(ONLINE_PATHS)}")
        if path == "python":
            return None
        if "_online_state" not in self.__dict__:
            from rbbench.rb.friction.wedge.compiled import prepare

            self.__dict__["_online_state"] = prepare(self)
        state = self.__dict__["_online_state"]
        if isinstance(state, str):
            if path == "compiled":
                raise RuntimeError(f"compiled online path unavailable: {state}")
            return None
        return state

    def __getstate__(self) -> dict:
        """Pickle without the compiled solve (packed plans: rebuilt on use)."""
        state = dict(self.__dict__)
        state.pop("_online_state", None)
        return state


def wedge_hyper_model(plain: WedgeReducedModel, basis: WedgeBasis, Z: np.ndarray,
                      slips: np.ndarray, layout: Any, free: np.ndarray, problem_at: Any,
                      bounds: np.ndarray, mus_eim: np.ndarray, tol: float | None = 1e-4,
                      m_max: int | None = None) -> WedgeHyperModel:
    """The hyper-reduced model of a plain one (same bases, training solutions): slip DEIM
    (:func:`slip_deim`), friction EIM on ``mus_eim`` with the slip rows, affine
    ``A_N``, ``F_N`` (``problem_at``: mu -> FrictionProblem, a few HF assemblies)."""
    sd = slip_deim(slips, basis.P, tol, m_max)
    feim = friction_eim(layout, *friction_training_operators(layout, mus_eim, free), Z,
                        basis.Ln, basis.Lt, free, mus_eim, tol=tol, m_max=m_max,
                        slip_rows=sd.nodes)
    ops = friction_operators(problem_at, bounds, feim, Z)
    info = {**plain.info, **sd.info, "slip_nodes": sd.nodes.tolist(),
            **{k: v for k, v in feim.info.items() if not k.startswith("errors")}}
    return WedgeHyperModel(P=sd.PQ, mus_train=plain.mus_train, x_train=plain.x_train,
                           parameters=plain.parameters, tol=plain.tol,
                           max_iter=plain.max_iter, info=info, A=ops.A, F=ops.F,
                           coefficients=ops.coefficients, eim=feim, basis=plain.basis)

"""The hyper-reduced collocation model: online work independent of the HF size.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slides "Preliminaries" (3: "Dependence of the RB problem on
the HF dimensions -> EIM") and "EIM errors" (EIM of ``B^n(mu)`` and ``B^tau(mu)``, training
sets of 61 and 150 parameters). The plain collocation model
(:mod:`rbbench.rb.friction.collocation.model`) assembles the HF problem at mu and projects it.
Here every reduced array of one load step comes from small dense data:

* ``A_N(mu)``, ``F_N(mu)``: exact affine decomposition
  (:func:`rbbench.rb.friction.eim.friction_operators`, verified by probing);
* ``Bn_N = Vn^T Bn(mu) Z``, ``Bt_N = Vt^T Bt(mu) Z``, ``Gn_N = Vn^T Gn(mu)``: the friction EIM
  (:func:`rbbench.rb.friction.eim.friction_eim`, the same as the wedge model's with the
  collocation model's normal cone ``Vn`` and tangential POD modes ``Vt``); ``gt_N = 0`` (the
  contact rows have no Dirichlet column, checked).

The collocated Coulomb constraint ``|(Qt theta)_r| <= F_r (Qn c_n)_r`` at the GCNS nodes
``r`` acts on the multipliers only: ``Qn = Vn[C]``, ``Qt = Vt[C]`` and the coefficients
``F_r`` do not depend on mu (the last checked by ``friction_operators``), so, unlike the
wedge model's slip (a function of the displacement at every node), the constraint needs no
row of ``Bt(mu) Z`` online. The EIM of the two operators is the whole hyper-reduction; the
online Coulomb solve is the plain model's (:meth:`FrictionReducedModel.solve_arrays`).

Measured (2 cores shared with other jobs; max over 20 validation mu; N = 30, R = S = 20, PGA
K = 40, 41 training mu, tol_eim 1e-4, published GCNS stop): on the coarse P1 mesh of the
``friction_rb`` matrix (8772 dofs) the EIM changes err_u max from 1.8764e-2 (plain) to
1.8768e-2 and err_lam_t max from 12.621 to 12.622 (patience 10: 4.805e-3 / 4.804e-3): the
model's error, not the EIM's. At P2 (143,896 dofs, 513 contact nodes): M_n = M_t = 161
(every distinct training parameter of 202: the moving pairing gives no compression), M_G = 4,
206 rows paired online; online median 19.8 ms (EIM 8.6 ms, Coulomb fixed point 9.7 ms)
against the HF 8.4 s (both under load): speed-up 426.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from rbbench.rb.friction.collocation.model import FrictionArrays, FrictionReducedModel
from rbbench.rb.friction.eim import (
    FrictionOperators,
    friction_eim,
    friction_operators,
    friction_training_operators,
)

__all__ = ["TimedOperators", "collocation_hyper_model"]


@dataclass
class TimedOperators:
    """``mu -> (FrictionArrays, seconds)`` from :class:`FrictionOperators` (no HF work): the
    ``arrays_at`` of a hyper-reduced :class:`FrictionReducedModel`, timed at every call."""

    operators: FrictionOperators

    def __call__(self, mu: np.ndarray) -> tuple[FrictionArrays, float]:
        t0 = time.perf_counter()
        arr = self.operators(np.atleast_1d(np.asarray(mu, float)))
        return arr, time.perf_counter() - t0


def collocation_hyper_model(plain: FrictionReducedModel, Z: np.ndarray, Vn: np.ndarray,
                            Vt: np.ndarray, layout: Any, free: np.ndarray, problem_at: Any,
                            bounds: np.ndarray, mus_eim: np.ndarray, tol: float = 1e-4,
                            m_max: int | None = None) -> FrictionReducedModel:
    """The hyper-reduced model of a plain collocation model (same bases, collocation nodes and
    training solutions; module docstring).

    Parameters
    ----------
    plain : FrictionReducedModel
        The plain model (its ``Qn``, ``Qt``, ``nodes``, warm starts and basis are kept).
    Z, Vn, Vt : (n_free, N), (m, R), (m, S)
        Primal basis (after stabilisation), normal cone generators, tangential modes.
    layout : ContactLayout
        The backend's reference contact layout.
    free : (n_free,)
        Global dof of each free dof.
    problem_at : mu -> FrictionProblem
        For the affine ``A_N``, ``F_N`` (a few HF assemblies offline).
    bounds : (p, 2)
        The parameter box D.
    mus_eim : (P, p)
        The EIM training set (only the contact operators are built there: it can be dense).
    tol, m_max
        EIM stopping: relative max-norm training error, largest size (each of the three).
    """
    feim = friction_eim(layout, *friction_training_operators(layout, mus_eim, free), Z, Vn,
                        Vt, free, mus_eim, tol=tol, m_max=m_max)
    ops = friction_operators(problem_at, bounds, feim, Z)
    info = {**plain.info, **{k: v for k, v in feim.info.items() if not k.startswith("errors")}}
    return replace(plain, arrays_at=TimedOperators(ops), info=info)

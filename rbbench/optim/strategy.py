"""Reaching the whole contact: a load-equalising design phase before the local solver.

Why the local solver alone stops short. ``J = sum_i lam_i^p`` (``p = 6``) of the nodal
normal forces; equilibrium fixes ``sum_i lam_i = P`` (the whole vertical load goes
through the contact nodes), so by Jensen's inequality ``J >= I (P / I)^p`` with equality
for the uniform forces ``lam* = P / I``
(:meth:`~rbbench.optim.shape_scene.ShapeScene.uniform_pressure_bound`). A node out of
contact has a positive gap: a small change of its design changes the state only through
the stiffness of the body, so its component of the subgradient is small (at the initial
design of the 21-node scene at most 0.8 % of the largest one on a contact node) and blind
to the load the node could take: the bundle method (a first-order method) does not see
that lowering it would share the load.
From the scene's initial parabola it stops with about half the nodes carrying the load.
Closing the gaps alone does not help: lowering each free node by its gap brings the nodes
onto the foundation with zero force (weak contact), where the same holds (measured from
the default design: after 10 closing steps every gap is zero, 24 of 81 nodes touch with
zero force, ``J`` is 81.1 times the bound against 80.8 at the start).

The phase (:func:`equalise_phase`). The design that carries the target forces is computed
directly, by the displacement-adjustment (DA) fixed point used to design tools for a
target shape under load (Gan & Wagoner 2004, *Int. J. Mech. Sci.* 46:1097-1113: adjust
the unloaded shape by the computed displacement until the loaded shape is the target). Here
the target loaded shape is the foundation itself, loaded by ``lam*``: at the current design
``alpha_k``, with its condensed stiffness ``S_k``, load ``f_k`` and tangential forces
``tau_k`` (:mod:`~rbbench.optim.shape_state`), solve ``S_k u = f_k + (tau_k, lam*)`` (the
body with the uniform nodal forces prescribed; its vertical translation fixed by
``u_nu^0 = 0``) and take ``alpha = -u_nu`` shifted so that ``min alpha = 0``: with the
stiffness of ``alpha_k`` that design is in contact at every node with exactly ``lam*``
(:func:`compensated_design`). The stiffness moves with the mesh and friction with the
slip, so the step is repeated from the new state: ``alpha_{k+1} = (1 - theta) alpha_k +
theta P(alpha~)``, ``P`` the projection onto the admissible polyhedron (a convex
combination of admissible designs is admissible: every iterate satisfies the constraints
to the projection's accuracy). An HF state solve judges each trial: it is accepted only if
``J`` decreases, else ``theta`` is halved (the relaxation of Gan & Wagoner's compensation
factor); the phase stops when the forces are within ``force_rtol`` of ``lam*``, when
``theta < relax_min`` or after ``max_steps`` solves. It needs states only, no adjoint.

The stages (:func:`staged`). The phase's design starts the local solver (the seed's bundle
trust-region method, HF- or RB-driven). A new stage starts only if the local run gained at
least ``stage_rtol`` in ``J`` over the phase's design (else the phase would start where it
stopped): the phase runs again from the local result, and the local solver from the
phase's design if the phase found a better one. ``J`` never increases from stage to stage:
the phase accepts decreases only and the local solvers are descent methods.

Scope: the target ``lam* = P / I`` is the minimiser of ``J`` over the forces alone for any
objective that is a symmetric convex function of the nodal forces under a fixed total
load (here ``sum lam^p``); another objective needs its own target forces.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from rbbench.optim.polyhedron import Polyhedron
from rbbench.optim.shape_scene import ShapeScene
from rbbench.optim.shape_state import ShapeState, StateSolveError, objective

#: ``rbbench optimize --strategy``: the load-equalising phase before the local solver, or
#: the local solver alone from the initial design (the seed's method)
STRATEGIES = ("equalise", "none")


@dataclass
class EqualiseOptions:
    """The phase (relaxation, budget, tolerance on the forces) and the stages."""

    relax0: float = 1.0
    relax_min: float = 1.0 / 16
    max_steps: int = 40
    force_rtol: float = 1e-2
    max_stages: int = 3
    stage_rtol: float = 1e-3

    def __post_init__(self) -> None:
        checks = [("relax0", 0 < self.relax_min <= self.relax0 <= 1,
                   "need 0 < relax_min <= relax0 <= 1"),
                  ("max_steps", _count(self.max_steps), "need an integer >= 1"),
                  ("force_rtol", _positive(self.force_rtol), "need a finite number > 0"),
                  ("max_stages", _count(self.max_stages), "need an integer >= 1"),
                  ("stage_rtol", _positive(self.stage_rtol), "need a finite number > 0")]
        for key, ok, why in checks:
            if not ok:
                raise ValueError(f"EqualiseOptions.{key} = {getattr(self, key)!r}: {why}")


def _count(v: object) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and v >= 1


def _positive(v: object) -> bool:
    return (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            and v > 0)


def compensated_design(S: np.ndarray, f: np.ndarray, tau: np.ndarray,
                       lam: np.ndarray) -> np.ndarray:
    """The design that carries the nodal forces ``lam`` at every node with stiffness ``S``.

    Solves ``S u = f + (tau, lam)`` on the contact dofs ``u = (u_t at nodes 1.., u_nu at
    nodes 0..)`` with ``u_nu^0 = 0`` (``S`` is singular in the vertical translation; the
    system is compatible when ``sum lam = -sum f_nu``) and returns ``-u_nu`` shifted to
    ``min = 0``: with that design every gap ``u_nu + alpha`` is zero (displacement
    adjustment, Gan & Wagoner 2004, with the foundation as the target shape).
    """
    n = lam.size
    m = 2 * n - 1
    if S.shape != (m, m) or f.size != m or tau.size != n - 1:
        raise ValueError(f"compensated_design: S {S.shape}, f {f.size}, tau {tau.size} do "
                         f"not fit {n} contact nodes")
    rhs = f.copy()
    rhs[:n - 1] += tau
    rhs[n - 1:] += lam
    keep = np.r_[np.arange(n - 1), np.arange(n, m)]
    u = np.zeros(m)
    u[keep] = np.linalg.solve(S[np.ix_(keep, keep)], rhs[keep])
    alpha = -u[n - 1:]
    return alpha - alpha.min()


def force_mismatch(lam: np.ndarray, target: np.ndarray) -> float:
    """``max_i |lam_i - lam*_i| / max_i lam*_i``: how far the forces are from the target."""
    return float(np.max(np.abs(lam - target)) / np.max(np.abs(target)))


@dataclass
class PhaseResult:
    """The phase's best design (``x``, its ``J`` and state), ``J`` at its start, counts and
    why it stopped."""

    x: np.ndarray
    J: float
    J_start: float
    state: ShapeState
    solves: int
    accepted: int
    mismatch: float
    reason: str
    wall_s: float


StateSolver = Callable[[np.ndarray], ShapeState]


def equalise_phase(sc: ShapeScene, alpha0: np.ndarray, state: StateSolver,
                   options: EqualiseOptions | None = None,
                   callback: Callable[[dict], None] | None = None,
                   first_kind: str = "start") -> PhaseResult:
    """The load-equalising phase from the admissible ``alpha0`` (module docstring).

    ``state(alpha)`` is the HF state solve (it may warm-start; every call counts as one
    solve). A trial whose state solve fails is treated as a rejection (``theta`` halved).
    ``callback`` gets one row per solve: ``first_kind`` for ``alpha0``, then ``equalise``
    (accepted) or ``equalise_rejected``.
    """
    o = options if options is not None else EqualiseOptions()
    t0 = time.perf_counter()
    poly = Polyhedron(**sc.admissible())
    x = np.array(alpha0, dtype=float).ravel()
    poly.check(x, "alpha0")
    n = x.size
    target = np.full(n, sc.pressure * (sc.b - sc.a) / n)
    st = state(x)
    J, solves, accepted, theta = objective(sc, st.lam), 1, 0, o.relax0
    J_start = J
    _row(callback, 0, first_kind, True, J, J, 0.0, theta, force_mismatch(st.lam, target), st)
    reason = f"max_steps = {o.max_steps}"
    while True:
        mismatch = force_mismatch(st.lam, target)
        if mismatch <= o.force_rtol:
            reason = f"forces within {mismatch:.3g} <= force_rtol of the uniform target"
            break
        if theta < o.relax_min:
            reason = f"relaxation {theta:.3g} < relax_min: no decrease of J"
            break
        if solves >= o.max_steps:
            break
        goal = poly.project(compensated_design(st.cond.S, st.cond.f, st.tau, target))
        y = (1.0 - theta) * x + theta * goal
        solves += 1
        try:
            st_y = state(y)
            J_y = objective(sc, st_y.lam)
        except StateSolveError:
            st_y, J_y = None, math.inf
        step = float(np.max(np.abs(y - x)))
        if J_y < J:
            x, st, J = y, st_y, J_y
            accepted += 1
            _row(callback, solves - 1, "equalise", True, J, J_y, step, theta,
                 force_mismatch(st.lam, target), st)
        else:
            _row(callback, solves - 1, "equalise_rejected", False, J, J_y, step, theta,
                 math.nan if st_y is None else force_mismatch(st_y.lam, target), st_y)
            theta *= 0.5
    return PhaseResult(x=x, J=J, J_start=J_start, state=st, solves=solves, accepted=accepted,
                       mismatch=force_mismatch(st.lam, target), reason=reason,
                       wall_s=time.perf_counter() - t0)


def _row(callback, it: int, kind: str, serious: bool, J: float, J_trial: float, step: float,
         theta: float, mismatch: float, st: ShapeState | None) -> None:
    if callback is None:
        return
    callback({"iteration": it, "kind": kind, "serious": serious, "f": J, "J": J,
              "f_trial": J_trial, "J_trial": J_trial, "step_norm": step, "step_inf": step,
              "relax": theta, "force_mismatch": mismatch,
              "contact_nodes": math.nan if st is None else int(np.sum(st.contact))})


@dataclass
class Stage:
    """One stage: the phase, then the local solver from its design."""

    phase: PhaseResult
    local: object | None      # the local solver's result (``x``, ``f``); None if not run
    J_local: float = math.nan  # HF J at the local solver's design
    local_wall_s: float = 0.0


@dataclass
class StagedResult:
    """The stages in order, the best design (the last local result) and the stop reason."""

    stages: list[Stage] = field(default_factory=list)
    reason: str = ""

    @property
    def final(self):
        """The last local solver's result (the best design: ``J`` never increases), None
        if no local run took place (the first state solve failed)."""
        return next((s.local for s in reversed(self.stages) if s.local is not None), None)


def staged(sc: ShapeScene, alpha0: np.ndarray, state: StateSolver,
           local: Callable[[np.ndarray], tuple[object, float]],
           options: EqualiseOptions | None = None,
           callback: Callable[[dict], None] | None = None) -> StagedResult:
    """Stages of (load-equalising phase, local solver) from ``alpha0`` (module docstring).

    ``local(x0) -> (result, J_hf)`` runs the local solver from ``x0`` (``result.x`` its
    design, ``J_hf`` the HF objective there). Stops after ``max_stages``; when a phase
    finds no better design than the last local result; when a local run gains less than
    ``stage_rtol`` over the phase's design (relative ``J``: the phase would start where it
    stopped); when the local run's ``stop_reason`` starts with ``oracle failed`` or ``HF
    state solve failed``; when a phase's first state solve fails (in stage 1 the reason
    then starts with ``oracle failed``).
    """
    o = options if options is not None else EqualiseOptions()
    out = StagedResult()
    x = np.array(alpha0, dtype=float).ravel()
    for k in range(1, o.max_stages + 1):
        try:
            ph = equalise_phase(sc, x, state, o, callback, "start" if k == 1 else "stage")
        except StateSolveError as exc:       # at alpha0 nothing is known: a failed run
            out.reason = (f"{'oracle failed: ' if k == 1 else ''}stage {k}: the phase's "
                          f"first state solve: {exc}")
            return out
        if k > 1 and ph.accepted == 0:
            out.stages.append(Stage(ph, None))
            out.reason = f"stage {k}: the phase found no better design ({ph.reason})"
            return out
        t0 = time.perf_counter()
        res, J_local = local(ph.x)
        out.stages.append(Stage(ph, res, J_local, time.perf_counter() - t0))
        stop = str(getattr(res, "stop_reason", ""))
        if stop.startswith(("oracle failed", "HF state solve failed")):
            out.reason = f"stage {k}: the local run failed"
            return out
        gain = (ph.J - J_local) / abs(ph.J)
        if gain < o.stage_rtol:
            out.reason = (f"stage {k}: the local run gained {gain:.3g} < stage_rtol over the "
                          "phase's design")
            return out
        x = np.asarray(res.x, dtype=float)
    out.reason = f"max_stages = {o.max_stages}"
    return out

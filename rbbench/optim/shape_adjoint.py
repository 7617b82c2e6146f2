"""Objective and one subgradient of ``Theta(alpha) = J(alpha, S(alpha))`` by one adjoint solve.

Implicit programming as in the talk "On coupling of complementarity with friction in contact
shape optimization": ``xi = grad_alpha J + (grad_alpha F)^T b`` with ``b`` solving
``0 = grad_y J + (grad_y F)^T b + D*Q(y, -F)(b)``. At every contact node the
limiting coderivative ``D*Q`` is replaced by one element: the derivative of the branch of
the semismooth system that the node is on (``shape_state``). On the strong sets of the
talk's partition (strong contact / no contact x sliding / strong sticking) this is the
coderivative itself; on the weak sets (weak contact, weak sticking: a kink of ``max`` or
of the projection) the branch convention of ``shape_state`` picks one of the limits that
make up Propositions 3 and 4, i.e. an element of the limiting coderivative, so ``xi`` is a
subgradient in the sense the bundle method needs. Where the active sets are stable ``Theta``
is differentiable and ``xi`` is its gradient (checked against central differences in
``tests/optim/test_shape_adjoint.py``).

Design dependence: the stiffness through the moving mesh (``dA / d alpha`` exactly, by the
complex step, :func:`~rbbench.optim.shape_mesh.stiffness_design_products`), the gap
``u_nu + alpha`` in the Signorini row; the top load does not move.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rbbench.optim.shape_mesh import stiffness_design_products
from rbbench.optim.shape_scene import ShapeScene
from rbbench.optim.shape_state import ShapeState, objective, solve_jacobian, solve_state


@dataclass
class Evaluation:
    """``Theta(alpha)``, one subgradient and the state it came from."""

    alpha: np.ndarray
    J: float
    xi: np.ndarray
    state: ShapeState
    partition: dict[str, int]


def objective_gradient_lam(sc: ShapeScene, lam: np.ndarray) -> np.ndarray:
    """``dJ / d lam`` of ``J = sum |lam_i|^p``."""
    return sc.power * np.sign(lam) * np.abs(lam) ** (sc.power - 1)


def subgradient(sc: ShapeScene, st: ShapeState) -> np.ndarray:
    """``xi = p . dR / d alpha`` with ``Jac^T p = -grad_y J`` (one dense adjoint solve)."""
    n = len(st.alpha)
    m = 2 * n - 1
    rhs = np.zeros(st.jacobian.shape[0])
    rhs[m:m + n] = -objective_gradient_lam(sc, st.lam)
    p = solve_jacobian(st.jacobian, rhs, m, transpose=True)
    p_full = np.zeros(2 * sc.grid.n_nodes)
    p_full[st.cond.free] = st.cond.extend(p[:m])
    xi = stiffness_design_products(sc.grid, st.alpha, sc.D, p_full, st.u)
    xi += st.c * st.contact * p[m:m + n]
    return xi


def partition(sc: ShapeScene, st: ShapeState, tol: float = 1e-9) -> dict[str, int]:
    """Counts of the shape-optimisation talk's partition of ``gph Q`` (model B table) at the state.

    Contact: ``no`` (gap > 0, lam = 0), ``weak`` (both 0 to ``tol``), ``strong``
    (lam > 0); friction on contact nodes: ``sliding`` (u_t != 0), ``weak sticking``
    (``u_t = 0``, ``|tau| = F(0) lam``), ``strong sticking`` (``|tau| < F(0) lam``). ``tol``
    is relative to the largest force / gap; the raw values are in the state.
    """
    gap = st.u_n + st.alpha
    lam_s = max(float(np.max(np.abs(st.lam))), 1e-300)
    gap_s = max(float(np.max(np.abs(gap))), 1e-300)
    lam0 = np.abs(st.lam) <= tol * lam_s
    gap0 = np.abs(gap) <= tol * gap_s
    out = {"no_contact": int(np.sum(lam0 & ~gap0)), "weak_contact": int(np.sum(lam0 & gap0)),
           "strong_contact": int(np.sum(~lam0))}
    on = ~lam0[1:]
    slip0 = np.abs(st.u_t) <= tol * max(float(np.max(np.abs(st.u_t))), 1e-300)
    F0 = sc.friction(np.zeros(1))[0][0]
    edge = np.abs(np.abs(st.tau) - F0 * st.lam[1:]) <= tol * lam_s
    out.update(sliding=int(np.sum(on & ~slip0)), weak_sticking=int(np.sum(on & slip0 & edge)),
               strong_sticking=int(np.sum(on & slip0 & ~edge)))
    return out


def evaluate(sc: ShapeScene, alpha: np.ndarray, y0: np.ndarray | None = None) -> Evaluation:
    """State solve, ``Theta(alpha)`` and one subgradient."""
    st = solve_state(sc, alpha, y0=y0)
    return Evaluation(np.asarray(alpha, float).copy(), objective(sc, st.lam),
                      subgradient(sc, st), st, partition(sc, st))


def branch_margins(sc: ShapeScene, st: ShapeState) -> dict[str, float]:
    """Distance of the state from a branch change, relative to the largest force.

    ``contact = min_i |lam_i - c g_i|``, ``friction = min_i ||tau_i - c u_t^i| - s_i|``:
    both clearly > 0 means the active sets are locally stable and ``Theta`` is smooth there.
    """
    scale = max(float(np.max(np.abs(st.lam))), 1e-300)
    sig = st.lam - st.c * (st.u_n + st.alpha)
    s = sc.friction(np.abs(st.u_t))[0] * np.maximum(st.lam[1:], 0.0)
    z = st.tau - st.c * st.u_t
    return {"contact": float(np.min(np.abs(sig))) / scale,
            "friction": float(np.min(np.abs(np.abs(z) - s))) / scale}

"""The mixed friction problem: :class:`rbbench.interfaces.FrictionProblem`.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slides "Coulomb contact problem", "Tangential constraints",
"Algebraic formulation / Collocation method": P2 (or P1) displacements, P1 multipliers on the
slave contact nodes for both the normal and the tangential constraint (``S = (d-1) R = R`` in
2D), so ``(lam_n, lam_t)`` pair up per collocation node. ``Bn = B_nodal``,
``Gn = G_nodal``, ``Bt = Mt^T diag(w) Ut``; Dirichlet dofs are eliminated by the lifting
of each load step (``Discretization.dirichlet_steps``).

Law data per node: the Tresca threshold is ``s`` itself (Pa) at every node, since the
multipliers are nodal values of the traction (not integrated forces); the Coulomb
coefficient is ``nu_F`` at every node; a slip law (model B) keeps its name and the
solver evaluates it at the mean tangential jump ``(Bt u)_i / int phi_i``.
"""

from __future__ import annotations

import numpy as np

from rbbench.interfaces import Discretization, FrictionLaw, FrictionProblem, LoadStep


def load_steps(disc: Discretization, free: np.ndarray) -> list[LoadStep]:
    """The lifted data of every load step (one step, the full load, without steps)."""
    c = disc.contact
    A = disc.A.tocsr()
    Bn, Bt, Gn = c.B_nodal(), c.Bt(), c.G_nodal()
    values = disc.dirichlet_steps if disc.dirichlet_steps else [disc.dirichlet_values]
    steps = []
    for vals in values:
        u_lift = np.zeros(disc.n_dofs)
        u_lift[disc.dirichlet_dofs] = vals
        steps.append(LoadStep(F=disc.F[free] - A[free] @ u_lift, Gn=Gn - Bn @ u_lift,
                              ut_lift=np.asarray(Bt @ u_lift).ravel(), u_lift=u_lift))
    return steps


def _law_arrays(friction: FrictionLaw, m: int) -> dict:
    """Per-node threshold / coefficient of the law (ValueError naming a bad one)."""
    if friction.law == "tresca":
        s = friction.threshold
        if s is None or not np.isfinite(s) or s < 0:
            raise ValueError(f"Tresca threshold must be finite and >= 0, got {s!r}")
        return {"threshold": np.full(m, float(s))}
    if friction.law != "coulomb":
        raise ValueError(f"friction law {friction.law!r}: expected 'tresca' or 'coulomb'")
    if friction.coefficient_law is not None:
        return {"coefficient_law": friction.coefficient_law}
    nu = friction.coefficient
    if nu is None or not np.isfinite(nu) or nu < 0:
        raise ValueError(f"Coulomb coefficient must be finite and >= 0, got {nu!r}")
    return {"coefficient": np.full(m, float(nu))}


def build_friction_problem(disc: Discretization, friction: FrictionLaw) -> FrictionProblem:
    """The :class:`FrictionProblem` of a friction scene at ``disc.mu``."""
    c = disc.contact
    if c.Mt is None or c.Ut is None:
        raise ValueError("a friction problem needs the tangential contact operators "
                         "(Backend.discretize(mu, needs={'tangential'}))")
    free = np.setdiff1d(np.arange(disc.n_dofs), disc.dirichlet_dofs)
    steps = load_steps(disc, free)
    A = disc.A.tocsr()
    Bn, Bt = c.B_nodal()[:, free].tocsr(), c.Bt()[:, free].tocsr()
    m = Bn.shape[0]
    last = steps[-1]
    return FrictionProblem(
        A=A[free][:, free].tocsr(), F=last.F, Bn=Bn, Gn=last.Gn, Bt=Bt, free=free,
        u_lift=last.u_lift, X=disc.X, W=c.Wt(), law=friction.law, steps=steps,
        node_weights=np.asarray(c.Mt.T @ c.weights).ravel(), factorize=disc.factorize,
        **_law_arrays(friction, m))

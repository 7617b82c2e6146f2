"""Mixed (Lagrange multiplier) formulation.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slide "Mixed formulation".

``B = Mlam^T diag(w) Un`` and ``G = Mlam^T diag(w) gap`` from the backend's
contact operators; Dirichlet dofs are eliminated by lifting. A friction scene (``friction``
given to :meth:`MixedFormulation.build`) gives a :class:`~rbbench.interfaces.FrictionProblem`
instead (:mod:`rbbench_plugins.formulations.friction`).
"""

from __future__ import annotations

import numpy as np

from rbbench.interfaces import (
    ContactProblem,
    Discretization,
    Formulation,
    FrictionLaw,
    FrictionProblem,
)


class MixedFormulation(Formulation):
    name = "mixed"

    def __init__(self, **options):
        if options:
            raise TypeError(f"mixed formulation: unknown options {sorted(options)}")

    def reduction(self, friction: str = "none"):
        """Offline steps of the reduced model: :class:`rbbench.rb.mixed.offline.MixedReduction`,
        for a friction scene (``friction``: its law)
        :class:`rbbench.rb.friction.offline.FrictionReduction`."""
        if friction != "none":
            from rbbench.rb.friction.offline import FrictionReduction

            return FrictionReduction()
        from rbbench.rb.mixed.offline import MixedReduction

        return MixedReduction()

    def build(self, disc: Discretization, friction: FrictionLaw | None = None
              ) -> ContactProblem | FrictionProblem:
        """The contact problem at ``disc.mu``; with ``friction`` (the scene's law at mu,
        :func:`rbbench.hf.components.friction_at`) the friction problem.

        A discretisation with tangential operators (a friction scene) but no ``friction``
        is refused: never a silently frictionless solve of a friction scene.
        """
        if friction is not None:
            from rbbench_plugins.formulations.friction import build_friction_problem

            return build_friction_problem(disc, friction)
        if disc.dirichlet_steps is not None:
            raise ValueError("mixed formulation: this discretisation has load steps (a "
                             "friction scene) but no friction law was given: "
                             "build(disc, friction=rbbench.hf.components.friction_at(scene, mu))")
        n = disc.n_dofs
        free = np.setdiff1d(np.arange(n), disc.dirichlet_dofs)
        u_lift = np.zeros(n)
        u_lift[disc.dirichlet_dofs] = disc.dirichlet_values
        A = disc.A.tocsr()
        Bfull = disc.contact.B()
        F = disc.F[free] - A[free] @ u_lift
        G = disc.contact.G() - Bfull @ u_lift
        return ContactProblem(A=A[free][:, free].tocsr(), F=F, B=Bfull[:, free].tocsr(), G=G,
                              free=free, u_lift=u_lift, X=disc.X, W=disc.contact.W(),
                              factorize=disc.factorize)

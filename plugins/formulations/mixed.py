"""Mixed (Lagrange multiplier) formulation, seed 000 slide "Mixed formulation".

``B = Mlam^T diag(w) Un`` and ``G = Mlam^T diag(w) gap`` from the backend's
contact operators; Dirichlet dofs are eliminated by lifting.
"""

from __future__ import annotations

import numpy as np

from rbbench.interfaces import ContactProblem, Discretization, Formulation


class MixedFormulation(Formulation):
    name = "mixed"

    def __init__(self, **options):
        if options:
            raise TypeError(f"mixed formulation: unknown options {sorted(options)}")

    def reduction(self):
        """Offline steps of the reduced model (:class:`rbbench.rb.mixed_offline.MixedReduction`)."""
        from rbbench.rb.mixed_offline import MixedReduction

        return MixedReduction()

    def build(self, disc: Discretization) -> ContactProblem:
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

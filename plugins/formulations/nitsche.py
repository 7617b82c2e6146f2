"""Nitsche formulation (frictionless contact), seed 000 slides "Nitsche's method (1/2), (2/2)".

Chouly & Hild (2013), Chouly, Hild & Renard (2015): the Alart-Curnier
equation ``sigma_nn(u) = [sigma_nn(u) - gamma (u_n - d^n)]_-`` imposed weakly
(:mod:`rbbench.hf.nitsche_algebra`). Only the backend's contact evaluation matrices are
used (``Un``, ``Snn``, weights, gap, facet lengths), so the formulation runs on
every backend that builds ``Snn`` on request (``needs = {"stress"}``).
"""

from __future__ import annotations

import numpy as np

from rbbench.hf.nitsche_algebra import gamma_scaling
from rbbench.interfaces import Discretization, Formulation, NitscheProblem

#: Default dimensionless Nitsche parameter (``gamma = gamma0 E / h``).
GAMMA0 = 10.0


class NitscheFormulation(Formulation):
    """Build a :class:`~rbbench.interfaces.NitscheProblem` from a Discretization.

    Parameters
    ----------
    theta : float
        1 (symmetric: the seed's choice, a minimisation), 0 (skew-less) or -1
        (skew-symmetric, well posed for every ``gamma0 > 0``).
    gamma0 : float
        Dimensionless Nitsche parameter, ``gamma = gamma0 E / h`` with ``E`` the
        slave's Young's modulus and ``h`` the slave facet length at each point.
        ``theta = 1`` needs ``gamma0`` large enough for the Nitsche energy to be
        convex (the inverse trace constant of the mesh; about 1 on the Hertz
        meshes, see ``tests/test_nitsche.py``); 10 by default.
    """

    name = "nitsche"
    needs = frozenset({"stress"})

    def __init__(self, theta: float = 1.0, gamma0: float = GAMMA0, **options):
        if options:
            raise TypeError(f"nitsche formulation: unknown options {sorted(options)}; "
                            "valid: 'theta', 'gamma0'")
        if not np.isfinite(gamma0) or gamma0 <= 0:
            raise ValueError(f"nitsche formulation: gamma0 = {gamma0!r} must be > 0")
        if not np.isfinite(theta):
            raise ValueError(f"nitsche formulation: theta = {theta!r} must be finite")
        self.theta, self.gamma0 = float(theta), float(gamma0)

    def cache_params(self) -> dict[str, float]:
        """What, besides the scene and the components, determines a solution (the HF
        snapshot cache key, :mod:`rbbench.hf.snapshots`)."""
        return {"theta": self.theta, "gamma0": self.gamma0}

    def reduction(self):
        """Offline steps of the reduced model
        (:class:`rbbench.rb.nitsche_offline.NitscheReduction`)."""
        from rbbench.rb.nitsche_offline import NitscheReduction

        return NitscheReduction()

    def build(self, disc: Discretization) -> NitscheProblem:
        c = disc.contact
        if c.Snn is None or c.facet_length is None:
            raise ValueError("nitsche formulation: the discretization has no normal stress "
                             "operator Snn; discretize with needs={'stress'}")
        if disc.physics != "elasticity":
            raise ValueError(f"nitsche formulation: physics {disc.physics!r} is not supported "
                             "(elasticity only)")
        n = disc.n_dofs
        free = np.setdiff1d(np.arange(n), disc.dirichlet_dofs)
        u_lift = np.zeros(n)
        u_lift[disc.dirichlet_dofs] = disc.dirichlet_values
        A = disc.A.tocsr()
        Un, Snn = c.Un.tocsr(), c.Snn.tocsr()
        E = float(disc.bodies[0].E)  # the slave (upper) body
        return NitscheProblem(
            A=A[free][:, free].tocsr(), F=disc.F[free] - A[free] @ u_lift,
            Un=Un[:, free].tocsr(), Snn=Snn[:, free].tocsr(),
            gap=np.asarray(c.gap - Un @ u_lift, dtype=float),
            snn_lift=np.asarray(Snn @ u_lift, dtype=float),
            weights=np.asarray(c.weights, dtype=float),
            gamma=gamma_scaling(self.gamma0, E, c.facet_length), theta=self.theta,
            gamma0=self.gamma0, E=E, h=np.asarray(c.facet_length, dtype=float), free=free,
            u_lift=u_lift, X=disc.X, Mlam=c.Mlam.tocsr(), factorize=disc.factorize)

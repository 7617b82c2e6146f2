"""Nitsche formulation (frictionless contact).

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slides "Nitsche's method (1/2), (2/2)".

Chouly & Hild (2013), Chouly, Hild & Renard (2015): the Alart-Curnier
equation ``sigma_nn(u) = [sigma_nn(u) - gamma (u_n - d^n)]_-`` imposed weakly
(:mod:`rbbench.hf.algebra.nitsche`). Only the backend's contact evaluation matrices are
used (``Un``, ``Snn``, weights, gap, facet lengths), so the formulation runs on
every backend that builds ``Snn`` on request (``needs = {"stress"}``).

Friction: Chouly-Hild-Renard's tangential term
(:mod:`rbbench.hf.algebra.nitsche_friction`) with the slave shear stress ``Snt`` and the tangential
jump ``Ut`` (built when a friction scene asks for the tangential operators), over the load
steps of the scene (:func:`rbbench_plugins.formulations.friction.load_steps`).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from rbbench_plugins.formulations.friction import _law_arrays, load_steps

from rbbench.hf.algebra.nitsche import gamma_scaling
from rbbench.interfaces import (
    Discretization,
    Formulation,
    FrictionLaw,
    NitscheFrictionProblem,
    NitscheProblem,
    NitscheStep,
)

#: Default dimensionless Nitsche parameter (``gamma = gamma0 E / h``).
GAMMA0 = 10.0
#: largest gamma0 taken: gamma = gamma0 E / h; beyond, the penalty term swamps the stiffness
#: (the gamma0 sweep of the tests converges up to 1e7)
MAX_GAMMA0 = 1.0e8


class NitscheFormulation(Formulation):
    """Build a :class:`~rbbench.interfaces.NitscheProblem` from a Discretization.

    Parameters
    ----------
    theta : float
        In [-1, 1]: 1 (symmetric: Benaceur et al.'s choice, a minimisation), 0
        (skew-less) or -1 (skew-symmetric, well posed for every ``gamma0 > 0``).
    gamma0 : float
        Dimensionless Nitsche parameter, ``gamma = gamma0 E / h`` with ``E`` the
        slave's Young's modulus and ``h`` the slave facet length at each point.
        ``theta = 1`` needs ``gamma0`` large enough for the Nitsche energy to be
        convex (the inverse trace constant of the mesh; about 1 on the Hertz
        meshes, measured by the gamma0 sweep of the tests); 10 by default, at most
        :data:`MAX_GAMMA0`.
    """

    name = "nitsche"
    needs = frozenset({"stress"})

    def __init__(self, theta: float = 1.0, gamma0: float = GAMMA0, **options):
        if options:
            raise TypeError(f"nitsche formulation: unknown options {sorted(options)}; "
                            "valid: 'theta', 'gamma0'")
        for key, v in (("gamma0", gamma0), ("theta", theta)):
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ValueError(f"nitsche formulation: {key} = {v!r} must be a number")
        if not (np.isfinite(gamma0) and 0 < gamma0 <= MAX_GAMMA0):
            raise ValueError(f"nitsche formulation: gamma0 = {gamma0!r} must lie in "
                             f"(0, {MAX_GAMMA0:g}] (larger only worsens the conditioning)")
        if not (np.isfinite(theta) and -1 <= theta <= 1):
            raise ValueError(f"nitsche formulation: theta = {theta!r} must lie in [-1, 1] "
                             "(1 symmetric, 0, -1 skew-symmetric)")
        self.theta, self.gamma0 = float(theta), float(gamma0)

    def cache_params(self) -> dict[str, float]:
        """What, besides the scene and the components, determines a solution (the HF
        snapshot cache key, :mod:`rbbench.hf.snapshots.compute`)."""
        return {"theta": self.theta, "gamma0": self.gamma0}

    def reduction(self):
        """Offline steps of the reduced model
        (:class:`rbbench.rb.nitsche.offline.NitscheReduction`)."""
        from rbbench.rb.nitsche.offline import NitscheReduction

        return NitscheReduction()

    def build(self, disc: Discretization, friction: FrictionLaw | None = None
              ) -> NitscheProblem | NitscheFrictionProblem:
        """The Nitsche problem at ``disc.mu``; with a ``friction`` law, the
        :class:`~rbbench.interfaces.NitscheFrictionProblem` (:func:`friction_problem`)."""
        if friction is not None:
            return friction_problem(self._frictionless(disc), disc, friction)
        return self._frictionless(disc)

    def _frictionless(self, disc: Discretization) -> NitscheProblem:
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


def _step(disc: Discretization, u_lift: np.ndarray, F: np.ndarray) -> NitscheStep:
    """The point data of one load step with the global lifting ``u_lift``."""
    c = disc.contact
    return NitscheStep(F=F, gap=np.asarray(c.gap - c.Un @ u_lift, dtype=float),
                       snn_lift=np.asarray(c.Snn @ u_lift, dtype=float),
                       snt_lift=np.asarray(c.Snt @ u_lift, dtype=float),
                       ut_lift=np.asarray(c.Ut @ u_lift, dtype=float), u_lift=u_lift)


def friction_problem(base: NitscheProblem, disc: Discretization, friction: FrictionLaw
                     ) -> NitscheFrictionProblem:
    """The Nitsche friction problem: ``base`` (the frictionless problem of the full load)
    with the tangential operators, the law per point and the load steps, its step fields
    those of the last step (``ut_prev = 0``)."""
    c = disc.contact
    if c.Snt is None or c.Ut is None:
        raise ValueError("nitsche friction: the discretization has no shear stress operator "
                         "Snt / tangential jump Ut; discretize with needs={'stress', "
                         "'tangential'}")
    steps = [_step(disc, s.u_lift, s.F) for s in load_steps(disc, base.free)]
    last = steps[-1]
    fields = {f.name: getattr(base, f.name) for f in dataclasses.fields(base)}
    fields.update(F=last.F, gap=last.gap, snn_lift=last.snn_lift, u_lift=last.u_lift)
    return NitscheFrictionProblem(
        **fields, Ut=c.Ut[:, base.free].tocsr(), Snt=c.Snt[:, base.free].tocsr(),
        snt_lift=last.snt_lift, ut_lift=last.ut_lift, ut_prev=np.zeros(c.n_quad),
        law=friction.law, steps=steps, **_law_arrays(friction, c.n_quad))

"""Shape optimisation with contact: implicit programming on a design vector.

After the talk "On coupling of complementarity with friction in contact shape optimization",
model B (Coulomb friction with the solution-dependent coefficient ``F(t) = 0.25 / (t^2 + 1)``,
2D).

Data flow: design alpha -> moving mesh and operators (``shape_mesh``) -> state solve of
the model-B Coulomb problem (``shape_state``) -> objective and subgradient by one adjoint
solve (``shape_adjoint``) -> nonsmooth optimiser (``bundle``, bundle trust region) over
the linear admissible set; ``rb_driver`` replaces the state solve by a reduced model that
is enriched along the optimisation path.
"""

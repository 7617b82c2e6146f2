"""Shape optimisation with contact (seed 001): implicit programming on a design vector.

Data flow: design alpha -> moving mesh and operators (``shape_mesh``) -> state solve of
the model-B Coulomb problem (``shape_state``) -> objective and subgradient by one adjoint
solve (``shape_adjoint``) -> nonsmooth optimiser (``bundle``, bundle trust region) over
the linear admissible set; ``rb_driver`` replaces the state solve by a reduced model that
is enriched along the optimisation path.
"""

"""Test utilities for rbbench and its plugins: the plugin contract suite.

See :mod:`rbbench.testing.contract`. Importing this package does not import
pytest or any finite-element backend.
"""

from rbbench.testing.contract import (
    HERTZ_COARSE,
    ROLE_CHECKS,
    ContractViolation,
    backend_scenes,
    check_backend,
    check_component,
    check_formulation,
    check_solver,
    check_spec,
    component_params,
    infeasible_contact_problem,
    random_contact_problem,
    redundant_contact_problem,
    reference_discretization,
)

__all__ = [
    "HERTZ_COARSE",
    "ROLE_CHECKS",
    "ContractViolation",
    "backend_scenes",
    "check_backend",
    "check_component",
    "check_formulation",
    "check_solver",
    "check_spec",
    "component_params",
    "infeasible_contact_problem",
    "random_contact_problem",
    "redundant_contact_problem",
    "reference_discretization",
]

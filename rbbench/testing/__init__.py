"""Test utilities for rbbench and its plugins: the contract suite, what every component and
every model must satisfy.

A third-party plugin package runs the same checks as the built-in components::

    import pytest
    from rbbench.testing import check_component, component_params

    @pytest.mark.parametrize("spec", component_params())
    def test_contract(spec):
        check_component(spec)

or calls one role's check on its own class::

    from rbbench.testing import check_solver
    check_solver(MySolver)                      # any callable returning a Solver
    check_backend(MyBackend, load_scene("membrane_obstacle"))

and an author of a reduced model checks it against the model interface
(:class:`rbbench.interfaces.Model`) at a few parameters of its domain::

    from rbbench.testing import check_reduced_model
    check_reduced_model(model, [mu_1, mu_2])

Without pytest (it is not in the base install), ``rbbench plugins --check --package NAME``
runs the same contracts on one package's components and exits 1 on a failure; in Python,
:func:`run_contracts` returns one :class:`ContractResult` per component and
:func:`run_contract` checks one.

Every check raises :class:`ContractViolation` (an ``AssertionError``) naming the
component and the property that failed; a check that cannot run here (not installed, no
backend for a formulation's physics) raises :class:`ContractSkipped`. The checks assert mathematical
properties of the role (symmetry, definiteness, KKT conditions, shapes), never
the output of a particular implementation.

Reference scenes: ``membrane_obstacle`` (scalar, cheap) for every backend, and
``hertz_halfdisks`` on a coarse mesh for backends declaring ``"elasticity"`` in
``capabilities["physics"]``.

``pytest`` is imported only by the helpers that need it (:func:`component_params`,
:func:`check_component`), so importing this module stays cheap and works without pytest.

The package gathers the public names; the code lives in one module per role
(``rbbench.testing.contract_backend``, ``_formulation``, ``_solver``, ``_primal``,
``_dual``, ``_stabilizer``, ``_executor``, ``_hyper``), the model interface's in
:mod:`rbbench.testing.contract_model`, the shared helpers in
:mod:`rbbench.testing.contract_base` and the registry-wide suite (:func:`check_spec`,
:func:`component_params`, :func:`check_component`, :func:`run_contract`) in
:mod:`rbbench.testing.contract_suite` and the report without pytest in
:mod:`rbbench.testing.contract_runner`.
:mod:`rbbench.testing.faulty` holds deliberately failing components (runner tests).
"""


from rbbench.testing.contract_backend import backend_scenes, check_backend
from rbbench.testing.contract_base import HERTZ_COARSE, ContractSkipped, ContractViolation
from rbbench.testing.contract_dual import check_dual, dual_test_data
from rbbench.testing.contract_executor import check_executor
from rbbench.testing.contract_formulation import check_formulation, reference_discretization
from rbbench.testing.contract_model import check_reduced_model
from rbbench.testing.contract_primal import PRIMAL_TOL_KINDS, check_primal, primal_test_data
from rbbench.testing.contract_runner import ContractResult, run_contracts
from rbbench.testing.contract_solver import (
    check_nitsche_solver,
    check_solver,
    infeasible_contact_problem,
    random_contact_problem,
    random_nitsche_problem,
    redundant_contact_problem,
)
from rbbench.testing.contract_stabilizer import (
    STABILIZER_GUARANTEES,
    check_stabilizer,
    stabilizer_test_data,
)
from rbbench.testing.contract_suite import (
    ROLE_CHECKS,
    check_component,
    check_spec,
    component_params,
    run_contract,
)

__all__ = [
    "ContractResult",
    "ContractSkipped",
    "ContractViolation",
    "HERTZ_COARSE",
    "PRIMAL_TOL_KINDS",
    "ROLE_CHECKS",
    "STABILIZER_GUARANTEES",
    "backend_scenes",
    "check_backend",
    "check_component",
    "check_dual",
    "check_executor",
    "check_formulation",
    "check_nitsche_solver",
    "check_primal",
    "check_reduced_model",
    "check_solver",
    "check_spec",
    "check_stabilizer",
    "component_params",
    "dual_test_data",
    "infeasible_contact_problem",
    "primal_test_data",
    "random_contact_problem",
    "random_nitsche_problem",
    "redundant_contact_problem",
    "reference_discretization",
    "run_contract",
    "run_contracts",
    "stabilizer_test_data",
]

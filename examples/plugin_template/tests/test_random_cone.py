"""The template's tests: the rbbench contract suite on this package's components only, and
what the random cone promises beyond it."""

from __future__ import annotations

import numpy as np
import pytest
import rbbench_plugin_template
from rbbench_plugin_template.random_cone import RandomCone
from scipy.optimize import nnls

from rbbench.registry import Registry
from rbbench.testing import dual_test_data, run_contract


def _own_registry() -> Registry:
    """A registry holding this package's declarations only (its hook called directly, so
    the test runs whether or not the package is installed)."""
    registry = Registry()
    rbbench_plugin_template.rbbench_register(registry)
    return registry


@pytest.mark.parametrize("spec", _own_registry().specs(), ids=lambda s: f"{s.role}:{s.name}")
def test_contract(spec):
    run_contract(spec, _own_registry())  # raises ContractViolation naming what fails


def test_every_selected_snapshot_is_reproduced():
    theta, W = dual_test_data(seed=3)
    basis = RandomCone(seed=5)(theta, W, tol=0.0, r_max=6)
    sw = np.sqrt(W.diagonal())
    for q in basis.selected:  # each selected snapshot lies in the cone (NNLS here)
        residual = nnls(sw[:, None] * basis.generators, sw * theta[:, q])[1]
        assert residual <= 1e-10 * np.linalg.norm(sw * theta[:, q])


def test_the_seed_decides_the_cone():
    theta, W = dual_test_data(seed=3)
    a, b = RandomCone(seed=1)(theta, W, r_max=4), RandomCone(seed=1)(theta, W, r_max=4)
    c = RandomCone(seed=2)(theta, W, r_max=4)
    assert a.selected == b.selected and np.array_equal(a.generators, b.generators)
    assert a.selected != c.selected
    assert a.info["seed"] == 1 and a.info["stop"] == "r_max"


def test_negative_snapshots_are_refused():
    theta, W = dual_test_data(seed=0)
    theta[0, 0] = -1.0
    with pytest.raises(ValueError, match="negative entries"):
        RandomCone()(theta, W)

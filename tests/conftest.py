"""Shared pytest setup: ``--runslow`` enables tests marked ``slow``; tests marked
``netgen`` (the 3D meshes) are skipped when Netgen is not installed (see pyproject.toml).

Hypothesis runs derandomized (fixed seed) by default, so CI is reproducible;
``HYPOTHESIS_PROFILE=explore pytest`` searches with fresh random examples (and
more of them). Counterexamples it finds become ``@example`` cases.
"""

import importlib.util
import os

import pytest
from hypothesis import settings

settings.register_profile("default", derandomize=True)
settings.register_profile("explore", derandomize=False, max_examples=1000)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))


def pytest_addoption(parser):
    parser.addoption("--runslow", action="store_true", default=False,
                     help="also run tests marked slow (long studies)")


def pytest_collection_modifyitems(config, items):
    if importlib.util.find_spec("netgen") is None:
        no_netgen = pytest.mark.skip(reason='3D meshes need Netgen: pip install "rbbench[ngsolve]"')
        for item in items:
            if "netgen" in item.keywords:
                item.add_marker(no_netgen)
    if config.getoption("--runslow"):
        return
    skip = pytest.mark.skip(reason="slow: run with --runslow")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)

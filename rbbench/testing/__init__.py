"""Test utilities for rbbench and its plugins: the plugin contract suite.

See :mod:`rbbench.testing.contract`. Importing this package does not import
pytest or any finite-element backend.
"""

from rbbench.testing.contract import *  # noqa: F403 - the public API is contract.__all__
from rbbench.testing.contract import __all__  # noqa: F401

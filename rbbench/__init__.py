"""rbbench: benchmark reduced-basis methods for parametric variational inequalities.

The core never imports a finite-element backend at import time; backends,
formulations and solvers are plugins discovered through the ``rbbench``
entry-point group (see :mod:`rbbench.registry`).
"""

from rbbench import _compat
from rbbench._version import __version__

_compat.install()

__all__ = ["__version__"]

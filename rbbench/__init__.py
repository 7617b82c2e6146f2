"""rbbench: benchmark reduced-basis methods for parametric variational inequalities.

The core never imports a finite-element backend at import time; backends,
formulations and solvers are plugins discovered through the ``rbbench``
entry-point group (see :mod:`rbbench.registry`).
"""

__version__ = "0.1.0"

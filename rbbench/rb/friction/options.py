"""The options of the mixed formulation's reduced friction models (friction scenes)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

__all__ = ["DEPRECATED_DUALS", "FRICTION_DUALS", "FrictionOptions"]

#: the reduced friction dual models: ``collocation`` (normal cone, POD of lam_t, Coulomb's
#: constraint collocated at the GCNS nodes: :mod:`rbbench.rb.friction.collocation`) and
#: ``wedge`` (cones of ``F lam_n +- lam_t``, De Saxce's modified gap:
#: :mod:`rbbench.rb.friction.wedge`)
FRICTION_DUALS = ("collocation", "wedge")
#: old names of the dual models, accepted with a DeprecationWarning until rbbench 0.3
DEPRECATED_DUALS = {"seed": "collocation"}


@dataclass
class FrictionOptions:
    """The options of a reduced friction model.

    ``friction_dual``: the dual model (:data:`FRICTION_DUALS`). The normal cone: ``dual``
    (a registered dual compressor), ``R`` generators at most, tolerance ``tol_dual``; the
    tangential space: ``S`` modes (collocation: POD of lam_t; wedge: generators of the
    ``F lam_n - lam_t`` cone; default ``R``). ``stabilizer``: ``none`` or ``pga`` on the
    combined form ``b^n + b^tau`` (``delta_pga``, ``k_pga_max`` as for the frictionless
    model); ``exact_max_r``: the largest set whose inf-sup constant is computed exactly.
    GCNS (collocation model): ``gcns_per_iteration`` nodes added per iteration,
    ``gcns_max`` iterations at most, stop after ``gcns_patience`` increases of its error.
    ``tol_eim``, ``m_eim``, ``n_eim_train``: the friction EIM (hyper ``eim``, wedge model).
    """

    friction_dual: str = "collocation"
    dual: str = "mcpg"
    R: int | None = None
    S: int | None = None
    tol_dual: float = 1e-3
    stabilizer: str = "pga"
    delta_pga: float | None = None
    k_pga_max: int | None = None
    exact_max_r: int = 10
    gcns_per_iteration: int = 2
    gcns_max: int | None = None
    gcns_patience: int = 1
    tol_eim: float = 1e-4
    m_eim: int | None = None
    n_eim_train: int | None = None

    def __post_init__(self) -> None:
        if self.friction_dual in DEPRECATED_DUALS:
            new = DEPRECATED_DUALS[self.friction_dual]
            warnings.warn(f"friction_dual {self.friction_dual!r} is now {new!r} (the old name "
                          "goes in rbbench 0.3)", DeprecationWarning, stacklevel=3)
            self.friction_dual = new
        if self.friction_dual not in FRICTION_DUALS:
            raise ValueError(f"friction dual model {self.friction_dual!r}: valid: "
                             f"{', '.join(FRICTION_DUALS)}")

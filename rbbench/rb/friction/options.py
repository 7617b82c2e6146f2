"""The options of the mixed formulation's reduced friction models (friction scenes)."""

from __future__ import annotations

import warnings
from dataclasses import dataclass

from rbbench.scene.parameters import FieldError

__all__ = ["AUTO", "DEPRECATED_DUALS", "FRICTION_DUALS", "FrictionOptions"]

#: the reduced friction dual models: ``collocation`` (normal cone, POD of lam_t, Coulomb's
#: constraint collocated at the GCNS nodes: :mod:`rbbench.rb.friction.collocation`) and
#: ``wedge`` (cones of ``F lam_n +- lam_t``, De Saxce's modified gap:
#: :mod:`rbbench.rb.friction.wedge`)
FRICTION_DUALS = ("collocation", "wedge")
#: ``auto``: the best measured model for the scene's law (the validation page on friction
#: reduced bases): ``wedge`` on Coulomb scenes, ``collocation`` on Tresca scenes (the wedge
#: model is Coulomb's cone)
AUTO = "auto"
#: old names of the dual models, accepted with a DeprecationWarning until rbbench 0.3
DEPRECATED_DUALS = {"seed": "collocation"}


@dataclass
class FrictionOptions:
    """The options of a reduced friction model.

    ``friction_dual``: the dual model (:data:`FRICTION_DUALS`; default ``auto``: the wedge
    model on Coulomb scenes, with the friction EIM when the hyper-reducer is ``auto``, and
    the collocation model on Tresca scenes). The normal cone: ``dual``
    (a registered dual compressor), ``R`` generators at most, tolerance ``tol_dual``; the
    tangential space: ``S`` modes (collocation: POD of lam_t; wedge: generators of the
    ``F lam_n - lam_t`` cone; default ``R``). ``stabilizer``: ``none`` or ``pga`` on the
    combined form ``b^n + b^tau`` (``delta_pga``; at most ``k_pga_max`` vectors, default
    40: the published dim V_off = 70 at N = 30); ``exact_max_r``: the largest set whose
    inf-sup constant is computed exactly.
    GCNS (collocation model): ``gcns_per_iteration`` nodes added per iteration,
    ``gcns_max`` iterations at most, stop after ``gcns_patience`` increases of its error.
    ``tol_eim``, ``m_eim``, ``n_eim_train``: the friction EIM (hyper ``eim``, both models).
    """

    friction_dual: str = AUTO
    dual: str = "mcpg"
    R: int | None = None
    S: int | None = None
    tol_dual: float = 1e-3
    stabilizer: str = "pga"
    delta_pga: float | None = None
    k_pga_max: int | None = 40
    exact_max_r: int = 10
    gcns_per_iteration: int = 2
    gcns_max: int | None = None
    gcns_patience: int = 1
    tol_eim: float = 1e-4
    m_eim: int | None = None
    n_eim_train: int | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.friction_dual, str):
            raise FieldError("", "friction_dual", self.friction_dual,
                             f"valid: {', '.join((AUTO, *FRICTION_DUALS))}")
        if self.friction_dual in DEPRECATED_DUALS:
            new = DEPRECATED_DUALS[self.friction_dual]
            warnings.warn(f"friction_dual {self.friction_dual!r} is now {new!r} (the old name "
                          "goes in rbbench 0.3)", DeprecationWarning, stacklevel=3)
            self.friction_dual = new
        if self.friction_dual not in (AUTO, *FRICTION_DUALS):
            raise FieldError("", "friction_dual", self.friction_dual, "valid: "
                             f"{', '.join((AUTO, *FRICTION_DUALS))}")

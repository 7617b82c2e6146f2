"""The options of the mixed formulation's reduced model (frictionless scenes): standard
library and the scene layer's error type only, so that the command line reads their defaults
without loading the numerics."""

from __future__ import annotations

from dataclasses import dataclass

from rbbench.scene.parameters import FieldError

__all__ = ["BOUND_MODES", "BOUND_POD_MAX", "ONLINE_METHODS", "MixedOptions"]

#: Online solvers of the reduced saddle point
#: (:meth:`rbbench.rb.mixed.model.ReducedModel.solve` ``method``; the first is the default):
#: ``auto`` (:meth:`rbbench.rb.mixed.model.ReducedModel.resolve_method`), the condensed LCP by
#: Lawson-Hanson's active set, the primal QP by daqp, the condensed LCP by the primal-dual
#: active set.
ONLINE_METHODS = ("auto", "nnls", "daqp", "pdas")
#: How the certified error bound is evaluated: ``auto`` online where the operators are
#: affine (cheap offline and online), else with the HF operators at each validation
#: parameter; ``online`` also online under the contact EIM of a two-body scene (the contact
#: rows paired online: an offline cost of minutes and an online cost of about ten reduced
#: solves); ``hf`` always with the HF operators (no online bound)
BOUND_MODES = ("auto", "online", "hf")
#: The default of ``bound_pod_max``: the most modes of the master half of ``B(mu)^T
#: lam_N`` in the two-body online bound (a speed / sharpness trade, measured by ``rbbench
#: studies bound-cap``: on hertz_halfdisks the knee of the curve, where fewer modes save
#: little time and the effectivity rises faster)
BOUND_POD_MAX = 60


@dataclass
class MixedOptions:
    """The options of the mixed formulation's reduced model (frictionless scenes).

    ``dual``: the registered dual compressor of the multiplier cone, ``R`` its maximal size
    (default: the tolerance ``tol_dual`` on ``e_proj``); ``stabilizer``: ``none``,
    ``supremizer`` (online) or ``pga`` (offline: tolerance ``delta_pga``, default the rule
    of :func:`rbbench.rb.compressors.pga_delta`; at most ``k_pga_max`` vectors);
    ``online_method``: the reduced solver (:data:`ONLINE_METHODS`);
    ``exact_max_r``: the largest cone whose inf-sup constant is computed exactly (larger:
    bounds); ``tol_eim``, ``m_eim``, ``n_eim_train``: the contact EIM's tolerance, size cap
    and training grid (hyper ``eim``); ``bound``: how the certified bound is evaluated
    (:data:`BOUND_MODES`); ``bound_pod_max``: with ``bound = "online"`` on a two-body scene,
    the most modes (eigenvectors and POD) of the master half of ``B(mu)^T lam_N`` (fewer: a
    cheaper bound with a larger, still rigorous, compression remainder; unused elsewhere).
    """

    dual: str = "mcpg"
    R: int | None = None
    tol_dual: float = 1e-3
    stabilizer: str = "pga"
    delta_pga: float | None = None
    k_pga_max: int | None = None
    online_method: str = "auto"
    exact_max_r: int = 10
    tol_eim: float = 1e-4
    m_eim: int | None = None
    n_eim_train: int | None = None
    bound: str = "auto"
    bound_pod_max: int = BOUND_POD_MAX

    def __post_init__(self) -> None:
        if not isinstance(self.bound, str) or self.bound not in BOUND_MODES:
            raise FieldError("", "bound", self.bound, f"valid: {', '.join(BOUND_MODES)}")
        if not isinstance(self.online_method, str) or self.online_method not in ONLINE_METHODS:
            raise FieldError("", "online_method", self.online_method, "valid: "
                             f"{', '.join(ONLINE_METHODS)}")

"""The options of the Nitsche formulation's reduced model: standard library only, so that the
command line reads their defaults without loading the numerics."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["NitscheOptions"]


@dataclass
class NitscheOptions:
    """The options of the Nitsche formulation's reduced model: the hyper-reduction's
    tolerance ``tol_eim`` (ECSW: on the relative residual of the training sums; DEIM: its
    relative max-norm training error), its size cap ``m_eim`` (ECSW default:
    :data:`rbbench.rb.nitsche.offline.ECSW_POINTS_PER_MODE` ``* N``) and training grid
    ``n_eim_train`` (default ``2 (n_train - 1) + 1`` points)."""

    tol_eim: float = 1e-4
    m_eim: int | None = None
    n_eim_train: int | None = None

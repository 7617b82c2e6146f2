"""The hyper-reducers as registry components (role ``"hyper"``, listed by ``rbbench plugins``).

A hyper-reducer makes the online stage independent of the HF size: it replaces the
mu-dependent (and, for Nitsche, solution-dependent) reduced operators by an affine or a
sampled approximation. Each formulation's offline steps carry out the ones it declares
(:mod:`rbbench.rb.mixed.offline`, :mod:`rbbench.rb.nitsche.offline`); these classes are the
declarations the registry instantiates to validate a choice (``ReduceConfig.hyper``,
``[components] hyper`` of a run matrix). ``"auto"`` is not a component: it is the
formulation's default rule (mixed: affine, else EIM, else none; Nitsche: ECSW).
"""

from __future__ import annotations

from typing import Any

#: ``ReduceConfig.hyper`` values: ``"auto"`` and the built-in hyper-reducers.
BUILTIN = ("affine", "eim", "ecsw", "deim", "none")


class HyperReducer:
    """Base of the built-in declarations: a name, the formulations, what it approximates.

    Constructed without options (they live in ``ReduceConfig``: ``tol_eim``, ``m_eim``,
    ``n_eim_train``); :meth:`check` raises a ValueError naming the formulation when the
    hyper-reducer does not apply to it.
    """

    name = ""
    formulations: tuple[str, ...] = ()
    approximates = ""

    def __init__(self, **options: Any) -> None:
        if options:
            raise TypeError(f"hyper {self.name!r}: options are ReduceConfig fields "
                            f"(tol_eim, m_eim, n_eim_train), not {sorted(options)}")

    def check(self, formulation: str) -> None:
        if formulation not in self.formulations:
            raise ValueError(f"hyper {self.name!r} applies to the formulation(s) "
                             f"{', '.join(self.formulations)}, not {formulation!r}")


class ExactAffine(HyperReducer):
    """Exact affine decomposition of A_N, F_N, B_N, G_N, verified by probing
    (:func:`rbbench.rb.algorithms.affine.affine_decomposition`)."""

    name, formulations = "affine", ("mixed",)
    approximates = "nothing: exact when the scene is affine in mu (refused otherwise)"


class ContactRowEIM(HyperReducer):
    """Mixed: EIM of the contact rows ``B(mu) Z``, ``G(mu)`` at magic rows
    (:func:`rbbench.rb.hyper.contact_eim.contact_eim`); Nitsche: DEIM of the contact point
    contributions (same as ``"deim"``)."""

    name, formulations = "eim", ("mixed", "nitsche")
    approximates = "the reduced contact constraint (mixed) / contact residual (Nitsche)"


class ECSW(HyperReducer):
    """Empirical cubature (energy-conserving sampling and weighting) at the contact
    quadrature points, weights by sparse NNLS (:func:`rbbench.rb.nitsche.model.sparse_nnls`)."""

    name, formulations = "ecsw", ("nitsche",)
    approximates = "the sum over contact points of the Nitsche residual and tangent"


class DEIM(HyperReducer):
    """DEIM of the Nitsche contact point contributions (:func:`rbbench.rb.algorithms.eim.deim`)."""

    name, formulations = "deim", ("nitsche",)
    approximates = "the Nitsche contact point contributions (interpolated)"


class NoHyper(HyperReducer):
    """Plain: the HF operators at mu projected online (online cost grows with the HF size)."""

    name, formulations = "none", ("mixed", "nitsche")
    approximates = "nothing (HF-size dependent online stage)"

"""Dual compressors: reduced positive cones ``W_R^+`` from multiplier snapshots.

Setting (``science.md`` section 2, step 2; Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model
order reduction methods: parametric variational inequalities" (talk), slides "CPG algorithm"
and "mCPG algorithm (1/4)" to "(4/4)"): the multiplier snapshots ``theta_q``
(``q = 1..Q``) are the columns of a dense ``Theta`` (``n x Q``) with
non-negative entries (the HF positive cone ``W^+`` is the non-negative orthant
of the coefficients). ``W`` is the SPD Gram matrix of the multiplier space and
``||x||_W = sqrt(x^T W x)``. A *dual compressor* returns a :class:`DualBasis`
whose generators ``v_1..v_R`` span the reduced cone
``W_R^+ = Span^+{v_r} = {V alpha, alpha >= 0}`` (or, for the POD baseline, a
linear space).

Error measures (Benaceur et al., slide "mCPG algorithm (4/4)"):

* ``e_proj(R) = max_q ||(I - Pi_{W_R^+}) theta_q||_W / max_q ||theta_q||_W``,
  with ``Pi_{W_R^+}`` the W-orthogonal projection onto the closed convex cone
  (computed exactly by :func:`cone_projection`).
* ``e_orth(r)``: Benaceur et al. write ``||(I - Pi_{W_R^+}) nu_r||_W``, which is zero
  for every generator of ``W_R^+`` if read literally. We read it as the
  *aperture of the new generator*: its normalised distance from the previous
  cone, ``e_orth(r) = ||(I - Pi_{W_{r-1}^+}) nu_r||_W / ||nu_r||_W`` in
  ``[0, 1]`` (``1``: ``nu_r`` is W-orthogonal to, or points away from, the
  previous cone; ``0``: it adds nothing). ``e_orth(1) = 1``.

Functions work on plain arrays. ``W`` may be a dense or scipy sparse
``(n, n)`` matrix, a 1-D array of diagonal weights, or a prebuilt
:class:`WMetric` (pass one to avoid refactorising a non-diagonal ``W``).

The numerics live in :mod:`rbbench.rb.algorithms.cones.metric` (metric, exact projections),
:mod:`rbbench.rb.algorithms.cones.split` (the mCPG QP), :mod:`rbbench.rb.algorithms.cones.greedy`
(CPG, mCPG, ENG, :class:`DualBasis`) and :mod:`rbbench.rb.algorithms.cones.baselines` (POD, NNMF);
this module re-exports them and holds :data:`DUAL_COMPRESSORS`, the built-in functions by
name (a lookup table for scripts and tests; the registry's dual compressors are the classes of
:mod:`rbbench.rb.compressors`, and a plugin's never appears here).
"""

from __future__ import annotations

from collections.abc import Callable

from rbbench.rb.algorithms.cones.baselines import nnmf, nnmf_compressor, pod_dual
from rbbench.rb.algorithms.cones.greedy import EXHAUSTED_RTOL as EXHAUSTED_RTOL
from rbbench.rb.algorithms.cones.greedy import NEG_RTOL as NEG_RTOL
from rbbench.rb.algorithms.cones.greedy import DualBasis, cpg, eng, mcpg
from rbbench.rb.algorithms.cones.greedy import _peel_all as _peel_all
from rbbench.rb.algorithms.cones.metric import (
    ConeGram,
    WMetric,
    as_metric,
    cone_gram,
    cone_projection,
    span_projection,
)
from rbbench.rb.algorithms.cones.split import mcpg_split

__all__ = [
    "DUAL_COMPRESSORS",
    "ConeGram",
    "DualBasis",
    "WMetric",
    "as_metric",
    "cone_gram",
    "cone_projection",
    "cpg",
    "eng",
    "mcpg",
    "mcpg_split",
    "nnmf",
    "nnmf_compressor",
    "pod_dual",
    "span_projection",
]

#: Common signature ``f(Theta, W, tol, r_max, **options) -> DualBasis``.
DUAL_COMPRESSORS: dict[str, Callable[..., DualBasis]] = {
    "pod": pod_dual,
    "cpg": cpg,
    "mcpg": mcpg,
    "eng": eng,
    "nnmf": nnmf_compressor,
}

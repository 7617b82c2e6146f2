"""Registry-facing protocol layer for the compressors and stabilisers of the RB pipeline.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slide "Decorrelated model reduction": the offline stage is
(1) training set and snapshots, (2) compression of the reduced spaces (a primal space ``V_N``
and a reduced
cone ``W_R^+``), then, since ``beta_dec`` may vanish, (3) a stabilisation of the primal
space (slides "Enhancement by supremizers", "Parameter-dependent context", "Projected
Greedy Algorithm (PGA)"). The numerics live in :mod:`rbbench.rb.algorithms.pod`,
:mod:`rbbench.rb.algorithms.cones` and :mod:`rbbench.rb.algorithms.pga`; this module only gives each
method a uniform, typed call so the pipeline can take it from the registry (roles ``"primal"``,
``"dual"``, ``"stabilizer"``; declared in ``rbbench_plugins``). Nothing here changes a result of
those functions.

Three protocols:

* primal compressor: ``compressor(U, X, *, tol=None, n=None) -> PrimalBasis``, an
  X-orthonormal basis ``Z`` of ``V_N`` built from the displacement snapshots;
* dual compressor: ``compressor(LAM, W, *, tol=1e-3, r_max=None) -> DualBasis``
  (:class:`rbbench.rb.algorithms.cones.DualBasis`), generators of ``W_R^+`` (or of a span, POD);
* stabiliser: ``offline(Z, Vg, X, x_solve, B_train, delta) -> (Z_off, history)`` builds
  the parameter-independent primal basis, and ``online_basis(Z_off, Vg, X, x_solve, B)``
  the basis used at one ``mu`` (equal to ``Z_off`` unless ``online`` is True).

Histories are JSON-serialisable (lists and floats): the pipeline writes them to
``result.json``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from rbbench.rb.algorithms import cones
from rbbench.rb.algorithms import infsup as inf
from rbbench.rb.algorithms.cones.greedy import DualBasis
from rbbench.rb.algorithms.pga import pga, supremizers, x_orthonormalize
from rbbench.rb.algorithms.pod import pod, weak_greedy

__all__ = [
    "CPG",
    "ENG",
    "MCPG",
    "NNMF",
    "DualCompressor",
    "GreedyPrimal",
    "NoStabilizer",
    "PGAStabilizer",
    "PODLam",
    "PODPrimal",
    "PrimalBasis",
    "PrimalCompressor",
    "Stabilizer",
    "SupremizerStabilizer",
    "pga_default_delta",
]

XSolve = Callable[[np.ndarray], np.ndarray]


# --------------------------------------------------------------------------- primal
@dataclass
class PrimalBasis:
    """Output of a primal compressor.

    Attributes
    ----------
    Z : (n, N) ndarray
        X-orthonormal basis of ``V_N`` (``Z^T X Z = I``).
    name : str
        Registered name of the compressor that built it.
    history : dict
        Method-specific, JSON-serialisable record (singular values, greedy errors, ...).
    """

    Z: np.ndarray
    name: str
    history: dict[str, Any] = field(default_factory=dict)

    @property
    def N(self) -> int:
        """``N = dim V_N``."""
        return int(self.Z.shape[1])


@runtime_checkable
class PrimalCompressor(Protocol):
    """``(U, X, *, tol=None, n=None) -> PrimalBasis``.

    ``U`` (n x P) holds the displacement snapshots, ``X`` the V inner product (sparse or
    dense, SPD). ``n`` caps ``N``; ``tol`` is the compressor's tolerance, whose meaning it
    declares in its ``capabilities["tol"]``: ``"energy"`` (relative Frobenius error of the
    snapshot set, ``sum_p ||u_p - Pi u_p||_X^2 <= tol^2 sum_p ||u_p||_X^2``) or ``"max"``
    (``max_p ||u_p - Pi u_p||_X <= tol max_p ||u_p||_X``).
    """

    name: str

    def __call__(self, U: np.ndarray, X: Any, *, tol: float | None = None,
                 n: int | None = None) -> PrimalBasis: ...


class PODPrimal:
    """POD of the displacement snapshots (Benaceur et al., "Method 1: Proper Orthogonal
    Decomposition").

    Wraps :func:`rbbench.rb.algorithms.pod.pod` (method of snapshots in the X inner product).
    ``tol`` is an energy tolerance: ``N`` is the smallest size with
    ``sum_{k > N} s_k^2 <= tol^2 sum_k s_k^2``; without ``tol`` (and without ``n``) ``N``
    is the numerical rank (correlation eigenvalues above ``1e-12`` of the largest). The
    spaces are nested in ``N``.

    History: ``singular_values`` (all kept), ``tail`` (relative squared projection error of
    the snapshot set after ``k`` modes, ``k = 0..rank``), ``total_energy``.
    """

    name = "pod"

    def __call__(self, U: np.ndarray, X: Any, *, tol: float | None = None,
                 n: int | None = None) -> PrimalBasis:
        res = pod(U, X, tol=tol, n=n)
        hist = {"singular_values": res.s.tolist(), "tail": res.tail.tolist(),
                "total_energy": float(res.total_energy)}
        return PrimalBasis(Z=res.Z, name=self.name, history=hist)


class GreedyPrimal:
    """Greedy selection of snapshots (Benaceur et al., "Method 2: (Ideal) Greedy algorithms").

    Wraps :func:`rbbench.rb.algorithms.pod.weak_greedy`. Indicator: by default (``indicator=None``)
    the TRUE projection error ``||u(mu) - Pi_{V_{N-1}} u(mu)||_X`` of every training snapshot,
    i.e. the *ideal* greedy on the training set (Benaceur et al.'s ``sigma_N``; it needs
    the snapshots, which the pipeline has, and makes ``sigma`` non-increasing). The talk notes
    that a posteriori error estimators replace it in practice: pass such an estimator as
    ``indicator(Z, p) -> float`` (``Z`` the current X-orthonormal basis, ``p`` the snapshot
    column) to run a weak greedy instead.

    ``tol`` is a max-norm tolerance relative to the largest snapshot:
    stop when ``sigma_N <= tol * max_p ||u_p||_X`` (default ``1e-8``, about the numerical
    rank). ``n`` caps ``N``. The spaces are nested in ``N``.

    History: ``sigma`` (largest indicated error before each addition, ``sigma[0] =
    max_p ||u_p||_X`` for the ideal greedy), ``picks`` (snapshot columns, in order),
    ``d_pod`` and ``dpw_bound`` (the DeVore-Petrova-Wojtaszczyk check, see
    :class:`rbbench.rb.algorithms.pod.GreedyResult`), ``indicator`` (``"true error"`` or
    ``"custom"``).
    """

    name = "greedy"
    DEFAULT_TOL: ClassVar[float] = 1e-8

    def __init__(self, indicator: Callable[[np.ndarray, int], float] | None = None) -> None:
        self.indicator = indicator

    def __call__(self, U: np.ndarray, X: Any, *, tol: float | None = None,
                 n: int | None = None) -> PrimalBasis:
        res = weak_greedy(U, X, indicator=self.indicator,
                          tol=self.DEFAULT_TOL if tol is None else float(tol), n_max=n)
        hist = {"sigma": res.sigma.tolist(), "picks": [int(p) for p in res.picks],
                "d_pod": res.d_pod.tolist(), "dpw_bound": res.dpw_bound.tolist(),
                "indicator": "true error" if res.ideal else "custom"}
        return PrimalBasis(Z=res.Z, name=self.name, history=hist)


# ----------------------------------------------------------------------------- dual
class DualCompressor:
    """Base class of the dual compressors: ``(LAM, W, *, tol=1e-3, r_max=None) -> DualBasis``.

    ``LAM`` (m x Q) holds the multiplier snapshots (non-negative for the cone methods),
    ``W`` the multiplier Gram matrix (sparse, dense or diagonal weights, see
    :func:`rbbench.rb.algorithms.cones.as_metric`). ``tol`` bounds ``e_proj(R)`` (Benaceur
    et al., slide "mCPG algorithm (4/4)"), ``r_max`` caps ``R``. Constructor keyword options
    are kept in :attr:`options` and passed on to :meth:`compress` (e.g. ``sweeps`` for ENG,
    ``seed`` / ``max_iter`` for NNMF).

    A subclass, built-in or from another package, sets :attr:`name` (its registered name)
    and implements :meth:`compress`; nothing else has to know about it. Registering it is a
    :class:`~rbbench.registry.ComponentSpec` with ``role="dual"`` and the capabilities
    ``cone`` and ``nested`` (see :func:`rbbench.testing.check_dual`).
    """

    name: ClassVar[str] = ""

    def __init__(self, **options: Any) -> None:
        self.options = options

    def __call__(self, LAM: np.ndarray, W: Any, *, tol: float = 1e-3,
                 r_max: int | None = None) -> DualBasis:
        return self.compress(LAM, W, tol=tol, r_max=r_max, **self.options)

    def compress(self, LAM: np.ndarray, W: Any, *, tol: float = 1e-3, r_max: int | None = None,
                 **options: Any) -> DualBasis:
        """Build the reduced cone (or span) from the snapshots ``LAM``.

        Parameters
        ----------
        LAM : (m, Q) ndarray
            Multiplier snapshots, one per column.
        W : sparse matrix, ndarray or WMetric
            The multiplier Gram matrix (:func:`rbbench.rb.algorithms.cones.as_metric`).
        tol : float
            Stop at the first size ``R`` with ``e_proj(R) <= tol``.
        r_max : int, optional
            At most ``r_max`` generators.
        **options
            The constructor's keyword options.

        Returns
        -------
        DualBasis
            Generators of unit W-norm (non-negative for a cone), ``e_proj`` and ``e_orth``
            per generator.
        """
        raise NotImplementedError(f"dual compressor {type(self).__name__} "
                                  f"({self.name or 'no name'}): implement "
                                  "compress(LAM, W, *, tol, r_max, **options) -> DualBasis")


class PODLam(DualCompressor):
    """POD of the multipliers, :func:`rbbench.rb.algorithms.cones.pod_dual`: a linear SPAN, not a
    cone.

    Baseline of ``science.md`` section 2 (shows why cones matter): W-orthonormal modes of
    mixed sign, ``is_cone = False``.
    """

    name = "pod"
    compress = staticmethod(cones.pod_dual)


class CPG(DualCompressor):
    """Cone Projected Greedy, :func:`rbbench.rb.algorithms.cones.cpg` (Benaceur et al., slide
    "CPG algorithm")."""

    name = "cpg"
    compress = staticmethod(cones.cpg)


class MCPG(DualCompressor):
    """Modified CPG, :func:`rbbench.rb.algorithms.cones.mcpg` (Benaceur et al., slide "mCPG
    algorithm (2/4)")."""

    name = "mcpg"
    compress = staticmethod(cones.mcpg)


class ENG(DualCompressor):
    """Enlarged Nonnegative Greedy as designed in :func:`rbbench.rb.algorithms.cones.eng`
    (Benaceur et al., slide "mCPG algorithm (3/4)": named only)."""

    name = "eng"
    compress = staticmethod(cones.eng)


class NNMF(DualCompressor):
    """Non-negative matrix factorisation baseline,
    :func:`rbbench.rb.algorithms.cones.nnmf_compressor`.

    Not nested: each rank is a new fit, so ``e_proj`` need not decrease with ``R``.
    """

    name = "nnmf"
    compress = staticmethod(cones.nnmf_compressor)


# ----------------------------------------------------------------------- stabilisers
@runtime_checkable
class Stabilizer(Protocol):
    """Primal enrichment making the reduced saddle point inf-sup stable over ``W_R^+``.

    ``offline(Z, Vg, X, x_solve, B_train, delta) -> (Z_off, history)``: ``Z`` (n x N,
    X-orthonormal) spans ``V_N``, ``Vg`` (m x R) holds the cone generators, ``X`` the primal
    Gram matrix on the free dofs and ``x_solve`` a solver for ``X y = rhs``, ``B_train``
    the constraint matrices ``B(mu)`` (m x n) of the training parameters, ``delta`` a
    tolerance (used by PGA). ``Z_off`` is X-orthonormal and contains ``span Z``.

    ``online_basis(Z_off, Vg, X, x_solve, B)`` is the primal basis for the parameter of
    ``B``: ``Z_off`` itself unless :attr:`online` is True, in which case it needs the HF
    ``B(mu)`` online (not compatible with an HF-independent affine online stage).
    """

    name: str
    online: bool

    def offline(self, Z: np.ndarray, Vg: np.ndarray, X: Any, x_solve: XSolve,
                B_train: Iterable[Any], delta: float | None = None,
                ) -> tuple[np.ndarray, dict[str, Any]]: ...

    def online_basis(self, Z_off: np.ndarray, Vg: np.ndarray, X: Any, x_solve: XSolve,
                     B: Any) -> np.ndarray: ...


class NoStabilizer:
    """No stabilisation: the "decorrelated" model ``V_N x W_R^+`` (Benaceur et al., slide
    "Decorrelated model reduction"), whose ``beta_dec`` is not guaranteed to be positive."""

    name = "none"
    online = False

    def offline(self, Z: np.ndarray, Vg: np.ndarray, X: Any, x_solve: XSolve,
                B_train: Iterable[Any], delta: float | None = None,
                ) -> tuple[np.ndarray, dict[str, Any]]:
        return np.asarray(Z, dtype=float), {}

    def online_basis(self, Z_off: np.ndarray, Vg: np.ndarray, X: Any, x_solve: XSolve,
                     B: Any) -> np.ndarray:
        return Z_off


class SupremizerStabilizer(NoStabilizer):
    """Online supremizers ``V_N + S_R(mu)`` (Benaceur et al., slide "Parameter-dependent context").

    ``S_R(mu) = span X^{-1} B(mu)^T Vg`` (:func:`rbbench.rb.algorithms.pga.supremizers`) contains
    the supremizer of every element of ``W_R^+``, so ``beta_on(mu) >= beta_HF(mu)`` for EVERY
    ``mu``; the price is that the space is built online from the HF ``B(mu)`` (``R`` HF
    solves with ``X``). Offline: ``Z`` unchanged.
    """

    name = "supremizer"
    online = True

    def online_basis(self, Z_off: np.ndarray, Vg: np.ndarray, X: Any, x_solve: XSolve,
                     B: Any) -> np.ndarray:
        Q, _ = x_orthonormalize(np.hstack([Z_off, supremizers(B, x_solve, Vg)]), X)
        return Q


class PGAStabilizer(NoStabilizer):
    """Projected Greedy Algorithm (Benaceur et al., slides "Projected Greedy Algorithm (PGA)",
    "Some details"): ``V_off = V_N + S_R^red`` built offline.

    :func:`rbbench.rb.algorithms.pga.pga` on the supremizers ``T(mu_p)`` of the training parameters:
    ``S_R^red`` grows greedily until ``max_train sigma_S(mu) <= delta``, so that
    ``beta_off(mu) >= sqrt(1 - delta^2) beta_on(mu) > 0`` on the TRAINING set
    (:func:`rbbench.rb.algorithms.pga.riesz_lower_bound`; Benaceur et al.'s "Main result" under its
    condition). Nothing is asserted outside the training set. ``Z_off = [Z, basis of S_R^red]``.

    History: ``sigma_max`` (before each addition, non-increasing), ``pga_delta``,
    ``pga_stop`` (``"tolerance"``, ``"exhausted"``, ``"max_dim"``), ``pga_picks``, ``K``.

    Parameters
    ----------
    max_dim : int, optional
        Cap on ``K = dim S_R^red`` (default: none).
    """

    name = "pga"

    def __init__(self, max_dim: int | None = None) -> None:
        self.max_dim = max_dim

    def offline(self, Z: np.ndarray, Vg: np.ndarray, X: Any, x_solve: XSolve,
                B_train: Iterable[Any], delta: float | None = None,
                ) -> tuple[np.ndarray, dict[str, Any]]:
        if delta is None:
            raise ValueError("pga: give delta (e.g. pga_default_delta(...))")
        Z = np.asarray(Z, dtype=float)
        T_list = [supremizers(B, x_solve, Vg) for B in B_train]
        res = pga(T_list, Z, X, float(delta), max_dim=self.max_dim)
        hist = {"sigma_max": res.sigma_max.tolist(), "pga_delta": float(delta),
                "pga_stop": res.stop_reason, "pga_picks": [int(p) for p in res.picks],
                "K": res.dim}
        return np.hstack([Z, res.basis]), hist


def pga_default_delta(B_train: Iterable[Any], W_train: Iterable[Any], x_solve: XSolve,
                      Vg: np.ndarray, fraction: float = 0.5, over: str = "min") -> float:
    """``fraction * min_mu beta_span(mu) / c(mu)`` over the given parameters.

    ``over="max"`` with ``fraction=1`` is Benaceur et al.'s own rule (the sup), used by
    :func:`rbbench.rb.offline.reduce`.

    Benaceur et al.'s choice is ``delta_PGA = sup_train beta_HF / c_HF`` (slide "Projected Greedy
    Algorithm (PGA)", 0.072 there). Computable stand-in, as in :func:`rbbench.rb.offline.
    reduce`: ``beta_span`` is :func:`rbbench.rb.algorithms.infsup.infsup_span` over the whole HF
    primal space and ``span(Vg)`` (a lower bound of ``beta_on``) and ``c`` the continuity constant
    on the same spaces (:func:`rbbench.rb.algorithms.infsup.boundedness_constant`); the minimum (not
    the sup) and ``fraction = 0.5`` keep the "Main result" condition
    ``sigma < beta_on / c_HF`` on the parameters probed. Pass a subset of the training
    matrices to save the ``R`` solves per parameter.
    """
    if over not in ("min", "max"):
        raise ValueError(f"pga_default_delta: over = {over!r}: 'min' or 'max'")
    Vg = np.asarray(Vg, dtype=float)
    ratios = []
    for B, W in zip(B_train, W_train, strict=True):
        # the quotient matrices of rbbench.rb.algorithms.infsup.quotient_matrices with Z = None,
        # from R solves (the supremizers) instead of m: S = (B^T Vg)^T X^{-1} (B^T Vg)
        S = np.asarray(B.T @ Vg).T @ supremizers(B, x_solve, Vg)
        M = inf._gram(W, Vg)
        ratios.append(inf.infsup_span(S, M) / inf.boundedness_constant(S, M))
    if not ratios:
        raise ValueError("pga_default_delta: no parameters given")
    return fraction * float(min(ratios) if over == "min" else max(ratios))


def make_stabilizer(reg: Any, config: Any) -> Any:
    """The registered stabiliser ``config.stabilizer`` (PGA capped at ``config.k_pga_max``);
    ``reg`` a :class:`~rbbench.registry.Registry`, ``config`` the formulation's options."""
    opts = {"max_dim": config.k_pga_max} if config.stabilizer == "pga" else {}
    return reg.create("stabilizer", config.stabilizer, **opts)


def takes_delta(reg: Any, name: str) -> bool:
    """Whether the registered stabiliser ``name`` is given the tolerance ``delta``: it declares
    the guarantee ``capabilities["inf_sup"] == "training set"``, which is stated in ``delta``
    (``pga``, or a plugin's offline stabiliser)."""
    return reg.get("stabilizer", name).capabilities.get("inf_sup") == "training set"


def is_online(reg: Any, name: str) -> bool:
    """Whether the registered stabiliser ``name`` needs the HF ``B(mu)`` online (its
    ``capabilities["online_hf"]``, as ``supremizer``)."""
    return bool(reg.get("stabilizer", name).capabilities.get("online_hf", False))


def pga_delta(config: Any, problems: list, x_solve: Any,
              Vg: np.ndarray, reg: Any = None) -> float | None:
    """The stabiliser's tolerance ``delta``: ``config.delta_pga``, else Benaceur et al.'s PGA
    rule (friction example: ``delta_PGA = sup beta_HF / c_HF = 0.072``) with beta the span
    value over the reduced cone (a lower bound), over every fifth training problem. ``None``
    unless the stabiliser takes one (:func:`takes_delta` with the registry ``reg``; without
    it, PGA only)."""
    if not (takes_delta(reg, config.stabilizer) if reg is not None
            else config.stabilizer == "pga"):
        return None
    if config.delta_pga is not None:
        return config.delta_pga
    probe = problems[:: max(1, len(problems) // 5)]
    return pga_default_delta([p.B for p in probe], [p.W for p in probe], x_solve, Vg,
                             fraction=1.0, over="max")

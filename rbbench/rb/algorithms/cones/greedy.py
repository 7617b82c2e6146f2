"""The greedy cone compressors CPG, mCPG and ENG, and their result :class:`DualBasis`.

Setting and error measures: :mod:`rbbench.rb.algorithms.cones`. One shared loop (:func:`_greedy`,
the selection of the "CPG algorithm" of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order
reduction methods: parametric variational inequalities" (talk)); the methods differ in the
generator they add
(the raw snapshot, or its mCPG residual, :func:`rbbench.rb.algorithms.cones.split.mcpg_split`) and,
for ENG, in a peeling pass over all generators after each addition.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rbbench.rb.algorithms.cones.metric import (
    ConeGram,
    WMetric,
    as_metric,
    cone_gram,
    cone_projection,
    span_projection,
)
from rbbench.rb.algorithms.cones.split import mcpg_split

__all__ = ["DualBasis", "cpg", "eng", "mcpg"]

#: A snapshot whose projection error is below this fraction of the largest
#: snapshot norm is considered exactly represented (greedy loops stop there).
EXHAUSTED_RTOL = 1e-11
#: Negative snapshot entries above ``-NEG_RTOL * max|Theta|`` are rounding noise
#: (clipped to 0); larger ones are an error for the cone methods.
NEG_RTOL = 1e-12


# -------------------------------------------------------------------- result object
@dataclass
class DualBasis:
    """Output of a dual compressor.

    Attributes
    ----------
    generators : (n, R) array
        Generators ``v_r``, each of unit W-norm; non-negative for cone methods.
    name : str
        Name of the compressor that built it (its registered name).
    is_cone : bool
        True: the reduced set is ``Span^+(generators)``; False: a linear span.
    selected : list of int
        Snapshot index ``q_r`` picked at each greedy iteration (empty if none).
    e_proj : list of float
        ``e_proj(r)``, ``r = 1..R`` (Benaceur et al., slide "mCPG algorithm (4/4)"); NaN where
        not computed (non-nested NNMF, see ``info``).
    e_orth : list of float
        Aperture ``||(I - Pi_{W_{r-1}^+}) v_r||_W / ||v_r||_W`` of each new
        generator (module docstring).
    info : dict
        ``stop`` (why the loop ended), timings, Gram condition numbers, ...
    """

    generators: np.ndarray
    name: str
    is_cone: bool
    selected: list[int] = field(default_factory=list)
    e_proj: list[float] = field(default_factory=list)
    e_orth: list[float] = field(default_factory=list)
    info: dict[str, Any] = field(default_factory=dict)

    @property
    def R(self) -> int:
        return int(self.generators.shape[1])

    def project(self, theta: np.ndarray, W: Any):
        """Project ``theta`` onto the reduced cone (or span): ``(coeffs, proj, err)``."""
        if self.is_cone:
            return cone_projection(theta, self.generators, W)
        return span_projection(theta, self.generators, W)


# ------------------------------------------------------------------------- helpers
def _check_snapshots(Theta: np.ndarray, nonneg: bool = True) -> tuple[np.ndarray, int]:
    T = np.array(Theta, dtype=float, copy=True)
    if T.ndim == 1:
        T = T[:, None]
    if T.ndim != 2:
        raise ValueError(f"Theta must be (n, Q), got shape {T.shape}")
    if not np.all(np.isfinite(T)):
        raise ValueError("Theta has non-finite entries")
    n_clipped = 0
    if nonneg and T.size:
        big = np.abs(T).max()
        if T.min() < -NEG_RTOL * big:
            raise ValueError(
                f"Theta has negative entries (min {T.min():.3e}, max |.| {big:.3e}): "
                "cone compressors need snapshots in W+ (the non-negative orthant)")
        neg = T < 0
        n_clipped = int(neg.sum())
        T[neg] = 0.0
    return T, n_clipped


def _normalise(v: np.ndarray, M: WMetric) -> np.ndarray:
    return v / M.norm(v)


def _greedy(
    Theta: np.ndarray,
    W: Any,
    tol: float,
    r_max: int | None,
    name: str,
    make_generator: Callable[[np.ndarray, ConeGram, dict], np.ndarray],
    post_add: Callable[[np.ndarray, WMetric, dict], np.ndarray] | None = None,
) -> DualBasis:
    """Shared loop of CPG / mCPG / ENG (selection of Benaceur et al.'s "CPG algorithm")."""
    t0 = time.perf_counter()
    M = as_metric(W)
    T, n_clipped = _check_snapshots(Theta)
    n, Q = T.shape
    if n != M.n:
        raise ValueError(f"Theta has {n} rows, W is {M.n} x {M.n}")
    norms = M.norm(T)
    scale = float(norms.max()) if Q else 0.0
    r_max = Q if r_max is None else int(r_max)
    info: dict[str, Any] = {"n": n, "Q": Q, "tol": tol, "r_max": r_max,
                            "clipped_negative": n_clipped, "cond_G": []}
    V = np.zeros((n, 0))
    gram = cone_gram(V, M)
    selected: list[int] = []
    e_proj: list[float] = []
    e_orth: list[float] = []
    if scale == 0.0:
        info["stop"] = "zero_snapshots"
        return DualBasis(V, name, True, selected, e_proj, e_orth, info)
    errs = np.asarray(norms, dtype=float).copy()  # projection errors on {0}
    ep = 1.0
    while True:
        if ep <= tol:
            info["stop"] = "tol"
            break
        if len(selected) >= r_max:
            info["stop"] = "r_max"
            break
        q = int(np.argmax(errs))
        if errs[q] <= EXHAUSTED_RTOL * scale:
            info["stop"] = "exhausted"  # every snapshot is in the cone
            break
        if q in selected:
            info["stop"] = "no_progress"  # numerical: a selected snapshot left the cone
            break
        nu = make_generator(T[:, q], gram, info)
        nrm = M.norm(nu)
        if not nrm > 0:
            info["stop"] = "no_progress"
            break
        nu = nu / nrm
        e_orth.append(float(np.clip(cone_projection(nu, gram=gram)[2], 0.0, 1.0)))
        V = np.column_stack([V, nu])
        if post_add is not None:
            V = post_add(V, M, info)
        gram = cone_gram(V, M)
        _, _, errs = cone_projection(T, gram=gram)
        errs = np.asarray(errs)
        selected.append(q)
        ep = float(errs.max() / scale)
        e_proj.append(ep)
        info["cond_G"].append(gram.cond())
    info["time"] = time.perf_counter() - t0
    return DualBasis(V, name, True, selected, e_proj, e_orth, info)


# ----------------------------------------------------------------------- greedies
def cpg(Theta: np.ndarray, W: Any, tol: float = 1e-3, r_max: int | None = None,
        **options: Any) -> DualBasis:
    """Cone Projected Greedy (Benaceur et al., slide "CPG algorithm" [Benaceur, Ern, Ehrlacher
    2020]).

    Iteration ``r``: select ``q_r = argmax_q ||(I - Pi_{W_{r-1}^+}) theta_q||_W``
    and set ``W_r^+ = Span^+{theta_{q_1}, ..., theta_{q_r}}``; each generator is
    the selected snapshot normalised in ``W`` (no Gram-Schmidt: it would destroy
    positivity). The cones are nested, so ``e_proj`` is non-increasing and every
    selected snapshot is reproduced exactly.

    Parameters
    ----------
    Theta : (n, Q) array, non-negative
        Multiplier snapshots (columns).
    W : metric (see :func:`as_metric`)
    tol : float
        Stop when ``e_proj(r) <= tol`` (``delta_CPG``).
    r_max : int, optional
        At most ``r_max`` generators (default ``Q``).

    Returns
    -------
    DualBasis
        ``info["stop"]`` is ``"tol"``, ``"r_max"``, ``"exhausted"`` (all
        snapshots in the cone to rounding) or ``"no_progress"``.
    """
    if options:
        raise TypeError(f"cpg: unexpected options {sorted(options)}")
    return _greedy(Theta, W, tol, r_max, "cpg", lambda th, gram, info: th)


def _init_qp_counters(info: dict) -> None:
    """The mCPG QP tallies of ``info``, at zero unless already counting."""
    for key, val in (("qp_retries", 0), ("qp_fallbacks", 0), ("qp_min_shrink", 1.0)):
        info.setdefault(key, val)


def _count_qp(status: dict, info: dict) -> bool:
    """Tally QP retries / failures in ``info``; True if the QP was solved."""
    _init_qp_counters(info)
    ok = bool(status["ok"])
    if not ok:
        info["qp_fallbacks"] += 1
    elif status["attempt"] > 0:
        info["qp_retries"] += 1
    info["qp_min_shrink"] = min(info["qp_min_shrink"], status["shrink"])
    return ok


def _mcpg_generator(th: np.ndarray, gram: ConeGram, info: dict) -> np.ndarray:
    _, _, nu, status = mcpg_split(th, gram=gram)
    _count_qp(status, info)
    if nu.min() < 0:
        raise AssertionError("mCPG generator left W+")
    return nu


def mcpg(Theta: np.ndarray, W: Any, tol: float = 1e-3, r_max: int | None = None,
         **options: Any) -> DualBasis:
    """Modified Cone Projected Greedy (Benaceur et al., slide "mCPG algorithm (2/4)").

    Same selection as :func:`cpg`; the new generator is
    ``nu_r = theta_{q_r} - theta_tilde_{r-1}`` (normalised in ``W``), where
    ``theta_tilde_{r-1}`` is the element of ``W_{r-1}^+`` closest to
    ``theta_{q_r}`` such that ``nu_r`` stays in ``W^+`` (:func:`mcpg_split`, an
    exact QP). Since ``theta_{q_r} = nu_r + theta_tilde`` with
    ``theta_tilde in W_{r-1}^+``, the cones are nested and contain the selected
    snapshots, as for CPG, but the generators are "peeled" of what the previous
    cone already explains. Benaceur et al. (slides "(3/4)", "(4/4)") report a wider
    aperture (larger ``e_orth``), better accuracy and a better conditioned
    Gram matrix than CPG; this is an empirical claim, not a theorem (the
    selections of the two greedies differ after the first step).

    Parameters and returns as :func:`cpg`; ``info["qp_fallbacks"]`` counts QP
    solves that failed (then ``nu_r = theta_{q_r}``, the CPG step; none seen
    in our tests, including ``r > n``), ``info["qp_retries"]`` those solved
    only by a retry (shifted Hessian or looser tolerance), and
    ``info["qp_min_shrink"]`` the smallest feasibility scaling (see
    :func:`mcpg_split`).
    Requires the ``daqp`` package.
    """
    if options:
        raise TypeError(f"mcpg: unexpected options {sorted(options)}")
    basis = _greedy(Theta, W, tol, r_max, "mcpg", _mcpg_generator)
    _init_qp_counters(basis.info)
    return basis


def _peel_all(V: np.ndarray, M: WMetric, info: dict, sweeps: int,
              min_gain: float) -> np.ndarray:
    """ENG enlargement: replace each generator by its mCPG residual against the others."""
    V = V.copy()
    R = V.shape[1]
    n_rep = 0
    for _ in range(sweeps):
        changed = 0
        for i in range(R):
            others = np.delete(V, i, axis=1)
            _, tt, nu, status = mcpg_split(V[:, i], gram=cone_gram(others, M))
            if not _count_qp(status, info):
                continue
            # v_i = nu + tt, tt in Span+(others): replacing v_i by nu can only
            # enlarge the cone. Skip negligible peels, and near-total ones
            # (v_i almost inside the others' cone: nu would be rounding noise).
            if M.norm(tt) <= min_gain or M.norm(nu) <= 1e-8:
                continue
            V[:, i] = _normalise(nu, M)
            changed += 1
        n_rep += changed
        if not changed:
            break
    info["peel_replacements"] = info.get("peel_replacements", 0) + n_rep
    return V


def eng(Theta: np.ndarray, W: Any, tol: float = 1e-3, r_max: int | None = None,
        *, sweeps: int = 1, min_gain: float = 1e-10, **options: Any) -> DualBasis:
    """Enlarged Nonnegative Greedy: CPG selection + mCPG peeling of *all* generators.

    Benaceur et al. (slide "mCPG algorithm (3/4)") only name ENG [Bakhta, Boiveau,
    Maday & Mula 2020] as the idea of building progressively a cone of wider
    aperture inside ``W^+``; the paper's algorithm was not available to us.
    What is implemented here is our design, built on one elementary fact:

        if ``v_i = nu + theta_tilde`` with ``nu >= 0`` and
        ``theta_tilde in Span^+(other generators)``, then replacing ``v_i`` by
        ``nu`` gives a cone that contains the old one (``v_i`` is still in it)
        and stays in ``W^+``.

    Iteration ``r``:

    1. select ``q_r`` as in CPG/mCPG (worst projected snapshot);
    2. add ``nu_r`` = mCPG residual of ``theta_{q_r}`` against the current cone
       (exactly the mCPG step; ``e_orth(r)`` is measured on this ``nu_r``);
    3. *enlarge*: for ``i = 1..r`` (``sweeps`` passes), replace ``v_i`` by its
       mCPG residual against the cone of the other ``r - 1`` generators
       (:func:`mcpg_split`), normalised. By the fact above each replacement
       enlarges the cone, so the cones remain nested across iterations
       (``e_proj`` non-increasing), keep every selected snapshot exactly, and
       keep non-negative generators.

    Difference from CPG / mCPG: CPG keeps raw snapshots (narrowest cone, Gram
    matrix close to singular for similar snapshots); mCPG peels only the new
    generator against the *previous* cone, so early generators stay raw
    snapshots and the cone is never revisited; ENG peels every generator
    against all the others each time one is added, so older generators also
    shed what newer ones explain. For the same selected snapshots the ENG
    cone contains the mCPG cone; generators become closer to extreme rays
    (more localised, less correlated: better-conditioned Gram matrix). The
    price: ``r`` extra small QPs per iteration, and a cone that may contain
    directions far from the snapshots (to be checked against the inf-sup
    stability of the reduced problem).

    Parameters
    ----------
    Theta, W, tol, r_max : as :func:`cpg`
    sweeps : int
        Enlargement passes over all generators per iteration (default 1).
    min_gain : float
        Skip a replacement when the peeled part ``||theta_tilde||_W`` (of a
        unit generator) is below this.

    Returns
    -------
    DualBasis
        ``info["peel_replacements"]`` counts generator replacements.
    """
    if options:
        raise TypeError(f"eng: unexpected options {sorted(options)}")

    def post(V: np.ndarray, M: WMetric, info: dict) -> np.ndarray:
        return _peel_all(V, M, info, sweeps, min_gain) if V.shape[1] > 1 else V

    basis = _greedy(Theta, W, tol, r_max, "eng", _mcpg_generator, post)
    _init_qp_counters(basis.info)
    basis.info.setdefault("peel_replacements", 0)
    basis.info["sweeps"] = sweeps
    return basis


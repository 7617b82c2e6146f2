"""Training and validation parameter sets.

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric variational
inequalities" (talk), slide "Finite training set and snapshots".

:func:`parameter_set` draws ``D_train`` or ``D_valid`` inside the closed
parameter domain ``D`` of a scene, honouring the scene's ``[sampling]`` table
(``train``/``n_train``, ``valid``/``n_valid``, ``seed``). Three kinds:

* ``"uniform"``: tensor grid, endpoints included (deterministic, no seed);
* ``"random"``: i.i.d. uniform draws;
* ``"lhs"``: Latin hypercube (own implementation): on every axis, each of the
  ``n`` equal strata holds exactly one point.

Training and validation draw from different random streams of the same seed
(``default_rng((seed, 0))`` and ``default_rng((seed, 1))``), so with the same
kind and size the two sets still differ. A ``"uniform"`` grid ignores ``seed``:
a uniform validation set of the same size as a uniform training set is the
same grid.
"""

from __future__ import annotations

import logging
from typing import Any

import numpy as np

__all__ = ["KINDS", "latin_hypercube", "parameter_set", "uniform_count", "uniform_grid"]

KINDS = ("uniform", "random", "lhs")
_STREAM = {"train": 0, "valid": 1}

log = logging.getLogger(__name__)


def uniform_count(n: int, p: int) -> tuple[int, int]:
    """Points per axis ``k = max(1, round(n**(1/p)))`` and the actual count ``k**p``."""
    if n < 1 or p < 1:
        raise ValueError(f"need n >= 1 and p >= 1, got n = {n}, p = {p}")
    k = max(1, int(round(n ** (1.0 / p))))
    if (k + 1) ** p <= n:  # guard against n**(1/p) rounding down (e.g. 64**(1/3))
        k += 1
    return k, k**p


def uniform_grid(bounds: np.ndarray, n: int) -> np.ndarray:
    """Tensor grid of ``k**p`` points, ``k = round(n**(1/p))`` per axis, endpoints included.

    With ``k = 1`` the single point per axis is the midpoint. Rows are ordered
    with the last parameter varying fastest.
    """
    bounds = np.asarray(bounds, dtype=float)
    p = bounds.shape[0]
    k, _ = uniform_count(n, p)
    axes = [np.array([0.5 * (lo + hi)]) if k == 1 else np.linspace(lo, hi, k)
            for lo, hi in bounds]
    mesh = np.meshgrid(*axes, indexing="ij")
    return np.stack([m.ravel() for m in mesh], axis=1)


def latin_hypercube(bounds: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """Latin hypercube of ``n`` points: on each axis every stratum ``[j/n, (j+1)/n)`` of the
    (scaled) range holds exactly one point; strata are paired by independent permutations and
    each point is uniform within its cell (McKay, Beckman, Conover 1979)."""
    bounds = np.asarray(bounds, dtype=float)
    p = bounds.shape[0]
    unit = np.empty((n, p))
    for j in range(p):
        unit[:, j] = (rng.permutation(n) + rng.random(n)) / n
    return _scale(unit, bounds)


def _scale(unit: np.ndarray, bounds: np.ndarray) -> np.ndarray:
    lo, hi = bounds[:, 0], bounds[:, 1]
    return np.clip(lo + unit * (hi - lo), lo, hi)  # clip: rounding may not leave D


def parameter_set(scene: Any, which: str = "train", n: int | None = None,
                  kind: str | None = None, seed: int | None = None) -> np.ndarray:
    """A training or validation set inside the closed domain of ``scene``.

    Parameters
    ----------
    scene : Scene
        Provides ``bounds`` (p x 2) and the defaults in ``scene.data["sampling"]``.
    which : {"train", "valid"}
        Which set; selects the defaults and the random stream.
    n : int, optional
        Requested size (default ``n_train`` / ``n_valid``). For ``"uniform"`` the
        actual size is ``k**p`` with ``k = round(n**(1/p))`` points per axis (e.g.
        ``n = 20, p = 2`` gives ``4 x 4 = 16``); the rows of the result are the truth.
    kind : {"uniform", "random", "lhs"}, optional
        Default ``train`` / ``valid`` of the scene.
    seed : int, optional
        Default the scene's ``seed``. The generator is ``default_rng((seed, s))`` with
        ``s = 0`` for training and ``1`` for validation.

    Returns
    -------
    ndarray (n, p)
        One parameter point per row, every one inside ``D`` (bounds included).
    """
    if which not in _STREAM:
        raise ValueError(f"which = {which!r}: expected 'train' or 'valid'")
    sampling = scene.data.get("sampling", {})
    kind = kind if kind is not None else sampling.get(which, "uniform")
    n = int(n if n is not None else sampling.get(f"n_{which}", 21))
    seed = int(seed if seed is not None else sampling.get("seed", 0))
    if kind not in KINDS:
        raise ValueError(f"kind = {kind!r}: expected one of {', '.join(KINDS)}")
    if n < 1:
        raise ValueError(f"n = {n}: need at least one point")
    if seed < 0:
        raise ValueError(f"seed = {seed}: expected a non-negative integer")
    bounds = np.asarray(scene.bounds, dtype=float)
    if kind == "uniform":
        mus = uniform_grid(bounds, n)
        if mus.shape[0] != n:
            log.warning("scene %s: uniform %s set: %d points requested, %d = %d^%d used (a "
                        "tensor grid)", getattr(scene, "name", "?"), which, n, mus.shape[0],
                        uniform_count(n, bounds.shape[0])[0], bounds.shape[0])
        return mus
    rng = np.random.default_rng((seed, _STREAM[which]))
    if kind == "random":
        return _scale(rng.random((n, bounds.shape[0])), bounds)
    return latin_hypercube(bounds, n, rng)

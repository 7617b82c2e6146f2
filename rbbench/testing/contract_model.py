"""Contract of the model interface (:class:`rbbench.interfaces.Model`): what the HF model and
every reduced model must satisfy for the benchmark to compare them.

:func:`check_reduced_model` runs it on a built model and a few parameters of its domain: the
common fields of every solution, the HF vectors of ``reconstruct``, repeatability, the same
solutions after a pickle round trip, and the same refusal of a parameter outside D as the
HF solve's (:class:`~rbbench.scene.parameters.SceneError` naming the parameter). Imports
neither pytest nor a backend.
"""

from __future__ import annotations

import pickle
from collections.abc import Iterable
from typing import Any

import numpy as np

from rbbench.interfaces import HFVectors, Model, Solution
from rbbench.scene.parameters import SceneError
from rbbench.testing.contract_base import ContractViolation, require

__all__ = ["REPEAT_RTOL", "check_reduced_model"]

#: relative difference allowed between two solves at the same mu (same process, or after a
#: pickle round trip): round-off of one deterministic computation
REPEAT_RTOL = 1e-12


def _close(a: np.ndarray, b: np.ndarray) -> bool:
    a, b = np.asarray(a, float), np.asarray(b, float)
    if a.shape != b.shape:
        return False
    scale = max(float(np.abs(a).max(initial=0.0)), float(np.abs(b).max(initial=0.0)))
    return float(np.abs(a - b).max(initial=0.0)) <= REPEAT_RTOL * scale


def _check_solution(name: str, model: Any, sol: Any, mu: np.ndarray) -> None:
    where = f"{name}.solve({mu.tolist()})"
    require(isinstance(sol, Solution), f"{where}: returned {type(sol).__name__}, which lacks "
            "the common fields of rbbench.interfaces.Solution (mu, u, lam, iterations, "
            "stop_reason, time_s)")
    require(np.array_equal(np.asarray(sol.mu, float).ravel(), mu),
            f"{where}: solution.mu = {np.asarray(sol.mu).tolist()}, not the checked mu")
    for field in ("u", "lam"):
        require(isinstance(getattr(sol, field), np.ndarray),
                f"{where}: solution.{field} is not an ndarray")
    require(isinstance(sol.iterations, (int, np.integer)) and sol.iterations >= 0,
            f"{where}: iterations = {sol.iterations!r} (an integer >= 0)")
    require(isinstance(sol.stop_reason, str) and sol.stop_reason,
            f"{where}: stop_reason = {sol.stop_reason!r} (a non-empty string)")
    require(isinstance(sol.time_s, float) and np.isfinite(sol.time_s) and sol.time_s > 0,
            f"{where}: time_s = {sol.time_s!r} (a finite time > 0, s)")
    if sol.stop_reason.startswith("converged"):
        require(np.all(np.isfinite(sol.u)) and np.all(np.isfinite(sol.lam)),
                f"{where}: converged with non-finite u or lam")


def _check_vectors(name: str, hf: Any, mu: np.ndarray, sizes: dict[str, Any]) -> None:
    where = f"{name}.reconstruct(solution at {mu.tolist()})"
    require(isinstance(hf, HFVectors), f"{where}: returned {type(hf).__name__}, not HFVectors")
    for field in ("u", "lam", "lam_t"):
        v = getattr(hf, field)
        if v is None and field == "lam_t":
            shape = None
        else:
            require(isinstance(v, np.ndarray) and v.ndim == 1,
                    f"{where}: {field} is not a 1-D ndarray")
            require(bool(np.all(np.isfinite(v))), f"{where}: {field} has non-finite entries")
            shape = v.shape
        require(sizes.setdefault(field, shape) == shape,
                f"{where}: {field} has shape {shape}, {sizes[field]} at another mu")
    require(hf.u.size > 0, f"{where}: an empty displacement")


def _outside(parameters: Any) -> np.ndarray:
    """A parameter just outside the closed box D (the first one above its upper bound)."""
    mu = np.asarray(parameters.bounds, float).mean(axis=1)
    lo, hi = parameters.low[0], parameters.high[0]
    mu[0] = hi + max(hi - lo, abs(hi), 1.0)
    return mu


def check_reduced_model(model: Any, mus: Iterable[Any], name: str | None = None,
                        pickled: bool = True) -> None:
    """Check ``model`` against the model interface at the parameters ``mus`` (in D).

    Parameters
    ----------
    model : Model
        A built model (HF or reduced).
    mus : iterable of array_like
        Parameters inside the model's domain (one or two suffice; each is solved about four
        times).
    name : str, optional
        The model's name in the messages (default: its class name).
    pickled : bool
        Also check that a pickled copy solves the same (every model of the benchmark is
        picklable; a copy rebuilds what it dropped, e.g. the HF components of a plain model).

    Raises
    ------
    ContractViolation
        Naming the model and the property that fails: the protocol's members, the common
        fields of the solution, the HF vectors of ``reconstruct``, repeatability to
        :data:`REPEAT_RTOL`, the pickle round trip, or the refusal of a parameter outside
        D (a :class:`~rbbench.scene.parameters.SceneError` naming the parameter).
    """
    name = name or type(model).__name__
    require(isinstance(model, Model), f"{name}: not a rbbench.interfaces.Model (it needs "
            "parameters, solve(mu) and reconstruct(solution))")
    ps = model.parameters
    require(ps is not None and hasattr(ps, "check"),
            f"{name}: parameters is {ps!r}, not a ParameterSpace")
    mus = [ps.check(mu).copy() for mu in mus]
    require(len(mus) > 0, f"{name}: no parameter given")
    clone = pickle.loads(pickle.dumps(model)) if pickled else None
    sizes: dict[str, Any] = {}
    for mu in mus:
        sol = model.solve(mu)
        _check_solution(name, model, sol, mu)
        hf = model.reconstruct(sol)
        _check_vectors(name, hf, mu, sizes)
        again = model.solve(mu)
        require(_close(again.u, sol.u) and _close(again.lam, sol.lam),
                f"{name}: two solves at {mu.tolist()} differ beyond {REPEAT_RTOL:g} (relative)")
        if clone is not None:
            other = clone.solve(mu)
            require(_close(other.u, sol.u) and _close(other.lam, sol.lam)
                    and _close(clone.reconstruct(other).u, hf.u),
                    f"{name}: the pickled copy solves {mu.tolist()} differently")
    bad = _outside(ps)
    try:
        model.solve(bad)
    except SceneError as exc:
        require(ps.names[0] in str(exc), f"{name}: the error for {bad.tolist()} outside D "
                f"does not name the parameter {ps.names[0]!r}: {exc}")
    else:
        raise ContractViolation(f"{name}: solve({bad.tolist()}) outside D did not raise a "
                                "SceneError")
    try:
        model.solve(np.append(mus[0], mus[0][:1]))
    except SceneError:
        pass
    else:
        raise ContractViolation(f"{name}: solve with {ps.dim + 1} values for {ps.dim} "
                                "parameter(s) did not raise a SceneError")

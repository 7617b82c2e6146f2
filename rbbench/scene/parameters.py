"""The parameter domain D of a scene, small and picklable: what every model checks mu against.

Every model (:class:`rbbench.interfaces.Model`: the HF model and each reduced model) holds one
as ``parameters`` and calls :meth:`ParameterSpace.check` in ``solve(mu)`` (pyMOR's
``Model.solve(mu)`` parses mu the same way), so a reduced model rejects what the HF solve
rejects.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np


class SceneError(ValueError):
    """A scene file or override is invalid; the message says where and what is valid."""


class FieldError(SceneError):
    """A value that a named field (a reduction option) does not take.

    ``where``: whose field (e.g. the formulation), ``field``, ``value``, ``rule``: what is
    valid. :meth:`message` shows the field by a function of its name (the command line:
    its flag).
    """

    def __init__(self, where: str, field: str, value: object, rule: str) -> None:
        self.where, self.field, self.value, self.rule = where, field, value, rule
        super().__init__(self.message(str))

    def message(self, show: Callable[[str], str]) -> str:
        """The message with the field's name shown by ``show``."""
        head = f"{self.where}: " if self.where else ""
        return f"{head}{show(self.field)} = {self.value!r}: {self.rule}"


@dataclass(frozen=True)
class ParameterSpace:
    """The box ``D = prod_i [low_i, high_i]`` (closed), with names and units.

    ``where`` and ``scene`` (the scene file and name) only serve the error messages.
    """

    names: tuple[str, ...]
    low: tuple[float, ...]
    high: tuple[float, ...]
    units: tuple[str, ...] = ()
    where: str = "<scene>"
    scene: str = ""

    @property
    def dim(self) -> int:
        return len(self.names)

    @property
    def bounds(self) -> np.ndarray:
        """``(p, 2)`` array of ``[low, high]`` rows."""
        return np.array([self.low, self.high], dtype=float).T.reshape(self.dim, 2)

    def _domains(self) -> str:
        return ", ".join(f"{n} in [{lo:g}, {hi:g}]"
                         for n, lo, hi in zip(self.names, self.low, self.high, strict=True))

    def _as_array(self, mu: Any) -> np.ndarray:
        """``mu`` (numbers, or a dict by parameter name) as a flat float array, or
        :class:`SceneError` saying what to give."""
        if isinstance(mu, dict):
            unknown = sorted(map(str, set(mu) - set(self.names)))
            missing = [n for n in self.names if n not in mu]
            if unknown or missing:
                raise SceneError(f"{self.where}: mu given by name needs exactly the "
                                 f"parameters of scene {self.scene!r} ({self._domains()}); "
                                 f"unknown: {unknown or 'none'}, missing: {missing or 'none'}")
            mu = [mu[n] for n in self.names]
        try:
            arr = np.asarray(mu)
        except ValueError:  # ragged nesting
            arr = np.empty(0, dtype=object)
        if arr.dtype.kind not in "iuf":  # strings, bools, objects: not numbers
            raise SceneError(f"{self.where}: mu = {mu!r}: give {self.dim} number(s) "
                             f"({self._domains()}), or a dict of them by name")
        return np.atleast_1d(arr.astype(float)).ravel()

    def check(self, mu: Any) -> np.ndarray:
        """``mu`` as a float array of length :attr:`dim`, or :class:`SceneError` naming the
        parameter and its domain (wrong count, non-finite, or outside D).

        A 1-D float64 array inside D is returned as it is (no copy): the check costs well
        under a microsecond, so the online solves of the reduced models keep it.
        """
        if type(mu) is np.ndarray and mu.dtype == np.float64 and mu.ndim == 1:
            arr = mu
        else:
            arr = self._as_array(mu)
        if arr.size == len(self.low):
            for x, lo, hi in zip(arr.tolist(), self.low, self.high, strict=True):
                if not lo <= x <= hi:  # NaN fails too: the messages below name it
                    break
            else:
                return arr
        if arr.size != self.dim:
            raise SceneError(
                f"{self.where}: scene {self.scene!r} has {self.dim} parameter(s) "
                f"({self._domains()}); got {arr.size} value(s): {arr.tolist()}"
            )
        units = self.units or ("",) * self.dim
        for value, name, lo, hi, unit in zip(arr, self.names, self.low, self.high, units,
                                             strict=True):
            if not np.isfinite(value) or value < lo or value > hi:  # D is closed
                raise SceneError(
                    f"{self.where}: parameter {name} = {float(value):g} is outside its domain "
                    f"[{lo:g}, {hi:g}]{' ' + unit if unit else ''}"
                )
        return arr

"""A backend plugin: a registered backend wrapped so that a repeated ``mu`` is discretized
once (the inner backend is any registered one, ``skfem`` by default)."""

from __future__ import annotations

from typing import Any

import numpy as np

from rbbench.plugin import Backend, ComponentSpec, Discretization, hookimpl


class CachedBackend(Backend):
    """The discretizations of a registered backend, kept per (``mu``, ``needs``)."""

    name = "cached-skfem"

    def __init__(self, scene: Any, inner: str = "skfem", **options: Any) -> None:
        from rbbench.registry import default_registry

        self.inner = default_registry().create("backend", inner, scene=scene, **options)
        self.cache: dict[tuple, Discretization] = {}

    def discretize(self, mu: np.ndarray | float,
                   needs: frozenset[str] = frozenset()) -> Discretization:
        key = (tuple(np.atleast_1d(np.asarray(mu, dtype=float)).tolist()), frozenset(needs))
        if key not in self.cache:
            self.cache[key] = (self.inner.discretize(mu, needs=needs) if needs
                               else self.inner.discretize(mu))
        return self.cache[key]

    def warm_up(self) -> None:
        self.inner.warm_up()

    def inner_product(self) -> Any:
        """The inner backend's ``X`` (the RB pipeline asks the backend for it)."""
        return self.inner.inner_product()


@hookimpl
def rbbench_register(registry):
    registry.add(ComponentSpec(
        name="cached-skfem", role="backend", target="cached_backend:CachedBackend",
        modules=("skfem",),
        capabilities={"physics": ("elasticity", "poisson"), "degree": (1, 2),
                      "friction": ("none",)},
        description="the skfem backend, each (mu, needs) discretized once",
    ))

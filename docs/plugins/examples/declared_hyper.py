"""A hyper-reducer plugin: the declaration of a hyper-reducer that the offline steps of a
formulation (here a plugin formulation named ``my-formulation``) carry out."""

from __future__ import annotations

from rbbench.plugin import ComponentSpec, HyperReducer, hookimpl


class GappyPOD(HyperReducer):
    """Gappy POD of the contact rows (carried out by ``my-formulation``'s steps, which read
    ``config.hyper``)."""

    name = "gappy-pod"
    formulations = ("my-formulation",)
    approximates = "the reduced contact rows, from a few sampled rows"


@hookimpl
def rbbench_register(registry):
    registry.add(ComponentSpec(
        name="gappy-pod", role="hyper", target="declared_hyper:GappyPOD",
        capabilities={"formulations": ("my-formulation",)},
        description="gappy POD of the contact rows (my-formulation)",
    ))

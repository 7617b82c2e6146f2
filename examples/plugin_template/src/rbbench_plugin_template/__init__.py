"""A template rbbench plugin: one dual compressor, ``random-cone``.

This module is what the ``rbbench`` entry point names. It only declares the component
(name, role, import target, capabilities): rbbench imports the target,
:mod:`rbbench_plugin_template.random_cone`, when a run uses it, so importing this module
stays cheap (no numpy).
"""

from rbbench.plugin import ComponentSpec, hookimpl

__version__ = "0.1.0"


@hookimpl
def rbbench_register(registry):
    """Declare the package's components (called once by rbbench's plugin discovery)."""
    registry.add(ComponentSpec(
        name="random-cone",
        role="dual",
        target="rbbench_plugin_template.random_cone:RandomCone",
        # what the dual contract checks: a cone (non-negative generators), nested in R
        capabilities={"cone": True, "nested": True},
        description="snapshots drawn at random (seeded) as cone generators: the baseline "
                    "that shows what the greedy selection of cpg / mcpg buys",
    ))

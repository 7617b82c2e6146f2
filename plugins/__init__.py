"""Built-in rbbench plugins, registered through the ``rbbench`` entry point.

Declarations only: nothing heavy is imported here. Each target module is
imported when a run uses it.
"""

from rbbench.hookspecs import hookimpl
from rbbench.registry import ComponentSpec

_ALL_PHYSICS = ("elasticity", "poisson")


@hookimpl
def rbbench_register(registry):
    add = registry.add
    add(ComponentSpec(
        name="skfem", role="backend",
        target="rbbench_plugins.backends.skfem_backend:SkfemBackend",
        modules=("skfem",),
        capabilities={"physics": _ALL_PHYSICS, "degree": (1, 2),
                      "multiplier": ("lac", "p0", "p1", "nodal"), "friction": ("none",)},
        description="scikit-fem: graded triangle meshes, P1/P2, GPTS contact pairing",
    ))
    add(ComponentSpec(
        name="mixed", role="formulation",
        target="rbbench_plugins.formulations.mixed:MixedFormulation",
        capabilities={"physics": _ALL_PHYSICS, "solvers": ("ssn", "uzawa")},
        description="Lagrange multipliers: A u + B^T lam = F, 0 <= lam _|_ G - B u >= 0",
    ))
    add(ComponentSpec(
        name="ssn", role="solver",
        target="rbbench_plugins.solvers.condensed:SemismoothNewtonSolver",
        capabilities={"formulations": ("mixed",)},
        description="primal-dual active set (semismooth Newton) on the condensed contact LCP",
    ))
    add(ComponentSpec(
        name="uzawa", role="solver",
        target="rbbench_plugins.solvers.condensed:UzawaSolver",
        capabilities={"formulations": ("mixed",)},
        description="Uzawa projected dual iteration (seed 000 baseline), condensed",
    ))

"""The mixed friction model's offline steps (the plain reduced model).

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slides "Plain RBM", "Preliminaries", "Greedy Collocation
Node Selection (GCNS)".
After the primal space V_N (shared skeleton, :mod:`rbbench.rb.offline`; POD of u):

1. the normal cone ``W_R^n = Span+(Vn)`` of the lam_n snapshots (a registered dual
   compressor, mCPG by default) and the tangential space ``X_S = span(Vt)``, the POD of
   the lam_t snapshots (:func:`tangential_pod`, ``S`` modes, default ``S = R``), both in
   the L2(Gamma_c) Gram matrix ``Wt`` of the nodal multipliers at the default mu;
2. a stabiliser of the combined form ``b = b^n + b^tau`` (``none``; ``pga``: the registered
   PGA on ``B = [Bn; Bt]`` against ``blockdiag(Vn, Vt)``);
3. GCNS (:func:`rbbench.rb.algorithms.gcns.gcns`) picks the collocation nodes of the tangential
   constraint on the training set;
4. the online stage: plain (hyper ``none``), the HF operators at mu projected on the bases
   (:func:`rbbench.rb.friction.collocation.model.project_friction`, its time included in the
   online time), or hyper-reduced (hyper ``eim``: the friction EIM and the affine ``A_N``,
   ``F_N``, :mod:`rbbench.rb.friction.collocation.hyper`; the wedge model's:
   :mod:`rbbench.rb.friction.wedge.hyper`), then the small Coulomb solve
   (:class:`rbbench.rb.friction.collocation.model.FrictionReducedModel`).

These steps are Benaceur et al.'s model, the collocation model
(:class:`rbbench.rb.friction.collocation.stage.FrictionStage`, ``friction_dual = "collocation"``;
the default ``auto`` takes it on Tresca scenes). ``friction_dual = "wedge"`` selects our
alternative (the default ``auto`` on Coulomb scenes, :func:`resolve_auto`)
(:class:`rbbench.rb.friction.wedge.stage.WedgeStage`): cones of ``F lam_n +- lam_t`` in
place of steps 1 and 3 (the Coulomb cone at every HF node, no GCNS) and De Saxce's fixed
point online (:mod:`rbbench.rb.friction.wedge.model`). The choice is read from the ReduceConfig
(:func:`friction_dual`).
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from rbbench.rb.compressors import is_online
from rbbench.rb.config import ReduceConfig
from rbbench.rb.friction.collocation.stage import FrictionStage
from rbbench.rb.friction.options import AUTO, FrictionOptions
from rbbench.rb.friction.wedge.stage import WedgeStage
from rbbench.rb.offline import fixed_contact_points
from rbbench.registry import Registry
from rbbench.scene.loading import Scene, SceneError

__all__ = ["FrictionReduction", "resolve_auto"]


def resolve_auto(scene: Scene, config: ReduceConfig) -> ReduceConfig:
    """``friction_dual = "auto"``: the wedge model on a Coulomb scene, the collocation model
    on a Tresca scene; with the wedge model, hyper ``auto`` becomes the friction EIM when the
    scene's contact points are fixed (else the plain model). The choice measured best on the
    published case (errors near the floors, the Coulomb cone at every node, an online stage
    independent of the mesh)."""
    options = config.options
    if options.friction_dual != AUTO:
        return config
    law = scene.data.get("friction", {}).get("law", "coulomb")
    dual = "wedge" if law == "coulomb" else "collocation"
    hyper = config.hyper
    if dual == "wedge" and hyper == "auto":
        hyper = "eim" if fixed_contact_points(scene, "auto") else "none"
    return replace(config, hyper=hyper, options=replace(options, friction_dual=dual))


class FrictionReduction:
    """The mixed friction model's steps in the offline skeleton (``reduction(friction=...)``
    of the mixed formulation)."""

    name = "mixed-friction"
    label = "the mixed formulation on friction scenes"
    friction_laws = ("tresca", "coulomb")
    Options = FrictionOptions

    def prepare(self, scene: Scene, config: ReduceConfig, registry: Registry) -> ReduceConfig:
        """Checks before any HF work: the named components exist, the stage's choices."""
        options = config.options
        registry.get("primal", config.primal)
        registry.get("dual", options.dual)
        registry.get("stabilizer", options.stabilizer)
        config = resolve_auto(scene, config)
        options = config.options
        wedge = options.friction_dual == "wedge"
        if config.hyper not in ("auto", "none", "eim"):
            raise SceneError(f"{scene.path}: hyper {config.hyper!r}: the reduced friction "
                             "models take hyper 'none' / 'auto' (plain) or 'eim' (the "
                             "friction EIM)")
        if config.hyper == "eim":
            fixed_contact_points(scene, "eim")
        if is_online(registry, options.stabilizer):
            raise SceneError(f"{scene.path}: stabilizer {options.stabilizer!r} builds its "
                             "space online from the HF B(mu): the reduced friction model takes "
                             "an offline stabiliser ('none', 'pga', or a plugin's declaring "
                             "online_hf = False)")
        if scene.data.get("friction", {}).get("coefficient_law"):
            raise SceneError(f"{scene.path}: a slip-dependent friction coefficient (model B) "
                             "has no reduced model")
        if wedge and \
                scene.data.get("friction", {}).get("law", "coulomb") != "coulomb":
            raise SceneError(f"{scene.path}: the wedge dual model is Coulomb's cone; Tresca "
                             "takes the collocation model (friction_dual = 'collocation')")
        return config

    def reduce(self, ctx: Any) -> FrictionStage:
        if ctx.options.friction_dual == "wedge":
            return WedgeStage(ctx)
        return FrictionStage(ctx)

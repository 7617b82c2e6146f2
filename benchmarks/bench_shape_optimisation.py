"""asv: the reduced-basis-driven shape optimisation of ``shape_coulomb`` on a small body mesh.

:func:`rbbench.optim.rb_driver.optimize_rb` (the trust region of reduced models behind
``rbbench optimize shape_coulomb --driver rb --strategy none``) from the scene's initial
design on :data:`SHAPE_CASES`: model B with its 81 contact nodes (the design) and a body
of ``geometry.ny`` element rows (10: 1,782 dofs; the shipped 40: 6,642 dofs), and one
reduced evaluation (state + subgradient) at the initial design with the interior space
of the HF factors there. One BLAS thread (the study ``rbbench studies shape-side-by-side``
measures the HF-driven run beside it).
"""

from rbbench.optim.rb_driver import RBOptions, optimize_rb
from rbbench.optim.shape_adjoint import evaluate
from rbbench.optim.shape_reduced import ReducedModel, interior_space, state_vector
from rbbench.optim.shape_scene import load_shape_scene
from rbbench.runtime.threads import one_blas_thread

from ._common import TIMEOUT

#: body meshes of the suite: ``geometry.ny`` (element rows), the contact nodes kept
SHAPE_CASES = ["ny10", "ny40"]


def shape_scene(case: str):
    """The ``shape_coulomb`` scene of ``case`` (``ny<rows>``)."""
    return load_shape_scene("shape_coulomb", {"geometry.ny": int(case.removeprefix("ny"))})


class ShapeRBDriver:
    """The RB-driven optimisation from the initial design (``RBOptions()`` defaults: the
    HF state and adjoint added to the basis at each new centre); the HF solves it needs
    and its ``J`` relative to the uniform-pressure bound are tracked beside the time."""

    params = (SHAPE_CASES,)
    param_names = ["mesh"]
    timeout = TIMEOUT
    number = 1
    repeat = (1, 3, 60.0)

    def setup(self, mesh):
        self.sc = shape_scene(mesh)
        self.alpha0 = self.sc.initial_design()
        self._result = None

    def _run(self):
        with one_blas_thread():
            return optimize_rb(self.sc, self.alpha0, RBOptions())

    def _tracked(self):
        """The run the ``track_`` benchmarks read (one run per setup)."""
        if self._result is None:
            self._result = self._run()
        return self._result

    def time_rb_driven_optimisation(self, mesh):
        """Wall time (s) of one RB-driven run (HF centres, reduced bundle runs, updates)."""
        self._run()

    def track_hf_solves(self, mesh):
        """HF state solves of the RB-driven run (the start included)."""
        return float(self._tracked().hf_solves)

    track_hf_solves.unit = "solves"

    def track_J_over_bound(self, mesh):
        """HF-verified J at the RB optimum over the uniform-pressure bound (>= 1)."""
        return float(self._tracked().J_hf / self.sc.uniform_pressure_bound())

    track_J_over_bound.unit = "ratio"


class ShapeReducedEvaluation:
    """One reduced evaluation (state by the semismooth Newton on the reduced Schur
    complement, objective, subgradient) at the initial design, warm-started from the HF
    state there, with the interior space of the HF factors at that design (N = 162)."""

    params = (SHAPE_CASES,)
    param_names = ["mesh"]
    timeout = TIMEOUT

    def setup(self, mesh):
        sc = shape_scene(mesh)
        self.alpha = sc.initial_design()
        with one_blas_thread():
            ev = evaluate(sc, self.alpha)
            self.model = ReducedModel(sc)
            self.model.enrich(interior_space(sc, ev.state))
        self.y0 = state_vector(ev.state)

    def time_reduced_evaluation(self, mesh):
        """Wall time (s) of one reduced state + subgradient evaluation, one BLAS thread."""
        with one_blas_thread():
            self.model.evaluate(self.alpha, y0=self.y0)

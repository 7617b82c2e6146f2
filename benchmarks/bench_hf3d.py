"""asv: the 3D HF solve (``hertz_sphere``, two quarter hemispheres), time, memory and
accuracy against 3D Hertz, on both backends."""

from rbbench.hf.components import make_components
from rbbench.hf.model import solve_hf
from rbbench.scene.loading import load_scene

from ._common import TIMEOUT, finite

#: the level-0 mesh (the scene's default is level 1)
LEVEL0 = ["discretization.level=0"]


class HFSolve3D:
    """One mixed 3D HF solve of ``hertz_sphere`` (level 0, P1, about 5e3 dofs) at mu = 1,
    meshing excluded (``setup`` builds the components; the reference mesh is kept on disk
    after its first build): discretise (stiffness, 3D pairing), condense, solve with
    ``ssn``, compute the summary metrics."""

    params = (["skfem", "ngsolve"],)
    param_names = ["backend"]
    timeout = TIMEOUT
    repeat = (1, 5, 20.0)

    def setup(self, backend):
        self.scene = load_scene("hertz_sphere", overrides=LEVEL0)
        self.components = make_components(self.scene, backend=backend, solver="ssn")

    def time_hf_solve_3d(self, backend):
        """Wall time (s) of ``solve_hf`` at mu = 1 on the level-0 mesh."""
        sol = solve_hf(self.scene, 1.0, solver="ssn", components=self.components)
        if not sol.result.converged:
            raise RuntimeError(f"hertz_sphere/{backend}: HF solve did not converge "
                               f"({sol.result.stop_reason})")

    def peakmem_hf_solve_3d(self, backend):
        """Peak resident memory (bytes) of the process around one 3D HF solve (asv's
        process maximum, a constant base included)."""
        solve_hf(self.scene, 1.0, solver="ssn", components=self.components)


class HertzAccuracy3D:
    """Signed relative errors against 3D Hertz at the computed force (``hertz`` block of
    the summary), level 0, mu = 1, scikit-fem: a (quantised to LAC patches) and p0 (the
    peak multiplier); tracked as absolute values."""

    timeout = TIMEOUT

    def setup_cache(self):
        m = solve_hf(load_scene("hertz_sphere", overrides=LEVEL0), 1.0).metrics["hertz"]
        return {"a": abs(m["a_rel_error"]), "p0": abs(m["p0_rel_error"])}

    def track_a_rel_error(self, cache):
        """|a_rel_error| of the contact radius (fraction, not %)."""
        return finite(cache["a"], "|a_rel_error|")

    def track_p0_rel_error(self, cache):
        """|p0_rel_error| of the peak pressure (fraction, not %)."""
        return finite(cache["p0"], "|p0_rel_error|")

    track_a_rel_error.unit = "relative"
    track_p0_rel_error.unit = "relative"

"""asv: HF solve time and tracked accuracy, through the same entry points as the CLI."""

from rbbench.hf import make_components, solve_hf
from rbbench.scene import load_scene


class HFSolve:
    """Time of one Hertz HF solve (mesh once in setup; discretize + formulate + solve timed)."""

    params = (["ssn", "uzawa"],)
    param_names = ["solver"]
    timeout = 300

    def setup(self, solver):
        self.scene = load_scene("hertz_halfdisks")
        self.components = make_components(self.scene, solver=solver)

    def time_solve(self, solver):
        solve_hf(self.scene, 1.0, solver=solver, components=self.components)

    def peakmem_solve(self, solver):
        solve_hf(self.scene, 1.0, solver=solver, components=self.components)


class HertzAccuracy:
    """Tracked |relative error| vs 2D Hertz on the default mesh (lower is better)."""

    timeout = 300

    def setup_cache(self):
        m = solve_hf(load_scene("hertz_halfdisks"), 1.0).metrics["hertz"]
        return {"a": abs(m["a_rel_error"]), "p0": abs(m["p0_rel_error"])}

    def track_a_rel_error(self, cache):
        return cache["a"]

    def track_p0_rel_error(self, cache):
        return cache["p0"]

    track_a_rel_error.unit = "relative"
    track_p0_rel_error.unit = "relative"

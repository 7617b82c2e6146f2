"""asv: the HF solve of ``rbbench solve`` (:func:`rbbench.hf.solve_hf`), time and accuracy."""

from rbbench.hf import make_components, solve_hf

from ._common import CASES, TIMEOUT, finite, scene


class HFSolve:
    """One HF contact solve at the scene's default mu, meshing excluded.

    ``setup`` builds the components once (backend: meshes the reference configuration;
    formulation; solver), so the timed call is what ``rbbench solve`` does after meshing:
    discretise at mu (assemble A, F, X, W, B, G), build the contact problem, solve it,
    compute the summary metrics. Cases: see :mod:`benchmarks._common`; solvers ``ssn``
    (primal-dual active set) and ``uzawa``.
    """

    params = (list(CASES), ["ssn", "uzawa"])
    param_names = ["scene", "solver"]
    timeout = TIMEOUT
    repeat = (1, 5, 10.0)  # at most 5 samples or 10 s per round (hertz_default: ~3 s a solve)

    def setup(self, case, solver):
        self.scene = scene(case)
        self.mu = self.scene.default_mu
        self.components = make_components(self.scene, solver=solver)

    def time_hf_solve(self, case, solver):
        """Wall time (s) of ``solve_hf`` at the default mu: discretise + formulate + solve."""
        sol = solve_hf(self.scene, self.mu, solver=solver, components=self.components)
        if not sol.result.converged:
            raise RuntimeError(f"{case}/{solver}: HF solve did not converge "
                               f"({sol.result.stop_reason})")

    def peakmem_hf_solve(self, case, solver):
        """Peak resident memory (bytes) of the benchmark process around one HF solve.

        asv's measure: the process maximum (interpreter, libraries, the components built
        in ``setup`` and the solve), so the level includes a constant base; its change
        along the history is what matters.
        """
        solve_hf(self.scene, self.mu, solver=solver, components=self.components)


class HertzAccuracy:
    """|relative error| of the HF solution against 2D Hertz theory, default mesh, mu = 1.

    Signed errors are (computed - theory) / theory at the solver's own contact force
    (``rbbench solve`` summary, ``hertz`` block); tracked as absolute values, so lower
    is better. Unit: relative (dimensionless).
    """

    timeout = TIMEOUT

    def setup_cache(self):
        m = solve_hf(scene("hertz_default"), 1.0).metrics["hertz"]
        return {"a": abs(m["a_rel_error"]), "p0": abs(m["p0_rel_error"])}

    setup_cache.timeout = TIMEOUT

    def track_a_rel_error(self, cache):
        """|a_h - a| / a: contact half-width against Hertz (relative, lower is better)."""
        return finite(cache["a"], "Hertz half-width error")

    def track_p0_rel_error(self, cache):
        """|p0_h - p0| / p0: peak pressure against Hertz (relative, lower is better)."""
        return finite(cache["p0"], "Hertz peak-pressure error")

    track_a_rel_error.unit = "relative"
    track_p0_rel_error.unit = "relative"

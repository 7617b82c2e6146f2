"""asv: the linear scenes without contact: HF solve, reduced solve, error bound.

Cases: ``thermal_block`` (2 x 2 blocks, 32 x 32 squares, POD with N = 10 on 30 training
parameters) and ``heat_robin`` (32 x 32 squares, 50 implicit Euler steps, POD-greedy with
N = 10 on 9 training parameters). ``setup_cache`` reduces both once
(:func:`rbbench.rb.linear.offline.reduce_linear`) and keeps the reduced models (small dense
arrays) and the summaries; the HF benchmark assembles and solves at the default mu.
"""

import tempfile

from ._common import TIMEOUT, finite

#: case -> (scene overrides, ReduceConfig fields)
LINEAR_CASES = {
    "thermal_block": (["discretization.n_cells=32"], {"N": 10, "n_train": 30, "n_valid": 5}),
    "heat_robin": (["discretization.n_cells=32"], {"N": 10, "n_train": 9, "n_valid": 4}),
}
CASES = list(LINEAR_CASES)


def _scene(case):
    from rbbench.scene.loading import load_scene

    return load_scene(case, LINEAR_CASES[case][0])


def reduced_linear(case, cache_dir, **changes):
    """``{"model", "mu", "summary"}`` of one linear reduction of ``case``."""
    from rbbench.rb.config import make_config
    from rbbench.rb.linear.offline import reduce_linear

    sc = _scene(case)
    fields = {**LINEAR_CASES[case][1], **changes}
    cfg = make_config(formulation="linear", primal="pod", cache_dir=cache_dir,
                      online_repeats=3, **fields)
    res = reduce_linear(sc, cfg)
    res.model.basis = None  # reconstruction only: not needed online
    s = res.summary()
    return {"model": res.model, "mu": sc.default_mu,
            "summary": {k: s[k] for k in ("err_u_max", "effectivity_min", "N")}}


def setup_cache():
    """One reduction per case: ``{case: {"model", "mu", "summary"}}``."""
    with tempfile.TemporaryDirectory(prefix="rbbench-asv-") as d:
        return {case: reduced_linear(case, d) for case in CASES}


setup_cache.timeout = TIMEOUT


class LinearHF:
    """One HF solve (assembly at mu + one factorisation; heat: 50 implicit Euler steps)."""

    params = (CASES,)
    param_names = ["scene"]
    timeout = TIMEOUT

    def setup(self, cache, case):
        from rbbench.hf.linear.model import LinearHF as Model

        self.model = Model(_scene(case))
        self.mu = self.model.scene.default_mu

    def time_hf_solve(self, cache, case):
        """Wall time (s) of one HF solve at the default mu (meshing excluded)."""
        self.model.solve(self.mu)


class LinearOnline:
    """One reduced solve and one error bound at the default mu, and the accuracy."""

    params = (CASES,)
    param_names = ["scene"]
    timeout = TIMEOUT

    def setup(self, cache, case):
        self.model, self.mu = cache[case]["model"], cache[case]["mu"]
        self.coef = self.model.solve(self.mu).u

    def time_online_solve(self, cache, case):
        """Wall time (s) of one reduced solve (affine sums + dense solve / K steps)."""
        self.model.solve(self.mu)

    def time_error_bound(self, cache, case):
        """Wall time (s) of the residual-based error bound of one reduced solution."""
        self.model.estimate(self.mu, self.coef)

    def track_err_u_max(self, cache, case):
        """max_valid relative error (X norm; heat: L2(0, T; X)); lower is better."""
        return finite(cache[case]["summary"]["err_u_max"], f"{case} err_u_max")

    track_err_u_max.unit = "relative error"

    def track_effectivity_min(self, cache, case):
        """min_valid bound / error (>= 1: rigorous; close to 1 is sharp)."""
        return finite(cache[case]["summary"]["effectivity_min"], f"{case} effectivity_min")

    track_effectivity_min.unit = "ratio"

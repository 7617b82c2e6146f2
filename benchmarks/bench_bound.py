"""asv: the online error bound beside the reduced solve it certifies.

``setup_cache`` runs :func:`rbbench.rb.offline.reduce` once per RB case with ``bound =
"online"`` (the membrane: the affine bound; coarse Hertz: the bound of a moving contact
under the contact EIM, with its default number of master-half modes) and keeps the reduced
model with its bound (small dense arrays, pickled by asv). No HF data at run time.
"""

import tempfile

import numpy as np

from ._common import RB_CASES, TIMEOUT, reduced_case

#: rounds of one solve then one bound at the default mu
REPEATS = 200


def setup_cache():
    """One reduction per RB case with the online bound: ``{case: {"model", "mu", ...}}``."""
    with tempfile.TemporaryDirectory(prefix="rbbench-asv-") as d:
        return {case: reduced_case(case, d, bound="online", online_repeats=1)
                for case in RB_CASES}


setup_cache.timeout = TIMEOUT


def _side_by_side(model, mu, repeats: int) -> tuple[float, float]:
    """Medians (s) of the reduced solve's own time and of the bound's wall time at its
    coefficients, ``repeats`` rounds of one solve then one bound (the row's protocol: one
    untimed round, one BLAS thread, garbage collector paused)."""
    import time

    from rbbench.runtime.threads import one_blas_thread
    from rbbench.runtime.timing import gc_paused

    ts, tb = [], []
    with one_blas_thread(), gc_paused():
        sol = model.solve(mu)
        model.bound(mu, sol.c, sol.alpha)
        for _ in range(repeats):
            sol = model.solve(mu)
            t0 = time.perf_counter()
            model.bound(mu, sol.c, sol.alpha)
            tb.append(time.perf_counter() - t0)
            ts.append(float(sol.time_s))
    return float(np.median(ts)), float(np.median(tb))


class OnlineBound:
    """The certified bound's online time, each evaluation right after a reduced solve at
    the scene's default mu (the data the solve evicted come back: the fair comparison)."""

    params = (RB_CASES,)
    param_names = ["scene"]
    timeout = TIMEOUT

    def setup(self, cache, case):
        self.model, self.mu = cache[case]["model"], cache[case]["mu"]
        if getattr(self.model, "bound", None) is None:
            raise NotImplementedError(f"{case}: the reduction built no online bound")

    def track_bound_median_s(self, cache, case):
        """Median (s) of :data:`REPEATS` bound evaluations, each after a solve."""
        return _side_by_side(self.model, self.mu, REPEATS)[1]

    def track_bound_over_solve(self, cache, case):
        """The bound's median time over the reduced solve's, from the same loop (the
        row's ``t_bound_ratio`` at one mu; the target is at most 2)."""
        solve, bound = _side_by_side(self.model, self.mu, REPEATS)
        return bound / solve

    track_bound_median_s.unit = "seconds"
    track_bound_over_solve.unit = "ratio"

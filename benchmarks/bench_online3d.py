"""asv: the 3D online solve (``hertz_sphere``, two quarter hemispheres, the contact EIM on
triangulated surfaces) at mesh levels 0 and 1, the counterpart of
:class:`benchmarks.bench_online.OnlineSolve`.

``setup_cache`` runs :func:`rbbench.rb.offline.reduce` once per level (POD, mCPG, PGA, EIM;
N = R = 20, the sizes of :data:`benchmarks._common.RB_OPTIONS`) and keeps the reduced model
(small dense arrays). The figure to watch is the ratio of the two levels: the online solve
does not depend on the HF size.
"""

import tempfile

from ._common import SPHERE_CASES, TIMEOUT, online_median_s, reduced_case

#: timed solves per online benchmark (the protocol's ``repeats`` at one mu)
REPEATS = 200


def setup_cache():
    """One reduction per 3D case: ``{case: {"model", "mu", "summary"}}``."""
    with tempfile.TemporaryDirectory(prefix="rbbench-asv-") as d:
        return {case: reduced_case(case, d) for case in SPHERE_CASES}


setup_cache.timeout = 4 * TIMEOUT  # level 1: 21 3D HF solves of 31,764 dofs


class OnlineSolve3D:
    """One online solve of the 3D reduced model at the scene's default mu, per online
    method: the pairing of the EIM magic rows' slave points with their master windows, the
    magic entries of ``B(mu) Z`` and rows of ``G(mu)``, the reduced arrays, then ``nnls``
    or ``daqp`` (the compiled path where numba is installed).

    Timed under the online-time protocol of ``rbbench reduce``
    (:func:`rbbench.rb.online.timed_online_solves`): the median of :data:`REPEATS` solves'
    own times.
    """

    params = (SPHERE_CASES, ("nnls", "daqp"))
    param_names = ["scene", "method"]
    timeout = TIMEOUT

    def setup(self, cache, case, method):
        self.model = cache[case]["model"]
        self.mu = cache[case]["mu"]
        self.model.solve(self.mu, method=method)  # compile or load the kernels: not timed

    def track_online_median_s(self, cache, case, method):
        """Median (s) of :data:`REPEATS` online solves at the default mu, protocol
        ``ONLINE_PROTOCOL`` (warm-up solve excluded, one BLAS thread, garbage collector
        paused)."""
        return online_median_s(self.model, self.mu, REPEATS, method, case)

    track_online_median_s.unit = "seconds"

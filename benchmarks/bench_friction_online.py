"""asv: the online solve of the hyper-reduced wedge friction model, per mesh level and path.

``setup_cache`` runs :func:`rbbench.rb.offline.reduce` once per friction case
(:data:`benchmarks._common.FRICTION_CASES`: hertz_friction at P1 on two contact mesh
sizes; the wedge dual model with its EIM and slip DEIM, N = 8, R = S = 4, PGA capped at
6, 5 training and 2 validation mu) and keeps the
:class:`~rbbench.rb.friction.wedge.hyper.WedgeHyperModel` (small dense arrays, pickled by
asv). The online time should not grow with the mesh (the hyper-reduction's point).
"""

import tempfile

from ._common import FRICTION_CASES, TIMEOUT, reduced_case


def setup_cache():
    """One reduction per friction case: ``{case: {"model", "mu", "summary"}}``."""
    with tempfile.TemporaryDirectory(prefix="rbbench-asv-") as d:
        return {case: reduced_case(case, d) for case in FRICTION_CASES}


setup_cache.timeout = 2 * TIMEOUT


class FrictionOnlineSolve:
    """One online solve of the wedge model at the scene's default mu, per path.

    :meth:`WedgeHyperModel.solve`: the friction EIM at mu (pairing of the magic rows,
    magic entries, slip rows), the affine ``A_N``, ``F_N``, the condensation on the wedge
    coefficients and De Saxce's fixed point; ``compiled`` (one numba kernel) or ``python``
    (the reference: numpy, daqp from a Python loop).
    """

    params = (FRICTION_CASES, ("compiled", "python"))
    param_names = ["scene", "path"]
    timeout = TIMEOUT

    def setup(self, cache, case, path):
        self.model = cache[case]["model"]
        self.mu = cache[case]["mu"]
        if path == "compiled" and self.model.online_path().startswith("python"):
            raise NotImplementedError(self.model.online_path())  # asv: skipped (no numba)
        self.model.solve(self.mu, path=path)  # compile or load the kernel: not timed

    def time_online_solve(self, cache, case, path):
        """Wall time (s) of one online solve (EIM evaluation + De Saxce's fixed point)."""
        res = self.model.solve(self.mu, path=path)
        if res.stop_reason != "converged" or res.path != path:
            raise RuntimeError(f"{case}: online solve on the {res.path} path stopped: "
                               f"{res.stop_reason}")

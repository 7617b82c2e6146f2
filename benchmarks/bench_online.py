"""asv: the online stage and the accuracy of one ``rbbench reduce`` per case.

``setup_cache`` (module level, shared by both classes) runs
:func:`rbbench.rb.offline.reduce` once per RB case (CLI defaults: POD, mCPG, PGA, hyper
auto, i.e. exact-affine on the membrane and EIM on coarse Hertz; training / validation
sizes of :data:`benchmarks._common.RB_OPTIONS`) and keeps the
:class:`~rbbench.rb.mixed.model.ReducedModel` (small dense arrays, pickled by asv) and the
scalar results. The online benchmarks therefore run without any HF data.
"""

import math
import tempfile

from ._common import RB_CASES, TIMEOUT, finite, online_median_s, reduced_case

#: ``-log10(beta_off)`` is capped here when ``beta_off`` is zero to machine precision
NEG_LOG10_CAP = 16.0
#: timed solves per online benchmark (the protocol's ``repeats`` at one mu)
REPEATS = 200


def setup_cache():
    """One reduction per RB case: ``{case: {"model", "mu", "summary"}}``."""
    with tempfile.TemporaryDirectory(prefix="rbbench-asv-") as d:
        return {case: reduced_case(case, d) for case in RB_CASES}


setup_cache.timeout = TIMEOUT


class OnlineSolve:
    """One online solve of the reduced model at the scene's default mu, per online method.

    :meth:`ReducedModel.solve`: evaluate the reduced arrays at mu (affine sums; on Hertz
    the EIM magic rows of ``B(mu)``, ``G(mu)``), then ``nnls`` (the default: the ``R x R``
    LCP condensed through the eigenbasis of ``A_N``, Lawson-Hanson) or ``daqp`` (the primal
    QP), on the compiled path where numba is installed.

    Timed under the online-time protocol of ``rbbench reduce`` and ``rbbench run`` rows and
    ``online-scaling`` (:func:`rbbench.rb.online.timed_online_solves`,
    :data:`rbbench.runtime.timing.ONLINE_PROTOCOL`): the median of :data:`REPEATS` solves'
    own times, so asv's figure is the rows' ``t_online_median_s`` at one mu, not asv's
    wall time of a call.
    """

    params = (RB_CASES, ("nnls", "daqp"))
    param_names = ["scene", "method"]
    timeout = TIMEOUT

    def setup(self, cache, case, method):
        self.model = cache[case]["model"]
        self.mu = cache[case]["mu"]
        self.model.solve(self.mu, method=method)  # compile or load the kernels: not timed

    def track_online_median_s(self, cache, case, method):
        """Median (s) of :data:`REPEATS` online solves (reduced assembly + LCP or QP) at
        the default mu, protocol ``ONLINE_PROTOCOL`` (warm-up solve excluded, one BLAS
        thread, garbage collector paused)."""
        return online_median_s(self.model, self.mu, REPEATS, method, case)

    track_online_median_s.unit = "seconds"

    def peakmem_online_solve(self, cache, case, method):
        """Peak resident memory (bytes) of the process doing online solves.

        asv's measure: the process maximum, imports and the unpickled model included
        (no HF data is loaded); its change along the history is what matters.
        """
        self.model.solve(self.mu, method=method)


class Accuracy:
    """Validation accuracy and stability of the reduction (lower is better for all three).

    Errors: max over the validation set of the relative error, u in the X norm and lam
    in the W(mu) norm (``result.json`` ``err_u_max``, ``err_lam_max``). Stability:
    ``beta_off_min``, the min over the validation set of the inf-sup constant of
    ``V_N + S_PGA`` against the reduced cone.
    """

    params = (RB_CASES,)
    param_names = ["scene"]
    timeout = TIMEOUT

    def track_err_u_max(self, cache, case):
        """max_valid ||u - u_N||_X / ||u||_X (relative; lower is better)."""
        return finite(cache[case]["summary"].get("err_u_max"), f"{case} err_u_max")

    def track_err_lam_max(self, cache, case):
        """max_valid ||lam - lam_R||_W / ||lam||_W (relative; lower is better)."""
        return finite(cache[case]["summary"].get("err_lam_max"), f"{case} err_lam_max")

    def track_neg_log10_beta_off(self, cache, case):
        """-log10(beta_off_min): oriented so that LOWER is better (a more stable model).

        beta_off_min is the min over the validation set of the offline-stabilised inf-sup
        constant (its kind, exact cone value or upper estimate, is in ``result.json``).
        A value below 10**-NEG_LOG10_CAP (zero to machine precision) gives the cap, 16.
        Unit: decades (-log10 of a dimensionless constant).
        """
        beta = finite(cache[case]["summary"].get("beta_off_min"), f"{case} beta_off_min")
        if beta <= 10.0 ** -NEG_LOG10_CAP:
            return NEG_LOG10_CAP
        return -math.log10(beta)

    track_err_u_max.unit = "relative"
    track_err_lam_max.unit = "relative"
    track_neg_log10_beta_off.unit = "-log10(beta_off)"

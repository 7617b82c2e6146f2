"""The online-time protocol: one untimed warm-up solve, repeats per mu, one BLAS thread and
the garbage collector paused during the timed solves, medians over what was timed."""

from __future__ import annotations

import gc
from types import SimpleNamespace

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from rbbench.rb.online import timed_online_solves
from rbbench.runtime.timing import ONLINE_PROTOCOL, ONLINE_PROTOCOL_DEFINITION, gc_paused


def _blas_threads() -> list[int]:
    return [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]


class _Model:
    """Records, per solve, mu, the garbage collector's state and the BLAS threads; returns
    a made-up time (the call count) so that the medians can be checked exactly."""

    def __init__(self, paths=("compiled",)):
        self.calls, self.paths = [], paths

    def solve(self, mu, **kw):
        self.calls.append((float(mu[0]), gc.isenabled(), _blas_threads(), kw))
        k = len(self.calls)
        return SimpleNamespace(time_s=float(k), path=self.paths[k % len(self.paths)],
                               method="nnls")


def test_gc_paused_restores_the_collector_state():
    assert gc.isenabled()
    with gc_paused():
        assert not gc.isenabled()
    assert gc.isenabled()
    gc.disable()
    try:
        with gc_paused():
            pass
        assert not gc.isenabled()  # a caller's own pause is kept
    finally:
        gc.enable()


def test_the_protocol_warms_up_once_then_times_repeats_per_mu():
    mus = [np.array([1.0]), np.array([2.0]), np.array([3.0])]
    model = _Model()
    with threadpool_limits(limits=2):
        outside = _blas_threads()
        run = timed_online_solves(model, mus, repeats=4, method="daqp")
    assert [c[0] for c in model.calls] == [1.0] + [1.0] * 4 + [2.0] * 4 + [3.0] * 4
    assert all(not enabled for _, enabled, _, _ in model.calls)  # gc paused in every solve
    assert outside and all(t and set(t) == {1} for _, _, t, _ in model.calls)
    assert all(kw == {"method": "daqp"} for *_, kw in model.calls)
    assert gc.isenabled()
    # the warm-up (call 1, time 1.0) is not among the timed solves (calls 2..13)
    assert run.times == [float(k) for k in range(2, 14)]
    s = run.summary()
    assert s["t_online_median_s"] == pytest.approx(7.5)
    assert s["t_online_iqr_s"] == pytest.approx(np.percentile(range(2, 14), 75)
                                                 - np.percentile(range(2, 14), 25))
    assert s["online_protocol"] == ONLINE_PROTOCOL and ONLINE_PROTOCOL in (
        ONLINE_PROTOCOL_DEFINITION)
    assert s["online_path"] == "compiled" and s["online_method"] == "nnls"


def test_without_warm_up_every_solve_is_timed_and_both_paths_are_named():
    model = _Model(paths=("compiled", "python"))
    run = timed_online_solves(model, [np.array([1.0])], repeats=0, warm_up=False)
    assert len(model.calls) == 1 and run.times == [1.0]  # repeats: at least one
    run = timed_online_solves(model, [np.array([1.0])], repeats=2, warm_up=False)
    assert run.paths == "compiled/python"

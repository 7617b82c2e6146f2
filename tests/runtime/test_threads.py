"""One BLAS thread per HF solve and per online validation loop; the floor of ``rbbench solve``."""

from __future__ import annotations

import time
from types import SimpleNamespace

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from rbbench.cli.console import print_summary
from rbbench.hf.components import make_components
from rbbench.hf.model import solve_floor, solve_hf
from rbbench.interfaces import HFVectors, ReducedSolution
from rbbench.rb.validation import ReducedStage, validate
from rbbench.runtime import threads
from rbbench.runtime.threads import blas_pools, one_blas_thread
from rbbench.scene.loading import load_scene
from rbbench.testing import HERTZ_COARSE


def _blas_threads() -> list[int]:
    """threadpoolctl's own report: the threads of every BLAS pool of this process."""
    return [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"]


@pytest.fixture
def two_threads():
    """Every pool at 2 threads around the test (so that a limit to 1 is visible)."""
    with threadpool_limits(limits=2):
        yield _blas_threads()


def test_one_blas_thread_inside_and_restored(two_threads):
    assert two_threads and all(n == 2 for n in two_threads)
    with one_blas_thread() as rec:
        assert _blas_threads() == [1] * len(two_threads)
        with one_blas_thread() as inner:  # nested: no scan, the outer limit holds
            assert inner["how"] == "nested"
        assert _blas_threads() == [1] * len(two_threads)  # the inner exit restored nothing
    assert _blas_threads() == two_threads
    assert rec["limit"] == 1 and rec["how"] == "threadpoolctl"
    assert sorted(rec["outside"].values()) == sorted(
        p["num_threads"] for p in threadpool_info())


def test_process_cap_makes_it_free(two_threads, monkeypatch):
    """A process capped at one thread (a snapshot worker) needs no scan: nothing applied."""
    monkeypatch.setitem(threads._STATE, "process_limit", 1)
    with one_blas_thread() as rec:
        assert rec["how"] == "process"
        assert _blas_threads() == two_threads  # this test process is not really capped
    assert threads._STATE["limiter"] is None


def test_hf_solve_runs_with_one_thread(two_threads):
    sc = load_scene("membrane_obstacle")
    comps = make_components(sc)  # may load another pool (MKL): its own count
    outside = _blas_threads()
    assert 2 in outside
    seen, real = [], comps[2].solve

    def spy(problem, *a, **kw):
        seen.append([p["num_threads"] for p in blas_pools()])
        return real(problem, *a, **kw)

    comps[2].solve = spy
    sol = solve_hf(sc, components=comps, floor=False)
    assert seen and all(n == 1 for n in seen[0])
    assert sol.metrics["blas_threads"]["limit"] == 1
    assert "floor_s" not in sol.metrics
    assert _blas_threads() == outside


class _Model:
    """A reduced model that returns the HF solution and records the BLAS threads online."""

    parameters = None

    def __init__(self, valid):
        self.valid, self.seen = valid, []

    def solve(self, mu):
        self.seen.append(_blas_threads())
        j = int(np.flatnonzero(self.valid.mus[:, 0] == mu[0])[0])
        return ReducedSolution(mu=mu, u=np.array([float(j)]), lam=np.zeros(0), iterations=0,
                               stop_reason="converged", time_s=1e-6)

    def reconstruct(self, sol):
        return HFVectors(u=self.valid.U[:, int(sol.u[0])], lam=np.zeros(0))


class _Stage(ReducedStage):
    config, histories, definitions, beta = {"stabilizer": "none"}, {}, {}, {}

    def __init__(self, valid):
        self.model = _Model(valid)

    def metrics(self, mu, p, u, lam, result, hf):
        return {"err_lam": 0.0}


def test_validation_loop_runs_with_one_thread(two_threads):
    n = 3
    sets = SimpleNamespace(mus=np.arange(1.0, n + 1)[:, None], U=np.eye(n), LAM=np.ones((1, n)),
                           times=np.ones(n), P=n, n_computed=n, n_dofs=n)
    prob = SimpleNamespace(A=np.eye(n), F=np.zeros(n))
    ctx = SimpleNamespace(valid=sets, train=sets, X=np.eye(n), timings={}, t0=time.perf_counter(),
                          mus_train=sets.mus, scene=SimpleNamespace(name="fake"),
                          problem_at=lambda mu: prob, progress=lambda s: None,
                          config=SimpleNamespace(online_repeats=1))
    stage = _Stage(sets)
    res = validate(ctx, stage)
    seen = stage.model.seen
    # n timed solves (online_repeats = 1) after the protocol's one warm-up solve
    assert len(seen) == n + 1 and all(t == [1] * len(two_threads) for t in seen)
    assert res.summary()["blas_threads"]["limit"] == 1
    assert _blas_threads() == two_threads
    assert res.err_u == [0.0] * n  # the HF solution returned: zero error


def test_floor_keys_on_a_contact_solve(capsys):
    """``rbbench solve``'s floor: positive parts, the ratio it defines, the keys defined
    (no timing comparison: the solve against its floor is measured in benchmarks)."""
    sol = solve_hf(load_scene("hertz_halfdisks", list(HERTZ_COARSE)))
    m = sol.metrics
    assert m["floor_s"] > 0 and m["solve_over_floor"] > 0
    assert m["floor"]["factor_s"] > 0 and m["floor"]["solve_s"] > 0
    assert m["solve_over_floor"] == pytest.approx(m["times_s"]["solve_s"] / m["floor_s"])
    assert m["n_active"] > 0
    for key in ("floor_s", "solve_over_floor", "blas_threads"):
        assert key in m["definitions"]
    print_summary(m, {"mu": 1.0})
    out = capsys.readouterr().out
    assert "floor_s" in out and "solve_over_floor" in out


def test_floor_solves_the_stiffness():
    """The floor's factorisation solves A x = F (checked against a dense solve)."""
    sol = solve_hf(load_scene("membrane_obstacle"), floor=False)
    p = sol.problem
    x = np.linalg.solve(p.A.toarray(), p.F)
    got = {}

    def factorize(A):
        from rbbench.hf.condensation.dense import factorize as lu

        solve = lu(A).solve

        def s(b):
            got["x"] = solve(b)
            return got["x"]

        return s

    fl = solve_floor(SimpleNamespace(A=p.A, F=p.F, factorize=factorize))
    assert fl["solver"] == "backend factorize" and fl["floor_s"] > 0
    np.testing.assert_allclose(got["x"], x, rtol=1e-10, atol=1e-14 * np.abs(x).max())


def test_floor_uses_the_solves_linear_solver():
    """A solve condensed on PARDISO is timed against a PARDISO floor (same solver, not
    SuperLU), named in floor.solver; the floor's x solves A x = F (dense reference)."""
    from rbbench.hf.condensation.pardiso import available, warm_up

    if not available():
        pytest.skip("pypardiso not installed")
    assert warm_up() and warm_up()  # once per process, then free
    sc = load_scene("membrane_obstacle")
    sol = solve_hf(sc, solver_options={"condensation": "schur", "linear_solver": "pardiso"})
    assert sol.result.info["condensation_linear_solver"] == "pardiso"
    assert sol.metrics["floor"]["solver"].startswith("PARDISO")
    assert sol.metrics["solve_over_floor"] == pytest.approx(
        sol.times["solve_s"] / sol.metrics["floor_s"], rel=1e-12)
    p = sol.problem
    fl = solve_floor(p, "pardiso")
    assert fl["solver"].startswith("PARDISO")
    from rbbench.hf.condensation.pardiso import factorized

    x = factorized(p.A)(np.asarray(p.F, float))
    ref = np.linalg.solve(p.A.toarray(), p.F)
    np.testing.assert_allclose(x, ref, rtol=1e-9, atol=1e-12 * np.abs(ref).max())
    sol_lu = solve_hf(sc, solver_options={"condensation": "schur", "linear_solver": "superlu"})
    assert sol_lu.metrics["floor"]["solver"].startswith("SuperLU")


def test_only_the_pools_off_the_limit_are_set(two_threads, monkeypatch):
    """``_limit_changed`` calls ``set_num_threads`` on the pools not at the limit only (a
    call after a fork re-creates OpenBLAS's spinning threads), and restores just those."""
    from threadpoolctl import ThreadpoolController

    controller = ThreadpoolController()
    libs = controller.lib_controllers
    if len(libs) < 2:
        pytest.skip("needs two thread pools")
    called = []
    for lc in libs:
        real = lc.set_num_threads
        monkeypatch.setattr(lc, "set_num_threads",
                            lambda n, lc=lc, real=real: called.append(lc.filepath) or real(n))
    libs[0].set_num_threads(1)  # this pool is at the limit already
    called.clear()
    limiter = threads._limit_changed(controller, 1)
    assert called == [lc.filepath for lc in libs[1:]]
    assert [lc.num_threads for lc in libs] == [1] * len(libs)
    limiter.restore_original_limits()
    assert [lc.num_threads for lc in libs] == [1] + [2] * (len(libs) - 1)
    libs[0].set_num_threads(2)
    assert threads._limit_changed(controller, 2) is None  # all at 2: nothing to do


def test_capped_for_fork_caps_and_restores(two_threads):
    with threads.capped_for_fork(1) as how:
        assert how == "threadpoolctl"
        assert _blas_threads() == [1] * len(two_threads)
        with threads.capped_for_fork(1) as inner:
            assert inner == "inherited"  # nothing left to cap
        assert _blas_threads() == [1] * len(two_threads)
    assert _blas_threads() == two_threads


def test_a_fork_child_of_capped_for_fork_inherits_the_openblas_cap(two_threads):
    """In a ``fork`` child of :func:`capped_for_fork`, every OpenBLAS pool is at the cap
    already, so the child's :func:`limit_blas_threads` calls nothing on OpenBLAS (a call
    would re-create its spinning threads); it sets again only pools whose runtime resets
    at fork (Intel's OpenMP, loaded with MKL, comes back at its default count)."""
    import json
    import os

    with threads.capped_for_fork(1):
        r, w = os.pipe()
        pid = os.fork()
        if pid == 0:  # pragma: no cover - the child reports through the pipe
            code = 1
            try:
                before = [(p["internal_api"], p["num_threads"]) for p in threadpool_info()]
                how = threads.limit_blas_threads(1)
                after = [p["num_threads"] for p in threadpool_info()]
                os.write(w, json.dumps([before, how, after]).encode())
                code = 0
            finally:
                os._exit(code)
        os.close(w)
        with os.fdopen(r) as fh:
            before, how, after = json.loads(fh.read())
        assert os.waitpid(pid, 0)[1] == 0
    openblas = [n for api, n in before if api == "openblas"]
    assert openblas and openblas == [1] * len(openblas)  # inherited, not set again
    reset = [api for api, n in before if n != 1]
    assert "openblas" not in reset
    assert how == ("threadpoolctl" if reset else "inherited")
    assert after == [1] * len(after)


_ENV_AT_NUMPY = """
import os, sys
seen = {}
class Spy:
    def find_spec(self, name, path=None, target=None):
        if name == "numpy" and "v" not in seen:
            seen["v"] = os.environ.get("OPENBLAS_THREAD_TIMEOUT")
        return None
sys.meta_path.insert(0, Spy())
import rbbench.cli
import numpy
print(seen.get("v"))
"""


@pytest.mark.parametrize("given, expected", [(None, "20"), ("28", "28")])
def test_the_command_sets_the_openblas_thread_timeout_before_numpy_loads(given, expected):
    """``rbbench.cli`` sets ``OPENBLAS_THREAD_TIMEOUT`` (unless the user did) before the
    first import of numpy, which loads OpenBLAS and reads it once; ``import rbbench``
    alone sets nothing."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_THREAD_TIMEOUT"}
    if given is not None:
        env["OPENBLAS_THREAD_TIMEOUT"] = given
    out = subprocess.run([sys.executable, "-c", _ENV_AT_NUMPY], env=env, check=True,
                         capture_output=True, text=True).stdout.split()
    assert out == [expected]
    lib = subprocess.run([sys.executable, "-c", "import os, rbbench, numpy; "
                          "print(os.environ.get('OPENBLAS_THREAD_TIMEOUT'))"], env=env,
                         check=True, capture_output=True, text=True).stdout.split()
    assert lib == [str(given)]

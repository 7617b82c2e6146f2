"""Snapshots that scale: components built once per process (reused by the
next call, inherited by ``fork`` workers), one task per parameter taken by an idle worker,
results in parameter order and equal to the serial ones."""

from __future__ import annotations

import contextlib
import json
import multiprocessing
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from rbbench.hf.snapshots import compute as snapshots
from rbbench.hf.snapshots.compute import compute_snapshots
from rbbench.runtime import workers as worker_pool_module
from rbbench.runtime.workers import keep_workers, kept_pool_alive, release_free_heap
from rbbench.scene.loading import load_scene
from rbbench.scene.sampling import parameter_set

fork_only = pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(),
                               reason="needs the fork start method")


@pytest.fixture
def scene():
    return load_scene("membrane_obstacle")


@pytest.fixture
def log(tmp_path, monkeypatch):
    """``snapshots.make_components`` and ``snapshots.solve_hf`` write ``(what, pid, mu)``
    lines to a file (shared by forked workers); a clean component cache around the test."""
    path = tmp_path / "log.txt"
    real_make, real_solve = snapshots.make_components, snapshots.solve_hf

    def write(line):
        with open(path, "a") as fh:
            fh.write(line + "\n")

    def make(*a, **kw):
        write(f"build {os.getpid()}")
        return real_make(*a, **kw)

    def solve(scene, mu, **kw):
        mu = np.atleast_1d(np.asarray(mu, float))
        if np.array_equal(mu, solve.slow):
            time.sleep(1.5)
        write(f"solve {os.getpid()} {mu.tolist()}")
        return real_solve(scene, mu, **kw)

    solve.slow = None
    monkeypatch.setattr(snapshots, "make_components", make)
    monkeypatch.setattr(snapshots, "solve_hf", solve)
    snapshots._COMPONENTS.clear()
    yield path, solve
    snapshots._COMPONENTS.clear()


def _lines(path, what):
    return [ln.split(maxsplit=2)[1:] for ln in path.read_text().splitlines()
            if ln.startswith(what)]


def test_serial_builds_once_per_process(scene, tmp_path, log):
    path, _ = log
    mus = parameter_set(scene, "train", n=4)
    compute_snapshots(scene, mus[:2], cache_dir=tmp_path / "c", n_jobs=1, progress=False)
    compute_snapshots(scene, mus[2:], cache_dir=tmp_path / "c", n_jobs=1, progress=False)
    assert len(_lines(path, "build")) == 1  # the second call reuses the components
    assert len(_lines(path, "solve")) == 4
    # another solver option is another key: built again
    compute_snapshots(scene, mus[:1], cache_dir=tmp_path / "d", n_jobs=1, progress=False,
                      solver_options={"tol": 1e-11})
    assert len(_lines(path, "build")) == 2


@fork_only
def test_fork_workers_inherit_and_tasks_balance(scene, tmp_path, log):
    """No worker meshes; a slow first parameter occupies one worker while the other takes
    every other task; the columns are in parameter order and equal the serial ones."""
    path, solve = log
    mus = parameter_set(scene, "train", n=6)
    solve.slow = mus[0]
    par = compute_snapshots(scene, mus, cache_dir=tmp_path / "p", n_jobs=2, progress=False,
                            mp_context="fork")
    assert [pid for (pid,) in _lines(path, "build")] == [str(os.getpid())]
    solves = _lines(path, "solve")
    slow_pid = next(pid for pid, mu in solves if mu == str(mus[0].tolist()))
    assert slow_pid != str(os.getpid())
    assert [mu for pid, mu in solves if pid == slow_pid] == [str(mus[0].tolist())]
    assert len({pid for pid, _ in solves}) == 2
    serial = compute_snapshots(scene, mus, cache_dir=tmp_path / "s", n_jobs=1, progress=False)
    np.testing.assert_array_equal(par.mus, mus)
    np.testing.assert_allclose(par.U, serial.U, rtol=0, atol=1e-12 * np.abs(serial.U).max())
    np.testing.assert_allclose(par.LAM, serial.LAM, rtol=0,
                               atol=1e-12 * np.abs(serial.LAM).max())


def test_warm_up_before_the_first_solve(scene, tmp_path, log, monkeypatch):
    """The inner product is assembled at start-up, not inside the first snapshot's time."""
    path, _ = log
    calls = []
    real = snapshots._components

    def spy(*a, **kw):
        comps = real(*a, **kw)
        calls.append(comps[0]._X is not None)
        return comps

    monkeypatch.setattr(snapshots, "_components", spy)
    compute_snapshots(scene, parameter_set(scene, "train", n=2), cache_dir=tmp_path,
                      n_jobs=1, progress=False)
    assert calls == [True]


@fork_only
def test_a_dying_worker_gives_error_rows_not_a_crash(scene, tmp_path, monkeypatch):
    """A worker killed in the middle of a solve: its parameter becomes an error row saying
    so (and so do the tasks the broken pool still held), every row is there, what was
    solved is kept; nothing raises."""
    parent, real = os.getpid(), snapshots.solve_hf
    mus = parameter_set(scene, "train", n=4)

    def dies_in_a_worker(scene, mu, **kw):
        if os.getpid() != parent and np.array_equal(np.atleast_1d(mu), mus[0]):
            os._exit(3)
        return real(scene, mu, **kw)

    monkeypatch.setattr(snapshots, "solve_hf", dies_in_a_worker)
    snapshots._COMPONENTS.clear()
    out = compute_snapshots(scene, mus, cache_dir=tmp_path, n_jobs=2, progress=False,
                            mp_context="fork", strict=False)
    snapshots._COMPONENTS.clear()
    assert out.stop_reasons[0] == "error" and "died" in out.errors[0]
    solved = [j for j, r in enumerate(out.stop_reasons) if r == "converged"]
    assert all(r == "converged" or "died" in out.errors[j]
               for j, r in enumerate(out.stop_reasons))
    assert np.isnan(out.U[:, 0]).all() and np.isfinite(out.U[:, solved]).all()


# ---------------------------------------------------------------- a pool kept in a block
def _pids(path, mus):
    """The pids that solved ``mus`` (from the log)."""
    wanted = {str(m.tolist()) for m in mus}
    return {pid for pid, mu in _lines(path, "solve") if mu in wanted}


def _gone(pid: int) -> bool:
    """``pid`` has exited (a zombie counts: it runs no more)."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] == "Z"
    except FileNotFoundError:
        return True


def _wait_gone(pid: int, timeout: float = 10.0) -> bool:
    """Wait up to ``timeout`` s for :func:`_gone`."""
    end = time.monotonic() + timeout
    while not _gone(pid):
        if time.monotonic() > end:
            return False
        time.sleep(0.05)
    return True


@fork_only
def test_a_block_keeps_the_workers_for_the_next_call(scene, tmp_path, log):
    """Inside ``keep_workers`` the second call with the same key is solved by the first
    call's workers (and equals the serial snapshots); outside, each call forks anew; the
    block's end shuts the pool down and its workers exit."""
    path, _ = log
    mus = parameter_set(scene, "train", n=9)  # a 3 x 3 grid
    assert len(mus) == 9
    kw = dict(n_jobs=2, progress=False, mp_context="fork")
    compute_snapshots(scene, mus[:2], cache_dir=tmp_path / "a", **kw)
    compute_snapshots(scene, mus[2:4], cache_dir=tmp_path / "a", **kw)
    assert not _pids(path, mus[:2]) & _pids(path, mus[2:4])  # no block: fresh workers
    with keep_workers():
        compute_snapshots(scene, mus[4:6], cache_dir=tmp_path / "b", **kw)
        assert kept_pool_alive()
        workers = {str(p.pid) for p in multiprocessing.active_children()}
        second = compute_snapshots(scene, mus[6:], cache_dir=tmp_path / "b", **kw)
    assert not kept_pool_alive()
    assert len(workers) == 2 and str(os.getpid()) not in workers
    assert _pids(path, mus[4:]) <= workers  # both calls: the same two processes
    assert all(_wait_gone(int(p)) for p in workers)
    serial = compute_snapshots(scene, mus[6:], cache_dir=tmp_path / "s", n_jobs=1,
                               progress=False)
    np.testing.assert_allclose(second.U, serial.U, rtol=0, atol=1e-12 * np.abs(serial.U).max())


@fork_only
def test_a_block_starts_a_new_pool_for_another_key(scene, tmp_path, log):
    """Another key (a solver option) gets new workers, and the old ones exit."""
    path, _ = log
    mus = parameter_set(scene, "train", n=4)
    kw = dict(n_jobs=2, progress=False, mp_context="fork")
    with keep_workers():
        compute_snapshots(scene, mus[:2], cache_dir=tmp_path, **kw)
        first = {p.pid for p in multiprocessing.active_children()}
        compute_snapshots(scene, mus[2:], cache_dir=tmp_path, solver_options={"tol": 1e-11},
                          **kw)
        assert not {str(p) for p in first} & _pids(path, mus[2:])
        assert all(_wait_gone(p) for p in first)


def _kill_a_kept_worker(wait_until_noticed: bool) -> int:
    """SIGKILL one worker of the kept pool; optionally wait until ``concurrent.futures``
    has marked the pool broken. Returns the victim's pid."""
    pool = worker_pool_module._KEPT["pool"]
    victim = next(iter(pool._processes))
    os.kill(victim, signal.SIGKILL)
    end = time.monotonic() + 30
    while wait_until_noticed and not pool._broken:
        assert time.monotonic() < end, "the pool was never marked broken"
        time.sleep(0.01)
    return victim


@fork_only
@pytest.mark.parametrize("case", ["noticed", "at-once", "submit-fails"])
def test_a_killed_kept_worker_costs_no_row(scene, tmp_path, log, monkeypatch, case):
    """A worker of the kept pool killed between two calls: once noticed, the next call
    starts a new pool (none of the old workers solves); killed just before the call,
    whichever path it takes, every row converges. ``submit-fails`` forces one path: the
    reuse check misses the death, so ``submit`` raises, and the parameters not submitted
    are solved in a new pool."""
    path, _ = log
    noticed = case != "at-once"
    if case == "submit-fails":
        monkeypatch.setattr(worker_pool_module, "_broken", lambda pool: pool is None)
    mus = parameter_set(scene, "train", n=9)
    assert len(mus) == 9
    kw = dict(n_jobs=2, progress=False, mp_context="fork")
    with keep_workers():
        compute_snapshots(scene, mus[:2], cache_dir=tmp_path, **kw)
        old = {str(p.pid) for p in multiprocessing.active_children()}
        victim = _kill_a_kept_worker(noticed)
        out = compute_snapshots(scene, mus[2:], cache_dir=tmp_path, **kw)
    assert out.stop_reasons == ["converged"] * 7
    assert str(victim) not in _pids(path, mus[2:])
    if noticed:
        assert not old & _pids(path, mus[2:])
    if case == "submit-fails":
        assert worker_pool_module._KEPT["pool"] is None  # and the block shut down the new one


def test_process_pool_executor_has_the_attributes_worker_pool_reads():
    """``worker_pool._broken`` reads ``ProcessPoolExecutor._broken`` and ``._processes``
    (private): a Python that renames them must fail here, not silently reuse dead pools."""
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(1) as pool:
        assert pool.submit(abs, -1).result() == 1
        assert pool._broken is False and isinstance(pool._processes, dict)
        assert all(p.is_alive() for p in pool._processes.values())


@fork_only
def test_a_reused_pool_that_loses_a_worker_solves_its_tasks_again(scene, tmp_path,
                                                                   monkeypatch):
    """A worker of a reused pool dies in the middle of a call (once: a marker file): the
    parameters it lost are solved in a new pool, every row converged."""
    parent, real = os.getpid(), snapshots.solve_hf
    mus = parameter_set(scene, "train", n=4)
    marker = tmp_path / "died"

    def dies_once(scene, mu, **kw):
        if (os.getpid() != parent and np.array_equal(np.atleast_1d(mu), mus[2])
                and not marker.exists()):
            marker.touch()
            os._exit(3)
        return real(scene, mu, **kw)

    monkeypatch.setattr(snapshots, "solve_hf", dies_once)
    snapshots._COMPONENTS.clear()
    kw = dict(cache_dir=tmp_path / "c", n_jobs=2, progress=False, mp_context="fork")
    with keep_workers():
        compute_snapshots(scene, mus[:2], **kw)
        out = compute_snapshots(scene, mus[2:], **kw)
    snapshots._COMPONENTS.clear()
    assert marker.exists()
    assert out.stop_reasons == ["converged", "converged"]


@fork_only
def test_kept_workers_die_with_their_parent(tmp_path):
    """A process that ends with ``os._exit`` inside a block (as the runner's snapshot
    child does) leaves no worker behind: each asked the kernel for SIGKILL."""
    script = tmp_path / "child.py"
    script.write_text(
        "import multiprocessing, os, sys\n"
        "from rbbench.hf.snapshots.compute import compute_snapshots\n"
        "from rbbench.runtime.workers import keep_workers\n"
        "from rbbench.scene.loading import load_scene\n"
        "from rbbench.scene.sampling import parameter_set\n"
        "sc = load_scene('membrane_obstacle')\n"
        "with keep_workers():\n"
        "    compute_snapshots(sc, parameter_set(sc, 'train', n=4), cache_dir=sys.argv[1],\n"
        "                      n_jobs=2, progress=False, mp_context='fork')\n"
        "    print(*[p.pid for p in multiprocessing.active_children()], flush=True)\n"
        "    os._exit(0)\n")
    pids_file = tmp_path / "pids.txt"
    pids: list[int] = []
    try:
        with open(pids_file, "w") as out:  # not a pipe: orphans would hold it open
            subprocess.run([sys.executable, str(script), str(tmp_path / "c")], stdout=out,
                           timeout=60, check=True)
        pids = [int(p) for p in pids_file.read_text().split()]
        assert len(pids) == 2
        assert all(_wait_gone(p) for p in pids)
    finally:
        for p in pids:  # if the test failed: no orphan outlives it
            if not _gone(p):
                os.kill(p, signal.SIGKILL)


@fork_only
def test_a_kept_pool_serves_only_its_process_and_main_thread(scene, tmp_path, log):
    """A process forked inside a block does not use the parent's pool (whose manager
    thread it lacks: it would hang) but starts its own; a call from another thread, with
    another key, gets a pool of its own and leaves the kept one alone; a block entered in
    another thread does nothing."""
    path, _ = log
    mus = parameter_set(scene, "train", n=9)
    kw = dict(n_jobs=2, progress=False, mp_context="fork")
    with keep_workers():
        compute_snapshots(scene, mus[:2], cache_dir=tmp_path, **kw)
        kept = worker_pool_module._KEPT["pool"]
        pid = os.fork()
        if pid == 0:  # pragma: no cover - the child's status is asserted below
            signal.alarm(60)
            out = compute_snapshots(scene, mus[2:4], cache_dir=tmp_path, **kw)
            os._exit(0 if out.stop_reasons == ["converged"] * 2 else 1)
        assert os.waitpid(pid, 0)[1] == 0

        depth_in_thread = []

        def other_thread():
            with keep_workers():
                depth_in_thread.append(worker_pool_module._KEPT["depth"])
                compute_snapshots(scene, mus[4:6], cache_dir=tmp_path,
                                  solver_options={"tol": 1e-11}, **kw)

        thread = threading.Thread(target=other_thread)
        thread.start()
        thread.join(120)
        assert not thread.is_alive() and depth_in_thread == [1]
        assert worker_pool_module._KEPT["pool"] is kept and kept_pool_alive()
        assert worker_pool_module._KEPT["depth"] == 1
        compute_snapshots(scene, mus[6:], cache_dir=tmp_path, **kw)
        assert _pids(path, mus[6:]) <= {str(p) for p in kept._processes}
    assert compute_snapshots(scene, mus[4:6], cache_dir=tmp_path, n_jobs=1, progress=False,
                             solver_options={"tol": 1e-11}).n_computed == 0


#: run by the test below in a fresh interpreter: the shape benchmark's setup (which keeps
#: SciPy SuperLU factorisations alive), a kept fork pool, then calls from a second thread
_FORK_FROM_THREAD = """
import json, multiprocessing, os, sys, threading

from rbbench.hf.snapshots import compute


def hook_completed():
    return threading.main_thread() is threading.current_thread()


if __name__ == "__main__":
    sys.path.insert(0, sys.argv[2])  # the repository root: benchmarks/
    from benchmarks import bench_shape_optimisation as shape
    from rbbench.runtime.workers import keep_workers, start_method
    from rbbench.scene.loading import load_scene
    from rbbench.scene.sampling import parameter_set

    methods, real_pool = [], compute.ProcessPoolExecutor

    def recording_pool(*args, mp_context, **kwargs):
        methods.append((threading.current_thread() is threading.main_thread(),
                        mp_context.get_start_method()))
        return real_pool(*args, mp_context=mp_context, **kwargs)

    compute.ProcessPoolExecutor = recording_pool
    bench = shape.ShapeReducedEvaluation()
    bench.setup(shape.SHAPE_CASES[0])
    sc = load_scene("membrane_obstacle")
    mus = parameter_set(sc, "train", n=4)
    kw = dict(cache_dir=sys.argv[1], n_jobs=2, progress=False, mp_context="fork")
    out = {}

    def other():
        res = compute.compute_snapshots(sc, mus[2:], solver_options={"tol": 1e-11}, **kw)
        out["thread_rows"] = res.stop_reasons
        ctx = multiprocessing.get_context(start_method("fork"))
        with real_pool(1, mp_context=ctx) as pool:
            out["hook"] = pool.submit(hook_completed).result(timeout=60)

    with keep_workers():
        out["main_rows"] = compute.compute_snapshots(sc, mus[:2], **kw).stop_reasons
        thread = threading.Thread(target=other)
        thread.start()
        thread.join(120)
        out["thread_alive"] = thread.is_alive()
    out["methods"] = methods
    print(json.dumps(out), flush=True)
    os._exit(0)
"""


@fork_only
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="killpg, forkserver")
def test_a_pool_started_in_another_thread_is_not_forked_from_it(tmp_path):
    """With SciPy SuperLU factorisations alive (the shape benchmark's setup keeps some), a
    process forked from a second thread gets a broken ``threading`` state and its
    ``threading._shutdown`` can wait for ever (a worker of such a pool did, at its exit):
    a pool started outside the main thread is forked from a fork server instead, its
    workers' state is whole, the calls end with every row converged."""
    script = tmp_path / "fork_from_thread.py"
    script.write_text(_FORK_FROM_THREAD)
    out_file = tmp_path / "out.json"
    root = str(Path(__file__).resolve().parents[2])
    with open(out_file, "w") as out:  # not a pipe: a hung worker would hold it open
        proc = subprocess.Popen([sys.executable, str(script), str(tmp_path / "c"), root],
                                stdout=out, start_new_session=True)
        try:
            proc.wait(timeout=180)
        except subprocess.TimeoutExpired:
            pass
        finally:  # the script, its workers and a hung worker: none outlives the test
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    text = out_file.read_text()
    assert text.strip(), "the script did not finish (hung in a pool started by a thread?)"
    data = json.loads(text.splitlines()[-1])
    assert data["main_rows"] == ["converged"] * 2 and data["thread_rows"] == ["converged"] * 2
    assert data["thread_alive"] is False and data["hook"] is True
    assert data["methods"] == [[True, "fork"], [False, "forkserver"]]


def _worker_threads() -> tuple[int, list[int]]:
    """In a worker: its threads (Linux) and the threads of its BLAS pools."""
    from threadpoolctl import threadpool_info

    return (len(os.listdir("/proc/self/task")),
            [p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"])


@fork_only
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="counts /proc/self/task")
@pytest.mark.parametrize("cap", [1, 0])
def test_fork_workers_inherit_the_blas_cap_and_start_no_blas_threads(scene, tmp_path, cap):
    """A fork pool started with this process capped (``blas_cap``, as compute_snapshots
    starts one) has workers at one BLAS thread that never called ``set_num_threads`` on
    OpenBLAS: one thread in all. Without the cap (``0``) the worker's own limit re-creates
    OpenBLAS's threads (the spinning ones), which shows the check can fail."""
    from threadpoolctl import threadpool_limits

    run = snapshots._Run(scene, np.zeros((0, 1)), [], ("skfem", "mixed", "ssn"), None, None,
                         None, False, "k")
    ctx = multiprocessing.get_context("fork")
    with threadpool_limits(limits=2):
        with worker_pool_module.worker_pool(("k",), None, lambda: run._pool(ctx, 1, 1),
                                            blas_cap=cap) as (pool, _):
            n_threads, pools = pool.submit(_worker_threads).result()
    assert pools and all(n == 1 for n in pools)
    if cap:
        assert n_threads == 1
    else:
        assert n_threads > 1


def test_release_free_heap_runs_on_linux():
    assert release_free_heap() is sys.platform.startswith("linux")


def test_snapshot_workers_study_reports_every_case(tmp_path):
    """``rbbench studies snapshot-workers``: one row per case, the serial median is the
    reference of the speed-ups, the parameters as asked."""
    from rbbench.cli import main
    from rbbench.studies.snapshot_workers import CASES

    out = tmp_path / "s.json"
    assert main(["studies", "snapshot-workers", "membrane_obstacle", "-P", "3",
                 "--rounds", "1", "--pause", "0", "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    assert (data["P"], data["jobs"], data["rounds"], data["pause_s"]) == (3, 2, 1, 0.0)
    assert data["serial_settled"] is True and data["settle_faults"] >= 0
    assert list(data["cases"]) == list(CASES)
    assert data["cases"]["serial"]["speedup"] == 1.0
    for row in data["cases"].values():
        assert row["median_s"] > 0 and row["iqr_s"] == 0.0  # one round: no spread
        assert row["speedup"] == pytest.approx(
            data["cases"]["serial"]["median_s"] / row["median_s"], rel=1e-12)


def test_snapshot_workers_study_settles_this_process_before_each_serial_call(monkeypatch):
    """Every timed serial call comes right after an untimed one-parameter serial call (the
    faults a previous fork left are paid there), and only serial calls get one."""
    from rbbench.hf.snapshots import compute as snapshots
    from rbbench.scene.loading import load_scene
    from rbbench.studies.snapshot_workers import snapshot_workers

    calls: list[tuple[int, int]] = []

    def record(scene, mus, cache_dir=None, n_jobs=None, progress=True):
        calls.append((len(mus), n_jobs))

    monkeypatch.setattr(snapshots, "compute_snapshots", record)
    out = snapshot_workers(load_scene("membrane_obstacle", []), np.zeros((3, 2)), n_jobs=2,
                           rounds=3, pause=0.0)  # the recorder reads only len(mus)
    timed_serial = [k for k, c in enumerate(calls) if c == (3, 1)]
    assert len(timed_serial) == 3
    assert all(calls[k - 1] == (1, 1) for k in timed_serial)
    assert calls.count((1, 1)) == 3 + 1  # one per serial call, and the components first
    assert out["settle_faults"] >= 0 and set(out["cases"]) == {"serial", "fresh", "kept_1st",
                                                               "kept_2nd"}


@pytest.mark.parametrize("flag", ["-P", "--jobs", "--rounds"])
def test_snapshot_workers_study_refuses_counts_below_one(flag, capsys):
    from rbbench.cli import main

    assert main(["studies", "snapshot-workers", "membrane_obstacle", flag, "0"]) == 2
    assert f"{flag} 0: must be an integer in [1, " in capsys.readouterr().err


def test_snapshot_workers_study_refuses_a_negative_pause(capsys):
    from rbbench.cli import main

    assert main(["studies", "snapshot-workers", "membrane_obstacle", "--pause", "-1"]) == 2
    assert "--pause -1: must be a finite number in [0, 60]" in capsys.readouterr().err

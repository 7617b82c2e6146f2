"""Snapshots that scale (issue 17, item 4): components built once per process (reused by the
next call, inherited by ``fork`` workers), one task per parameter taken by an idle worker,
results in parameter order and equal to the serial ones."""

from __future__ import annotations

import multiprocessing
import os
import time

import numpy as np
import pytest

from rbbench.hf import snapshots
from rbbench.hf.snapshots import compute_snapshots
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

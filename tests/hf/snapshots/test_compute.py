"""The HF snapshot cache (rbbench.hf.snapshots.compute): contents, cache hits, keys, worker
processes, interrupted and failing runs, atomic writes."""

from __future__ import annotations

import multiprocessing
import os

import numpy as np
import pytest

import rbbench.hf.snapshots.compute as snapshots
from rbbench.hf.snapshots.cache import SnapshotError
from rbbench.hf.snapshots.compute import compute_snapshots
from rbbench.hf.snapshots.key import snapshot_key
from rbbench.scene.loading import load_scene
from rbbench.scene.sampling import parameter_set

FAST = ["discretization.n_cells=6"]


@pytest.fixture(scope="module")
def scene():
    return load_scene("membrane_obstacle", FAST)


@pytest.fixture
def counter(monkeypatch):
    """Count the HF solves made in this process (n_jobs=1)."""
    calls = []
    real = snapshots.solve_hf

    def counting(scene, mu, **kw):
        calls.append(np.array(mu))
        return real(scene, mu, **kw)

    monkeypatch.setattr(snapshots, "solve_hf", counting)
    return calls


def _files(folder):
    return sorted(p.name for p in folder.iterdir() if p.name != "key.json")


def test_snapshot_set_contents(scene, tmp_path):
    mus = parameter_set(scene, "train", n=9)
    S = compute_snapshots(scene, mus, cache_dir=tmp_path, n_jobs=1, progress=False)
    assert S.P == 9 and S.U.shape == (25, 9) and S.LAM.shape == (25, 9)  # 5 x 5 interior dofs
    assert S.U.dtype == np.float64 and S.converged.all() and S.n_dofs == 49
    assert S.n_computed == 9 and S.free.size == 25
    np.testing.assert_array_equal(S.mus, mus)
    assert np.all(S.LAM >= 0) and np.all(S.times > 0)
    assert len(_files(tmp_path / S.key)) == 9
    # the files hold the free-dof vectors of solve_hf
    from rbbench.hf.model import solve_hf

    sol = solve_hf(scene, mus[4])
    np.testing.assert_allclose(S.U[:, 4], sol.result.u[sol.problem.free], rtol=0, atol=1e-13)
    np.testing.assert_allclose(S.LAM[:, 4], sol.result.lam, rtol=0, atol=1e-10)


def test_second_call_hits_cache(scene, tmp_path, counter):
    mus = parameter_set(scene, "train", n=9)
    S1 = compute_snapshots(scene, mus, cache_dir=tmp_path, n_jobs=1, progress=False)
    assert len(counter) == 9
    S2 = compute_snapshots(scene, mus, cache_dir=tmp_path, n_jobs=1, progress=False)
    assert len(counter) == 9 and S2.n_computed == 0
    np.testing.assert_array_equal(S1.U, S2.U)
    np.testing.assert_array_equal(S1.LAM, S2.LAM)
    assert S1.stop_reasons == S2.stop_reasons


def test_key_covers_overrides_not_sampling(scene):
    base = snapshot_key(scene)
    assert snapshot_key(load_scene("membrane_obstacle", FAST)) == base
    assert snapshot_key(scene.with_overrides(["load.source=-7.0"])) != base
    assert snapshot_key(scene.with_overrides(["discretization.n_cells=7"])) != base
    assert snapshot_key(scene, solver="uzawa") != base
    assert snapshot_key(scene, solver_options={"tol": 1e-8}) != base
    # the training-set definition does not change a snapshot: cached ones are reused
    assert snapshot_key(scene.with_overrides(["sampling.n_train=30", "sampling.seed=5"])) == base


def test_parallel_equals_serial(scene, tmp_path):
    mus = parameter_set(scene, "train", n=8, kind="lhs", seed=1)
    serial = compute_snapshots(scene, mus, cache_dir=tmp_path / "a", n_jobs=1, progress=False)
    par = compute_snapshots(scene, mus, cache_dir=tmp_path / "b", n_jobs=2, progress=False)
    assert par.n_computed == 8 and par.key == serial.key
    np.testing.assert_array_equal(serial.U, par.U)
    np.testing.assert_array_equal(serial.LAM, par.LAM)
    np.testing.assert_array_equal(serial.iterations, par.iterations)
    assert _files(tmp_path / "a" / serial.key) == _files(tmp_path / "b" / par.key)


def test_spawned_workers(scene, tmp_path):
    """Nothing relies on fork: the scene and results pickle, workers mesh on their own."""
    mus = parameter_set(scene, "valid", n=3)
    serial = compute_snapshots(scene, mus, cache_dir=tmp_path / "a", n_jobs=1, progress=False)
    par = compute_snapshots(scene, mus, cache_dir=tmp_path / "b", n_jobs=2, progress=True,
                            mp_context="spawn")
    np.testing.assert_array_equal(serial.U, par.U)
    np.testing.assert_array_equal(serial.LAM, par.LAM)


def _worker_state():
    return snapshots._WORKER.get("thread_limit"), os.environ.get("OMP_NUM_THREADS")


def test_workers_cap_blas_threads(scene):
    """Workers cap their BLAS pools (oversubscription made 2 workers 10x slower)."""
    if "fork" not in multiprocessing.get_all_start_methods():
        pytest.skip("needs the fork start method")
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("fork"),
                             initializer=snapshots._init_worker,
                             initargs=(scene, ("skfem", "mixed", "ssn"), None, 1)) as pool:
        how, omp = pool.submit(_worker_state).result()
    assert how != "none" and omp == "1"


def test_interrupted_run_recomputes_only_missing(scene, tmp_path, counter):
    mus = parameter_set(scene, "train", n=16)
    compute_snapshots(scene, mus[::2], cache_dir=tmp_path, n_jobs=1, progress=False)
    assert len(counter) == 8
    S = compute_snapshots(scene, mus, cache_dir=tmp_path, n_jobs=1, progress=False)
    assert len(counter) == 16 and S.n_computed == 8
    done = {tuple(m) for m in mus[::2]}
    assert all(tuple(m) not in done for m in counter[8:])


def test_failing_solve_keeps_the_others(scene, tmp_path, monkeypatch):
    mus = parameter_set(scene, "train", n=4)
    bad = mus[1]
    real = snapshots.solve_hf

    def flaky(scene, mu, **kw):
        if np.array_equal(mu, bad):
            raise FloatingPointError("boom")
        return real(scene, mu, **kw)

    monkeypatch.setattr(snapshots, "solve_hf", flaky)
    with pytest.raises(SnapshotError, match="boom") as info:
        compute_snapshots(scene, mus, cache_dir=tmp_path, n_jobs=1, progress=False)
    assert str(bad.tolist()) in str(info.value)
    assert len(info.value.failed) == 1
    S = compute_snapshots(scene, mus, cache_dir=tmp_path, n_jobs=1, progress=False,
                          strict=False)
    assert S.n_computed == 1  # only the failing one is retried: the others were cached
    assert S.stop_reasons[1] == "error" and 1 in S.errors
    assert np.isnan(S.U[:, 1]).all() and np.isfinite(np.delete(S.U, 1, axis=1)).all()
    assert len(_files(tmp_path / S.key)) == 3


def test_non_converged_is_reported(scene, tmp_path):
    mus = parameter_set(scene, "train", n=4)
    with pytest.raises(SnapshotError, match="max_iterations"):
        compute_snapshots(scene, mus, cache_dir=tmp_path, n_jobs=1, progress=False,
                          solver_options={"max_iter": 1})
    S = compute_snapshots(scene, mus, cache_dir=tmp_path, n_jobs=1, progress=False,
                          solver_options={"max_iter": 1}, strict=False)
    assert S.n_computed == 0 and not S.converged.all()


@pytest.mark.parametrize("n_jobs", [1, 2])
def test_atomic_write_leaves_no_partial_file(scene, tmp_path, monkeypatch, n_jobs):
    if n_jobs > 1 and multiprocessing.get_start_method() != "fork":
        pytest.skip("the patched writer reaches worker processes only when they are forked")
    mus = parameter_set(scene, "train", n=4)

    def broken_savez(fh, **arrays):
        fh.write(b"PK\x03\x04 partial")
        raise OSError("disk full")

    monkeypatch.setattr(np, "savez", broken_savez)
    with pytest.raises(OSError, match="disk full"):
        compute_snapshots(scene, mus, cache_dir=tmp_path, n_jobs=n_jobs, progress=False)
    assert _files(tmp_path / snapshot_key(scene)) == []  # neither .npz nor .tmp
    monkeypatch.undo()
    S = compute_snapshots(scene, mus, cache_dir=tmp_path, n_jobs=1, progress=False)
    assert S.n_computed == 4 and all(f.endswith(".npz") for f in _files(tmp_path / S.key))


def test_corrupt_cache_file_is_recomputed(scene, tmp_path):
    mus = parameter_set(scene, "train", n=4)
    S = compute_snapshots(scene, mus, cache_dir=tmp_path, n_jobs=1, progress=False)
    path = snapshots.cache_path(tmp_path, S.key, mus[2])
    path.write_bytes(b"garbage")
    with pytest.warns(RuntimeWarning, match="cached snapshot not used, recomputed: unreadable"):
        S2 = compute_snapshots(scene, mus, cache_dir=tmp_path, n_jobs=1, progress=False)
    assert S2.n_computed == 1
    np.testing.assert_array_equal(S.U, S2.U)


def test_a_tampered_cache_file_is_recomputed(scene, tmp_path):
    """u multiplied by 1000 under the same key and mu: the checksum catches it, the
    snapshot is recomputed and equals the original (it was used silently before)."""
    mus = parameter_set(scene, "train", n=3)
    S = compute_snapshots(scene, mus, cache_dir=tmp_path, n_jobs=1, progress=False)
    path = snapshots.cache_path(tmp_path, S.key, mus[1])
    with np.load(path, allow_pickle=False) as z:
        data = {k: z[k] for k in z.files}
    data["u"] = data["u"] * 1000
    np.savez(path, **data)
    with pytest.warns(RuntimeWarning, match="checksum does not match"):
        S2 = compute_snapshots(scene, mus, cache_dir=tmp_path, n_jobs=1, progress=False)
    assert S2.n_computed == 1
    np.testing.assert_array_equal(S.U, S2.U)


def test_mu_file_name_round_trips(tmp_path):
    mu = np.array([0.1 + 0.2, 1 / 3])
    path = snapshots.cache_path(tmp_path, "k", mu)
    values = [float(t) for t in path.name[len("mu_"):-len(".npz")].split("_")]
    np.testing.assert_array_equal(values, mu)


def test_out_of_domain_rejected(scene, tmp_path):
    from rbbench.scene.loading import SceneError

    with pytest.raises(SceneError):
        compute_snapshots(scene, [[0.5, 4.0]], cache_dir=tmp_path, n_jobs=1, progress=False)


def test_snapshots_feed_pod_and_greedy(scene, tmp_path):
    """End to end on the fast scene: X must be restricted to the free dofs of U."""
    from rbbench.hf.model import solve_hf
    from rbbench.rb.algorithms.pod import pod, projection_errors, weak_greedy

    S = compute_snapshots(scene, parameter_set(scene, "train"), cache_dir=tmp_path, n_jobs=1,
                          progress=False)
    X = solve_hf(scene).problem.X
    Xf = X[S.free][:, S.free]
    r = pod(S.U, Xf, tol=1e-2)
    assert 1 <= r.N < S.P
    np.testing.assert_allclose(r.Z.T @ Xf @ r.Z, np.eye(r.N), atol=1e-12)
    g = weak_greedy(S.U, Xf, tol=1e-2)
    assert projection_errors(S.U, g.Z, Xf).max() <= 1e-2 * g.sigma[0] * (1 + 1e-9)


def test_unknown_component_fails_early(scene, tmp_path):
    from rbbench.registry import UnknownComponentError

    with pytest.raises(UnknownComponentError):
        compute_snapshots(scene, parameter_set(scene, n=4), backend="nope", cache_dir=tmp_path,
                          n_jobs=2, progress=False)

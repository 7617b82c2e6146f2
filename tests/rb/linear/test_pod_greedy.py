"""POD-greedy on the heat scene: a size the training set cannot give is built as far as the
training trajectories span, with the stop reason and a warning; the basis is checked against
the trajectories themselves (X-orthonormal, every trajectory reproduced)."""

from __future__ import annotations

import numpy as np
import pytest

import rbbench
from rbbench.hf.linear.model import LinearHF, linear_snapshots
from rbbench.rb.linear.offline import LinearData, pod_greedy
from rbbench.registry import default_registry
from rbbench.scene.sampling import parameter_set

pytestmark = pytest.mark.timeout(120)
SMALL = ["discretization.n_cells=6", "time.steps=4"]


@pytest.fixture(scope="module")
def heat(tmp_path_factory):
    scene = rbbench.load_scene("heat_robin", SMALL)
    reg = default_registry()
    hf = LinearHF(scene, "skfem", reg, {})
    mus = parameter_set(scene, "train", 3)
    train = linear_snapshots(scene, mus, hf, "skfem", str(tmp_path_factory.mktemp("c")), reg)
    return scene, LinearData(hf, scene), train.U, mus


def test_a_size_beyond_the_span_stops_on_rank(heat):
    scene, lin, U, mus = heat
    basis = pod_greedy(lin, U, mus, 10**5, None)
    Z, n = basis.Z, lin.X.shape[0]
    assert basis.history["pod_greedy"]["stop_reason"] == "rank"
    assert 1 <= Z.shape[1] <= 3 * 4  # 3 trajectories of 4 steps span at most 12
    assert np.allclose(Z.T @ (lin.X @ Z), np.eye(Z.shape[1]), atol=1e-8)
    for j in range(U.shape[1]):  # every trajectory lies in the basis' span
        T = U[:, j].reshape(-1, n).T
        E = T - Z @ (Z.T @ (lin.X @ T))
        assert np.sum(E * (lin.X @ E)) <= 1e-14 * np.sum(T * (lin.X @ T))


def test_a_size_within_the_span_is_built_whole(heat):
    scene, lin, U, mus = heat
    basis = pod_greedy(lin, U, mus, 2, None)
    assert basis.Z.shape[1] == 2 and basis.history["pod_greedy"]["stop_reason"] == "size"


def test_reduce_warns_that_N_was_clipped(tmp_path):
    res = rbbench.reduce(rbbench.load_scene("heat_robin", SMALL), N=10**5, n_train=3,
                         n_valid=2, online_repeats=1, cache_dir=str(tmp_path))
    s = res.summary()
    assert s["N"] <= 12
    assert any("-N 100000" in w and "'rank'" in w for w in s["warnings"]), s["warnings"]

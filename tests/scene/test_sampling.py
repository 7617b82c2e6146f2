"""Training / validation sets (rbbench.scene.sampling): the scene's defaults, uniform grids,
random and Latin-hypercube sets, bad arguments."""

from __future__ import annotations

import numpy as np
import pytest

from rbbench.scene.loading import load_scene
from rbbench.scene.sampling import latin_hypercube, parameter_set, uniform_count

FAST = ["discretization.n_cells=6"]


@pytest.fixture(scope="module")
def scene():
    return load_scene("membrane_obstacle", FAST)


def _inside(mus, bounds):
    return bool(np.all(mus >= bounds[:, 0]) and np.all(mus <= bounds[:, 1]))


def test_scene_defaults(scene):
    train = parameter_set(scene, "train")  # uniform, n_train = 25, p = 2: 5 x 5
    valid = parameter_set(scene, "valid")  # random, n_valid = 20
    assert train.shape == (25, 2) and valid.shape == (20, 2)
    assert _inside(train, scene.bounds) and _inside(valid, scene.bounds)
    # endpoints included
    for j in range(2):
        assert set(np.unique(train[:, j])) >= set(scene.bounds[j])


@pytest.mark.parametrize("n, p, k", [(25, 2, 5), (20, 2, 4), (30, 2, 5), (64, 3, 4), (1, 2, 1),
                                     (7, 1, 7)])
def test_uniform_count(n, p, k):
    assert uniform_count(n, p) == (k, k**p)


def test_uniform_actual_count(scene):
    mus = parameter_set(scene, "train", n=20, kind="uniform")
    assert mus.shape == (16, 2)
    assert len(np.unique(mus, axis=0)) == 16
    assert _inside(mus, scene.bounds)


@pytest.mark.parametrize("kind", ["random", "lhs"])
def test_random_kinds_reproducible_and_distinct(scene, kind):
    a = parameter_set(scene, "train", n=15, kind=kind, seed=3)
    b = parameter_set(scene, "train", n=15, kind=kind, seed=3)
    c = parameter_set(scene, "train", n=15, kind=kind, seed=4)
    v = parameter_set(scene, "valid", n=15, kind=kind, seed=3)
    assert a.shape == (15, 2)
    np.testing.assert_array_equal(a, b)
    assert not np.allclose(a, c)
    assert not np.allclose(a, v)  # the validation stream differs from the training stream
    for m in (a, c, v):
        assert _inside(m, scene.bounds)


@pytest.mark.parametrize("n", [1, 7, 50])
def test_lhs_stratification(n):
    bounds = np.array([[0.1, 0.4], [2.0, 6.0], [-1.0, 1.0]])
    mus = latin_hypercube(bounds, n, np.random.default_rng(11))
    assert mus.shape == (n, 3) and _inside(mus, bounds)
    unit = (mus - bounds[:, 0]) / (bounds[:, 1] - bounds[:, 0])
    strata = np.minimum(np.floor(unit * n).astype(int), n - 1)
    for j in range(3):  # each of the n strata hit exactly once per axis
        np.testing.assert_array_equal(np.sort(strata[:, j]), np.arange(n))


def test_bad_arguments(scene):
    with pytest.raises(ValueError, match="which"):
        parameter_set(scene, "test")
    with pytest.raises(ValueError, match="kind"):
        parameter_set(scene, kind="sobol")

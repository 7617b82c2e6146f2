"""The mixed RB pipeline on the 3D scene hertz_sphere (level 0, 5,352 dofs, a few training
parameters): exact at a training parameter with full bases, errors falling as N grows, and a
clear refusal of what the 3D reduced model does not do."""

from __future__ import annotations

import numpy as np
import pytest

from rbbench.hf.model import solve_hf
from rbbench.rb.config import ReduceConfig, make_config
from rbbench.rb.offline import offline, prepare_config, reduce
from rbbench.registry import default_registry
from rbbench.scene.loading import SceneError, load_scene

pytestmark = pytest.mark.netgen

LEVEL0 = ["discretization.level=0", "sampling.n_train=4"]


def _quiet(_msg: str) -> None:
    pass


@pytest.fixture(scope="module")
def sphere():
    return load_scene("hertz_sphere", LEVEL0)


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return str(tmp_path_factory.getbasetemp() / "cache3d")


def test_full_bases_reproduce_the_hf_solution_at_a_training_parameter(sphere, cache):
    """N = R = n_train: the primal basis spans every training u, the cone every training
    lam, so the reduced solution at a training mu is the HF one (HF solved independently)."""
    off = offline(sphere, make_config(N=4, R=4, hyper="none", n_jobs=1, cache_dir=cache,
                                      n_valid=1), progress=_quiet, validation_snapshots=False)
    model, mus = off.model, off.context.mus_train
    for mu in (mus[0], mus[2]):
        hf = solve_hf(sphere, mu, floor=False)
        free = hf.problem.free
        res = model.solve(mu)
        assert res.stop_reason == "converged"
        u_rb = model.reconstruct(res).u
        u = hf.result.u[free]
        assert np.linalg.norm(u_rb - u) <= 1e-6 * np.linalg.norm(u)


def test_errors_fall_as_n_grows(sphere, cache):
    """err_u max over the same validation set, N = 1 then 3 (training set of 4)."""
    errs = [reduce(sphere, make_config(N=n, R=4, hyper="none", n_jobs=1, cache_dir=cache,
                                       n_valid=3, online_repeats=1),
                   progress=_quiet).summary()["err_u_max"] for n in (1, 3)]
    assert errs[1] < 0.5 * errs[0]


@pytest.mark.parametrize("field,value,match", [
    ("formulation", "nitsche", "formulation 'mixed' only, not 'nitsche'"),
    ("hyper", "ecsw", "hyper 'ecsw' is not available in 3D; valid hypers: 'auto'"),
])
def test_3d_refuses_what_it_does_not_reduce(sphere, field, value, match):
    with pytest.raises(SceneError, match=match):
        prepare_config(sphere, ReduceConfig(**{field: value}), default_registry())


def test_rigid_flat_cubic_decomposition_matches_the_assembled_model(cache):
    """Rigid flat: B(mu), G(mu) are exact cubics in mu (a similarity map against z = 0), so
    the ``affine`` model (no HF data online) solves as the model assembling the HF
    operators at mu, at parameters off the training set."""
    flat = load_scene("hertz_sphere", [*LEVEL0, "geometry.lower=rigid_flat"])
    models = {h: offline(flat, make_config(N=3, R=3, hyper=h, n_jobs=1, cache_dir=cache,
                                           n_valid=1), progress=_quiet,
                         validation_snapshots=False).model for h in ("affine", "none")}
    assert models["affine"].info["affine_degree"] == 3
    for mu in ([0.77], [1.21]):
        u = {h: m.reconstruct(m.solve(np.array(mu))).u for h, m in models.items()}
        assert np.linalg.norm(u["affine"] - u["none"]) <= 1e-8 * np.linalg.norm(u["none"])


def test_two_body_contact_eim_keeps_the_reduced_accuracy(sphere, cache):
    """Two elastic bodies: the contact EIM (3D magic rows, on the compiled path where numba
    is installed, and on the Python path) moves the reduced solution by less than a tenth
    of the reduced model's own error against HF (the model assembling the HF operators at
    mu), off the training set."""
    models = {h: offline(sphere, make_config(N=3, R=3, hyper=h, n_jobs=1, cache_dir=cache,
                                             n_valid=1, tol_eim=1e-6), progress=_quiet,
                         validation_snapshots=False).model for h in ("eim", "none")}
    for mu in ([0.77], [1.21]):
        hf = solve_hf(sphere, mu, floor=False)
        u_hf = hf.result.u[hf.problem.free]
        u = {h: m.reconstruct(m.solve(np.array(mu))).u for h, m in models.items()}
        e_rb = np.linalg.norm(u["none"] - u_hf)
        assert e_rb > 0
        assert np.linalg.norm(u["eim"] - u["none"]) <= 0.1 * e_rb
        py = models["eim"]
        u_py = py.reconstruct(py.solve(np.array(mu), path="python")).u
        assert np.linalg.norm(u_py - u["none"]) <= 0.1 * e_rb

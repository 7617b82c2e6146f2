"""The model contract (:func:`rbbench.testing.check_reduced_model`) over the HF models and every
reduced model of the benchmark, each built small; and the contract catching broken models."""

from __future__ import annotations

import dataclasses

import pytest

from rbbench.hf.linear.model import LinearHF
from rbbench.hf.model import HFModel
from rbbench.rb.config import make_config
from rbbench.rb.offline import offline
from rbbench.scene.loading import load_scene
from rbbench.testing import HERTZ_COARSE, ContractViolation, check_reduced_model

MEMBRANE = ["discretization.n_cells=8"]
FRICTION = ["discretization.degree=1", "discretization.h_contact=0.02",
            "discretization.h_max=0.25"]


def _reduced(tmp, scene, overrides, **fields):
    sc = load_scene(scene, overrides)
    base = dict(n_train=5, n_valid=2, online_repeats=1, cache_dir=str(tmp), n_jobs=1)
    cfg = make_config(**{**base, **fields})
    return offline(sc, cfg, validation_snapshots=False).model, sc


def _mid(sc, t=0.37):
    lo, hi = sc.bounds[:, 0], sc.bounds[:, 1]
    return [lo + t * (hi - lo), lo + (1 - t) * (hi - lo)]


def _mixed_affine(tmp):
    m, sc = _reduced(tmp, "membrane_obstacle", MEMBRANE, N=4, R=4, dual="cpg",
                     stabilizer="pga")
    return m, _mid(sc)


def _mixed_plain_supremizer(tmp):
    m, sc = _reduced(tmp, "membrane_obstacle", MEMBRANE, N=4, R=4, dual="cpg",
                     stabilizer="supremizer", hyper="none")
    return m, _mid(sc)


def _mixed_eim(tmp):
    m, sc = _reduced(tmp, "hertz_halfdisks", list(HERTZ_COARSE), N=4, R=4, dual="mcpg",
                     stabilizer="none", hyper="eim")
    return m, _mid(sc)


def _nitsche(tmp):
    m, sc = _reduced(tmp, "hertz_halfdisks", list(HERTZ_COARSE), N=4, formulation="nitsche",
                     solver="newton")
    return m, _mid(sc)


def _collocation(tmp):
    m, sc = _reduced(tmp, "hertz_friction", FRICTION, N=6, R=4, S=4, solver="friction-ssn",
                     stabilizer="none")
    return m, _mid(sc)[:1]


def _wedge_eim(tmp):
    cfg = dict(N=6, R=4, S=4, solver="friction-ssn", stabilizer="none", hyper="eim",
               tol_eim=1e-8, friction_dual="wedge")
    m, sc = _reduced(tmp, "hertz_friction", FRICTION, **cfg)
    return m, _mid(sc)[:1]


def _linear(tmp):
    from rbbench.rb.config import make_config
    from rbbench.rb.linear.offline import reduce_linear

    sc = load_scene("thermal_block", MEMBRANE)
    cfg = make_config(formulation="linear", N=4, n_train=8, n_valid=2, cache_dir=str(tmp),
                      online_repeats=1)
    return reduce_linear(sc, cfg).model, _mid(sc)


def _shape(tmp):
    from rbbench.optim.shape_adjoint import evaluate
    from rbbench.optim.shape_reduced import ReducedModel, interior_space
    from rbbench.optim.shape_scene import load_shape_scene

    sc = load_shape_scene(overrides={"geometry.contact_nodes": 11, "geometry.ny": 4})
    model = ReducedModel(sc)
    model.enrich(interior_space(sc, evaluate(sc, sc.initial_design()).state))
    return model, [sc.initial_design()]


def _hf(tmp):
    sc = load_scene("membrane_obstacle", MEMBRANE)
    return HFModel(sc), _mid(sc)[:1]


def _linear_hf(tmp):
    sc = load_scene("thermal_block", MEMBRANE)
    return LinearHF(sc), _mid(sc)[:1]


MODELS = {"hf": _hf, "linear-hf": _linear_hf, "mixed-affine": _mixed_affine,
          "mixed-plain-supremizer": _mixed_plain_supremizer, "mixed-eim": _mixed_eim,
          "nitsche": _nitsche, "friction-collocation": _collocation,
          "friction-wedge-eim": _wedge_eim, "linear": _linear, "shape": _shape}


@pytest.mark.parametrize("name", list(MODELS))
def test_every_model_keeps_the_model_contract(name, tmp_path):
    model, mus = MODELS[name](tmp_path)
    check_reduced_model(model, mus, name=name)


def test_the_contract_names_what_a_broken_model_breaks(tmp_path):
    model, mus = _mixed_affine(tmp_path)
    unchecked = dataclasses.replace(model, parameters=None)

    class NoCheck:  # forgets to check mu against D
        parameters = model.parameters

        def solve(self, mu):
            return unchecked.solve(mu, path="python")

        def reconstruct(self, sol):
            return model.reconstruct(sol)

    with pytest.raises(ContractViolation, match="outside D did not raise"):
        check_reduced_model(NoCheck(), mus, pickled=False)

    class Untimed(NoCheck):  # reports no online time
        def solve(self, mu):
            s = model.solve(mu)
            s.time_s = 0.0
            return s

    with pytest.raises(ContractViolation, match="time_s"):
        check_reduced_model(Untimed(), mus, pickled=False)

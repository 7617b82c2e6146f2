"""The hyper-reduced collocation model (rbbench.rb.friction.collocation.hyper): with the EIM
tolerance driven small it reproduces the plain collocation model (HF operators projected at
mu, another code path) on the EIM training set, it pickles, and its online solve touches no
HF-size array or HF assembly."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest

from rbbench.rb.config import make_config
from rbbench.rb.friction.collocation.hyper import TimedOperators
from rbbench.rb.friction.collocation.model import project_friction
from rbbench.rb.offline import eim_training_set, offline, prepare_config
from rbbench.registry import default_registry
from rbbench.scene.loading import SceneError, load_scene

COARSE = ["discretization.degree=1", "discretization.h_contact=0.02",
          "discretization.h_max=0.25"]
_CACHE: dict = {}


def _offline(tol_eim: float = 1e-10):
    """Coarse P1 hertz_friction, collocation model, hyper 'eim' (5 training, 2 validation mu)."""
    if tol_eim not in _CACHE:
        import tempfile

        scene = load_scene("hertz_friction", overrides=COARSE)
        cfg = make_config(solver="friction-ssn", n_train=5, n_valid=2, n_jobs=2, N=8, R=4,
                          S=4, stabilizer="pga", k_pga_max=6, hyper="eim", tol_eim=tol_eim,
                          online_repeats=1, friction_dual="collocation",
                          cache_dir=_CACHE.setdefault("dir", tempfile.mkdtemp()))
        _CACHE[tol_eim] = offline(scene, cfg)
    return _CACHE[tol_eim]


def _rel(a: np.ndarray, b: np.ndarray, M=None) -> float:
    """``||a - b|| / ||b||`` in the inner product ``M`` (Euclidean without)."""
    d = a - b
    if M is None:
        return float(np.linalg.norm(d) / np.linalg.norm(b)) if np.any(b) else \
            float(np.linalg.norm(d))
    return float(np.sqrt(d @ (M @ d) / (b @ (M @ b))))


def test_hyper_collocation_equals_plain_on_the_eim_training_set():
    """At every EIM training mu (the snapshot parameters and the EIM grid, where the EIM
    interpolates exactly up to its tolerance 1e-10), the hyper-reduced solve equals the plain
    one: u_N, lam_n = Vn c_n and lam_t = Vt theta (raw reconstructed values) to 1e-9, the same
    fixed-point stop; the EIM used fewer rows than contact nodes."""
    off = _offline()
    st, ctx = off.stage, off.context
    model = st.model
    assert st.hyper == "eim" and isinstance(model.arrays_at, TimedOperators)
    assert model.info["rows"] < model.info["m"]  # the magic rows: fewer than the contact nodes
    assert np.array_equal(model.nodes, st.reduced.nodes)  # the same collocation set
    mus = eim_training_set(ctx.scene, ctx.options, ctx.mus_train)
    assert len(mus) == model.info["n_eim_train"] == 5 + 17
    worst = np.zeros(3)
    for mu in mus:
        plain = st.reduced.solve_arrays(mu, project_friction(ctx.problem_at(mu), st.Z_off,
                                                             st.Vn, st.Vt))
        hyper = model.solve(mu)
        assert plain.stop_reason == hyper.stop_reason == "converged"
        worst = np.maximum(worst, [_rel(st.Z_off @ hyper.a, st.Z_off @ plain.a, ctx.X),
                                   _rel(st.Vn @ hyper.c_n, st.Vn @ plain.c_n),
                                   _rel(st.Vt @ hyper.theta, st.Vt @ plain.theta)])
    assert worst.max() < 1e-9, worst  # measured <= 9e-14


def test_hyper_collocation_pickles_and_touches_no_hf_array(monkeypatch):
    """The pickled model solves the same at a new mu with every HF entry point disabled and
    without its reconstruction basis; apart from that basis it holds no array of HF size."""
    import rbbench.hf.geometry.operators as cg
    import rbbench.hf.model as ro
    import rbbench.rb.friction.collocation.model as cm

    off = _offline()
    st, ctx = off.stage, off.context
    model = pickle.loads(pickle.dumps(st.model))
    mu = np.array([0.5 * (ctx.mus_train[0, 0] + ctx.mus_train[1, 0]) + 0.01])
    ref = st.model.solve(mu)

    def refuse(*a, **k):
        raise AssertionError("HF work in the online stage")

    for mod, name in ((ro, "build_problem"), (cg, "contact_operators"),
                      (cm, "project_friction")):
        monkeypatch.setattr(mod, name, refuse)
    monkeypatch.setattr(type(ctx.problem_at), "__call__", refuse)
    light = dataclasses.replace(model, basis=None)
    res = light.solve(mu)
    assert res.stop_reason == "converged" and np.array_equal(res.x, ref.x)
    assert res.assembly_s > 0.0
    n_free = ctx.X.shape[0]
    dims = [d for a in _arrays(light) for d in a.shape]
    assert max(dims) < n_free / 10, (max(dims), n_free)
    np.testing.assert_array_equal(model.reconstruct(res).u, st.Z_off @ res.a)


def test_hyper_collocation_stage_validates_without_hf_assembly():
    """The stage's validation runs the hyper model (EIM evaluation timed apart, no HF
    assembly online); the reduced constraint holds at the collocation nodes (raw values)."""
    from rbbench.rb.validation import validate

    off = _offline()
    s = validate(off.context, off.stage).summary()
    assert s["hyper"] == "eim" and s["online_stops"] == {"converged": 2}
    assert "t_online_eim_s" in s["timings"] and "t_online_hf_assembly_s" not in s["timings"]
    assert s["collocation_violation_max"] <= 1e-8
    assert s["u_best_max"] <= s["err_u_max"] < 0.05
    assert s["M_eim"] == off.stage.model.info["rows"]


def test_friction_models_take_hyper_eim_and_refuse_other_hypers():
    """Both dual models accept hyper 'eim'; another hyper-reducer is refused with the valid
    values named."""
    scene = load_scene("hertz_friction", overrides=COARSE)
    reg = default_registry()
    for dual in ("collocation", "wedge"):
        _, cfg = prepare_config(scene, make_config(solver="friction-ssn", hyper="eim",
                                                   friction_dual=dual), reg)
        assert cfg.hyper == "eim" and cfg.options.friction_dual == dual
    with pytest.raises(SceneError, match="'none' / 'auto' \\(plain\\) or 'eim'"):
        prepare_config(scene, make_config(solver="friction-ssn", hyper="deim",
                                          friction_dual="collocation"), reg)


def _arrays(obj, seen=None):
    """Every ndarray reachable from ``obj`` (attributes, containers)."""
    seen = set() if seen is None else seen
    if id(obj) in seen:
        return
    seen.add(id(obj))
    if isinstance(obj, np.ndarray):
        yield obj
    elif isinstance(obj, dict):
        for v in obj.values():
            yield from _arrays(v, seen)
    elif isinstance(obj, (list, tuple)):
        for v in obj:
            yield from _arrays(v, seen)
    elif hasattr(obj, "__dict__"):
        yield from _arrays(vars(obj), seen)

"""The hyper-reduced wedge model (rbbench.rb.friction.wedge.hyper): equal to the plain wedge model
(HF operators projected at mu, another code path) to the EIM / DEIM tolerance on the training
mu, picklable, and its online solve touches no HF-size array or HF assembly."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest

from rbbench.rb.config import make_config
from rbbench.rb.friction.wedge.hyper import WedgeHyperModel, slip_deim
from rbbench.rb.friction.wedge.model import WedgeReducedModel, project_wedge
from rbbench.rb.offline import offline
from rbbench.scene.loading import load_scene

COARSE = ["discretization.degree=1", "discretization.h_contact=0.02",
          "discretization.h_max=0.25"]
_CACHE: dict = {}


def _offline(tol_eim: float = 1e-10):
    """Coarse P1 hertz_friction, wedge model, hyper 'eim' (5 training, 2 validation mu)."""
    if tol_eim not in _CACHE:
        import tempfile

        scene = load_scene("hertz_friction", overrides=COARSE)
        cfg = make_config(solver="friction-ssn", n_train=5, n_valid=2, n_jobs=2, N=8, R=4,
                           S=4, stabilizer="pga", k_pga_max=6, hyper="eim", tol_eim=tol_eim,
                          online_repeats=1, friction_dual="wedge",
                          cache_dir=_CACHE.setdefault("dir", tempfile.mkdtemp()))
        _CACHE[tol_eim] = offline(scene, cfg)
    return _CACHE[tol_eim]


def _u_err(ctx, a, b):
    d = a - b
    return float(np.sqrt(d @ (ctx.X @ d) / (b @ (ctx.X @ b))))


@pytest.mark.parametrize("tol_eim", [1e-10, 1e-4])
def test_hyper_wedge_equals_plain_on_training_mu(tol_eim):
    """On every training mu (the EIM and slip DEIM data), the hyper-reduced solve equals the
    plain one (HF operators at mu projected): the relative X distance of u_N is below the
    EIM / DEIM tolerance."""
    off = _offline(tol_eim)
    st, ctx = off.stage, off.context
    model = st.model
    assert isinstance(model, WedgeHyperModel) and st.hyper == "eim"
    assert 0 < model.info["M_s"] < model.info["m"]  # fewer slip nodes than contact nodes
    worst = 0.0
    for mu in ctx.mus_train:
        plain = st.reduced.solve_arrays(mu, project_wedge(ctx.problem_at(mu), st.Z_off,
                                                          st.wedge))
        hyper = model.solve(mu)
        assert plain.stop_reason == hyper.stop_reason == "converged"
        worst = max(worst, _u_err(ctx, st.Z_off @ hyper.a, st.Z_off @ plain.a))
        assert hyper.c.min() >= 0.0  # the cone holds at every node (raw coefficients)
    assert worst < tol_eim, worst  # measured 2e-15 (tol 1e-10), 1.3e-5 (tol 1e-4)


def test_hyper_wedge_pickles_and_touches_no_hf_array(monkeypatch):
    """The pickled model solves the same at a new mu with every HF entry point disabled and
    without its reconstruction basis; apart from that basis (HF size, used by
    ``reconstruct`` only) its pickled state holds no array of HF size (all dimensions far
    below the free dofs; the compiled path's packed plan, rebuilt on use, is not
    pickled)."""
    import rbbench.hf.geometry.operators as cg
    import rbbench.hf.model as ro
    import rbbench.rb.friction.wedge.model as fw

    off = _offline()
    st, ctx = off.stage, off.context
    blob = pickle.dumps(st.model)
    model = pickle.loads(blob)
    mu = np.array([0.5 * (ctx.mus_train[0, 0] + ctx.mus_train[1, 0])])
    ref = st.model.solve(mu)

    def refuse(*a, **k):
        raise AssertionError("HF work in the online stage")

    for mod, name in ((ro, "build_problem"), (cg, "contact_operators"),
                      (fw, "project_wedge")):
        monkeypatch.setattr(mod, name, refuse)
    monkeypatch.setattr(type(ctx.problem_at), "__call__", refuse)
    light = dataclasses.replace(model, basis=None)
    res = light.solve(mu)
    assert res.stop_reason == "converged" and np.array_equal(res.c, ref.c)
    n_free = ctx.X.shape[0]
    dims = [d for a in _arrays(pickle.loads(pickle.dumps(light))) for d in a.shape]
    assert max(dims) < n_free / 10, (max(dims), n_free)
    assert len(pickle.dumps(light)) < 400_000
    np.testing.assert_array_equal(model.reconstruct(res).u, st.Z_off @ res.a)


def test_hyper_wedge_stage_validates_without_hf_assembly():
    """The stage's validation runs the hyper model (EIM evaluation timed apart, no HF
    assembly online); raw reduced multipliers in the Coulomb cone at every HF node."""
    from rbbench.rb.validation import validate

    off = _offline()
    s = validate(off.context, off.stage).summary()
    assert s["hyper"] == "eim" and s["online_stops"] == {"converged": 2}
    assert "t_online_eim_s" in s["timings"] and "t_online_hf_assembly_s" not in s["timings"]
    assert s["friction_residual_max"] <= 1e-12
    assert s["u_best_max"] <= s["err_u_max"] < 0.05


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


def test_slip_deim_interpolates_at_its_nodes():
    """Slip DEIM: exact on its snapshots at full size and exact when there is no slip."""
    rng = np.random.default_rng(0)
    S = np.abs(rng.standard_normal((12, 3)) @ rng.standard_normal((3, 5)))
    P = rng.uniform(0, 1, (4, 12))
    sd = slip_deim(S, P, tol=1e-12)
    np.testing.assert_allclose(sd.PQ @ S[sd.nodes], P @ S, rtol=1e-10)
    zero = slip_deim(np.zeros((12, 3)), P)
    assert zero.info["M_s"] == 0 and not zero.PQ.any()
    assert WedgeReducedModel.__dataclass_fields__.keys() <= \
        WedgeHyperModel.__dataclass_fields__.keys()

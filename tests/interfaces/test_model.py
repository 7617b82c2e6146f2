"""One model interface: ``solve(mu)`` checks mu against D in the HF model and in
both reduced models; a reduced model is built without validation, pickles, and solves the
same as the validated one; the formulations are peers over one offline skeleton."""

from __future__ import annotations

import ast
import pickle
from pathlib import Path

import numpy as np
import pytest

from rbbench.hf.model import HFModel
from rbbench.rb.config import make_config
from rbbench.rb.offline import offline, reduce
from rbbench.registry import default_registry
from rbbench.scene.loading import load_scene
from rbbench.scene.parameters import ParameterSpace, SceneError

MEMBRANE = ("discretization.n_cells=10",)
HERTZ = ("discretization.level=0", "discretization.h_contact=0.02", "discretization.h_max=0.25")


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return str(tmp_path_factory.mktemp("model_cache"))


def _config(cache, **kw):
    base = dict(n_train=5, n_valid=3, N=4, R=4, dual="cpg", stabilizer="none",
                online_repeats=1, cache_dir=cache, n_jobs=1)
    return make_config(**{**base, **kw})


@pytest.mark.parametrize("bad, match", [
    ([99.0, 3.0], "height = 99 is outside its domain"),
    ([0.2, -5.0], "curvature = -5 is outside its domain"),
    ([0.2], "has 2 parameter"),
    ([np.nan, 3.0], "height = nan is outside"),
])
def test_hf_and_reduced_models_reject_the_same_mu(cache, bad, match):
    sc = load_scene("membrane_obstacle", MEMBRANE)
    off = offline(sc, _config(cache), validation_snapshots=False)
    hf = HFModel(sc)
    for model in (hf, off.model):
        assert model.parameters == sc.parameter_space
        with pytest.raises(SceneError, match=match):
            model.solve(bad)


def test_reduced_model_without_validation_pickles_and_matches_the_validated_one(cache):
    sc = load_scene("membrane_obstacle", MEMBRANE)
    cfg = _config(cache, stabilizer="pga")
    off = offline(sc, cfg, validation_snapshots=False)
    assert off.context.valid is None
    res = reduce(sc, cfg)
    mu = np.array([0.23, 4.1])
    a = pickle.loads(pickle.dumps(off.model)).solve(mu)
    b = res.model.solve(mu)
    assert a.stop_reason == b.stop_reason == "converged"
    np.testing.assert_array_equal(a.c, b.c)
    np.testing.assert_array_equal(a.alpha, b.alpha)
    # the reduced solution approximates the HF one at a parameter outside the training set
    sol = HFModel(sc).solve(mu)
    Z = off.stage.Z_off
    u_hf = sol.result.u[sol.problem.free] if sol.result.u.size != Z.shape[0] else sol.result.u
    err = np.linalg.norm(Z @ a.c - u_hf) / np.linalg.norm(u_hf)
    assert err < 0.2


def test_parameter_space_is_the_scenes_domain():
    sc = load_scene("hertz_halfdisks", HERTZ)
    ps = sc.parameter_space
    assert isinstance(ps, ParameterSpace) and ps.names == ("mu",)
    np.testing.assert_array_equal(ps.bounds, sc.bounds)
    assert pickle.loads(pickle.dumps(ps)) == ps
    np.testing.assert_array_equal(ps.check(1.3), [1.3])  # D is closed
    with pytest.raises(SceneError, match=r"mu = 1.3001 is outside its domain \[0.7, 1.3\]"):
        ps.check(1.3001)


def test_formulations_supply_their_steps_and_are_peers():
    reg = default_registry()
    mixed = reg.create("formulation", "mixed").reduction()
    nitsche = reg.create("formulation", "nitsche").reduction()
    assert (mixed.name, nitsche.name) == ("mixed", "nitsche")
    import rbbench.rb.mixed.offline as mo
    import rbbench.rb.nitsche.offline as no
    import rbbench.rb.offline as skeleton

    def imported(mod):
        tree = ast.parse(Path(mod.__file__).read_text())
        return {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)}

    assert not {m for m in imported(mo) if "nitsche" in m}
    assert not {m for m in imported(no) if "mixed_offline" in m}
    # the skeleton knows no formulation: it asks the plugin for its steps
    assert not {m for m in imported(skeleton) if m.endswith("_offline")}


@pytest.mark.parametrize("formulation, hyper, ok", [
    ("mixed", "ecsw", False), ("mixed", "deim", False), ("nitsche", "affine", False),
    ("mixed", "affine", True), ("nitsche", "ecsw", True), ("nitsche", "deim", True),
])
def test_hyper_reducers_declare_their_formulations(formulation, hyper, ok):
    reg = default_registry()
    spec = reg.get("hyper", hyper)
    assert (formulation in spec.capabilities["formulations"]) is ok
    h = reg.create("hyper", hyper)
    if ok:
        h.check(formulation)
    else:
        with pytest.raises(ValueError, match=f"not '{formulation}'"):
            h.check(formulation)


def test_mixed_refuses_a_nitsche_hyper_reducer_before_any_hf_work(tmp_path):
    sc = load_scene("membrane_obstacle", MEMBRANE)
    with pytest.raises(ValueError, match="hyper 'ecsw' applies to the formulation"):
        offline(sc, _config(str(tmp_path), hyper="ecsw"))
    assert not any(tmp_path.iterdir())  # no snapshot was computed


def test_matrices_prune_hyper_reducers_by_their_declared_formulations(tmp_path):
    from rbbench.bench.matrix import load_matrix

    path = tmp_path / "mx.toml"
    path.write_text('[matrix]\nname = "mx"\nscenes = ["hertz_halfdisks"]\n[components]\n'
                    'formulation = ["mixed", "nitsche"]\nsolver = ["ssn", "newton"]\n'
                    'dual = ["cpg"]\nstabilizer = ["none"]\n'
                    'hyper = ["affine", "ecsw", "deim", "eim"]\n[sizes]\nN = [4]\nR = [4]\n')
    m = load_matrix(path, registry=default_registry())
    run = sorted((c.components["formulation"], c.components["hyper"])
                 for c in m.cases if c.status == "run")
    assert run == [("mixed", "affine"), ("mixed", "eim"), ("nitsche", "deim"),
                   ("nitsche", "ecsw"), ("nitsche", "eim")]
    skipped = [c.reason for c in m.cases if c.components["solver"] in ("ssn", "newton")
               and c.status == "skip" and "hyper" in c.reason]
    assert "hyper 'ecsw' does not apply to the 'mixed' formulation" in " ".join(skipped)


def test_a_friction_scene_is_refused_by_components_that_do_not_declare_its_law(tmp_path):
    """No silently frictionless solve: the HF model refuses a frictionless-only solver
    (``ssn``) and the matrix a component that does not declare the friction law
    (``capabilities["friction"]``: ``ssn`` under Nitsche, which now declares Tresca and
    Coulomb, as ``newton`` does); the mixed formulation's friction solvers take it."""
    from rbbench.bench.matrix import compatibility

    sc = load_scene("hertz_halfdisks", [*HERTZ, 'friction.law="coulomb"',
                                        "friction.coefficient=0.2"])
    with pytest.raises(SceneError, match=r"\[friction\] law = 'coulomb'.*'mixed'"):
        HFModel(sc, solver="ssn").solve()
    assert HFModel(sc).names["solver"] == "friction-ssn"
    comp = {"backend": "skfem", "formulation": "nitsche", "solver": "newton", "primal": "pod",
            "dual": "cpg", "stabilizer": "none", "hyper": "auto"}
    assert compatibility(sc, comp, default_registry())[0] == "run"  # Nitsche friction
    status, reason = compatibility(sc, {**comp, "solver": "ssn"}, default_registry())
    assert status == "skip" and "friction law 'coulomb'" in reason
    frictionless = load_scene("hertz_halfdisks", HERTZ)
    comp = {**comp, "formulation": "mixed", "solver": "ssn"}
    assert compatibility(frictionless, comp, default_registry())[0] == "run"


def test_matrix_skips_a_frictionless_solver_and_reduce_refuses_a_friction_scene(tmp_path):
    from rbbench.bench.matrix import compatibility

    sc = load_scene("hertz_halfdisks", [*HERTZ, 'friction.law="coulomb"',
                                        "friction.coefficient=0.2"])
    comp = {"backend": "skfem", "formulation": "mixed", "solver": "ssn", "primal": "pod",
            "dual": "cpg", "stabilizer": "none", "hyper": "auto"}
    status, reason = compatibility(sc, comp, default_registry())
    assert status == "skip" and reason.startswith("solver 'ssn' does not support the friction")
    assert compatibility(sc, {**comp, "solver": "friction-ssn"}, default_registry())[0] == "run"
    # the mixed formulation reduces friction; Nitsche's reduced model does not
    with pytest.raises(SceneError, match="reduced 'nitsche' model supports 'none'"):
        offline(sc, _config(str(tmp_path), formulation="nitsche", solver="newton"))
    assert not any(tmp_path.iterdir())  # refused before any snapshot


def test_friction_solve_writes_the_per_node_contact_table(tmp_path):
    from rbbench.hf.output import contact_table, write_contact_csv

    sc = load_scene("hertz_halfdisks", [*HERTZ, 'friction.law="coulomb"',
                                        "friction.coefficient=0.2",
                                        "load.tangential_displacement=0.002",
                                        "load.load_steps=[{normal = 1.0}, "
                                        "{normal = 1.0, tangential = 1.0}]"])
    sol = HFModel(sc).solve()
    assert sol.result.converged
    table = contact_table(sol)
    n = sol.disc.contact.Mt.shape[1]
    assert all(len(v) == n for v in table.values())
    states = set(table["state"])
    assert states <= {"open", "stick", "slip"} and {"stick", "slip"} <= states
    # slip nodes carry |lam_t| = nu_F lam_n (raw values, Coulomb's slip condition)
    slip = table["state"] == "slip"
    np.testing.assert_allclose(np.abs(table["lam_t"][slip]), 0.2 * table["pressure"][slip],
                               rtol=1e-6, atol=1e-9 * table["pressure"].max())
    text = write_contact_csv(sol, tmp_path).read_text().splitlines()
    assert text[0].startswith("x (m),y (m),pressure (Pa),lam_t (Pa)")
    assert len(text) == n + 1


def test_cli_solve_with_component_options_refuses_an_undeclared_friction_law(capsys):
    """``--backend-option`` builds the components in the CLI: the same name and friction
    checks as :func:`rbbench.hf.components.make_components` run before any meshing."""
    from rbbench.cli import main

    argv = ["solve", "hertz_halfdisks", *sum((["--set", s] for s in [
        *HERTZ, 'friction.law="coulomb"', "friction.coefficient=0.2"]), []),
        "--solver", "ssn", "--backend-option", "mesh=skfem", "--quiet"]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "the 'ssn' solver supports 'none' only" in err and "'friction-ssn'" in err

"""PETSc solver plugins (petsc-vi: SNES VI on the KKT system, petsc-tao: TAO on the dual).

The solver contract itself runs in tests/testing/test_contract.py (every registered solver);
here: agreement with ``ssn``, the sign convention, stop reasons, options, the CLI.
"""

from __future__ import annotations

import contextlib
import io
import json
import subprocess
import sys

import numpy as np
import pytest
import scipy.sparse as sp

pytest.importorskip("petsc4py", reason='petsc4py not installed: pip install "rbbench[petsc]"')

from rbbench_plugins.solvers import petsc as ps  # noqa: E402
from rbbench_plugins.solvers.condensed import SemismoothNewtonSolver  # noqa: E402

from rbbench.cli import main  # noqa: E402
from rbbench.interfaces import STOP_REASONS, ContactProblem  # noqa: E402
from rbbench.registry import default_registry  # noqa: E402
from rbbench.testing import (  # noqa: E402
    HERTZ_COARSE,
    check_solver,
    infeasible_contact_problem,
    random_contact_problem,
    redundant_contact_problem,
)

pytestmark = pytest.mark.timeout(300)

#: (solver class, options): every configuration offered.
CONFIGS = [
    (ps.PetscVISolver, {}),
    (ps.PetscVISolver, {"snes_type": "vinewtonssls"}),
    (ps.PetscVISolver, {"ordering": "nd", "linesearch": "bt"}),
    (ps.PetscTaoSolver, {}),
    (ps.PetscTaoSolver, {"tao_type": "gpcg"}),
    (ps.PetscTaoSolver, {"pc_type": "cholesky"}),
]
CONFIG_IDS = ["vi-rsls", "vi-ssls", "vi-nd-bt", "tao-tron", "tao-gpcg", "tao-cholesky"]


def _one_dof(F: float, G: float) -> ContactProblem:
    """``u + lam = F``, ``u <= G``: contact iff ``F > G`` (then ``u = G, lam = F - G``)."""
    one = sp.csr_matrix(np.ones((1, 1)))
    return ContactProblem(A=one, F=np.array([F]), B=one, G=np.array([G]), free=np.array([0]),
                          u_lift=np.zeros(1), X=one, W=one)


def _rel(a, b) -> float:
    return float(np.linalg.norm(np.asarray(a) - np.asarray(b))
                 / max(np.linalg.norm(b), np.finfo(float).tiny))


# ---------------------------------------------------------------------------
# correctness
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("cls, opts", CONFIGS, ids=CONFIG_IDS)
@pytest.mark.parametrize("F, G, u, lam", [(2.0, 1.0, 1.0, 1.0),    # in contact
                                          (0.5, 1.0, 0.5, 0.0),    # gap stays open
                                          (-1.0, -2.0, -2.0, 1.0)])  # contact, negative gap
def test_sign_convention_on_one_dof(cls, opts, F, G, u, lam):
    # a flipped complementarity sign (R_lam = B u - G) or B^T sign gives another answer
    res = cls(**opts).solve(_one_dof(F, G))
    assert res.stop_reason == "converged", res.info
    assert res.u == pytest.approx([u], abs=1e-12)
    assert res.lam == pytest.approx([lam], abs=1e-12)


@pytest.mark.parametrize("cls, opts", CONFIGS, ids=CONFIG_IDS)
@pytest.mark.parametrize("seed, n, m", [(0, 30, 8), (1, 60, 20), (2, 120, 40), (3, 40, 1),
                                        (4, 200, 60)])
def test_agrees_with_ssn_on_random_problems(cls, opts, seed, n, m):
    prob = random_contact_problem(seed, n=n, m=m)
    ref = SemismoothNewtonSolver(tol=1e-13).solve(prob)
    assert ref.converged
    res = cls(**opts).solve(prob)
    assert res.stop_reason == "converged", res.info
    assert _rel(res.lam, ref.lam) < 1e-9
    assert _rel(res.u, ref.u) < 1e-10
    assert res.info["kkt_errors"]["max"] < 1e-10
    assert res.info["petsc_reason"].startswith("CONVERGED_")
    assert res.residuals and res.residuals[-1] < res.residuals[0]
    key = "snes_s" if cls is ps.PetscVISolver else "tao_s"
    assert res.times[key] > 0
    assert not {"setup_s", "solve_s", "total_s"} & set(res.times)  # the HF driver's keys


@pytest.mark.parametrize("cls, opts", CONFIGS, ids=CONFIG_IDS)
@pytest.mark.parametrize("scale", [1e-9, 1e9])
def test_tolerances_are_scale_invariant(cls, opts, scale):
    # TAO's default absolute gatol (1e-8) stops at the initial guess when the data are
    # small; an absolute SNES atol never triggers when they are large
    prob = random_contact_problem(1, n=60, m=20)
    ref = cls(**opts).solve(prob)
    small = ContactProblem(A=prob.A, F=scale * prob.F, B=prob.B, G=scale * prob.G,
                           free=prob.free, u_lift=scale * prob.u_lift, X=prob.X, W=prob.W)
    res = cls(**opts).solve(small)
    assert res.converged, res.info
    assert _rel(res.lam, scale * ref.lam) < 1e-9
    assert _rel(res.u, scale * ref.u) < 1e-10
    assert res.iterations <= ref.iterations + 1


@pytest.mark.parametrize("cls, opts", CONFIGS, ids=CONFIG_IDS)
@pytest.mark.parametrize("beta", [1e-6, 1e6])
def test_constraint_scaling_is_invisible(cls, opts, beta):
    # B -> beta B, G -> beta G: the same constraints, lam -> lam / beta (the Hertz B is
    # 1e-3 while A is 1e12: multipliers and gaps live on very different scales)
    prob = random_contact_problem(1, n=60, m=20)
    ref = cls(**opts).solve(prob)
    scaled = ContactProblem(A=prob.A, F=prob.F, B=beta * prob.B, G=beta * prob.G,
                            free=prob.free, u_lift=prob.u_lift, X=prob.X, W=prob.W)
    res = cls(**opts).solve(scaled)
    assert res.converged, res.info
    assert _rel(res.lam, ref.lam / beta) < 1e-9
    assert _rel(res.u, ref.u) < 1e-10
    assert res.iterations <= ref.iterations + 1


@pytest.mark.parametrize("cls, opts", CONFIGS, ids=CONFIG_IDS)
def test_passes_the_solver_contract(cls, opts):
    check_solver(cls, options=opts, name=f"{cls.__name__} {opts}")


@pytest.mark.parametrize("cls", [ps.PetscVISolver, ps.PetscTaoSolver])
def test_warm_start_from_the_solution_is_cheap(cls):
    prob = random_contact_problem(5, n=80, m=30)
    cold = cls().solve(prob)
    warm = cls().solve(prob, warm_start=cold.lam)
    assert cold.converged and warm.converged
    assert warm.iterations <= 1 < cold.iterations
    assert _rel(warm.u, cold.u) < 1e-10


@pytest.mark.parametrize("cls, opts", [(ps.PetscVISolver, {}),
                                       (ps.PetscVISolver, {"snes_type": "vinewtonssls"}),
                                       (ps.PetscTaoSolver, {}),
                                       (ps.PetscTaoSolver, {"tao_type": "gpcg"})])
def test_redundant_constraints_converge(cls, opts):
    # duplicated rows of B: singular Delassus operator / zero pivot in the KKT LU
    for seed in range(5):
        prob = redundant_contact_problem(seed)
        ref = SemismoothNewtonSolver().solve(prob)
        res = cls(**opts).solve(prob)
        assert res.converged, res.info
        assert _rel(res.u, ref.u) < 1e-10


def test_vi_zero_pivot_without_shift_is_a_linear_solve_failure():
    res = ps.PetscVISolver(pivot_shift=0.0).solve(redundant_contact_problem(0))
    assert res.info["petsc_reason"] == "DIVERGED_LINEAR_SOLVE"
    assert res.stop_reason == "diverged"


# ---------------------------------------------------------------------------
# stop reasons
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("cls", [ps.PetscVISolver, ps.PetscTaoSolver])
def test_nan_input_stops_with_nan(cls):
    prob = random_contact_problem(0)
    bad = ContactProblem(A=prob.A, F=np.where(np.arange(prob.F.size) == 3, np.nan, prob.F),
                         B=prob.B, G=prob.G, free=prob.free, u_lift=prob.u_lift, X=prob.X,
                         W=prob.W)
    res = cls().solve(bad)
    assert res.stop_reason == "nan"
    assert res.u.shape == prob.u_lift.shape and res.lam.shape == prob.G.shape
    assert cls().solve(prob, warm_start=np.full(prob.G.size, np.nan)).stop_reason == "nan"


@pytest.mark.parametrize("cls, opts", CONFIGS, ids=CONFIG_IDS)
def test_infeasible_problem_is_not_converged(cls, opts):
    for seed in range(3):
        res = cls(**opts).solve(infeasible_contact_problem(seed))
        assert res.stop_reason in STOP_REASONS and res.stop_reason != "converged"
        assert res.info["petsc_reason"]


@pytest.mark.parametrize("cls", [ps.PetscVISolver, ps.PetscTaoSolver])
def test_iteration_limit(cls):
    prob = random_contact_problem(2, n=120, m=40)
    res = cls(max_iter=1).solve(prob)
    assert res.iterations <= 1
    assert res.stop_reason == "max_iterations"
    assert "MAX" in res.info["petsc_reason"]


def test_map_reason():
    assert ps.map_reason("CONVERGED_FNORM_RELATIVE") == "converged"
    assert ps.map_reason("CONVERGED_GATOL") == "converged"
    assert ps.map_reason("DIVERGED_MAX_IT") == "max_iterations"
    assert ps.map_reason("DIVERGED_MAXITS") == "max_iterations"
    assert ps.map_reason("DIVERGED_FUNCTION_NANORINF") == "nan"
    assert ps.map_reason("DIVERGED_NAN") == "nan"
    assert ps.map_reason("DIVERGED_LINE_SEARCH") == "stagnation"
    assert ps.map_reason("CONVERGED_STEPTOL") == "stagnation"
    assert ps.map_reason("CONVERGED_MINF") == "diverged"
    assert ps.map_reason("DIVERGED_LINEAR_SOLVE") == "diverged"
    assert ps.map_reason("CONVERGED_ITERATING") == "diverged"
    PETSc = ps.petsc()
    for enum in (PETSc.SNES.ConvergedReason, PETSc.TAO.ConvergedReason):
        for name, code in vars(enum).items():
            if name.isupper():
                assert ps.map_reason(name) in STOP_REASONS
                assert ps._reason_name(enum, code) in vars(enum)


def test_false_convergence_is_demoted():
    # an impossible KKT tolerance: PETSc converges, our check refuses the claim
    prob = random_contact_problem(0)
    res = ps.PetscVISolver(kkt_tol=0.0).solve(prob)
    assert res.info["petsc_reason"].startswith("CONVERGED_")
    assert res.stop_reason == "stagnation" and "kkt_tol" in res.info["why"]


# ---------------------------------------------------------------------------
# options
# ---------------------------------------------------------------------------
@pytest.mark.parametrize("cls, bad", [(ps.PetscVISolver, "tao_type"),
                                      (ps.PetscTaoSolver, "snes_type")])
def test_unknown_option_names_the_valid_ones(cls, bad):
    with pytest.raises(TypeError, match="valid options: .*max_iter"):
        cls(**{bad: "x"})


def test_invalid_choices():
    with pytest.raises(ValueError, match="vinewtonrsls"):
        ps.PetscVISolver(snes_type="newtonls")
    with pytest.raises(ValueError, match="tron"):
        ps.PetscTaoSolver(tao_type="bqpip")
    with pytest.raises(ValueError, match="nd"):
        ps.PetscVISolver(ordering="amd")


def test_petsc_options_stay_with_their_instance():
    prob = random_contact_problem(2, n=120, m=40)
    capped = ps.PetscVISolver(petsc_options={"snes_max_it": 1})
    plain = ps.PetscVISolver()
    assert capped.prefix != plain.prefix
    assert capped.solve(prob).stop_reason == "max_iterations"
    assert plain.solve(prob).converged  # not affected by the other instance's options
    db = ps.petsc().Options()
    assert not db.hasName(f"{capped.prefix}snes_max_it")  # removed after the solve
    tao = ps.PetscTaoSolver(petsc_options={"tao_max_it": 1})
    assert tao.solve(prob).stop_reason == "max_iterations"
    assert ps.PetscTaoSolver().solve(prob).converged


def test_registered_and_core_does_not_import_petsc():
    reg = default_registry()
    assert isinstance(reg.create("solver", "petsc-vi"), ps.PetscVISolver)
    assert isinstance(reg.create("solver", "petsc-tao", tao_type="gpcg"), ps.PetscTaoSolver)
    code = ("import sys, rbbench, rbbench.hf.model, rbbench.cli, rbbench.hf.solvers.lcp, "
            "rbbench.testing; "
            "rbbench.registry.default_registry(); "
            "assert 'petsc4py' not in sys.modules, 'petsc4py imported by the core'")
    subprocess.run([sys.executable, "-c", code], check=True, timeout=120)


# ---------------------------------------------------------------------------
# the Hertz scene through the CLI
# ---------------------------------------------------------------------------
def _cli_summary(tmp_path, solver: str) -> dict:
    out = tmp_path / solver
    argv = ["solve", "hertz_halfdisks", "--solver", solver, "--out", str(out), "--quiet",
            "--no-plot"]
    for ov in HERTZ_COARSE:
        argv += ["--set", ov]
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        rc = main(argv)
    assert rc == 0
    return json.loads((out / "summary.json").read_text())


def test_hertz_contact_force_matches_ssn(tmp_path):
    ref = _cli_summary(tmp_path, "ssn")
    assert ref["stop_reason"] == "converged" and ref["n_active"] > 2
    for solver in ("petsc-vi", "petsc-tao"):
        s = _cli_summary(tmp_path, solver)
        assert s["stop_reason"] == "converged", s["solver_info"]
        assert s["solver_info"]["petsc_reason"].startswith("CONVERGED_")
        assert s["n_active"] == ref["n_active"]
        assert s["contact_force"] == pytest.approx(ref["contact_force"], rel=1e-6)
        assert s["max_pressure"] == pytest.approx(ref["max_pressure"], rel=1e-6)
        inner = s["times_s"].get("snes_s", s["times_s"].get("tao_s"))
        assert 0 < inner <= s["times_s"]["solve_s"]  # the driver's solve time is kept


@pytest.fixture(scope="module")
def hertz_coarse_problem():
    from rbbench.hf.components import make_components
    from rbbench.scene.loading import load_scene

    scene = load_scene("hertz_halfdisks", list(HERTZ_COARSE))
    backend, formulation, _ = make_components(scene)
    return formulation.build(backend.discretize(1.0))


def test_hertz_vi_follows_the_active_set_rule_of_ssn(hertz_coarse_problem):
    prob = hertz_coarse_problem
    ref = SemismoothNewtonSolver(tol=1e-13).solve(prob)
    vi = ps.PetscVISolver().solve(prob)
    assert vi.converged and ref.converged
    assert _rel(vi.lam, ref.lam) < 1e-10
    # one extra step (the first one ignores contact); without the rounding guard
    # vinewtonrsls re-solves wrongly kept constraints (50 iterations measured here)
    assert vi.iterations <= ref.iterations + 1
    assert vi.info["degenerate_guarded"] > 0


def test_hertz_vi_rounding_guard_saves_iterations():
    """Without the guard, vinewtonrsls re-solves wrongly kept constraints: more iterations
    at every mu of a sweep, more than twice as many in total (which constraints round the
    wrong way depends on the last bits of A, so no single mu is a fair sample: at mu = 1
    the unguarded run once took 20+ steps, after a round-off change of A 10 against 6)."""
    from rbbench.hf.components import make_components
    from rbbench.scene.loading import load_scene

    scene = load_scene("hertz_halfdisks", list(HERTZ_COARSE))
    backend, formulation, _ = make_components(scene)
    guarded = unguarded = 0
    for mu in (0.8, 0.9, 1.0, 1.1, 1.2):
        prob = formulation.build(backend.discretize(mu))
        vi = ps.PetscVISolver().solve(prob)
        raw = ps.PetscVISolver(degenerate_tol=0.0, max_iter=20).solve(prob)
        assert vi.converged and vi.info["degenerate_guarded"] > 0
        assert raw.iterations > vi.iterations, mu
        guarded, unguarded = guarded + vi.iterations, unguarded + raw.iterations
    assert unguarded > 2 * guarded


@pytest.mark.parametrize("cls, opts", CONFIGS, ids=CONFIG_IDS)
def test_hertz_agrees_with_ssn(hertz_coarse_problem, cls, opts):
    prob = hertz_coarse_problem
    ref = SemismoothNewtonSolver(tol=1e-13).solve(prob)
    res = cls(**opts).solve(prob)
    assert res.converged, res.info
    assert _rel(res.lam, ref.lam) < 1e-9
    assert _rel(res.u, ref.u) < 1e-10

"""PETSc friction: SNES VI and TAO on the condensed Tresca box QP, Coulomb and model B by the
fixed point of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods:
parametric variational inequalities" (talk) around them.

Every PETSc solution is checked against the primal-dual active set
(:func:`rbbench.hf.solvers.friction.pdas_tresca`, an independent algorithm) or against
``friction-ssn``, and its reported residuals against the definitions in
:func:`rbbench.hf.algebra.friction.friction_residuals` on the raw multipliers.
"""

from __future__ import annotations

from collections import Counter

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

pytest.importorskip("petsc4py", reason='petsc4py not installed: pip install "rbbench[petsc]"')

from rbbench_plugins.solvers.friction import FrictionSSNSolver  # noqa: E402
from rbbench_plugins.solvers.petsc.tao import PetscTaoSolver  # noqa: E402
from rbbench_plugins.solvers.petsc.vi import PetscVISolver

from rbbench.hf.algebra import friction as fa  # noqa: E402
from rbbench.hf.components import make_components  # noqa: E402
from rbbench.hf.solvers import friction as fs  # noqa: E402
from rbbench.interfaces import STOP_REASONS, FrictionLaw  # noqa: E402
from rbbench.scene.loading import load_scene  # noqa: E402

pytestmark = pytest.mark.timeout(300)

#: the PETSc configurations that solve the box QP (TAO gpcg: see the extremes test)
PETSC = [(PetscVISolver, {}), (PetscVISolver, {"snes_type": "vinewtonssls"}),
         (PetscTaoSolver, {})]
PETSC_IDS = ["vi-rsls", "vi-ssls", "tao-tron"]
#: mindlin_cylinders' Tresca threshold (Pa) where stick (8 nodes) and slip (11) coexist on
#: the coarse mesh (p0 ~ 1e9 Pa; 4e7: all slip, 8e7: all stick)
S_MIXED = 5e7
KEYS = {*fa.RESIDUAL_NAMES, "max"}


def _random_tresca(seed: int, m: int) -> tuple[np.ndarray, np.ndarray]:
    """A random SPD ``D`` and ``q`` of the physical orders (D ~ 1e-13 m^2/Pa, q ~ 1e-5 m)."""
    rng = np.random.default_rng(seed)
    M = rng.standard_normal((2 * m, 2 * m))
    D = (M @ M.T / (2 * m) + 0.05 * np.eye(2 * m)) * 1e-13
    return D, rng.standard_normal(2 * m) * 1e-5


def _rel(x: np.ndarray, ref: np.ndarray) -> float:
    return float(np.abs(x - ref).max() / max(np.abs(ref).max(), np.finfo(float).tiny))


@pytest.mark.parametrize(("cls", "opts"), PETSC, ids=PETSC_IDS)
@settings(max_examples=25, deadline=None, derandomize=True)
@given(seed=st.integers(0, 10_000), m=st.integers(1, 15),
       log_s=st.one_of(st.just(-np.inf), st.floats(4.0, 12.0)))
def test_tresca_equals_pdas_on_random_spd(cls, opts, seed, m, log_s):
    """The same box QP, two algorithms: multipliers within 1e-10 of max|x|, the residuals
    reported are the ones recomputed here, below kkt_tol."""
    D, q = _random_tresca(seed, m)
    s = 10.0**log_s
    ref = fs.pdas_tresca(D, q, s)
    r = cls(**opts).tresca(D, q, s)
    assert ref.stop_reason == "converged"
    assert r.stop_reason == "converged", (r.info.get("petsc_reason"), r.info.get("why"))
    assert isinstance(r.info["petsc_reason"], str)
    assert _rel(r.x, ref.x) <= 1e-10
    assert r.residuals == fa.friction_residuals(D, q, r.lam_n, r.lam_t, np.full(m, s))
    assert r.residuals["max"] <= 1e-8 and set(r.residuals) == KEYS


@pytest.mark.parametrize(("cls", "opts"), PETSC, ids=PETSC_IDS)
def test_nan_data_stops_with_nan(cls, opts):
    D, q = _random_tresca(0, 4)
    q[1] = np.nan
    r = cls(**opts).tresca(D, q, 1e6)
    assert r.stop_reason == "nan" and r.info["petsc_reason"] == "not run"


@pytest.fixture(scope="module")
def mindlin():
    """mindlin_cylinders on the coarse contact mesh of tests/hf/references/test_mindlin_scene.py (33
    friction nodes): its discretisation and mixed formulation. Tresca is built through
    ``build(friction=...)``: the scene's ``coefficient`` key cannot be removed by an
    override, and ``law = "tresca"`` with it is refused."""
    sc = load_scene("mindlin_cylinders", ["discretization.h_contact=0.002"])
    b, f, _ = make_components(sc)
    return b.discretize(sc.default_mu), f


def _solve(mindlin, law: FrictionLaw, solver):
    disc, f = mindlin
    prob = f.build(disc, friction=law)
    return prob, solver.solve(prob)


def _agree(res, ref, rtol: float) -> None:
    scale = ref.lam.max()
    assert np.abs(res.lam - ref.lam).max() <= rtol * scale
    assert np.abs(res.info["lam_t"] - ref.info["lam_t"]).max() <= rtol * scale
    assert np.abs(res.u - ref.u).max() <= rtol * np.abs(ref.u).max()


@pytest.mark.parametrize(("cls", "opts"), [PETSC[0], PETSC[2]], ids=["vi-rsls", "tao-tron"])
def test_mindlin_tresca_equals_friction_ssn(mindlin, cls, opts):
    """Stick and slip coexist; both load steps converge with PETSc's reason per solve and
    the friction residuals under the same keys as friction-ssn."""
    law = FrictionLaw("tresca", threshold=S_MIXED)
    _, ref = _solve(mindlin, law, FrictionSSNSolver())
    prob, res = _solve(mindlin, law, cls(**opts))
    assert res.converged, res.info["load_steps"]
    assert [s["stop_reason"] for s in res.info["load_steps"]] == ["converged"] * 2
    assert res.info["petsc_reason"].startswith("CONVERGED_")
    assert set(res.info["friction_residuals"]) == set(ref.info["friction_residuals"]) == KEYS
    assert res.info["friction_residuals"]["max"] <= 1e-10
    states = Counter(res.info["states"])
    assert states["stick"] > 0 and states["slip"] > 0
    assert list(res.info["states"]) == list(ref.info["states"])
    _agree(res, ref, 1e-9)


def test_mindlin_tresca_ssls_is_slow_and_says_so(mindlin):
    """vinewtonssls (Fischer-Burmeister) on the sheared step: measured 117 iterations to
    converge; at its default limit of 50 it stops with PETSc's DIVERGED_MAX_IT, i.e.
    "max_iterations", and the load steps stop there; with 500 it equals friction-ssn."""
    law = FrictionLaw("tresca", threshold=S_MIXED)
    _, res = _solve(mindlin, law, PetscVISolver(snes_type="vinewtonssls"))
    assert res.stop_reason == "max_iterations" and res.info["petsc_reason"] == "DIVERGED_MAX_IT"
    assert [s["stop_reason"] for s in res.info["load_steps"]] == ["converged", "max_iterations"]
    _, ref = _solve(mindlin, law, FrictionSSNSolver())
    _, res = _solve(mindlin, law, PetscVISolver(snes_type="vinewtonssls", max_iter=500))
    assert res.converged
    _agree(res, ref, 1e-9)


@pytest.mark.parametrize(("cls", "opts"),
                         [*PETSC, (PetscTaoSolver, {"tao_type": "gpcg"})],
                         ids=[*PETSC_IDS, "tao-gpcg"])
def test_mindlin_tresca_extremes_converge_or_stop_with_a_reason(mindlin, cls, opts):
    """s in {0, 1e-3 Pa, 1e20 Pa}: a stop reason of the contract; a "converged" solve
    satisfies every condition (never a false convergence); s = 0 gives lam_t = 0 exactly,
    a huge s no slipping node. Measured: every configuration converges except TAO gpcg,
    which stops on its iteration limit at s = 0 and 1e20 on random problems."""
    for s in (0.0, 1e-3, 1e20):
        _, res = _solve(mindlin, FrictionLaw("tresca", threshold=s), cls(**opts))
        assert res.stop_reason in STOP_REASONS and isinstance(res.info["petsc_reason"], str)
        if not res.converged:
            continue
        assert res.info["friction_residuals"]["max"] <= 1e-8
        if s == 0.0:
            assert np.all(res.info["lam_t"] == 0.0)
        if s == 1e20:
            assert "slip" not in res.info["states"]


@pytest.mark.parametrize("cls", [PetscVISolver, PetscTaoSolver], ids=["vi", "tao"])
def test_mindlin_coulomb_and_model_b_by_the_fixed_point_on_petsc_tresca(mindlin, cls):
    """Coulomb (nu_F = 0.2) and model B: Benaceur et al.'s fixed point with SNES VI / TAO inside
    equals friction-ssn's fixed point on PDAS (1e-9) and reports its contraction and the
    last inner PETSc reason."""
    for law in (FrictionLaw("coulomb", coefficient=0.2),
                FrictionLaw("coulomb", coefficient_law="model_b")):
        _, ref = _solve(mindlin, law, FrictionSSNSolver(method="fixed_point"))
        _, res = _solve(mindlin, law, cls())
        assert res.converged and ref.converged, res.info.get("why")
        assert res.info["inner_petsc_reason"].startswith("CONVERGED_")
        assert "contraction" in res.info
        _agree(res, ref, 1e-9)
        states = Counter(res.info["states"])
        assert states["stick"] > 0 and states["slip"] > 0

"""The Delassus operator as the Schur complement of the KKT matrix.

The new path (:func:`rbbench.hf.condensation.schur.condense_schur`, SuperLU or PARDISO) against
today's dense ``A^{-1} B^T`` (:func:`rbbench.hf.condensation.dense.condense`,
``condensation="columns"``) and against dense linear algebra written out here; on raw values (``D``,
``q``, ``u``, ``lam``), never after clipping.
"""

from __future__ import annotations

import types

import numpy as np
import pytest
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from rbbench.hf.condensation import schur as cd
from rbbench.hf.condensation.dense import condense, factorize
from rbbench.hf.condensation.pardiso import available as pardiso_available
from rbbench.registry import default_registry

SOLVERS = ["superlu"] + (["pardiso"] if pardiso_available() else [])


def _rel(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return float(np.abs(a - b).max() / max(np.abs(b).max(), 1e-300))


def _problem(n: int = 60, m: int = 8, seed: int = 0, zero_row: bool = True):
    """A random SPD ``A`` (a perturbed 1D Laplacian), a sparse ``B`` (row 3 zero)."""
    rng = np.random.default_rng(seed)
    lap = sp.diags([-np.ones(n - 1), 2.5 * np.ones(n), -np.ones(n - 1)], [-1, 0, 1])
    R = sp.random(n, n, density=0.03, random_state=seed)
    A = (lap + 0.1 * (R @ R.T)).tocsr()
    B = sp.random(m, n, density=0.1, random_state=seed + 1).tolil()
    for i in range(m):
        B[i, rng.integers(n)] = 1.0 + rng.random()
    if zero_row:
        B[3, :] = 0.0
    return A, rng.standard_normal(n), B.tocsr(), rng.standard_normal(m)


def test_kkt_matrix_is_the_saddle_point_matrix_and_its_lower_triangle():
    A, _, B, _ = _problem()
    n, m = B.shape[1], B.shape[0]
    ref = np.block([[A.toarray(), B.toarray().T], [B.toarray(), np.zeros((m, m))]])
    K = cd.kkt_matrix(A, B)
    assert np.array_equal(K.toarray(), ref) and K.has_sorted_indices
    assert np.array_equal(np.diff(K.indptr)[n:], np.diff(B.indptr) + m)  # the zero block
    assert np.array_equal(cd.kkt_matrix(A, B, lower=True).toarray(), np.tril(ref))


@pytest.mark.parametrize("solver", SOLVERS)
def test_schur_condensation_equals_the_dense_columns(solver):
    A, F, B, G = _problem()
    ref = condense(A, F, B, G)
    new = cd.condense_schur(A, F, B, G, linear_solver=solver)
    Ad, Bd = A.toarray(), B.toarray()
    D_dense = Bd @ np.linalg.solve(Ad, Bd.T)
    assert _rel(new.D, D_dense) < 1e-12 and _rel(ref.D, D_dense) < 1e-12
    assert np.all(new.D[3] == 0) and np.all(new.D[:, 3] == 0)  # zero row of B left out
    assert new.info["kkt_size"] == 60 + 7
    if solver == "superlu":  # minimum degree put a multiplier early: the reordered path
        assert new.info["reordered"]
    assert _rel(new.q, ref.q) < 1e-12
    lam = np.abs(np.random.default_rng(1).standard_normal(G.size))
    assert _rel(new.displacement(lam), np.linalg.solve(Ad, F - Bd.T @ lam)) < 1e-12
    F2, G2 = F[::-1].copy(), G + 1.0  # another load, same factorisation
    assert _rel(new.load(F2, G2).q, ref.load(F2, G2).q) < 1e-12
    assert _rel(new.load(F2, G2).displacement(lam), ref.load(F2, G2).displacement(lam)) < 1e-12


@pytest.mark.parametrize("solver", SOLVERS)
def test_no_active_row_is_the_plain_solve(solver):
    A, F, B, G = _problem()
    cond = cd.condense_schur(A, F, 0.0 * B, G, linear_solver=solver)
    assert np.all(cond.D == 0) and np.array_equal(cond.q, G)
    assert _rel(cond.displacement(np.ones(G.size)), np.linalg.solve(A.toarray(), F)) < 1e-12


def test_trailing_schur_eliminates_dofs_ordered_after_the_multipliers():
    A, _, B, _ = _problem(zero_row=False)
    n, m = B.shape[1], B.shape[0]
    K = cd.kkt_matrix(A, B)
    order = np.concatenate([np.arange(n - 5), n + np.arange(m), np.arange(n - 5, n)])
    lu = spla.splu(K[order][:, order].tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0,
                   options={"SymmetricMode": True})
    pos = lu.perm_c[np.argsort(order)]  # the position of every original variable
    D, k = cd._trailing_schur(types.SimpleNamespace(L=lu.L, U=lu.U, perm_c=pos, perm_r=pos),
                              n, m)
    Bd = B.toarray()
    assert k == 5
    assert _rel(D, Bd @ np.linalg.solve(A.toarray(), Bd.T)) < 1e-12


def test_dependent_rows_fall_back_to_the_columns_and_say_so():
    A, F, B, G = _problem(zero_row=False)
    B2 = sp.vstack([B, B[:1]]).tocsr()  # a repeated row: K singular
    cond = cd.condense_problem(A, F, B2, np.append(G, G[0]), linear_solver="superlu")
    assert "columns" in cond.info["fallback"] and cond.info["condensation"] == "columns"
    ref = condense(A, F, B2, np.append(G, G[0]))
    assert _rel(cond.D, ref.D) == 0.0


def test_options_are_checked_and_auto_keeps_a_backend_solver():
    with pytest.raises(ValueError, match="condensation = 'dense'.*'schur', 'columns'"):
        default_registry().create("solver", "ssn", condensation="dense")
    with pytest.raises(ValueError, match="linear_solver = 'mumps'.*'superlu', 'pardiso'"):
        default_registry().create("solver", "friction-ssn", linear_solver="mumps")
    A, F, B, G = _problem()
    calls = []

    def backend(M):
        calls.append(M.shape)
        return factorize(M).solve

    cond = cd.condense_problem(A, F, B, G, factorize=backend)
    assert calls == [A.shape] and cond.info["linear_solver"] == "backend"
    cond = cd.condense_problem(A, F, B, G, linear_solver="superlu", factorize=backend)
    assert calls == [A.shape] and cond.info["condensation"] == "schur"


@pytest.fixture(scope="module")
def coarse_hertz():
    """The contract suite's coarse Hertz problem (8888 dofs, 64 multipliers) at mu = 1."""
    from rbbench.hf.components import make_components
    from rbbench.scene.loading import load_scene
    from rbbench.testing import HERTZ_COARSE

    sc = load_scene("hertz_halfdisks", list(HERTZ_COARSE))
    b, f, _ = make_components(sc)
    return f.build(b.discretize(sc.default_mu))


@pytest.mark.parametrize("solver", SOLVERS)
def test_ssn_on_hertz_gives_todays_solution(coarse_hertz, solver):
    reg = default_registry()
    ref = reg.create("solver", "ssn", condensation="columns").solve(coarse_hertz)
    new = reg.create("solver", "ssn", linear_solver=solver).solve(coarse_hertz)
    assert ref.converged and new.converged and ref.info["condensation"] == "columns"
    assert new.info["condensation"] == "schur"
    assert new.info["condensation_linear_solver"] == solver
    assert _rel(new.u, ref.u) < 1e-10 and _rel(new.lam, ref.lam) < 1e-10
    assert new.iterations == ref.iterations


def test_friction_ssn_over_load_steps_gives_todays_solution():
    """Sheared Coulomb scene of tests/hf/solvers/test_friction.py (two load steps): u, lam_n,
    lam_t."""
    from rbbench.hf.components import friction_at, make_components
    from rbbench.scene.loading import load_scene

    sc = load_scene("hertz_halfdisks", [
        "discretization.level=0", "discretization.h_contact=0.04",
        "discretization.h_max=0.25", 'discretization.multiplier="p1"',
        'friction.law="coulomb"', "friction.coefficient=0.2",
        "load.tangential_displacement=0.002",
        "load.load_steps=[{normal = 1.0}, {normal = 1.0, tangential = 1.0}]"])
    b, f, _ = make_components(sc)
    prob = f.build(b.discretize(sc.default_mu), friction=friction_at(sc, sc.default_mu))
    reg = default_registry()
    ref = reg.create("solver", "friction-ssn", condensation="columns").solve(prob)
    new = reg.create("solver", "friction-ssn", linear_solver="superlu").solve(prob)
    assert ref.converged and new.converged and new.info["condensation"] == "schur"
    assert _rel(new.u, ref.u) < 1e-10 and _rel(new.lam, ref.lam) < 1e-10
    assert _rel(new.info["lam_t"], ref.info["lam_t"]) < 1e-10
    assert list(new.info["states"]) == list(ref.info["states"])


@pytest.mark.skipif("pardiso" not in SOLVERS, reason="pypardiso not installed")
def test_pardiso_solves_in_halves_around_the_schur_block():
    """PARDISO's KKT factorisation (Schur block left unfactorised): the forward half leaves
    ``q = G - B A^{-1} F`` in the multiplier rows, the backward half with ``lam`` there gives
    ``u = A^{-1} (F - B^T lam)``, and ``solve`` is ``K^{-1}`` (dense references)."""
    A, F, B, G = _problem(zero_row=False)
    fac = cd.schur_factor(A, B, "pardiso")
    n, m = B.shape[1], B.shape[0]
    Ad, Bd = A.toarray(), B.toarray()
    K = np.block([[Ad, Bd.T], [Bd, np.zeros((m, m))]])
    b = np.concatenate([F, G])
    w = fac.halves.forward(b)
    assert _rel(w[n:], G - Bd @ np.linalg.solve(Ad, F)) < 1e-12
    lam = np.random.default_rng(2).standard_normal(m)
    w[n:] = lam
    assert _rel(fac.halves.backward(w)[:n], np.linalg.solve(Ad, F - Bd.T @ lam)) < 1e-12
    assert _rel(fac.solve(b), np.linalg.solve(K, b)) < 1e-12
    X = np.random.default_rng(3).standard_normal((n + m, 2))
    assert _rel(fac.solve(X), np.linalg.solve(K, X)) < 1e-12


@pytest.mark.skipif("pardiso" not in SOLVERS, reason="pypardiso not installed")
def test_pardiso_floor_factorisation_takes_spd_and_indefinite_matrices():
    """The floor's ``factorized``: Cholesky for an SPD stiffness, and a symmetric
    indefinite matrix (which Cholesky refuses) still solved exactly by LDL^T."""
    from rbbench.hf.condensation.pardiso import factorized

    A, F, _, _ = _problem(zero_row=False)
    assert _rel(factorized(A)(F), np.linalg.solve(A.toarray(), F)) < 1e-12
    Kd = np.array([[1.0, 2.0, 0.0], [2.0, 1.0, 1.0], [0.0, 1.0, -3.0]])
    b = np.array([1.0, -2.0, 0.5])
    assert _rel(factorized(sp.csr_matrix(Kd))(b), np.linalg.solve(Kd, b)) < 1e-12

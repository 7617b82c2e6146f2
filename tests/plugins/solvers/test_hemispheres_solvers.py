"""Every mixed HF solver on the 3D Hertz hemispheres (level 0) against ``ssn``: multipliers
and whole-body contact force within a rigorous a posteriori bound of each solution's own
natural residual, and that residual within the solver's stopping tolerance.

The bound: ``D`` (the Delassus matrix, symmetric positive definite) scaled by
``c = 1 / mean(diag D)`` (the condensed solvers' own scaling), ``M = c D`` with extreme
eigenvalues ``sigma`` and ``L``, the natural residual ``r = min(lam, c (D lam + q))``. Then
``y = lam - r`` solves the LCP with ``q' = c q + (M - I) r`` (``y`` and ``M y + q'`` are
nonnegative and complementary componentwise), and the LCP of a matrix with
``x^T M x >= sigma |x|^2`` is ``1 / sigma``-Lipschitz in ``q``, so
``|lam - lam*| <= |r| + |(M - I) r| / sigma <= (1 + (1 + L) / sigma) |r|``.
"""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla

from rbbench.hf.components import make_components
from rbbench.hf.condensation.dense import delassus_scaling
from rbbench.hf.condensation.schur import condense_problem
from rbbench.hf.metrics3d import symmetry_factor
from rbbench.hf.model import solve_hf
from rbbench.registry import default_registry
from rbbench.scene.loading import load_scene

pytestmark = [pytest.mark.timeout(600), pytest.mark.netgen]

#: (solver, options, the stopping tolerance on r / (c |q|) or None: the PETSc solvers stop
#: on their own measures, checked through their stop reason)
SOLVERS = [
    ("ssn", {"condensation": "columns"}, 1e-10),
    ("ssn", {"condensation": "schur", "linear_solver": "superlu"}, 1e-10),
    ("uzawa", {}, 1e-9),
    ("uzawa", {"condensation": "columns"}, 1e-9),
    ("petsc-tao", {}, None),
    ("petsc-vi", {}, None),
]


@pytest.fixture(scope="module")
def reference():
    """The scene at level 0, its components (meshed once), the ``ssn`` solution and the
    columns-condensed ``D``, ``q`` with the bound's constants."""
    scene = load_scene("hertz_sphere", overrides=["discretization.level=0"])
    b, f, s = make_components(scene, "skfem", "mixed", "ssn")
    ref = solve_hf(scene, None, "skfem", "mixed", "ssn", components=(b, f, s), floor=False)
    p = ref.problem
    cond = condense_problem(p.A, p.F, p.B, p.G, condensation="columns")
    c = delassus_scaling(cond.D)
    ev = sla.eigvalsh(c * cond.D)
    assert ev[0] > 0  # symmetric positive definite: the bound applies
    c_con = ref.disc.contact
    # the force is linear in lam: its gradient
    grad = symmetry_factor(ref.disc.info["geometry"]) * np.asarray(
        c_con.Mlam.T @ (c_con.weights * -c_con.normals[:, 2])).ravel()
    return {"scene": scene, "backend": b, "formulation": f, "ref": ref, "D": cond.D,
            "q": cond.q, "c": c, "amp": 1.0 + (1.0 + ev[-1]) / ev[0], "grad": grad}


def _residual(R, lam):
    return float(np.linalg.norm(np.minimum(lam, R["c"] * (R["D"] @ lam + R["q"]))))


def test_the_reference_is_a_3d_contact_with_several_active_multipliers(reference):
    m = reference["ref"].metrics
    assert m["dim"] == 3 and m["converged"] and m["n_active"] >= 4
    lam = reference["ref"].result.lam
    # ssn is exact on its final active set: its bound is at round-off
    assert reference["amp"] * _residual(reference, lam) <= 1e-10 * np.linalg.norm(lam)


@pytest.mark.parametrize("solver, options, tol", SOLVERS,
                         ids=[f"{s}-{'-'.join(map(str, o.values())) or 'default'}"
                              for s, o, _ in SOLVERS])
def test_solver_agrees_with_ssn_within_its_residual_bound(reference, solver, options, tol):
    reg = default_registry()
    spec = reg.get("solver", solver)
    ok, why = reg.availability(spec)
    if not ok:
        pytest.skip(why)
    R = reference
    sol = solve_hf(R["scene"], None, "skfem", "mixed", solver,
                   components=(R["backend"], R["formulation"], reg.create("solver", solver,
                                                                          **options)),
                   floor=False)
    assert sol.result.converged, sol.result.stop_reason
    lam, lam_ref = sol.result.lam, R["ref"].result.lam
    r, r_ref = _residual(R, lam), _residual(R, lam_ref)
    if tol is not None:  # the residual the solver stopped on (condensed solvers: the same)
        assert r <= tol * R["c"] * np.linalg.norm(R["q"]) * (1 + 1e-6)
    bound = R["amp"] * (r + r_ref)  # both within their bounds of the one solution
    assert np.linalg.norm(lam - lam_ref) <= bound
    f, f_ref = sol.metrics["contact_force"], R["ref"].metrics["contact_force"]
    assert abs(f - f_ref) <= np.linalg.norm(R["grad"]) * bound
    # the bound is tight enough to mean something: the stopping tolerances give
    # relative multiplier errors of at most 1e-5 here
    assert bound <= 1e-5 * np.linalg.norm(lam_ref)
    assert sol.metrics["contact_radius"] == pytest.approx(R["ref"].metrics["contact_radius"])

"""The labelled numbers of an HF solution (``summary.json``): contact force, half-widths,
pressure, complementarity, penetration, friction and Nitsche outputs, the Hertz and
Cattaneo-Mindlin checks, and :data:`DEFINITIONS`, what each number is."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import scipy.sparse as sp

from rbbench.hf.geometry.checks import gap_checks
from rbbench.hf.references.hertz import hertz_of_bodies
from rbbench.hf.references.mindlin import MINDLIN_DEFINITION, mindlin_metrics
from rbbench.interfaces import (
    FrictionProblem,
    NitscheFrictionProblem,
    NitscheProblem,
    SolveResult,
)
from rbbench.runtime.threads import BLAS_THREADS_DEFINITION

#: Relative threshold on lam (w.r.t. max lam) above which a multiplier counts as active.
ACTIVE_THRESHOLD = 1e-8


#: Poisson's ratio from which P1 displacements are flagged for volumetric locking
NU_LOCKING = 0.45


def locking_warnings(degree: int, nus: dict[str, float]) -> list[str]:
    """A warning per body whose Poisson's ratio is at least :data:`NU_LOCKING` when the
    displacements are P1: linear triangles lock as nu -> 1/2 (the discrete divergence-free
    space is too small; Brenner & Scott, ch. 11), so stresses and contact pressures are
    wrong without any solver failure."""
    if degree != 1:
        return []
    return [f"body {name!r}: nu = {nu:g} >= {NU_LOCKING:g} with P1 displacements "
            "(discretization.degree = 1): volumetric locking makes stresses and contact "
            "pressures unreliable; use discretization.degree = 2 (P2) or a mixed u-p element"
            for name, nu in nus.items() if nu >= NU_LOCKING]


def nitsche_discretization_warnings(disc_data: dict[str, Any]) -> list[str]:
    """A warning when a Nitsche solve uses facet normals or Gauss-point-to-segment contact
    integration: each alone keeps Benaceur et al.'s e_AC from converging under mesh
    refinement (docs: user guide, Nitsche). They stay the defaults because the hyper-reducers
    of the reduced Nitsche model (EIM, ECSW) evaluate fixed contact points online, which
    segmented integration moves with mu, and because earlier results stay bit for bit."""
    normals = disc_data.get("normals", "facet")
    integration = disc_data.get("contact_integration", "gauss")
    if normals == "smooth" and integration == "segmented":
        return []
    return [f"Nitsche with discretization.normals = {normals!r} and "
            f"discretization.contact_integration = {integration!r}: e_AC does not converge "
            "under mesh refinement with these; set normals = \"smooth\" and "
            "contact_integration = \"segmented\" for a first-order e_AC (segmented "
            "integration is refused by the EIM and ECSW hyper-reducers)"]


def contact_metrics(sol: Any) -> dict[str, Any]:
    """Labelled contact quantities of an HF solution (:class:`rbbench.hf.model.HFSolution`;
    see ``definitions`` in the output)."""
    disc, res, prob = sol.disc, sol.result, sol.problem
    c = disc.contact
    lam = res.lam
    u = res.u
    B, G, basis, extent = normal_operators(prob, c)
    s = G - B @ u  # weighted gap per multiplier
    support = np.asarray(basis.T @ c.weights).ravel()  # int phi_i
    lam_q = np.asarray(basis @ lam).ravel()
    if disc.physics == "elasticity":
        force = float(np.sum(c.weights * lam_q * -c.normals[:, 1]))
    else:
        force = float(np.sum(c.weights * lam_q))
    extra = (_nitsche_metrics(prob, res, c) if isinstance(prob, NitscheProblem)
             else _friction_metrics(prob, res, c) if isinstance(prob, FrictionProblem) else {})
    if isinstance(prob, NitscheFrictionProblem):
        extra.update(_nitsche_friction_metrics(prob, res, c))
    force = extra.get("contact_force", force)
    lam_max = float(np.max(lam)) if lam.size else 0.0
    active = lam > ACTIVE_THRESHOLD * max(lam_max, np.finfo(float).tiny)
    if active.any():
        half_width = 0.5 * float(extent[active, 1].max() - extent[active, 0].min())
        saturated = bool(active[0] or active[-1]) if disc.physics == "elasticity" else False
    else:
        half_width, saturated = 0.0, False
    pen_q = np.asarray(c.Un @ u).ravel() - c.gap
    A = disc.A
    energy = float(0.5 * u @ (A @ u) - disc.F @ u)
    denom = np.linalg.norm(lam) * np.linalg.norm(G)
    m = {
        "n_dofs": int(disc.n_dofs),
        "n_free_dofs": int(prob.free.size),
        "n_contact": int(basis.shape[1]),
        "n_contact_quadrature": int(c.n_quad),
        "n_active": int(active.sum()),
        "multiplier": "p1 (friction nodes)" if basis is not c.Mlam else c.multiplier,
        "iterations": int(res.iterations),
        "converged": bool(res.converged),
        "stop_reason": res.stop_reason,
        "solver_info": {k: v for k, v in res.info.items() if k not in _ARRAY_INFO},
        "final_residual": float(res.residuals[-1]) if res.residuals else None,
        "solve_time_s": float(sol.times["total_s"]),
        "times_s": {**sol.times, **res.times},
        "contact_force": force,
        "contact_half_width": half_width,
        "max_pressure": lam_max,
        "complementarity": float(abs(lam @ s) / denom) if denom > 0 else 0.0,
        "penetration_max": float(max(0.0, np.max(-s / support))) if s.size else 0.0,
        "penetration_pointwise_max": float(max(0.0, pen_q.max())) if pen_q.size else 0.0,
        "min_multiplier": float(lam.min()) if lam.size else 0.0,
        "energy": energy,
        "zone_saturated": saturated,
    }
    nitsche = isinstance(prob, (NitscheProblem, NitscheFrictionProblem))
    m.update(gap_checks(c, u, basis, active, disc.physics == "elasticity",
                        None if nitsche else m["multiplier"],
                        sol.scene.data["discretization"].get("lac_patch")))
    if nitsche:
        m["warnings"] += nitsche_discretization_warnings(sol.scene.data["discretization"])
    if disc.physics == "elasticity":
        geo = disc.info["geometry"]
        m["material"] = {b.name: {"E": b.E, "nu": b.nu} for b in disc.bodies}
        m["material"]["plane_strain"] = True
        m["radii"] = {"R1": geo["R1"], "R2": geo["R2"]}
        m["warnings"] += locking_warnings(sol.scene.data["discretization"].get("degree", 1),
                                          {b.name: b.nu for b in disc.bodies})
        if sol.scene.data["reference"]["hertz"] and force > 0:
            m["hertz"] = _hertz_block(hertz_of_bodies(force, geo, disc.bodies), m)
    m.update(extra)
    if sol.scene.data["reference"].get("mindlin") and isinstance(
            prob, (FrictionProblem, NitscheFrictionProblem)):
        m["mindlin"] = _mindlin_block(sol, m)
    m["units"] = units_of(disc.physics)
    m["definitions"] = DEFINITIONS
    return m


def _hertz_block(h: Any, m: dict[str, Any]) -> dict[str, Any]:
    """The ``hertz`` block: 2D Hertz ``h`` at the computed force against the computed
    half-widths (quantised and from the gap) and peak pressure."""
    return {"P": h.P, "R_star": h.R_star, "E_star": h.E_star, "a": h.a, "p0": h.p0,
            "a_rel_error": (m["contact_half_width"] - h.a) / h.a,
            "a_gap_rel_error": (m["contact_half_width_gap"] - h.a) / h.a,
            "p0_rel_error": (m["max_pressure"] - h.p0) / h.p0,
            "note": "theory evaluated at the solver's own force P; errors are signed, "
                    "relative: (computed - theory) / theory; a_rel_error of "
                    "contact_half_width (quantised to multiplier supports), a_gap_rel_error "
                    "of contact_half_width_gap"}


def _mindlin_block(sol: Any, m: dict[str, Any]) -> dict[str, Any]:
    """The ``mindlin`` block (:func:`rbbench.hf.references.mindlin.mindlin_metrics`) at the
    solver's own ``contact_force`` and ``tangential_force``."""
    info, c = sol.result.info, sol.disc.contact
    if isinstance(sol.problem, NitscheFrictionProblem):  # point values: Mt = identity
        c = SimpleNamespace(colloc_points=c.points, Mt=sp.identity(c.n_quad, format="csr"),
                            points=c.points, normals=c.normals, weights=c.weights)
        lam_t, states = info["lam_t_points"], info["states_points"]
    else:
        lam_t, states = info["lam_t"], info["states"]
    return mindlin_metrics(c, np.asarray(lam_t, float), np.asarray(states, dtype=object),
                           m["contact_force"], m["tangential_force"],
                           m["friction"]["coefficient"], sol.disc.info["geometry"],
                           sol.disc.bodies)


#: per-node arrays a friction solver leaves in ``SolveResult.info`` (not in solver_info);
#: per-point arrays of the Nitsche friction Newton
#: (``rbbench_plugins.solvers.nitsche_friction_newton.POINT_INFO``)
_ARRAY_INFO = ("lam_t", "states", "slip", "ut_prev", "coefficient", "lam_n_points",
               "lam_t_points", "slip_points", "states_points", "ut_prev_points", "S_points",
               "coefficient_points")


def normal_operators(prob: Any, c: Any) -> tuple[Any, np.ndarray, Any, np.ndarray]:
    """``(B, G, basis, extent)`` of the normal multipliers: the scene's multiplier space, or
    for a :class:`FrictionProblem` the P1 friction nodes (``B_nodal``, ``G_nodal``, ``Mt``,
    the hat supports ``[x_{i-1}, x_{i+1}]`` of the collocation nodes along the chain)."""
    if not isinstance(prob, FrictionProblem):
        return c.B(), c.G(), c.Mlam, c.mult_extent
    x = np.asarray(c.colloc_points, float)[:, 0]
    lo, hi = np.r_[x[:1], x[:-1]], np.r_[x[1:], x[-1:]]
    ext = np.stack([np.minimum(np.minimum(lo, hi), x), np.maximum(np.maximum(lo, hi), x)], 1)
    return c.B_nodal(), c.G_nodal(), c.Mt, ext


def _friction_metrics(prob: FrictionProblem, res: SolveResult, c: Any) -> dict[str, Any]:
    """Friction outputs: tangential force, node states, stick-zone half-width,
    the stick / slip residual of the last load step (see :data:`DEFINITIONS`)."""
    info = res.info
    lam_t = np.asarray(info.get("lam_t", np.zeros(prob.n_nodes)), float)
    states = np.asarray(info.get("states", ["nan"] * prob.n_nodes), dtype=object)
    lam_tq = np.asarray(c.Mt @ lam_t).ravel()
    return _friction_outputs(prob, c, lam_tq, states, np.asarray(c.colloc_points, float),
                             info.get("friction_residuals", {}))


def _friction_outputs(prob: FrictionProblem | NitscheFrictionProblem, c: Any,
                      lam_tq: np.ndarray, states: np.ndarray, where: np.ndarray,
                      fr: dict) -> dict[str, Any]:
    """The friction outputs from ``lam_t`` at the contact quadrature (``lam_tq``), the
    states at the positions ``where`` (friction nodes or points) and the residuals ``fr``."""
    stick = states == "stick"
    xs = where[stick, 0]
    return {
        "tangential_force": float(np.sum(c.weights * lam_tq * -c.normals[:, 1])),
        "n_stick": int(stick.sum()), "n_slip": int(np.sum(states == "slip")),
        "n_open": int(np.sum(states == "open")),
        "stick_half_width": 0.5 * float(xs.max() - xs.min()) if xs.size else 0.0,
        "friction_residual": max(float(fr.get("stick", np.nan)), float(fr.get("slip", np.nan))),
        "friction": {"law": prob.law, "load_steps": len(prob.steps),
                     "threshold": None if prob.threshold is None else float(prob.threshold[0]),
                     "coefficient": None if prob.coefficient is None
                     else float(prob.coefficient[0]),
                     "coefficient_law": prob.coefficient_law},
    }


def _nitsche_friction_metrics(prob: NitscheFrictionProblem, res: SolveResult, c: Any
                              ) -> dict[str, Any]:
    """Friction outputs of a Nitsche solve from its point tractions ``-[P_t]_S`` and the
    point states (counts of contact points, not nodes; see :data:`DEFINITIONS`)."""
    info, nq = res.info, c.n_quad
    lam_tq = np.asarray(info.get("lam_t_points", np.full(nq, np.nan)), float)
    states = np.asarray(info.get("states_points", ["nan"] * nq), dtype=object)
    out = _friction_outputs(prob, c, lam_tq, states, np.asarray(c.points, float),
                            info.get("friction_residuals", {}))
    out["friction"]["states_of"] = "contact quadrature points (Nitsche)"
    return out


def _nitsche_metrics(prob: NitscheProblem, res: SolveResult, c: Any) -> dict[str, Any]:
    """Nitsche: force from the point pressures ``-[P_gamma(u)]_-`` (the consistent reaction of
    the Nitsche equation), their peak, and the relative AC residual ``e_ac`` of Benaceur,
    Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric variational
    inequalities" (talk), slide "Relative error on the Alart-Curnier reformulation".

    ``lam`` (hence ``max_pressure``, half-width, complementarity) is the L2 projection of
    that pressure on the multiplier space (:func:`rbbench.hf.algebra.nitsche.project_pressure`).
    """
    from rbbench.hf.algebra import nitsche as nt

    if not np.all(np.isfinite(res.u)):
        return {"contact_force": float("nan"), "e_ac": None,
                "nitsche": {"theta": prob.theta, "gamma0": prob.gamma0}}
    u = res.u[prob.free]
    p = nt.pressure(prob, u)
    return {"contact_force": float(np.sum(prob.weights * p * -c.normals[:, 1])),
            "max_pressure_quadrature": float(p.max()) if p.size else 0.0,
            "e_ac": nt.ac_residual(prob, u),
            "nitsche": {"theta": prob.theta, "gamma0": prob.gamma0, "E": prob.E,
                        "h_min": float(prob.h.min()), "h_max": float(prob.h.max()),
                        "n_active_points": int(np.sum(p > 0))}}


#: The unit of each dimensional number of an HF summary on an elasticity scene (SI, plane
#: strain: forces and energies per unit thickness). The scalar scenes (physics ``poisson``:
#: the membrane) are nondimensional (unit ``"1"``); times carry theirs in the name (``_s``:
#: seconds). :data:`DEFINITIONS`, ``summary.json`` ``units`` (:func:`units_of`) and the
#: console read the units here.
SI_UNITS = {
    "contact_force": "N/m", "tangential_force": "N/m", "energy": "J/m",
    "max_pressure": "Pa", "max_pressure_quadrature": "Pa",
    "contact_half_width": "m", "contact_half_width_gap": "m", "contact_half_width_gap_tol": "m",
    "stick_half_width": "m", "penetration_max": "m", "penetration_pointwise_max": "m",
}
_U = SI_UNITS


def units_of(physics: str) -> dict[str, str]:
    """``{number: unit}`` of the dimensional numbers of an HF summary for a scene of
    ``physics``: :data:`SI_UNITS` on elasticity, ``"1"`` (nondimensional) on the scalar
    scenes."""
    return dict(SI_UNITS) if physics == "elasticity" else dict.fromkeys(SI_UNITS, "1")


DEFINITIONS = {
    "n_dofs": "displacement (or scalar) degrees of freedom of the HF discretisation, "
              "constrained ones included",
    "n_free_dofs": "the degrees of freedom left after the Dirichlet conditions",
    "n_contact": "columns of the multiplier basis (friction: the slave contact nodes, each "
                 "carrying lam_n and lam_t)",
    "n_contact_quadrature": "contact quadrature points on the slave boundary",
    "n_active": "multipliers above 1e-8 of the largest (rbbench.hf.metrics.ACTIVE_THRESHOLD): "
                "the active set",
    "multiplier": "the multiplier space (lac, p0, p1, nodal; friction: p1 friction nodes)",
    "iterations": "iterations of the contact solver (active-set, Newton or Uzawa steps)",
    "converged": "true when stop_reason is 'converged'",
    "solve_time_s": "wall time of the solve (s): operators at mu, contact solver and "
                    "recovery of u, without meshing; its parts in times_s",
    "times_s": "wall times of the solve's parts (s)",
    "solver_info": "the contact solver's own diagnostics (fallbacks, condensation used, ...)",
    "min_multiplier": "smallest multiplier value (negative: a sign violation, in the units "
                      "of max_pressure)",
    "flagged": "true when every multiplier is 0 while the bodies penetrate beyond "
               "contact_half_width_gap_tol: the result is then reported as not converged "
               "(stop_reason 'flagged')",
    "material": "E (Pa) and nu of each body, plane strain",
    "radii": "R1, R2 (m): the radii of the upper and lower bodies at this mu",
    "contact_force": "total normal contact force per unit thickness "
                     f"({_U['contact_force']}): vertical resultant int lam (-n_y) over the "
                     "slave zone (obstacle: int lam); Nitsche: int p (-n_y) with the point "
                     "pressures p = -[P_gamma(u)]_-",
    "e_ac": "Nitsche only: relative Alart-Curnier residual (Benaceur et al.) "
            "||sigma_nn(u) - [P_gamma(u)]_-|| / ||sigma_nn(u)||, L2(Gamma_c) norms by the "
            "contact quadrature, a fraction (not %)",
    "max_pressure_quadrature": "Nitsche only: largest point pressure -[P_gamma(u)]_- "
                               f"({_U['max_pressure_quadrature']})",
    "contact_half_width": "half the horizontal extent of the supports of the active multipliers "
                          f"({_U['contact_half_width']}): QUANTISED to whole multiplier "
                          "supports (LAC patches, facets, hats), so it moves in steps of one "
                          "support and may stay constant under refinement; overestimates the "
                          "true half-width by at most one support (contact_half_width_gap: "
                          "the pointwise edge)",
    "contact_half_width_gap": "half the horizontal extent of the set where the pointwise gap "
                              "g = gap - Un u at the contact quadrature points is <= "
                              "contact_half_width_gap_tol, its edges linearly interpolated "
                              "between the last closed and the first open point "
                              f"({_U['contact_half_width_gap']}); None without a contact "
                              "curve along x (membrane)",
    "contact_half_width_gap_tol": "the gap tolerance of contact_half_width_gap and of the "
                                  "under-resolution check "
                                  f"({_U['contact_half_width_gap_tol']}): 1e-3 max_q |Un u|_q "
                                  "(rbbench.hf.geometry.checks.GAP_RTOL)",
    "warnings": "what makes the result doubtful, in words: penetration beyond "
                "contact_half_width_gap_tol at contact points that no active multiplier's "
                "support covers (supports coarser than the contact zone; mixed "
                "formulations only); P1 displacements with nu >= 0.45 (volumetric "
                "locking); Nitsche with facet normals or Gauss-point-to-segment "
                "integration (e_AC does not converge under refinement)",
    "stop_reason": "the solver's stop reason (converged, max_iterations, stagnation, nan, "
                   "diverged), or 'flagged': the solver converged (solver_stop_reason) but "
                   "every multiplier is 0 while the bodies penetrate beyond "
                   "contact_half_width_gap_tol (zero contact force on an overlapping "
                   "solution, see warnings); a flagged solve counts as not converged "
                   "(rbbench solve exits 1, snapshots refuse it)",
    "max_pressure": f"largest multiplier value ({_U['max_pressure']}): the peak of the "
                    "discrete pressure (Nitsche: of its L2 projection on the multiplier space)",
    "complementarity": "|lam . (G - B u)| / (||lam||_2 ||G||_2), dimensionless; 0 at an exact "
                       "solution",
    "penetration_max": "largest mean penetration over one multiplier's support "
                       f"({_U['penetration_max']}): max_i (B u - G)_i / int phi_i, clipped at 0",
    "penetration_pointwise_max": "largest penetration (Un u - gap) at a contact quadrature "
                                 f"point ({_U['penetration_pointwise_max']}), clipped at 0; "
                                 "LAC only constrains patch means",
    "final_residual": "relative natural residual ||min(lam, c s)|| / ||c q|| of the condensed "
                      "LCP at the last iterate (friction: the largest relative residual of "
                      "friction_residuals at the last iterate of the last load step; Nitsche: "
                      "the relative Newton residual ||R(u)|| of the last load step)",
    "energy": f"J(u) = 1/2 u^T A u - F^T u on all dofs ({_U['energy']})",
    "tangential_force": "friction only: horizontal resultant int lam_t t_x over the slave zone "
                        f"({_U['tangential_force']}), t = (-n_y, n_x) = +x under the upper "
                        "body; lam_t enters A u + Bt^T lam_t = F as lam_n does, so this is "
                        "the force the slave body exerts on the master, > 0 for a shear of the "
                        "upper body along +x (the friction on the slave is its opposite); "
                        "Nitsche: lam_t = "
                        "-[sigma_nt(u) - gamma (u_t - ut_prev)]_S at the contact points",
    "n_stick": "friction only: collocation nodes in contact with |lam_t| < s at the last load "
               "step (s = threshold, or nu_F lam_n); Nitsche: contact points with "
               "P_n < 0 and |P_t| < S",
    "n_slip": "friction only: collocation nodes in contact with |lam_t| = s (last load step); "
              "Nitsche: contact points with P_n < 0 and |P_t| >= S",
    "n_open": "friction only: collocation nodes with lam_n = 0 (last load step); Nitsche: "
              "contact points with P_n >= 0",
    "stick_half_width": "friction only: half the horizontal extent of the stick nodes' "
                        "collocation points C(mu) "
                        f"({_U['stick_half_width']}); 0 without stick nodes (Nitsche: of "
                        "the stick contact points)",
    "friction_residual": "friction only: max of the relative stick and slip residuals of the "
                         "condensed problem at the last load step (friction_residuals: "
                         "min(|v|, s - |lam_t|) over sticking, min(|v|, |lam_t - s sign v|) "
                         "over slipping nodes; slip v / max|q|, forces / force scale); "
                         "Nitsche: the same at the contact points with the tractions "
                         "-[P_n]_-, -[P_t]_S, not zero at the discrete solution (the weak "
                         "conditions' consistency error)",
    "mindlin": MINDLIN_DEFINITION,
    "floor_s": "the floor of the solve (s): one factorisation + one solve A x = F of the same "
               "stiffness on the free dofs with the direct solver of the solve's condensation "
               "(PARDISO when it ran on PARDISO, else the backend's factorize, else SuperLU "
               "as rbbench.hf.condensation.dense.factorize; floor.solver names it), timed "
               "in the same run right after the solve, with one BLAS thread as the solve; "
               "floor.factor_s, floor.solve_s its parts. PARDISO's first call in a process "
               "(library "
               "loading, ~0.6 s) is paid at solver construction (times_s.setup_s)",
    "solve_over_floor": "times_s.solve_s / floor_s: the solver's time (condensation, "
                        "contact iterations, recovery of u; no assembly, no meshing) over "
                        "the floor; 1 is one factorisation + one solve (target: <= 1.5)",
    "blas_threads": BLAS_THREADS_DEFINITION,
    "units": "the unit of each dimensional number on this scene: SI on the elasticity "
             "scenes (per unit thickness, plane strain), the units these definitions give; "
             "'1' (nondimensional) on the scalar scenes (membrane); times: the _s suffix, "
             "seconds",
    "zone_saturated": "true if the first or last multiplier of the potential zone is active: "
                      "the contact patch reaches the edge of the potential zone",
}

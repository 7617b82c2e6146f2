"""The labelled numbers of a 3D HF contact solution (``summary.json``, frictionless mixed or
Nitsche formulation): contact force (whole body), contact radius (quantised and from the
pointwise gap), peak pressure, complementarity, penetration, and the 3D Hertz check
(:mod:`rbbench.hf.references.hertz3d`, at the solver's own force).

A Nitsche solve's ``lam`` is its point pressure ``-[P_gamma(u)]_-`` projected on the
multiplier space (as in 2D), so radii and peak read as for mixed; its force is integrated
from the point pressures (the reaction of the Nitsche equation), and ``e_ac`` is added.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rbbench.hf.geometry.checks import gap_tolerance, under_resolution
from rbbench.hf.references.hertz3d import hertz3d_of_bodies
from rbbench.interfaces import NitscheProblem

#: Relative threshold on lam (w.r.t. max lam) above which a multiplier counts as active
#: (the 2D one, :data:`rbbench.hf.metrics.ACTIVE_THRESHOLD`).
ACTIVE_THRESHOLD = 1e-8

#: Multiplier spaces whose basis functions are support indicators (a value is a patch mean).
PIECEWISE_CONSTANT = ("lac", "p0")

#: The unit of each dimensional number of a 3D summary (SI; whole bodies).
SI_UNITS_3D = {"contact_force": "N", "energy": "J", "max_pressure": "Pa",
               "contact_radius": "m", "contact_radius_max": "m", "contact_radius_gap": "m",
               "contact_radius_gap_tol": "m",
               "penetration_max": "m", "penetration_pointwise_max": "m"}


def is_3d(disc: Any) -> bool:
    """A 3D discretisation (its backend says ``info["geometry"]["dim"] == 3``)."""
    return disc.info.get("geometry", {}).get("dim") == 3


def symmetry_factor(geometry: dict) -> int:
    """How many copies of the modelled part make the whole body: ``2 ** len(symmetry)``
    (quarter: 4)."""
    return 2 ** len(geometry.get("symmetry", ()))


def contact_metrics_3d(sol: Any) -> dict[str, Any]:
    """Labelled contact quantities of a 3D mixed HF solution (see ``definitions``)."""
    disc, res, prob = sol.disc, sol.result, sol.problem
    c, lam, u = disc.contact, res.lam, res.u
    geo = disc.info["geometry"]
    copies = symmetry_factor(geo)
    B, G = c.B(), c.G()
    s = G - B @ u
    support = np.asarray(c.Mlam.T @ c.weights).ravel()
    lam_q = np.asarray(c.Mlam @ lam).ravel()
    force = copies * float(np.sum(c.weights * lam_q * -c.normals[:, 2]))
    extra = _nitsche_metrics(prob, res, c, copies) if isinstance(prob, NitscheProblem) else {}
    force = extra.get("contact_force", force)
    lam_max = float(np.max(lam)) if lam.size else 0.0
    active = lam > ACTIVE_THRESHOLD * max(lam_max, np.finfo(float).tiny)
    radius_max = float(c.mult_extent[active, 1].max()) if active.any() else 0.0
    # projected area of the union of the active multipliers' supports, whole body
    in_support = np.asarray(abs(c.Mlam[:, np.flatnonzero(active)]).sum(axis=1)).ravel() > 0
    area_active = copies * float(np.sum(c.weights[in_support]
                                        * np.abs(c.normals[in_support, 2])))
    un = np.asarray(c.Un @ u).ravel()
    gap_q = np.asarray(c.gap, float) - un
    tol = gap_tolerance(un)
    closed = gap_q <= tol
    # projected area of the closed quadrature cells, whole body -> radius of that disc
    area = copies * float(np.sum(c.weights[closed] * np.abs(c.normals[closed, 2])))
    r_q = np.hypot(c.points[:, 0], c.points[:, 1])
    denom = np.linalg.norm(lam) * np.linalg.norm(G)
    msg, flagged = under_resolution(c.Mlam, active, gap_q, tol, c.multiplier,
                                    sol.scene.data["discretization"].get("lac_patch"))
    m: dict[str, Any] = {
        "dim": 3, "n_dofs": int(disc.n_dofs), "n_free_dofs": int(prob.free.size),
        "n_contact": int(c.Mlam.shape[1]), "n_contact_quadrature": int(c.n_quad),
        "n_active": int(active.sum()), "multiplier": c.multiplier,
        "iterations": int(res.iterations), "converged": bool(res.converged),
        "stop_reason": res.stop_reason,
        "solver_info": {k: v for k, v in res.info.items() if np.ndim(v) == 0},
        "final_residual": float(res.residuals[-1]) if res.residuals else None,
        "solve_time_s": float(sol.times["total_s"]), "times_s": {**sol.times, **res.times},
        "symmetry_copies": copies,
        "contact_force": force,
        "contact_radius": math.sqrt(area_active / math.pi),
        "contact_radius_max": radius_max,
        "contact_radius_gap": math.sqrt(area / math.pi),
        "contact_radius_gap_tol": tol,
        "max_pressure": lam_max,
        "complementarity": float(abs(lam @ s) / denom) if denom > 0 else 0.0,
        "penetration_max": float(max(0.0, np.max(-s / support))) if s.size else 0.0,
        "penetration_pointwise_max": float(max(0.0, -gap_q.min())) if gap_q.size else 0.0,
        "min_multiplier": float(lam.min()) if lam.size else 0.0,
        "energy": copies * float(0.5 * u @ (disc.A @ u) - disc.F @ u),
        "zone_saturated": bool(closed.any() and r_q[closed].max() >= 0.95 * r_q.max()),
        "warnings": [msg] if msg else [], "flagged": flagged,
        "material": {b.name: {"E": b.E, "nu": b.nu} for b in disc.bodies},
        "radii": {"R1": geo["R1"], "R2": geo["R2"]},
    }
    m.update(extra)
    if sol.scene.data["reference"]["hertz"] and force > 0:
        m["hertz"] = _hertz_block(m, hertz3d_of_bodies(force, geo, disc.bodies).as_dict())
        m["hertz"].update(_profile_fit(c, lam, active, m["hertz"]))
        if c.multiplier in PIECEWISE_CONSTANT:
            m["hertz"].update(_peak_patch(c, lam, m["hertz"]))
    m["units"] = dict(SI_UNITS_3D)
    if extra:
        m["units"]["max_pressure_quadrature"] = "Pa"
    m["definitions"] = DEFINITIONS_3D
    return m


def _nitsche_metrics(prob: NitscheProblem, res: Any, c: Any, copies: int) -> dict[str, Any]:
    """Nitsche in 3D: the whole-body force ``copies int p (-n_z)`` from the point pressures
    ``p = -[P_gamma(u)]_-``, their peak, and Benaceur et al.'s relative Alart-Curnier
    residual ``e_ac`` (:func:`rbbench.hf.algebra.nitsche.ac_residual`)."""
    from rbbench.hf.algebra import nitsche as nt

    if not np.all(np.isfinite(res.u)):
        return {"contact_force": float("nan"), "e_ac": None,
                "nitsche": {"theta": prob.theta, "gamma0": prob.gamma0}}
    u = res.u[prob.free]
    p = nt.pressure(prob, u)
    return {"contact_force": copies * float(np.sum(prob.weights * p * -c.normals[:, 2])),
            "max_pressure_quadrature": float(p.max()) if p.size else 0.0,
            "e_ac": nt.ac_residual(prob, u),
            "nitsche": {"theta": prob.theta, "gamma0": prob.gamma0, "E": prob.E,
                        "h_min": float(prob.h.min()), "h_max": float(prob.h.max()),
                        "n_active_points": int(np.sum(p > 0))}}


def _hertz_block(m: dict[str, Any], h: dict[str, float]) -> dict[str, Any]:
    """3D Hertz ``h`` (:func:`~rbbench.hf.references.hertz3d.hertz_3d` as a dict) at the
    solver's own force against the computed radii and peak pressure."""
    return {**h, "a_rel_error": (m["contact_radius"] - h["a"]) / h["a"],
            "a_gap_rel_error": (m["contact_radius_gap"] - h["a"]) / h["a"],
            "p0_rel_error": (m["max_pressure"] - h["p0"]) / h["p0"],
            "note": "3D Hertz evaluated at the solver's own whole-body force P; errors are "
                    "signed, relative: (computed - theory) / theory; a_rel_error of "
                    "contact_radius (the area of the active multiplier supports, as a "
                    "disc: quantised to whole supports), a_gap_rel_error of "
                    "contact_radius_gap"}


def hertz_profile_fit(r: np.ndarray, p: np.ndarray) -> tuple[float, float]:
    """Least-squares fit of the 3D Hertz profile ``p(r) = p0 sqrt(1 - r^2 / a^2)``
    (Johnson 1985, eq. 4.22) to pressures ``p`` at radii ``r``, linear in ``r^2`` as
    ``p^2 = p0^2 - (p0 / a)^2 r^2``: ``(a, p0)``, or NaNs when fewer than two radii or a
    profile that does not fall with r."""
    r, p = np.asarray(r, float), np.asarray(p, float)
    if r.size < 2 or np.ptp(r) == 0:
        return math.nan, math.nan
    c0, c1 = np.linalg.lstsq(np.c_[np.ones(r.size), r ** 2], p ** 2, rcond=None)[0]
    if c0 <= 0 or c1 >= 0:
        return math.nan, math.nan
    return math.sqrt(-c0 / c1), math.sqrt(c0)


def hertz_patch_average(M: Any, weights: np.ndarray, r: np.ndarray, a: float,
                        p0: float) -> np.ndarray:
    """The 3D Hertz pressure ``p0 sqrt(1 - r^2 / a^2)`` (Johnson 1985, eq. 4.22) averaged
    over each multiplier's support with the contact quadrature:
    ``sum_q M_qi w_q p(r_q) / sum_q M_qi w_q`` (Pa), the quantity a piecewise-constant
    (LAC / P0) multiplier approximates (``b(v, eta) = int v_n eta`` tests the pressure
    with the support's indicator). ``M`` (n_q x n_mult): the multiplier basis at the
    points, ``weights`` their area weights, ``r`` their distances to the axis."""
    r = np.asarray(r, float)
    p = p0 * np.sqrt(np.clip(1.0 - (r / a) ** 2, 0.0, None))
    area = np.asarray(M.T @ weights).ravel()
    return np.asarray(M.T @ (weights * p)).ravel() / area


def _peak_patch(c: Any, lam: np.ndarray, h: dict) -> dict[str, float]:
    """The largest multiplier against :func:`hertz_patch_average` on its own support (like
    with like: no averaging bias), and that average against the pointwise p0."""
    i = int(np.argmax(lam))
    ph = float(hertz_patch_average(c.Mlam[:, [i]], c.weights, np.hypot(c.points[:, 0],
                                   c.points[:, 1]), h["a"], h["p0"])[0])
    return {"peak_patch_p0": ph,
            "peak_patch_rel_error": (float(lam[i]) - ph) / ph if ph > 0 else math.nan,
            "peak_patch_averaging": (ph - h["p0"]) / h["p0"]}


def _profile_fit(c: Any, lam: np.ndarray, active: np.ndarray, h: dict) -> dict[str, float]:
    """:func:`hertz_profile_fit` of the active multipliers at their supports' centroids
    (projected onto z = const), with errors relative to ``h``'s a and p0."""
    S = abs(c.Mlam[:, np.flatnonzero(active)]).tocsc()
    w = np.asarray(S.T @ c.weights).ravel()
    cx = np.asarray(S.T @ (c.weights * c.points[:, 0])).ravel() / w
    cy = np.asarray(S.T @ (c.weights * c.points[:, 1])).ravel() / w
    a, p0 = hertz_profile_fit(np.hypot(cx, cy), lam[active])
    return {"profile_fit_a": a, "profile_fit_p0": p0,
            "profile_fit_a_rel_error": (a - h["a"]) / h["a"],
            "profile_fit_p0_rel_error": (p0 - h["p0"]) / h["p0"]}


DEFINITIONS_3D = {
    "dim": "space dimension of the scene (3)",
    "n_dofs": "displacement degrees of freedom of the modelled part (quarter), constrained "
              "ones included",
    "n_free_dofs": "the degrees of freedom left after the Dirichlet conditions",
    "n_contact": "columns of the multiplier basis",
    "n_contact_quadrature": "contact quadrature points on the slave surface (modelled part)",
    "n_active": "multipliers above 1e-8 of the largest: the active set",
    "symmetry_copies": "copies of the modelled part that make the whole bodies (quarter: 4); "
                       "forces and energies are of the whole bodies",
    "contact_force": "total normal contact force on the whole body (N): vertical resultant "
                     "int lam (-n_z) over the slave surface, times symmetry_copies (Nitsche: "
                     "int p (-n_z) with the point pressures p = -[P_gamma(u)]_-)",
    "contact_radius": "radius of the disc whose area is the projected (onto z) area of the "
                      "union of the active multipliers' supports, whole body (m): QUANTISED "
                      "to whole multiplier supports",
    "contact_radius_max": "largest radial extent r = sqrt(x^2 + y^2) of the supports of the "
                          "active multipliers (m): quantised, and biased outward by up to "
                          "one support diameter (the outermost support on the rim)",
    "contact_radius_gap": "radius of the disc whose area is the projected (onto z) area of "
                          "the contact quadrature cells where the pointwise gap gap - Un u "
                          "is <= contact_radius_gap_tol, whole body (m)",
    "contact_radius_gap_tol": "the gap tolerance of contact_radius_gap and of the "
                              "under-resolution check (m): 1e-3 max_q |Un u|_q",
    "max_pressure": "largest multiplier value (Pa): the peak of the discrete pressure "
                    "(Nitsche: of its L2 projection on the multiplier space)",
    "complementarity": "|lam . (G - B u)| / (||lam||_2 ||G||_2), dimensionless",
    "penetration_max": "largest mean penetration over one multiplier's support (m), "
                       "clipped at 0",
    "penetration_pointwise_max": "largest penetration (Un u - gap) at a contact quadrature "
                                 "point (m), clipped at 0",
    "min_multiplier": "smallest multiplier value (Pa; negative: a sign violation)",
    "energy": "J(u) = 1/2 u^T A u - F^T u, whole bodies (J)",
    "zone_saturated": "true if a closed contact point lies within 5 % of the outer radius "
                      "of the potential contact cap: the contact reaches its edge",
    "material": "E (Pa) and nu of each body (3D elasticity)",
    "radii": "R1, R2 (m): the radii of the upper and lower bodies at this mu",
    "hertz": "3D Hertz (Johnson 1985, eqs. 4.22-4.23) at the solver's own contact_force: "
             "a = (3 P R* / (4 E*))^(1/3), p0 = 3 P / (2 pi a^2), signed relative errors "
             "of contact_radius, contact_radius_gap and max_pressure; profile_fit_a and "
             "profile_fit_p0: the least-squares fit of p^2 = p0^2 (1 - r^2 / a^2) to the "
             "active multipliers at their supports' centroids; LAC / P0 multipliers only: "
             "peak_patch_p0, the Hertz pressure averaged (contact quadrature) over the "
             "support of the largest multiplier (Pa), peak_patch_rel_error = (max_pressure "
             "- peak_patch_p0) / peak_patch_p0 (like with like: the multiplier is a patch "
             "mean), and peak_patch_averaging = (peak_patch_p0 - p0) / p0 (the bias of "
             "comparing a patch mean with the pointwise peak); 1 + p0_rel_error = (1 + "
             "peak_patch_rel_error) (1 + peak_patch_averaging)",
    "final_residual": "relative natural residual of the condensed LCP at the last iterate "
                      "(Nitsche: relative Newton residual)",
    "e_ac": "Nitsche only: relative Alart-Curnier residual (Benaceur et al.) "
            "||sigma_nn - [P_gamma]_-|| / ||sigma_nn||, L2 by the contact quadrature, a "
            "fraction",
    "max_pressure_quadrature": "Nitsche only: largest point pressure -[P_gamma(u)]_- (Pa)",
    "nitsche": "Nitsche only: theta, gamma0, the slave E (Pa), the smallest and largest slave "
               "triangle diameter h (m) of gamma = gamma0 E / h, contact points with p > 0",
    "stop_reason": "the solver's stop reason, or 'flagged' (zero force on an overlapping "
                   "solution)",
}

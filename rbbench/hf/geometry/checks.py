"""Checks of a computed contact solution from its pointwise gap.

The mixed formulation constrains the mean gap over each multiplier's support (LAC patch,
facet or hat), not the gap at a point. Two numbers of ``summary.json`` come from the
pointwise gap ``g_q = gap_q - (Un u)_q`` at the contact quadrature points instead:

* :func:`gap_edge_half_width`: the contact zone's half-width where ``g`` rises above a
  tolerance (linear interpolation between neighbouring points), beside
  ``contact_half_width``, which is quantised to whole multiplier supports;
* :func:`under_resolution`: penetration beyond that tolerance at points that no active
  multiplier covers, i.e. supports wider than the contact zone (their mean gap stays
  positive while the bodies overlap). When no multiplier is active at all, the solver
  "converged" with zero force on a wrong solution: :func:`flag` marks the result
  ``flagged``.

The tolerance is relative to the motion at the contact:
``tol = GAP_RTOL * max_q |(Un u)_q|`` (1e-3: above the LAC wiggle of the pointwise gap
inside the contact zone, 2.3e-6 m against 4.2e-3 m on hertz_halfdisks at d = 0.005,
level 0).
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: pointwise gap tolerance, relative to the largest normal displacement at the contact points
GAP_RTOL = 1e-3


def gap_tolerance(un: np.ndarray) -> float:
    """``GAP_RTOL * max |un|`` (``un``: normal displacement ``Un u`` at the contact points)."""
    return GAP_RTOL * float(np.max(np.abs(un))) if un.size else 0.0


def gap_edge_half_width(x: np.ndarray, gap: np.ndarray, tol: float) -> float:
    """Half the horizontal extent of ``{x : g_h(x) <= tol}``, ``g_h`` the piecewise-linear
    interpolant of the pointwise gaps ``gap`` at the abscissae ``x`` (sorted here).

    The outermost closed points (``gap <= tol``) on each side are followed to the crossing
    of ``tol`` with the next open point; a closed end point of the zone is its own edge.
    0 when no point is closed.
    """
    order = np.argsort(x)
    x, g = np.asarray(x, float)[order], np.asarray(gap, float)[order]
    closed = np.nonzero(g <= tol)[0]
    if closed.size == 0:
        return 0.0
    i0, i1 = int(closed[0]), int(closed[-1])

    def crossing(i: int, j: int) -> float:  # i closed, j its open neighbour
        return float(x[i] + (tol - g[i]) / (g[j] - g[i]) * (x[j] - x[i]))

    left = crossing(i0, i0 - 1) if i0 > 0 else float(x[0])
    right = crossing(i1, i1 + 1) if i1 < x.size - 1 else float(x[-1])
    return 0.5 * (right - left)


def under_resolution(basis: Any, active: np.ndarray, gap: np.ndarray, tol: float,
                     multiplier: str, patch: int | None) -> tuple[str | None, bool]:
    """``(warning or None, flag)``: penetration ``-gap > tol`` at contact points that no
    active multiplier's support (``basis``: points x multipliers) covers. ``flag`` when no
    multiplier is active at all (zero contact force on an overlapping solution)."""
    covered = np.asarray(abs(basis) @ active.astype(float)).ravel() > 0
    pen = np.where(covered, 0.0, -np.asarray(gap, float))
    if pen.size == 0 or not np.all(np.isfinite(pen)) or pen.max() <= tol:
        return None, False
    what = f"LAC patches (lac_patch = {patch} facets)" if multiplier == "lac" else \
        f"{multiplier} multiplier supports"
    none_active = not active.any()
    head = ("every multiplier is 0 (contact force 0)" if none_active else
            f"{int(np.sum(pen > tol))} contact points outside the active multipliers' supports")
    msg = (f"{head} while the bodies penetrate by up to {pen.max():.3g} at contact points "
           f"(tolerance {tol:.3g}): the {what} are coarser than the contact zone (their mean "
           "gap stays >= 0 while the bodies overlap); refine the contact mesh "
           "(h_contact, level)" + (" or lower discretization.lac_patch"
                                   if multiplier == "lac" else ""))
    return msg, none_active


def flag(sol: Any) -> None:
    """Mark a solve whose metrics carry ``flagged``: ``stop_reason = "flagged"`` (so
    ``converged`` is false and the snapshot cache, ``rbbench solve`` (exit 1) and run rows
    treat it as not converged); the solver's own reason stays in ``solver_stop_reason``."""
    m = sol.metrics
    if not m.get("flagged"):
        return
    m["solver_stop_reason"] = sol.result.stop_reason
    sol.result.stop_reason = "flagged"
    m["stop_reason"], m["converged"] = "flagged", False


def gap_checks(contact: Any, u: np.ndarray, basis: Any, active: np.ndarray, curve: bool,
               multiplier: str | None, patch: int | None) -> dict[str, Any]:
    """The summary entries of the pointwise gap: ``contact_half_width_gap`` (``curve``: a
    contact curve along x, else None) with its tolerance, ``warnings`` and ``flagged``
    (``multiplier`` None: no multipliers, e.g. Nitsche, no under-resolution check)."""
    un = np.asarray(contact.Un @ u).ravel()
    gap = np.asarray(contact.gap, float) - un
    tol = gap_tolerance(un)
    out: dict[str, Any] = {
        "contact_half_width_gap": gap_edge_half_width(contact.points[:, 0], gap, tol)
        if curve else None,
        "contact_half_width_gap_tol": tol, "warnings": [], "flagged": False}
    if multiplier is not None:
        msg, flagged = under_resolution(basis, active, gap, tol, multiplier, patch)
        out["warnings"] += [msg] if msg else []
        out["flagged"] = flagged
    return out

"""The Cattaneo-Mindlin check of a friction solve (``[reference] mindlin``).

At the solver's own normal force ``P`` (``contact_force``) and tangential force ``Q``
(``tangential_force``), Hertz gives ``a`` and ``p0`` (:func:`rbbench.hf.references.hertz.hertz_2d`)
and Cattaneo-Mindlin the stick half-width ``c = a sqrt(1 - Q / (F P))`` and the shear
traction ``q(x)`` (:func:`rbbench.hf.references.hertz.mindlin_from_hertz`). The computed values:

* ``c``: the stick zone of the collocation nodes, its two ends each taken at the midpoint
  between the outermost stick node and its neighbour (slip or open) along x, so the
  nodal measure ``stick_half_width`` (which stops at the last stick node, ``h / 2`` short
  on each side) is not biased; both are reported.
* the shear traction: ``lam_t`` is the tangential multiplier of Benaceur, Drouet, Ehrlacher,
  Ern & Niakh, "Model order reduction methods: parametric variational inequalities" (talk),
  slide "HF model", entering ``A u + Bt^T lam_t = F``
  as ``lam_n`` does, so the traction on the slave body is ``-lam_t`` and ``lam_t t_x``
  (``t = (-n_y, n_x)``, ``t_x ~ 1`` under the upper body) is the traction the slave exerts
  on the master, of the sign of ``Q``. The relative L2 error
  ``||sign(Q) lam_t t_x - q||_{L2(-a, a)} / ||q||_{L2(-a, a)}`` uses the contact
  quadrature of the slave facets (the Gauss rule of ``contact_force``), P1 ``lam_t``
  evaluated at the quadrature points (``Mt``), over the points with ``|x| <= a``.
* ``lam_t_odd_fraction``: ``||lam_t(x) - lam_t(-x)|| / ||lam_t(x) + lam_t(-x)||`` over
  ``|x| <= a`` at the nodes; Mindlin's traction is even in x. The linearised contact
  kinematics (the tangent of the undeformed slave surface, tilted by ``x / R1``) couples
  the normal load into an odd tangential traction (measured: 0.14, 0.23, 0.36 of ``F p0``
  after the normal step alone at ``a / R* = 0.008, 0.015, 0.029``, mesh-independent);
  ``traction_l2_rel_error_even`` is the L2 error of the even part
  ``(lam_t(x) + lam_t(-x)) / 2``, which that coupling leaves alone.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rbbench.hf.references.hertz import hertz_of_bodies, mindlin_from_hertz

#: definitions of the ``mindlin`` block of ``summary.json``
MINDLIN_DEFINITION = (
    "friction + [reference] mindlin: Cattaneo-Mindlin at the solver's own P (contact_force) "
    "and Q (tangential_force), F the Coulomb coefficient: a, p0 (Hertz at P), c_theory = "
    "a sqrt(1 - Q/(F P)); c = stick half-width from the stick nodes, each end at the midpoint "
    "between the outermost stick node and its neighbour (c_nodes = stick_half_width, ends at "
    "the nodes); c_rel_error = (c - c_theory) / c_theory; traction_l2_rel_error = "
    "||sign(Q) lam_t t_x - q||/||q|| in L2(-a, a) by the contact quadrature (lam_t is the "
    "multiplier: the traction on the slave body is -lam_t); lam_t_odd_fraction = "
    "||lam_t(x) - lam_t(-x)|| / ||lam_t(x) + lam_t(-x)|| at the nodes with |x| <= a; "
    "traction_l2_rel_error_even: the same L2 error for the even part (lam_t(x) + lam_t(-x))/2")


def stick_zone_ends(x: np.ndarray, states: np.ndarray) -> tuple[float, float] | None:
    """Ends of the stick zone along x: each at the midpoint between the outermost stick
    node and its neighbour (the node itself when it is the last one); ``None`` without
    stick nodes."""
    order = np.argsort(x)
    xs, st = np.asarray(x, float)[order], np.asarray(states)[order]
    idx = np.flatnonzero(st == "stick")
    if idx.size == 0:
        return None
    lo, hi = idx[0], idx[-1]
    left = 0.5 * (xs[lo] + xs[lo - 1]) if lo > 0 else xs[lo]
    right = 0.5 * (xs[hi] + xs[hi + 1]) if hi < xs.size - 1 else xs[hi]
    return float(left), float(right)


def odd_fraction(x: np.ndarray, values: np.ndarray, a: float) -> float:
    """``||f(x) - f(-x)|| / ||f(x) + f(-x)||`` over the nodes with ``|x| <= a``
    (``f(-x)`` by linear interpolation of the nodal values)."""
    order = np.argsort(x)
    xs, fs = np.asarray(x, float)[order], np.asarray(values, float)[order]
    inside = np.abs(xs) <= a
    mirror = np.interp(-xs[inside], xs, fs)
    even = np.linalg.norm(fs[inside] + mirror)
    return float(np.linalg.norm(fs[inside] - mirror) / even) if even > 0 else float("nan")


def traction_l2_error(c: Any, lam_t: np.ndarray, q_of_x: Any, sign: float,
                      a: float) -> float:
    """``||sign lam_t t_x - q|| / ||q||`` in L2(-a, a) by the contact quadrature of ``c``
    (:class:`rbbench.interfaces.ContactOperators`)."""
    xq = np.asarray(c.points, float)[:, 0]
    tx = -np.asarray(c.normals, float)[:, 1]
    lam_q = sign * np.asarray(c.Mt @ lam_t).ravel() * tx
    inside = np.abs(xq) <= a
    w, q = np.asarray(c.weights)[inside], q_of_x(xq[inside])
    ref = math.sqrt(float(np.sum(w * q**2)))
    err = math.sqrt(float(np.sum(w * (lam_q[inside] - q) ** 2)))
    return err / ref if ref > 0 else float("nan")


def even_part(x: np.ndarray, values: np.ndarray) -> np.ndarray:
    """``(f(x) + f(-x)) / 2`` at the nodes ``x`` (``f(-x)`` by linear interpolation)."""
    order = np.argsort(x)
    return 0.5 * (values + np.interp(-np.asarray(x, float), np.asarray(x, float)[order],
                                     np.asarray(values, float)[order]))


def mindlin_metrics(c: Any, lam_t: np.ndarray, states: np.ndarray, P: float, Q: float,
                    coefficient: float | None, geometry: dict, bodies: list) -> dict[str, Any]:
    """The ``mindlin`` block of ``summary.json`` (see :data:`MINDLIN_DEFINITION`).

    ``c``: the contact operators; ``lam_t``, ``states``: per collocation node;
    ``P``, ``Q``: the solver's normal and tangential forces (N/m); ``coefficient``: the
    constant Coulomb ``F``; ``geometry``: ``R1``, ``R2``; ``bodies``: the two materials.
    A block without theory (``c_theory = None``) and a ``reason`` when Mindlin does not
    apply (no constant coefficient, ``P <= 0``, or ``|Q| >= F P``: full sliding).
    """
    x = np.asarray(c.colloc_points, float)[:, 0]
    ends = stick_zone_ends(x, states)
    c_h = 0.5 * (ends[1] - ends[0]) if ends else 0.0
    xs = x[np.asarray(states) == "stick"]
    out: dict[str, Any] = {"P": P, "Q": Q, "F": coefficient, "c": c_h,
                           "c_nodes": 0.5 * float(xs.max() - xs.min()) if xs.size else 0.0,
                           "stick_ends": list(ends) if ends else None}
    reason = None
    if coefficient is None:
        reason = "the Coulomb coefficient is not a constant (Mindlin needs one F)"
    elif not P > 0:
        reason = f"no normal force (P = {P!r})"
    elif not abs(Q) < coefficient * P:
        reason = f"|Q| = {abs(Q)!r} >= F P = {coefficient * P!r}: full sliding"
    if reason is not None:
        return {**out, "c_theory": None, "reason": reason}
    h = hertz_of_bodies(P, geometry, bodies)
    m = mindlin_from_hertz(h, abs(Q), coefficient)
    sign = 1.0 if Q >= 0 else -1.0
    return {**out, "a": h.a, "p0": h.p0, "R_star": h.R_star, "a_over_R_star": h.a / h.R_star,
            "Q_over_FP": abs(Q) / (coefficient * P), "c_theory": m.c,
            "c_rel_error": (c_h - m.c) / m.c if m.c > 0 else float("nan"),
            "c_nodes_rel_error": (out["c_nodes"] - m.c) / m.c if m.c > 0 else float("nan"),
            "traction_l2_rel_error": traction_l2_error(c, lam_t, m.shear_traction, sign, h.a),
            "traction_l2_rel_error_even": traction_l2_error(
                c, even_part(x, lam_t), m.shear_traction, sign, h.a),
            "lam_t_odd_fraction": odd_fraction(x, lam_t, h.a),
            "note": "theory at the solver's own P and Q; errors signed, relative: "
                    "(computed - theory) / theory; the L2 error is a fraction (not %)"}

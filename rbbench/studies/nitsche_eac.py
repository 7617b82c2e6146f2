"""The relative Alart-Curnier residual e_AC^n of the Nitsche solve against h and mu, beside
the published table (``rbbench nitsche-table``).

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slide "Relative error on the Alart-Curnier
reformulation".
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from rbbench.hf.model import solve_hf
from rbbench.scene.loading import load_scene
from rbbench.studies.formatting import markdown_table, observed_order, percent
from rbbench.studies.published import PUBLISHED_EAC, PUBLISHED_H, PUBLISHED_SETTING

__all__ = ["NITSCHE_COLUMNS", "nitsche_markdown", "nitsche_table", "published_h_overrides",
           "published_overrides"]


def published_overrides(**changes: Any) -> list[str]:
    """:data:`PUBLISHED_SETTING` as ``--set`` overrides, with ``changes`` (keys with ``__``
    for ``.``: ``discretization__degree=1``) applied."""
    setting = {**PUBLISHED_SETTING, **{k.replace("__", "."): v for k, v in changes.items()}}
    return [f"{k}={v!r}" if isinstance(v, str) else f"{k}={v}" for k, v in setting.items()]

#: Column definitions printed under ``rbbench nitsche-table`` (README "Nitsche").
NITSCHE_COLUMNS = (
    "e_AC quad: ||sigma_nn(u_h) - [P_gamma(u_h)]_-|| / ||sigma_nn(u_h)|| in L2(Gamma_c) by "
    "the contact quadrature of the solve (metric e_ac); e_AC nodal: the same with plain l2 "
    "norms over the slave contact nodes, sigma_nn and u_n - d^n averaged from the adjacent "
    "facets (e_ac_nodal); e_AC L2: L2(Gamma_c) of the finite-element functions, 6 Gauss "
    "points per slave facet (e_ac_l2); all with the solve's gamma. Orders: log ratio of "
    "e_AC over log ratio of the mean slave facet lengths ('facet'); published order from the "
    "published h. "
    "Defaults: two bodies, P2, gamma0 = 10, smooth slave normals and segment-to-segment "
    "contact quadrature, which give the published order 1; Gauss-point-to-segment with facet "
    "normals stagnates on the non-matching meshes (README 'The e_AC^n table').")


def _published_value(mu: float, h: float) -> float | None:
    """The published e_AC (%) at (mu, h), or None if the published table has no such entry."""
    for k, hs in enumerate(PUBLISHED_H):
        if np.isclose(h, hs) and any(np.isclose(mu, m) for m in PUBLISHED_EAC):
            return PUBLISHED_EAC[min(PUBLISHED_EAC, key=lambda m: abs(m - mu))][k]
    return None


def published_h_overrides(backend: str, h: float) -> list[str]:
    """Scene overrides giving contact facets of about ``h`` (m) on the unit reference arc.

    The published ``h`` is read as the size of the contact facets of the reference mesh
    (mapped by mu like ours, so the upper body's physical facets are ``mu h``).
    scikit-fem's graded mesh bisects a coarse arc of pi/16 facets until the element
    diameters are below ``h_contact``; its contact facets are pi/4 / 2^k long, about
    ``0.31 h_contact``, so ``h_contact = 4 h`` gives 6.1 / 3.1 / 1.5 mm facets for
    h = 5 / 2.5 / 1.25 mm (the nearest of its sizes; elements adjacent to the arc are
    12 / 6 / 3 mm across). Netgen (NGSolve backend) puts facets of ``h_contact`` on
    the arc: ``h_contact = h``.
    """
    factor = 1.0 if backend == "ngsolve" else 4.0
    return [f"discretization.h_contact={factor * h!r}"]


def nitsche_table(scene: str = "hertz_halfdisks", hs=PUBLISHED_H, mus=(0.7, 1.0, 1.3),
                  backend: str = "skfem", theta: float = 1.0, gamma0: float | None = None,
                  overrides=(), progress=print, mixed: bool = True) -> list[dict]:
    """Benaceur et al.'s e_AC^n table: the Nitsche HF solve at each published ``h`` and mu.

    Each ``h`` (m) maps to scene overrides by :func:`published_h_overrides`; the row holds the
    measured mean slave facet length at mu (physical), ``e_ac`` (fraction; the contact
    quadrature of the solve), ``e_ac_nodal`` and ``e_ac_l2`` (the other readings of the
    talk's norm, :func:`rbbench.hf.algebra.nitsche.ac_residual_variants`), Newton iterations,
    stop reason, time, the Nitsche contact force and, with ``mixed``, the mixed (LAC + ssn)
    force on the same mesh and their relative difference. ``gamma0``: default, the
    formulation's own.
    """
    from rbbench.hf.algebra.nitsche import ac_residual_variants
    from rbbench.registry import default_registry

    reg = default_registry()
    # gamma0 not given: the nitsche formulation's own default, read back from the instance
    # the registry builds (the core does not import the plugin for its constant)
    f_options = {"theta": theta} if gamma0 is None else {"theta": theta, "gamma0": float(gamma0)}
    rows = []
    for h in hs:
        sc = load_scene(scene, [*overrides, *published_h_overrides(backend, h)])
        b = reg.create("backend", backend, scene=sc)
        f = reg.create("formulation", "nitsche", **f_options)
        for mu in mus:
            t0 = time.perf_counter()
            sol = solve_hf(sc, mu, backend=backend, formulation="nitsche", solver="newton",
                           components=(b, f, reg.create("solver", "newton")), floor=False)
            t = time.perf_counter() - t0
            m = sol.metrics
            row = {"h_published": h, "mu": mu, "h_contact": float(sc.data["discretization"]
                                                             ["h_contact"]),
                   "facet": float(np.mean(sol.problem.h)), "n_dofs": m["n_dofs"],
                   "e_ac": m["e_ac"], "published_e_ac": _published_value(mu, h),
                   "e_ac_nodal": None, "e_ac_l2": None,
                   "iterations": m["iterations"], "stop": m["stop_reason"], "time_s": t,
                   "force": m["contact_force"], "theta": theta, "gamma0": f.gamma0}
            if m["e_ac"] is not None:
                v = ac_residual_variants(b.contact_layout(), sol.problem, sol.result.u,
                                         sol.mu)
                row["e_ac_nodal"], row["e_ac_l2"] = v["nodal"], v["l2"]
            if mixed:
                ms = solve_hf(sc, mu, backend=backend, components=(
                    b, reg.create("formulation", "mixed"), reg.create("solver", "ssn")),
                    floor=False)
                row["force_mixed"] = ms.metrics["contact_force"]
                row["force_rel_diff"] = (row["force"] - row["force_mixed"]) / row["force_mixed"]
            rows.append(row)
            progress(f"h = {1e3 * h:g} mm, mu = {mu:g}: e_AC = {100 * m['e_ac']:.3f} % "
                     f"({m['stop_reason']}, {m['iterations']} it, {t:.1f} s)")
    return rows


def nitsche_markdown(rows: list[dict]) -> str:
    """Side by side with the published table: the three e_AC readings (%) and their observed
    orders between successive h (ours from the measured facet lengths, the published ones
    from the published h),
    the contact forces. Column definitions: :data:`NITSCHE_COLUMNS`."""
    head = ("mu (m)", "h published (mm)", "facet (mm)", "HF dofs", "e_AC quad (%)", "order",
            "e_AC nodal (%)", "order", "e_AC L2 (%)", "order", "published e_AC (%)",
            "published order",
            "Newton it", "F Nitsche (N/m)", "F mixed (N/m)", "rel. diff")
    by_mu: dict[float, list[dict]] = {}
    for r in rows:
        by_mu.setdefault(r["mu"], []).append(r)
    return markdown_table(head, (_nitsche_cells(mu, r, rs[k - 1] if k else None)
                                 for mu, rs in by_mu.items() for k, r in enumerate(rs)))


def _nitsche_cells(mu: float, r: dict, p: dict | None) -> list[str]:
    """The table cells of row ``r``; orders against the previous ``h`` at the same mu,
    ``p`` (none for the first)."""
    cells = [f"{mu:g}", f"{1e3 * r['h_published']:g}", f"{1e3 * r['facet']:.2f}", str(r["n_dofs"])]
    for key in ("e_ac", "e_ac_nodal", "e_ac_l2"):
        order = observed_order(p.get(key), r.get(key), p["facet"], r["facet"]) if p else ""
        cells += [percent(r.get(key)), order]
    published_order = observed_order(p["published_e_ac"], r["published_e_ac"],
                                     p["h_published"], r["h_published"]) if p else ""
    published = "" if r["published_e_ac"] is None else f"{r['published_e_ac']:g}"
    fm = r.get("force_mixed")
    fm_txt = "" if fm is None else f"{fm:.5g}"
    diff = "" if fm is None else f"{100 * r['force_rel_diff']:+.3f} %"
    return [*cells, published, published_order, str(r["iterations"]), f"{r['force']:.5g}",
            fm_txt, diff]


from rbbench._compat import deprecated_names  # noqa: E402 - after the module's own names

__getattr__ = deprecated_names(__name__)  # renamed names (rbbench._compat)

"""Small studies printed as Markdown tables (``rbbench hertz-table``, ``online-scaling``)."""

from __future__ import annotations

import time

import numpy as np

from rbbench.hf.model import solve_hf
from rbbench.scene.loading import load_scene


def hertz_table(scene: str = "hertz_halfdisks", loads=(0.05, 0.01), levels=(0, 1, 2),
                mu: float = 1.0, overrides=(), progress=print) -> list[dict]:
    """2D Hertz errors against load and uniform mesh refinement (``discretization.level``).

    Errors are signed relative errors at the solver's own force:
    (computed - theory) / theory, for the half-width a and the peak pressure p0.
    """
    rows = []
    for d in loads:
        for level in levels:
            sc = load_scene(scene, [*overrides, f"load.displacement={d}",
                                    f"discretization.level={level}"])
            t0 = time.perf_counter()
            sol = solve_hf(sc, mu)
            m = sol.metrics
            rows.append({"d": d, "level": level, "n_dofs": m["n_dofs"],
                         "h_facet": _largest_facet(sc, sol.disc),
                         "n_active": m["n_active"], "P": m["contact_force"],
                         "a": m["contact_half_width"], "a_hertz": m["hertz"]["a"],
                         "a_err": m["hertz"]["a_rel_error"], "p0": m["max_pressure"],
                         "p0_hertz": m["hertz"]["p0"], "p0_err": m["hertz"]["p0_rel_error"],
                         "stop": m["stop_reason"], "time_s": time.perf_counter() - t0})
            progress(f"d = {d:g}, level {level}: done in {rows[-1]['time_s']:.1f} s")
    return rows


def markdown(rows: list[dict]) -> str:
    head = ("| d (m) | level | dofs | active | P (N/m) | a (m) | a Hertz | a err | "
            "p0 (Pa) | p0 Hertz | p0 err | HF time (s) |")
    lines = [head, "|" + "---|" * 12]
    for r in rows:
        lines.append(
            f"| {r['d']:g} | {r['level']} | {r['n_dofs']} | {r['n_active']} | {r['P']:.4g} | "
            f"{r['a']:.4g} | {r['a_hertz']:.4g} | {100 * r['a_err']:+.2f} % | {r['p0']:.4g} | "
            f"{r['p0_hertz']:.4g} | {100 * r['p0_err']:+.2f} % | {r['time_s']:.2f} |")
    return "\n".join(lines)


def online_scaling(scene: str, config, levels=(0, 1), overrides=(), repeats: int = 30,
                   progress=print) -> list[dict]:
    """Online time of the same reduction at several mesh levels, timed side by side.

    One reduced model is built per ``discretization.level``; then every model
    solves every validation mu ``repeats`` times, the models interleaved in
    each round so that machine load hits them alike. Reports per level the
    HF size, the reduced sizes, the median and inter-quartile range of the
    online time (s) and its ratio to the first level.
    """
    from rbbench.rb.offline import reduce

    results = []
    for level in levels:
        sc = load_scene(scene, [*overrides, f"discretization.level={level}"])
        progress(f"level {level}: offline")
        res = reduce(sc, config)
        if res.model is None:
            raise ValueError(f"hyper {res.hyper!r} builds no HF-independent model; use 'eim' "
                             "or 'affine'")
        results.append(res)
    times: list[list[float]] = [[] for _ in results]
    for _ in range(repeats):
        for k, res in enumerate(results):
            for mu in res.valid_mus:
                times[k].append(res.model.solve(mu).time_s)
    rows = []
    base = float(np.median(times[0]))
    for level, res, t in zip(levels, results, times, strict=True):
        s = res.summary()
        med = float(np.median(t))
        rows.append({"level": level, "n_hf_dofs": s["n_hf_dofs"], "n_contact": s["n_contact"],
                     "N": s["N"], "K_pga": s["K_pga"], "R": s["R"], "M_eim": s["M_eim"],
                     "err_u_max": s["err_u_max"], "err_lam_max": s["err_lam_max"],
                     "t_online_median_s": med,
                     "t_online_iqr_s": float(np.subtract(*np.percentile(t, [75, 25]))),
                     "ratio_to_first": med / base, "t_hf_median_s": s["t_hf_median_s"]})
    return rows


def scaling_markdown(rows: list[dict]) -> str:
    lines = ["| level | HF dofs | contact rows | N + K | R | EIM rows | err u max | "
             "err lam max | online median (ms) | IQR (ms) | ratio | HF median (s) |",
             "|" + "---|" * 12]
    for r in rows:
        lines.append(
            f"| {r['level']} | {r['n_hf_dofs']} | {r['n_contact']} | {r['N']} + {r['K_pga']} | "
            f"{r['R']} | {r['M_eim']} | {r['err_u_max']:.2e} | {r['err_lam_max']:.2e} | "
            f"{1e3 * r['t_online_median_s']:.3f} | {1e3 * r['t_online_iqr_s']:.3f} | "
            f"{r['ratio_to_first']:.2f} | {r['t_hf_median_s']:.2f} |")
    return "\n".join(lines)


#: Seed 000, slide "Relative error on the Alart-Curnier reformulation": e_AC^n in % at
#: h = 5, 2.5, 1.25 mm for mu = 0.7, 1, 1.3 m.
SEED_EAC = {0.7: (1.0, 0.52, 0.28), 1.0: (1.45, 0.72, 0.33), 1.3: (1.17, 1.1, 0.43)}
SEED_H = (0.005, 0.0025, 0.00125)


def _seed_value(mu: float, h: float) -> float | None:
    """The seed's e_AC (%) at (mu, h), or None if the seed has no such entry."""
    for k, hs in enumerate(SEED_H):
        if np.isclose(h, hs) and any(np.isclose(mu, m) for m in SEED_EAC):
            return SEED_EAC[min(SEED_EAC, key=lambda m: abs(m - mu))][k]
    return None


def _largest_facet(scene, disc) -> float:
    """Largest slave contact facet (m): ``facet_length`` when built, else the weights
    summed per facet (Gauss rule: the same points on every facet; NaN for segmented
    quadrature, whose pieces do not tell their facet)."""
    c, nf = disc.contact, int(disc.info.get("n_facets_slave", 0))
    if c.facet_length is not None:
        return float(np.max(c.facet_length))
    gauss = scene.data["discretization"].get("contact_integration", "gauss") == "gauss"
    if not gauss or nf <= 0 or c.n_quad % nf:
        return float("nan")
    return float(c.weights.reshape(nf, -1).sum(axis=1).max())


def seed_h_overrides(backend: str, h: float) -> list[str]:
    """Scene overrides giving contact facets of about ``h`` (m) on the unit reference arc.

    The seed's ``h`` is read as the size of the contact facets of the reference mesh
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


def nitsche_table(scene: str = "hertz_halfdisks", hs=SEED_H, mus=(0.7, 1.0, 1.3),
                  backend: str = "skfem", theta: float = 1.0, gamma0: float | None = None,
                  overrides=(), progress=print, mixed: bool = True) -> list[dict]:
    """The seed's e_AC^n table: the Nitsche HF solve at each seed ``h`` and mu.

    Each ``h`` (m) maps to scene overrides by :func:`seed_h_overrides`; the row holds the
    measured mean slave facet length at mu (physical), ``e_ac`` (fraction; the contact
    quadrature of the solve), ``e_ac_nodal`` and ``e_ac_l2`` (the other readings of the
    seed's norm, :func:`rbbench.hf.nitsche_algebra.ac_residual_variants`), Newton iterations, stop
    reason, time, the Nitsche contact force and, with ``mixed``, the mixed (LAC + ssn)
    force on the same mesh and their relative difference.
    """
    from rbbench_plugins.formulations.nitsche import GAMMA0

    from rbbench.hf.nitsche_algebra import ac_residual_variants
    from rbbench.registry import default_registry

    reg = default_registry()
    g0 = GAMMA0 if gamma0 is None else float(gamma0)
    rows = []
    for h in hs:
        sc = load_scene(scene, [*overrides, *seed_h_overrides(backend, h)])
        b = reg.create("backend", backend, scene=sc)
        f = reg.create("formulation", "nitsche", theta=theta, gamma0=g0)
        for mu in mus:
            t0 = time.perf_counter()
            sol = solve_hf(sc, mu, backend=backend, formulation="nitsche", solver="newton",
                           components=(b, f, reg.create("solver", "newton")))
            t = time.perf_counter() - t0
            m = sol.metrics
            row = {"h_seed": h, "mu": mu, "h_contact": float(sc.data["discretization"]
                                                             ["h_contact"]),
                   "facet": float(np.mean(sol.problem.h)), "n_dofs": m["n_dofs"],
                   "e_ac": m["e_ac"], "seed_e_ac": _seed_value(mu, h),
                   "e_ac_nodal": None, "e_ac_l2": None,
                   "iterations": m["iterations"], "stop": m["stop_reason"], "time_s": t,
                   "force": m["contact_force"], "theta": theta, "gamma0": g0}
            if m["e_ac"] is not None:
                v = ac_residual_variants(b.contact_layout(), sol.problem, sol.result.u,
                                         sol.mu)
                row["e_ac_nodal"], row["e_ac_l2"] = v["nodal"], v["l2"]
            if mixed:
                ms = solve_hf(sc, mu, backend=backend, components=(
                    b, reg.create("formulation", "mixed"), reg.create("solver", "ssn")))
                row["force_mixed"] = ms.metrics["contact_force"]
                row["force_rel_diff"] = (row["force"] - row["force_mixed"]) / row["force_mixed"]
            rows.append(row)
            progress(f"h = {1e3 * h:g} mm, mu = {mu:g}: e_AC = {100 * m['e_ac']:.3f} % "
                     f"({m['stop_reason']}, {m['iterations']} it, {t:.1f} s)")
    return rows


def _order(e_prev: float | None, e: float | None, h_prev: float, h: float) -> str:
    if not e_prev or not e or e_prev <= 0 or e <= 0:
        return ""
    return f"{np.log(e_prev / e) / np.log(h_prev / h):.2f}"


def _pct(x: float | None) -> str:
    return "" if x is None else f"{100 * x:.3f}"


#: Column definitions printed under ``rbbench nitsche-table`` (README "Nitsche").
NITSCHE_COLUMNS = (
    "e_AC quad: ||sigma_nn(u_h) - [P_gamma(u_h)]_-|| / ||sigma_nn(u_h)|| in L2(Gamma_c) by "
    "the contact quadrature of the solve (metric e_ac); e_AC nodal: the same with plain l2 "
    "norms over the slave contact nodes, sigma_nn and u_n - d^n averaged from the adjacent "
    "facets (e_ac_nodal); e_AC L2: L2(Gamma_c) of the finite-element functions, 6 Gauss "
    "points per slave facet (e_ac_l2); all with the solve's gamma. Orders: log ratio of "
    "e_AC over log ratio of the mean slave facet lengths ('facet'); seed order from its h. "
    "Defaults: two bodies, P2, gamma0 = 10, smooth slave normals and segment-to-segment "
    "contact quadrature, which give the seed's order 1; Gauss-point-to-segment with facet "
    "normals stagnates on the non-matching meshes (README 'The e_AC^n table').")


def nitsche_markdown(rows: list[dict]) -> str:
    """Side by side with the seed: the three e_AC readings (%) and their observed orders
    between successive h (ours from the measured facet lengths, the seed's from its h),
    the contact forces. Column definitions: :data:`NITSCHE_COLUMNS`."""
    lines = ["| mu (m) | h seed (mm) | facet (mm) | HF dofs | e_AC quad (%) | order | "
             "e_AC nodal (%) | order | e_AC L2 (%) | order | seed e_AC (%) | seed order | "
             "Newton it | F Nitsche (N/m) | F mixed (N/m) | rel. diff |",
             "|" + "---|" * 16]
    by_mu: dict[float, list[dict]] = {}
    for r in rows:
        by_mu.setdefault(r["mu"], []).append(r)
    for mu, rs in by_mu.items():
        for k, r in enumerate(rs):
            p = rs[k - 1] if k else None
            cols = []
            for key in ("e_ac", "e_ac_nodal", "e_ac_l2"):
                order = _order(p.get(key), r.get(key), p["facet"], r["facet"]) if p else ""
                cols.append(f"{_pct(r.get(key))} | {order}")
            seed_order = _order(p["seed_e_ac"], r["seed_e_ac"], p["h_seed"], r["h_seed"]) \
                if p else ""
            seed = "" if r["seed_e_ac"] is None else f"{r['seed_e_ac']:g}"
            fm = r.get("force_mixed")
            fm_txt = "" if fm is None else f"{fm:.5g}"
            diff = "" if fm is None else f"{100 * r['force_rel_diff']:+.3f} %"
            lines.append(
                f"| {mu:g} | {1e3 * r['h_seed']:g} | {1e3 * r['facet']:.2f} | {r['n_dofs']} | "
                f"{' | '.join(cols)} | {seed} | {seed_order} | {r['iterations']} | "
                f"{r['force']:.5g} | {fm_txt} | {diff} |")
    return "\n".join(lines)


def formulation_comparison(scene: str = "hertz_halfdisks", overrides=(), n_train: int = 61,
                           n_valid: int = 10, N: int = 20, Rs=(10, 30, 40),
                           cache_dir: str = ".rbbench_cache", progress=print) -> dict:
    """Seed 000, "Comparison with the mixed formulation (1/2), (2/2)".

    1. HF energies ``J(mu; u(mu)) = 1/2 a(u, u) - f(u)`` of the mixed (LAC + ssn) and
       Nitsche (newton) solutions over ``D_train``.
    2. Reduced errors (max over the validation set) of the mixed model (mCPG cone of
       size ``R``: no dual tolerance, so ``R`` generators unless the training set has
       fewer; PGA; hyper auto) for each ``R`` in ``Rs``, and of the Nitsche model
       (same ``N``; no dual space), u in the X norm and the multiplier / pressure in
       L2(Gamma_c) (mixed: the W norm of ``lam``).
    """
    from rbbench.rb.offline import ReduceConfig, reduce
    from rbbench.scene.sampling import parameter_set

    sc = load_scene(scene, list(overrides))
    mus = parameter_set(sc, "train", n_train)
    energies = []
    for mu in mus:
        m = solve_hf(sc, mu)
        n = solve_hf(sc, mu, formulation="nitsche")
        energies.append({"mu": float(mu[0]), "J_mixed": m.metrics["energy"],
                         "J_nitsche": n.metrics["energy"],
                         "rel_diff": (n.metrics["energy"] - m.metrics["energy"])
                         / abs(m.metrics["energy"])})
        progress(f"HF energies at mu = {float(mu[0]):.4g}")
    reduced = []
    common = dict(N=N, n_train=n_train, n_valid=n_valid, cache_dir=cache_dir)
    for R in Rs:
        s = reduce(sc, ReduceConfig(R=R, tol_dual=0.0, **common)).summary()
        reduced.append({"formulation": "mixed", "N": s["N"], "R": s["R"], "K": s["K_pga"],
                        "err_u_max": s["err_u_max"], "err_lam_max": s["err_lam_max"],
                        "t_online_s": s["t_online_median_s"]})
        progress(f"mixed reduction, R = {R}: err_u_max = {s['err_u_max']:.3e}")
    s = reduce(sc, ReduceConfig(formulation="nitsche", **common)).summary()
    reduced.append({"formulation": "nitsche", "N": s["N"], "R": None, "K": 0,
                    "err_u_max": s["err_u_max"], "err_lam_max": s["err_lam_max"],
                    "t_online_s": s["t_online_median_s"]})
    return {"energies": energies, "reduced": reduced}


def comparison_markdown(res: dict) -> str:
    """The two tables of :func:`formulation_comparison`."""
    lines = ["| mu (m) | J mixed (J/m) | J Nitsche (J/m) | rel. diff |", "|---|---|---|---|"]
    for r in res["energies"]:
        lines.append(f"| {r['mu']:.4g} | {r['J_mixed']:.6g} | {r['J_nitsche']:.6g} | "
                     f"{100 * r['rel_diff']:+.4f} % |")
    lines += ["", "| formulation | N | R | K (PGA) | err u max | err lam / pressure max | "
              "online (ms) |", "|---|---|---|---|---|---|---|"]
    for r in res["reduced"]:
        lines.append(f"| {r['formulation']} | {r['N']} | {'' if r['R'] is None else r['R']} | "
                     f"{r['K']} | {r['err_u_max']:.3e} | {r['err_lam_max']:.3e} | "
                     f"{1e3 * r['t_online_s']:.3f} |")
    return "\n".join(lines)

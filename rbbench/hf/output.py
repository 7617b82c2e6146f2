"""Files written by ``rbbench solve``: summary.json, contact.csv, solution.vtu, a PNG.

Matplotlib and meshio are imported inside the functions that need them.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np

from rbbench.hf.metrics import normal_operators
from rbbench.hf.metrics3d import is_3d
from rbbench.hf.model import HFSolution
from rbbench.hf.output3d import (
    save_solution_figure,
    write_contact_csv_3d,
    write_png_3d,
    write_vtu_3d,
)
from rbbench.interfaces import FrictionProblem
from rbbench.provenance import _jsonable, provenance


def summary(sol: HFSolution) -> dict[str, Any]:
    """The summary.json content: scene identity, components, metrics, provenance."""
    sc = sol.scene
    return _jsonable({
        "scene": sc.name, "scene_file": sc.path, "overrides": list(sc.overrides),
        "scene_fingerprint": sc.fingerprint(), "mu": sc.mu_dict(sol.mu),
        **sol.components, **sol.metrics, "provenance": provenance(),
    })


def write_summary(sol: HFSolution, out: Path) -> Path:
    path = out / "summary.json"
    path.write_text(json.dumps(summary(sol), indent=2) + "\n")
    return path


def contact_table(sol: HFSolution) -> dict[str, np.ndarray]:
    """Per multiplier: position, pressure, initial and final mean gaps; for a friction solve,
    per P1 friction node (collocation node ``C(mu)``), also ``lam_t``, the mean slip of the
    last load step ``(Bt u - ut_prev)_i / int phi_i`` (m) and the node's state (open / stick
    / slip). The operators are those of ``contact_metrics`` (:func:`normal_operators`)."""
    c, info = sol.disc.contact, sol.result.info
    if "lam_t_points" in info:
        return _point_table(sol)
    friction = isinstance(sol.problem, FrictionProblem)
    B, G, basis, _ = normal_operators(sol.problem, c)
    support = np.asarray(basis.T @ c.weights).ravel()
    n = support.size
    pts = c.colloc_points if friction else c.mult_points
    table = {"x": pts[:, 0], "y": pts[:, 1], "pressure": sol.result.lam}
    if friction:
        table["lam_t"] = np.asarray(info.get("lam_t", np.full(n, np.nan)), float)
    table.update(gap_initial=G / support, gap=(G - B @ sol.result.u) / support)
    if friction:
        table["slip"] = np.asarray(info.get("slip", np.full(n, np.nan)), float) / support
        table["state"] = np.asarray(info.get("states", ["nan"] * n), dtype=object)
    return table


def _point_table(sol: HFSolution) -> dict[str, np.ndarray]:
    """A Nitsche friction solve, per contact point (its tractions are point values,
    :mod:`rbbench_plugins.solvers.nitsche_friction_newton`): the normal and tangential
    tractions in the mixed multipliers' signs, initial and final normal gaps, the slip of
    the last load step ``u_t - ut_prev`` and the point's state."""
    c, info = sol.disc.contact, sol.result.info
    gap0 = np.asarray(c.gap, float)
    return {"x": c.points[:, 0], "y": c.points[:, 1],
            "pressure": np.asarray(info["lam_n_points"], float),
            "lam_t": np.asarray(info["lam_t_points"], float),
            "gap_initial": gap0, "gap": gap0 - np.asarray(c.Un @ sol.result.u).ravel(),
            "slip": np.asarray(info["slip_points"], float),
            "state": np.asarray(info["states_points"], dtype=object)}


_UNITS = {"x": "m", "y": "m", "pressure": "Pa", "lam_t": "Pa", "gap_initial": "m", "gap": "m",
          "slip": "m", "state": ""}


def write_contact_csv(sol: HFSolution, out: Path) -> Path:
    path = out / "contact.csv"
    table = contact_table(sol)
    units = {k: ("" if sol.disc.physics == "poisson" else _UNITS[k]) for k in table}
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([f"{k} ({u})" if u else k for k, u in units.items()])
        for row in zip(*table.values(), strict=True):
            w.writerow([v if isinstance(v, str) else f"{v:.10g}" for v in row])
    return path


def _vertex_values(sol: HFSolution, body) -> np.ndarray:
    return sol.result.u[body.vertex_dofs]


def von_mises(points: np.ndarray, tris: np.ndarray, disp: np.ndarray, E: float,
              nu: float) -> np.ndarray:
    """Element-wise plane-strain von Mises stress from vertex displacements (P1 gradient)."""
    lam = E * nu / ((1 + nu) * (1 - 2 * nu))
    mu = E / (2 * (1 + nu))
    p = points[tris]  # (nt, 3, 2)
    d = disp[tris]  # (nt, 3, 2)
    J = np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]], axis=2)  # columns: edges
    dU = np.stack([d[:, 1] - d[:, 0], d[:, 2] - d[:, 0]], axis=2)  # (nt, 2comp, 2)
    grad = dU @ np.linalg.inv(J)  # du_i/dx_j
    exx, eyy = grad[:, 0, 0], grad[:, 1, 1]
    exy = 0.5 * (grad[:, 0, 1] + grad[:, 1, 0])
    tr = exx + eyy
    sxx, syy, szz = lam * tr + 2 * mu * exx, lam * tr + 2 * mu * eyy, lam * tr
    sxy = 2 * mu * exy
    return np.sqrt(0.5 * ((sxx - syy) ** 2 + (syy - szz) ** 2 + (szz - sxx) ** 2) + 3 * sxy**2)


def write_vtu(sol: HFSolution, out: Path) -> Path:
    """All bodies in one VTU (ParaView): displacement, body id, von Mises per cell."""
    import meshio

    pts, cells, disp, body_id, vm = [], [], [], [], []
    offset = 0
    for k, body in enumerate(sol.disc.bodies):
        vals = _vertex_values(sol, body)
        pts.append(body.points)
        cells.append(body.triangles + offset)
        if vals.shape[1] == 1:
            disp.append(np.hstack([np.zeros((vals.shape[0], 2)), vals]))
        else:
            disp.append(np.hstack([vals, np.zeros((vals.shape[0], 1))]))
            vm.append(von_mises(body.points, body.triangles, vals, body.E, body.nu))
        body_id.append(np.full(body.triangles.shape[0], k))
        offset += body.points.shape[0]
    cell_data = {"body": [np.concatenate(body_id)]}
    if vm:
        cell_data["von_mises"] = [np.concatenate(vm)]
    xyz = np.hstack([np.vstack(pts), np.zeros((offset, 1))])  # VTU wants 3-D points
    mesh = meshio.Mesh(xyz, [("triangle", np.vstack(cells))],
                       point_data={"displacement": np.vstack(disp)}, cell_data=cell_data)
    path = out / "solution.vtu"
    mesh.write(path)
    return path


def _draw_pressure(ax: Any, table: dict, m: dict) -> None:
    """Pressure (multiplier) along x, centred at the pressure centroid, against 2D Hertz."""
    order = np.argsort(table["x"])
    x = table["x"][order] - float(np.sum(table["x"] * table["pressure"])
                                  / max(np.sum(table["pressure"]), 1e-300))
    ax.step(x, table["pressure"][order], where="mid", label="computed (multiplier)")
    if "hertz" in m:
        h = m["hertz"]
        xs = np.linspace(-1.3 * h["a"], 1.3 * h["a"], 400)
        ax.plot(xs, h["p0"] * np.sqrt(np.clip(1 - (xs / h["a"]) ** 2, 0, None)), "r--",
                label=f"2D Hertz at P = {h['P']:.3g} N/m")
        ax.set_xlim(-1.5 * h["a"], 1.5 * h["a"])
        ax.set_title(f"pressure: a err {100 * h['a_rel_error']:+.2f} %, "
                     f"p0 err {100 * h['p0_rel_error']:+.2f} %")
    ax.set_xlabel("x (m), centred")
    ax.set_ylabel("normal pressure (Pa)")
    ax.legend()


def _draw_friction(ax: Any, sol: HFSolution, table: dict) -> None:
    """The friction figure of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction
    methods: parametric variational inequalities" (talk), slide "HF solutions": ``lam_t`` and
    ``+- F lam_n`` per friction node, stick nodes marked; with a ``mindlin`` block, the
    Cattaneo-Mindlin shear traction ``q(x)`` (compared as ``sign(Q) lam_t t_x``,
    :mod:`rbbench.hf.references.mindlin`)."""
    m = sol.metrics
    order = np.argsort(table["x"])
    x, lam_t, lam_n = table["x"][order], table["lam_t"][order], table["pressure"][order]
    coef = sol.result.info.get("coefficient", getattr(sol.problem, "coefficient", None))
    label = "F lam_n"
    if coef is None:  # Tresca: the threshold
        coef, label = getattr(sol.problem, "threshold", None), "s"
        bound = None if coef is None else np.asarray(coef, float)[order] * (lam_n > 0)
    else:
        bound = np.asarray(coef, float)[order] * lam_n
    ax.plot(x, lam_t, "b.-", ms=3, lw=0.8, label="lam_t (computed)")
    if bound is not None:
        ax.plot(x, bound, "k:", lw=1, label=f"+/- {label}")
        ax.plot(x, -bound, "k:", lw=1)
    stick = np.asarray(table["state"])[order] == "stick"
    ax.plot(x[stick], lam_t[stick], "go", ms=3, mfc="none", label="stick nodes")
    mind = m.get("mindlin") or {}
    if mind.get("c_theory") is not None:
        from rbbench.hf.references.hertz import mindlin_2d

        th = mindlin_2d(mind["P"], abs(mind["Q"]), mind["F"], mind["a"], mind["p0"])
        xs = np.linspace(-1.2 * th.a, 1.2 * th.a, 600)
        sign = 1.0 if mind["Q"] >= 0 else -1.0
        ax.plot(xs, sign * th.shear_traction(xs), "r--",
                label=f"Cattaneo-Mindlin q(x), c = {th.c:.3g} m")
        ax.set_xlim(-1.5 * th.a, 1.5 * th.a)
        ax.set_title(f"shear traction: c err {100 * mind['c_rel_error']:+.2f} %, "
                     f"L2 err {100 * mind['traction_l2_rel_error']:.2f} %")
    else:
        act = lam_n > 0
        if act.any():
            w = float(np.ptp(x[act]))
            ax.set_xlim(x[act].min() - 0.25 * w, x[act].max() + 0.25 * w)
        ax.set_title(f"friction ({sol.problem.law}): {m.get('n_stick')} stick, "
                     f"{m.get('n_slip')} slip nodes")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("tangential multiplier (Pa)")
    ax.legend(fontsize=8)


def _draw_bodies(axes: Any, fig: Any, sol: HFSolution, table: dict) -> None:
    """Deformed bodies coloured by von Mises stress (whole and zoomed on the contact), or
    the membrane and its contact set."""
    from matplotlib.tri import Triangulation

    m = sol.metrics
    if sol.disc.physics == "elasticity":
        vmax, cols = 0.0, []
        for body in sol.disc.bodies:
            vals = _vertex_values(sol, body)
            vm = von_mises(body.points, body.triangles, vals, body.E, body.nu)
            vmax = max(vmax, float(np.percentile(vm, 99.5)))
            cols.append((Triangulation(*(body.points + vals).T, body.triangles), vm))
        for ax, zoom in ((axes[0], False), (axes[1], True)):
            for tri, vm in cols:
                pc = ax.tripcolor(tri, facecolors=vm, cmap="viridis", vmin=0, vmax=vmax,
                                  edgecolors="k" if zoom else "none", linewidth=0.1)
            ax.set_aspect("equal")
            ax.set_xlabel("x (m)")
            ax.set_ylabel("y (m)")
        a = max(m.get("contact_half_width", 0.05), 1e-3)
        yc = float(np.mean(table["y"]))
        axes[1].set_xlim(-2.5 * a, 2.5 * a)
        axes[1].set_ylim(yc - 1.5 * a, yc + 1.5 * a)
        axes[0].set_title("deformed configuration (scale 1)")
        axes[1].set_title("contact zone (zoom)")
        for ax in axes[:2]:  # same colour scale (vmin 0, vmax shared): one bar per panel
            fig.colorbar(pc, ax=ax, label="von Mises stress (Pa)")
        return
    body = sol.disc.bodies[0]
    tri = Triangulation(*body.points.T, body.triangles)
    pc = axes[0].tripcolor(tri, _vertex_values(sol, body)[:, 0], shading="gouraud")
    fig.colorbar(pc, ax=axes[0], label="u")
    axes[0].set_title("membrane displacement u")
    act = table["pressure"] > 0
    sc = axes[1].scatter(table["x"][act], table["y"][act], s=8, c=table["pressure"][act])
    fig.colorbar(sc, ax=axes[1], label="contact multiplier")
    axes[1].set_xlim(0, 1)
    axes[1].set_ylim(0, 1)
    axes[1].set_title("contact set (coloured by multiplier)")
    for ax in axes[:2]:
        ax.set_aspect("equal")


def write_png(sol: HFSolution, out: Path) -> Path:
    """Deformed mesh coloured by stress (or the membrane), pressure vs Hertz and, for a
    friction solve, the tangential multiplier against ``F lam_n`` and Cattaneo-Mindlin."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = contact_table(sol)
    friction = "lam_t" in table
    fig, axes = plt.subplots(1, 4 if friction else 3, figsize=(21 if friction else 16, 5))
    m = sol.metrics
    _draw_bodies(axes, fig, sol, table)
    if sol.disc.physics == "elasticity":
        _draw_pressure(axes[2], table, m)
    else:
        axes[2].hist(table["pressure"][table["pressure"] > 0], bins=30)
        axes[2].set_xlabel("multiplier (active nodes)")
        axes[2].set_title("multiplier distribution")
    if friction:
        _draw_friction(axes[3], sol, table)
    return save_solution_figure(fig, sol, out)


def write_all(sol: HFSolution, out: Path, plot: bool = True) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    if is_3d(sol.disc):
        paths = [write_summary(sol, out), write_contact_csv_3d(sol, out), write_vtu_3d(sol, out)]
        return paths + ([write_png_3d(sol, out)] if plot else [])
    paths = [write_summary(sol, out), write_contact_csv(sol, out), write_vtu(sol, out)]
    if plot:
        paths.append(write_png(sol, out))
    return paths

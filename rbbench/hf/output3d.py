"""Files of a 3D ``rbbench solve``: contact.csv (per multiplier, with ``z`` and ``r``),
solution.vtu (tetrahedra, displacement) and a PNG (pressure map on the contact cap and the
radial pressure profile against 3D Hertz ``p0 sqrt(1 - r^2 / a^2)``)."""

from __future__ import annotations

import csv
from pathlib import Path
from typing import Any

import numpy as np

_UNITS = {"x": "m", "y": "m", "z": "m", "r": "m", "pressure": "Pa", "gap_initial": "m",
          "gap": "m"}


def contact_table_3d(sol: Any) -> dict[str, np.ndarray]:
    """Per multiplier: its point (x, y, z), radius r about the z axis, pressure, initial and
    final mean gaps over its support."""
    c = sol.disc.contact
    support = np.asarray(c.Mlam.T @ c.weights).ravel()
    p = np.asarray(c.mult_points, float)
    B, G = c.B(), c.G()
    return {"x": p[:, 0], "y": p[:, 1], "z": p[:, 2], "r": np.hypot(p[:, 0], p[:, 1]),
            "pressure": sol.result.lam, "gap_initial": G / support,
            "gap": (G - B @ sol.result.u) / support}


def write_contact_csv_3d(sol: Any, out: Path) -> Path:
    path = out / "contact.csv"
    table = contact_table_3d(sol)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([f"{k} ({_UNITS[k]})" for k in table])
        for row in zip(*table.values(), strict=True):
            w.writerow([f"{v:.10g}" for v in row])
    return path


def write_vtu_3d(sol: Any, out: Path) -> Path:
    """All bodies (the modelled part) in one VTU: tetrahedra, displacement, body id."""
    import meshio

    pts, cells, disp, body_id = [], [], [], []
    offset = 0
    for k, body in enumerate(sol.disc.bodies):
        pts.append(body.points)
        cells.append(body.triangles + offset)  # (n, 4) tetrahedra in 3D
        disp.append(sol.result.u[body.vertex_dofs])
        body_id.append(np.full(body.triangles.shape[0], k))
        offset += body.points.shape[0]
    mesh = meshio.Mesh(np.vstack(pts), [("tetra", np.vstack(cells))],
                       point_data={"displacement": np.vstack(disp)},
                       cell_data={"body": [np.concatenate(body_id)]})
    path = out / "solution.vtu"
    mesh.write(path)
    return path


def write_png_3d(sol: Any, out: Path) -> Path:
    """Pressure at the contact quadrature points over the (x, y) cap, and the multipliers
    against r with the 3D Hertz profile at the computed force."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    c, m = sol.disc.contact, sol.metrics
    lam_q = np.asarray(c.Mlam @ sol.result.lam).ravel()
    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    sc = axes[0].scatter(c.points[:, 0], c.points[:, 1], c=lam_q, s=6, cmap="viridis")
    fig.colorbar(sc, ax=axes[0], label="pressure (Pa)")
    axes[0].set_aspect("equal")
    axes[0].set_xlabel("x (m)")
    axes[0].set_ylabel("y (m)")
    axes[0].set_title("pressure on the slave cap (modelled part)")
    table = contact_table_3d(sol)
    axes[1].plot(table["r"], table["pressure"], ".", label="multipliers")
    h = m.get("hertz")
    if h:
        r = np.linspace(0.0, h["a"], 200)
        axes[1].plot(r, h["p0"] * np.sqrt(np.clip(1 - (r / h["a"]) ** 2, 0, None)), "k-",
                     label=f"3D Hertz at P = {h['P']:.4g} N")
    axes[1].set_xlabel("r (m)")
    axes[1].set_ylabel("pressure (Pa)")
    axes[1].set_xlim(0, max(2.0 * m.get("contact_radius", 0.0), 1e-3))
    axes[1].legend(fontsize=8)
    axes[1].set_title("radial pressure profile")
    return save_solution_figure(fig, sol, out)


def save_solution_figure(fig: Any, sol: Any, out: Path) -> Path:
    """Title ``fig`` with the scene, mu, size and stop reason of ``sol``, write it to
    ``out / "solution.png"`` and close it (2D and 3D solution figures alike)."""
    import matplotlib.pyplot as plt

    m = sol.metrics
    mu_txt = ", ".join(f"{k} = {v:g}" for k, v in sol.scene.mu_dict(sol.mu).items())
    fig.suptitle(f"{sol.scene.name}: {mu_txt}; {m['n_dofs']} dofs, {m['stop_reason']} "
                 f"in {m['iterations']} iterations")
    fig.tight_layout()
    path = out / "solution.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path

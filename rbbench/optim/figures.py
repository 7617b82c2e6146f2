"""Pictures of a shape optimisation run: bodies, normal stress, history (the figures of the
talk "On coupling of complementarity with friction in contact shape optimization", Example 1)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from rbbench.optim.shape_mesh import element_stress, trapezoid_weights
from rbbench.optim.shape_scene import ShapeScene
from rbbench.optim.shape_state import ShapeState


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _outline(sc: ShapeScene, alpha: np.ndarray, u: np.ndarray | None, k: float):
    g = sc.grid
    x = g.coordinates(alpha) + (0.0 if u is None else k * u.reshape(-1, 2))
    ring = np.concatenate([g.bottom(), g.node(g.nx, np.arange(1, g.ny + 1)),
                           g.top()[::-1][1:], g.left()[::-1][1:]])
    return x[ring]


def plot_bodies(sc: ShapeScene, states: dict[str, ShapeState], path: Path,
                magnify: float | None = None) -> Path:
    """Unloaded outline and the deformed mesh coloured by sigma_22 (kPa), one panel a state.

    The shape-optimisation talk's "initial / optimal design: unloaded and deformed body" and
    "normal stress" figures in one picture; the displacement is magnified by ``magnify`` (stated).
    """
    plt = _plt()
    g = sc.grid
    umax = max(float(np.abs(s.u).max()) for s in states.values())
    k = magnify if magnify is not None else max(1.0, round(0.1 / max(umax, 1e-300)))
    fig, axes = plt.subplots(len(states), 1, figsize=(8, 3.4 * len(states)), squeeze=False,
                             layout="constrained")
    sig = {n: element_stress(g, s.alpha, sc.D, s.u)[:, 1] for n, s in states.items()}
    lo = min(float(v.min()) for v in sig.values())
    hi = max(float(v.max()) for v in sig.values())
    for ax, (name, st) in zip(axes[:, 0], states.items(), strict=True):
        x = g.coordinates(st.alpha) + k * st.u.reshape(-1, 2)
        quads = x[g.elements()]
        from matplotlib.collections import PolyCollection

        pc = PolyCollection(quads, array=sig[name], cmap="viridis", edgecolors="none")
        pc.set_clim(lo, hi)
        ax.add_collection(pc)
        ring = _outline(sc, st.alpha, None, 0.0)
        ax.plot(*np.vstack([ring, ring[:1]]).T, "k--", lw=0.8, label="unloaded")
        ax.axhline(0.0, color="0.3", lw=2, label="rigid foundation x2 = 0")
        ax.set_title(f"{name}: deformed (displacement x {k:g})", fontsize=10)
        ax.set_aspect("equal")
        ax.set_xlim(sc.a - 0.05, sc.b + 0.05 + k * float(np.abs(st.u[0::2]).max()))
        ax.set_ylim(min(-0.05, float(x[:, 1].min()) - 0.05), sc.gamma + 0.1)
        ax.legend(loc="upper right", fontsize=7)
    fig.colorbar(pc, ax=axes[:, 0].tolist(),
                 label="normal stress sigma_22 at element centres (kPa)")
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_pressure(sc: ShapeScene, states: dict[str, ShapeState], path: Path) -> Path:
    """Contact pressure ``lam_i / w_i`` (kPa, w the nodal length) along the bottom."""
    plt = _plt()
    w = trapezoid_weights(sc.grid)
    fig, ax = plt.subplots(figsize=(7, 3.5))
    for name, st in states.items():
        ax.plot(sc.grid.x1, st.lam / w, ".-", label=f"{name}: max {np.max(st.lam / w):.4g}")
    ax.axhline(sc.pressure, color="k", ls=":", label=f"applied top pressure {sc.pressure:g}")
    ax.set_xlabel("x1 (m)")
    ax.set_ylabel("contact pressure lam_i / w_i (kPa)")
    ax.set_title("normal contact stress on the design boundary")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_history(rows: list[dict], path: Path, J_bound: float | None = None) -> Path:
    """``J`` at the stability centre per iteration (log scale)."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6, 3.5))
    it = [r["iteration"] for r in rows]
    ax.semilogy(it, [r["f"] for r in rows], ".-", label="J (accepted design)")
    if J_bound is not None:
        ax.axhline(J_bound, color="k", ls=":", label="uniform-pressure lower bound")
    ax.set_xlabel("iteration")
    ax.set_ylabel("J = ||lam||_6^6")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path

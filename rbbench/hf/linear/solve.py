"""``rbbench solve`` of a linear scene: one sparse solve, its summary and files.

:func:`solve_linear_hf` returns the :class:`~rbbench.hf.model.HFSolution` of
:func:`rbbench.hf.model.solve_hf` (``problem``: a :class:`~rbbench.hf.linear.model.LinearProblem`,
``lam`` empty) with the numbers of :data:`DEFINITIONS` in ``metrics``: no contact field.
:func:`write_linear` writes ``summary.json``, ``solution.npz`` (``u``, the mesh) and a PNG of
``u`` (at the final time for ``heat``).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from rbbench.hf.linear.model import NO_CONTACT, LinearHF
from rbbench.hf.model import HFSolution
from rbbench.hf.output import write_summary
from rbbench.registry import Registry
from rbbench.runtime.threads import BLAS_THREADS_DEFINITION, one_blas_thread
from rbbench.scene.loading import Scene, SceneError

__all__ = ["DEFINITIONS", "linear_metrics", "solve_linear_hf", "write_linear"]

#: What each number of a linear ``summary.json`` is (``heat``: ``u`` at the final time T).
DEFINITIONS = {
    "n_dofs": "HF dofs (all nodes); n_free: without the Dirichlet dofs (thermal: u = 0)",
    "residual_rel": "||A u - F||_2 / ||F||_2 on the free dofs, recomputed from the assembled "
                    "operators (heat: max over the implicit Euler steps of ||M (u^k - "
                    "u^{k-1}) / dt + A u^k - F||_2 / ||F||_2)",
    "u_max": "max of the nodal values of u (heat: at T); u_min likewise",
    "u_integral": "int_Omega u dx = 1^T M u (M the mass matrix; heat: at T)",
    "u_norm_X": "||u||_X = (u^T X u)^(1/2), X the scene's inner product (h1_semi: |u|_1; "
                "h1: the H1 norm; heat: at T)",
    "u_norm_L2X": "heat: the discrete L2(0, T; X) norm (dt sum_k ||u^k||_X^2)^(1/2), the "
                  "norm of the reduced errors err_u",
    "solve_time_s": "wall time of the factorisation + solve(s), one BLAS thread "
                    "(times_s.discretize_s: the assembly at mu)",
    "contact": NO_CONTACT,
    "blas_threads": BLAS_THREADS_DEFINITION,
}


def _residual(prob: Any, u: np.ndarray) -> float:
    """:data:`DEFINITIONS` ``residual_rel`` of the free solution or trajectory ``u``."""
    nf = max(float(np.linalg.norm(prob.F)), 1e-300)
    if not prob.parabolic:
        return float(np.linalg.norm(prob.A @ u - prob.F)) / nf
    prev = np.vstack([prob.u0, u[:-1]])
    r = (prob.M @ (u - prev).T).T / prob.dt + (prob.A @ u.T).T - prob.F
    return float(np.max(np.linalg.norm(r, axis=1))) / nf


def linear_metrics(disc: Any, prob: Any, u: np.ndarray, times: dict) -> dict[str, Any]:
    """The numbers of :data:`DEFINITIONS` (``u``: free values, heat ``(K, n_free)`` rows)."""
    final = prob.expand(u[-1] if prob.parabolic else u)
    X = disc.X
    m = {"n_dofs": disc.n_dofs, "n_free": int(prob.free.size), "physics": disc.physics,
         "iterations": 1, "stop_reason": "converged", "residual_rel": _residual(prob, u),
         "u_max": float(final.max()), "u_min": float(final.min()),
         "u_integral": float(np.sum(disc.info["mass"] @ final)),
         "u_norm_X": float(np.sqrt(final @ (X @ final))), "solve_time_s": times["solve_s"],
         "times_s": dict(times)}
    if prob.parabolic:
        Xf = prob.X[prob.free][:, prob.free]
        m.update(steps=prob.steps, dt=prob.dt, final_time=prob.dt * prob.steps,
                 u_norm_L2X=float(np.sqrt(prob.dt * np.sum(u * (Xf @ u.T).T))))
    m["definitions"] = {k: v for k, v in DEFINITIONS.items() if k in m or k == "contact"}
    return m


def solve_linear_hf(scene: Scene, mu: Any = None, backend: str = "skfem",
                    formulation: str = "linear", registry: Registry | None = None,
                    backend_options: dict | None = None,
                    progress: Callable[[str], None] = lambda m: None) -> HFSolution:
    """Assemble at ``mu`` (default: the scene default; checked against D) and solve with one
    factorisation (:func:`rbbench.hf.linear.model.solve_linear`), one BLAS thread."""
    if formulation not in ("linear", "mixed"):  # "mixed": the default of rbbench solve
        raise SceneError(f"{scene.path}: a linear scene is solved by the formulation "
                         f"'linear', not {formulation!r}")
    t0 = time.perf_counter()
    progress("meshing and assembling the parameter-independent terms")
    hf = LinearHF(scene, backend, registry, backend_options)
    mu = scene.default_mu if mu is None else hf.parameters.check(mu)
    t1 = time.perf_counter()
    progress("solving (no contact)")
    with one_blas_thread() as threads:
        sol = hf.solve(mu)
    sol.times.update(setup_s=t1 - t0, total_s=sol.times["total_s"] + t1 - t0)
    prob = sol.problem
    u = sol.result.u.reshape(prob.steps, -1) if prob.parabolic else sol.result.u[prob.free]
    sol.metrics = {**linear_metrics(sol.disc, prob, u, sol.times), "blas_threads": threads}
    return sol


def trajectory(sol: HFSolution) -> np.ndarray:
    """``u`` on all dofs: ``(n_dofs,)``, or heat ``(K + 1, n_dofs)`` rows ``u^0 .. u^K``."""
    prob = sol.problem
    if not prob.parabolic:
        return sol.result.u
    rows = [prob.u0, *sol.result.u.reshape(prob.steps, -1)]
    return np.vstack([prob.expand(r) for r in rows])


def _write_png(sol: HFSolution, u: np.ndarray, out: Path) -> Path:
    """``u`` (heat: at T) coloured on the mesh."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    body = sol.disc.bodies[0]
    fig, ax = plt.subplots(figsize=(6, 5))
    tpc = ax.tripcolor(body.points[:, 0], body.points[:, 1], body.triangles,
                       u[body.vertex_dofs[:, 0]], shading="gouraud")
    fig.colorbar(tpc, ax=ax, label="u" + (" at T" if sol.problem.parabolic else ""))
    ax.set_aspect("equal")
    mu_txt = ", ".join(f"{k} = {v:g}" for k, v in sol.scene.mu_dict(sol.mu).items())
    ax.set_title(f"{sol.scene.name}: {mu_txt}", fontsize=9)
    path = out / "solution.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def write_linear(sol: HFSolution, out: Path, plot: bool = True) -> list[Path]:
    """``summary.json`` (scene, mu, components, :data:`DEFINITIONS` numbers, provenance),
    ``solution.npz`` (``u`` on all dofs: heat ``(K + 1, n_dofs)`` with ``t``; the mesh:
    ``points``, ``triangles``, ``vertex_dofs``) and a PNG."""
    out.mkdir(parents=True, exist_ok=True)
    u = trajectory(sol)
    body = sol.disc.bodies[0]
    arrays = {"u": u, "points": body.points, "triangles": body.triangles,
              "vertex_dofs": body.vertex_dofs}
    if sol.problem.parabolic:
        arrays["t"] = sol.problem.dt * np.arange(sol.problem.steps + 1)
    npz = out / "solution.npz"
    np.savez_compressed(npz, **arrays)
    paths = [write_summary(sol, out), npz]
    if plot:
        paths.append(_write_png(sol, u[-1] if u.ndim == 2 else u, out))
    return paths


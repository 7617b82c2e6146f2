"""The bound-driven weak greedy against today's POD, on the same validation set.

POD (``rbbench reduce``: the scene's training set, all of it solved by HF, POD of the
displacements, mCPG cone, PGA) gives ``err_u_max`` on the validation set with ``n_train``
HF solves. The greedy (:func:`rbbench.rb.mixed.greedy.bound_greedy`) searches a large
training set (Latin hypercube) with the certified bound and solves the HF problem only at
the parameters it picks; after each pick its ``err_u_max`` on the same validation set is
measured (validation HF snapshots: the reference of both, counted in neither). Reported:
the curve, and the first HF count at which the greedy reaches the POD's ``err_u_max``.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from rbbench.hf.components import make_components
from rbbench.hf.model import ProblemCache, solve_hf
from rbbench.hf.snapshots.compute import compute_snapshots
from rbbench.rb.algorithms.infsup import make_solver
from rbbench.rb.config import ReduceConfig
from rbbench.rb.mixed.greedy import BoundGreedy, bound_greedy
from rbbench.rb.offline import reduce
from rbbench.scene.loading import Scene
from rbbench.scene.sampling import parameter_set

__all__ = ["bound_greedy_study", "markdown"]


def bound_greedy_study(scene: Scene, n_train: int = 1000, tol: float = 1e-3, n_max: int = 25,
                       N: int = 8, R: int = 8, n_valid: int = 20,
                       cache_dir: str = ".rbbench_cache",
                       progress=lambda m: None,
                       pod_sizes: tuple[int, ...] = ()) -> dict[str, Any]:
    """Run both (module docstring); a dict of the figures and the greedy's curve.
    ``pod_sizes``: also the POD's curve, the same reduction from the scene's training grid
    at these sizes (``n_train``: uniform grids), on the same validation set."""
    pod = reduce(scene, ReduceConfig(N=N, n_valid=n_valid, cache_dir=cache_dir,
                                     online_repeats=1, options={"R": R}), progress)
    mus_valid = np.asarray(pod.valid_mus)
    pod_curve = []
    for k in pod_sizes:
        r = reduce(scene, ReduceConfig(N=N, n_train=k, n_valid=n_valid, cache_dir=cache_dir,
                                       online_repeats=1, options={"R": R}), progress)
        if not np.array_equal(np.asarray(r.valid_mus), mus_valid):
            raise RuntimeError("the POD curve's validation set differs from the reference's")
        pod_curve.append({"n_hf": r.n_train, "N": r.N, "R": r.R,
                          "err_u_max_valid": r.summary()["err_u_max"]})
    valid = compute_snapshots(scene, mus_valid, cache_dir=cache_dir)
    comps = make_components(scene)
    problem_at = ProblemCache(comps[0], comps[1], scene)
    X = problem_at.X_free(scene.default_mu)
    xs = make_solver(X)
    free = problem_at(scene.default_mu).free

    def hf_solve(mu):
        s = solve_hf(scene, mu, components=comps, floor=False)
        return s.result.u[free], s.result.lam

    curve: list[dict[str, Any]] = []

    def measure(state: BoundGreedy) -> None:
        errs = []
        for j, mu in enumerate(mus_valid):
            res = state.model.solve(mu, path="python", method="daqp")
            u = valid.U[:, j]
            e = u - state.Z @ res.c
            errs.append(float(np.sqrt(e @ (X @ e) / (u @ (X @ u)))))
        curve.append({"n_hf": state.n_hf, "dim_primal": int(state.Z.shape[1]),
                      "R": int(state.Vg.shape[1]), "max_bound_train": state.max_bound[-1],
                      "err_u_max_valid": max(errs)})

    train = parameter_set(scene, "train", n_train, kind="lhs", seed=1)
    t0 = time.perf_counter()
    g = bound_greedy(problem_at, hf_solve, X, xs, scene.bounds, train, tol, n_max, progress,
                     measure)
    target = pod.summary()["err_u_max"]
    reach = next((c["n_hf"] for c in curve if c["err_u_max_valid"] <= target), None)
    return {"scene": scene.name, "n_train_greedy": len(train), "tol": tol, "n_max": n_max,
            "greedy_stop": g.stop, "greedy_s": time.perf_counter() - t0,
            "pod": {"n_hf": pod.n_train, "N": pod.N, "R": pod.R, "K_pga": pod.K_pga,
                    "err_u_max_valid": target},
            "greedy_reaches_pod_at_n_hf": reach,
            "hf_ratio": pod.n_train / reach if reach else None, "curve": curve,
            "pod_curve": pod_curve}


def markdown(out: dict[str, Any]) -> str:
    """The curve as a Markdown table, and the comparison in one line."""
    lines = ["| HF solves | dim primal (u + supremizers) | R | max bound / ||u_N|| (train) "
             "| err_u_max (valid) |", "|---|---|---|---|---|"]
    for c in out["curve"]:
        lines.append(f"| {c['n_hf']} | {c['dim_primal']} | {c['R']} | "
                     f"{c['max_bound_train']:.3g} | {c['err_u_max_valid']:.3g} |")
    p = out["pod"]
    lines.append("")
    lines.append(f"POD: {p['n_hf']} HF solves, N = {p['N']}, R = {p['R']}, K_pga = "
                 f"{p['K_pga']}: err_u_max {p['err_u_max_valid']:.3g} on the validation set; "
                 f"the greedy ({out['n_train_greedy']} training parameters) reaches it after "
                 f"{out['greedy_reaches_pod_at_n_hf']} HF solves"
                 + (f" ({out['hf_ratio']:.3g}x fewer)" if out["hf_ratio"] else ""))
    if out.get("pod_curve"):
        lines += ["", "| POD: HF solves (training grid) | N | R | err_u_max (valid) |",
                  "|---|---|---|---|"]
        lines += [f"| {c['n_hf']} | {c['N']} | {c['R']} | {c['err_u_max_valid']:.3g} |"
                  for c in out["pod_curve"]]
    return "\n".join(lines)

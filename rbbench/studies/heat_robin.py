"""The talk's heat equation side by side with its published figures (``rbbench studies
heat-robin``).

Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods: parametric
variational inequalities" (talk), slides "Numerical results on an industrial test case:
original model" and "...: reduced-order model": the valve's heat problem, HF 51,500 nodes
x 50 time steps in about 140 s; the reduced model with N = 25 in about 0.1 s, error below
1 % in L2(0, T; H1). rbbench: the scene ``heat_robin`` (the talk's toy heat equation,
slide "Simple toy example: heat equation", on the unit square, data in its file),
POD-greedy to ``N``, validated on the scene's validation set (a fresh snapshot cache: the
HF solves are timed, not read).
"""

from __future__ import annotations

import tempfile
from typing import Any

from rbbench.studies.formatting import markdown_table

__all__ = ["PUBLISHED", "heat_robin_markdown", "heat_robin_study"]

#: The figures reported by Benaceur et al. (the valve; a nonlinear problem on another
#: geometry).
PUBLISHED = {"n_hf_dofs": 51500, "steps": 50, "t_hf_s": 140.0, "N": 25, "t_online_s": 0.1,
        "err_max": "< 1 %"}


def heat_robin_study(n_cells: int = 64, N: int = 25, n_train: int | None = None,
                     n_valid: int | None = None, repeats: int = 20, backend: str = "skfem",
                     progress=print) -> dict[str, Any]:
    """rbbench's figures on ``heat_robin`` (``n_cells`` squares per side) with ``N``."""
    from rbbench.rb.config import make_config
    from rbbench.rb.linear.offline import reduce_linear
    from rbbench.scene.loading import load_scene

    scene = load_scene("heat_robin", [f"discretization.n_cells={n_cells}"])
    progress(f"heat_robin, {n_cells} x {n_cells} squares, N = {N} ({backend})")
    with tempfile.TemporaryDirectory() as cache:
        cfg = make_config(formulation="linear", primal="pod", dual="", stabilizer="", N=N,
                           n_train=n_train, n_valid=n_valid, cache_dir=cache,
                           online_repeats=repeats, backend=backend)
        s = reduce_linear(scene, cfg).summary()
    return {"n_hf_dofs": s["n_hf_dofs"], "steps": scene.data["time"]["steps"],
            "t_hf_s": s["t_hf_median_s"], "N": s["N"], "t_online_s": s["t_online_median_s"],
            "err_max": s["err_u_max"], "err_est_max": s["err_est_max"],
            "effectivity_min": s["effectivity_min"], "t_offline_s": s["t_offline_hf_s"],
            "n_train": s["n_train"], "n_valid": s["n_valid"], "backend": backend}


def heat_robin_markdown(res: dict[str, Any]) -> str:
    """The published column (Benaceur et al.'s valve) beside rbbench's."""
    rows = [("HF nodes", f"{PUBLISHED['n_hf_dofs']:,}", f"{res['n_hf_dofs']:,}"),
            ("time steps", PUBLISHED["steps"], res["steps"]),
            ("HF solve, one trajectory (s)", f"{PUBLISHED['t_hf_s']:g}", f"{res['t_hf_s']:.3g}"),
            ("N", PUBLISHED["N"], res["N"]),
            ("reduced solve, one trajectory (s)", f"{PUBLISHED['t_online_s']:g}",
             f"{res['t_online_s']:.3g}"),
            ("max relative error, L2(0, T; H1)", PUBLISHED["err_max"], f"{res['err_max']:.2e}"),
            ("error bound relative to u, max", "", f"{res['err_est_max']:.2e}"),
            ("bound effectivity, min", "", f"{res['effectivity_min']:.3g}"),
            ("offline (training HF + POD-greedy + model) (s)", "",
             f"{res['t_offline_s']:.3g}")]
    return (f"Benaceur et al.'s valve (a nonlinear heat problem, its mesh) against rbbench's "
            f"heat_robin ({res['backend']}, {res['n_train']} training / {res['n_valid']} "
            "validation mus)\n\n"
            + markdown_table(("quantity", "published (valve)", "rbbench heat_robin"), rows))

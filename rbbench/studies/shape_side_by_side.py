"""HF- and RB-driven shape optimisation side by side (``rbbench studies shape-side-by-side``).

Model B of the talk "On coupling of complementarity with friction in contact shape optimization".

:func:`rbbench.optim.rb_driver.side_by_side` in one process with one BLAS thread: the
bundle trust-region method on the HF ``Theta`` and the trust region of reduced models from
the same initial design, then the per-evaluation times (state + subgradient) of the HF
and of the reduced model at the RB optimum. Rows: the final ``J`` (HF-verified for the
RB driver), its ratio to ``J0`` and to the uniform-pressure lower bound, HF solves, wall
time, stop reasons and the largest constraint residual (raw, > 0 violated); with several
body meshes (``ny``) one table per mesh and the curve of the wall-time ratio over them.
"""

from __future__ import annotations

from typing import Any

from rbbench._compat import deprecated_names
from rbbench.studies.formatting import markdown_table

__all__ = ["shape_markdown", "shape_side_by_side"]


def shape_side_by_side(scene: str = "shape_coulomb", overrides: dict | None = None,
                       metric: str = "identity", max_iter: int = 100, max_evals: int = 300,
                       eps: float = 1e-6, ny: list[int] | None = None,
                       progress: Any = None) -> dict[str, Any]:
    """Run both drivers (bundle options ``metric``, ``max_iter``, ``max_evals``, ``eps``
    for the HF run and the RB driver's inner runs) on the scene's mesh, or on each body
    mesh of ``ny`` element rows (``geometry.ny``; the contact nodes, the design and the
    admissible set stay the same): per mesh the figures of
    :func:`~rbbench.optim.rb_driver.side_by_side` plus ``ny``, ``dofs`` and
    ``J_uniform_bound``, in ``runs``."""
    from rbbench.optim.bundle import BundleOptions
    from rbbench.optim.rb_driver import RBOptions, side_by_side
    from rbbench.optim.shape_scene import load_shape_scene

    base = dict(overrides or {})
    scenes = [load_shape_scene(scene, base if n is None else {**base, "geometry.ny": n})
              for n in (ny or [None])]
    hf_opts = BundleOptions(max_iter=max_iter, max_evals=max_evals, eps=eps, metric=metric)
    rb_opts = RBOptions(inner=BundleOptions(max_iter=100, max_evals=200, eps=eps,
                                            metric=metric))
    runs = []
    for sc in scenes:
        if progress is not None:
            progress(f"mesh ny = {sc.ny}: {2 * sc.grid.n_nodes} dofs")
        res = side_by_side(sc, rb_opts, hf_opts)
        res.pop("rb_history", None)
        runs.append({**res, "ny": sc.ny, "dofs": 2 * sc.grid.n_nodes,
                     "J_uniform_bound": sc.uniform_pressure_bound()})
    sc = scenes[0]
    return {"runs": runs, "metric": metric, "initial": sc.initial,
            "initial_height": sc.initial_height, "J_uniform_bound": sc.uniform_pressure_bound()}


def _mesh_table(r: dict[str, Any]) -> str:
    """The figures of one mesh's run as a Markdown table."""
    bound = r["J_uniform_bound"]
    rows = [("J at the returned design (HF)", f"{r['hf_J']:.6e}", f"{r['rb_J_hf']:.6e}"),
            ("J / J0", f"{r['hf_J'] / r['J0']:.4f}", f"{r['rb_J_hf'] / r['J0']:.4f}"),
            ("J / uniform-pressure bound", f"{r['hf_J'] / bound:.3f}",
             f"{r['rb_J_hf'] / bound:.3f}"),
            ("HF solves (state + adjoint)", r["hf_evaluations"], r["rb_hf_solves"]),
            ("reduced solves", "", r["rb_solves"]),
            ("reduced basis size", "", r["rb_basis"]),
            ("wall time (s)", f"{r['hf_wall_s']:.1f}", f"{r['rb_wall_s']:.1f}"),
            ("one evaluation at the RB optimum (s)", f"{r['eval_hf_s']:.3f}",
             f"{r['eval_rb_s']:.3f}"),
            ("largest constraint residual (raw)", f"{max(r['hf_residuals'].values()):.2e}",
             f"{max(r['rb_residuals'].values()):.2e}"),
            ("stop", r["hf_stop"], r["rb_stop"])]
    return (f"mesh ny = {r['ny']} ({r['dofs']} dofs, J0 = {r['J0']:.6e})\n\n"
            + markdown_table(("", "HF-driven", "RB-driven"), rows)
            + f"\n\nwall HF / RB {r['wall_ratio']:.2f}, (J_RB - J_HF) / J_HF "
              f"{r['J_rel_diff']:.2e}, one evaluation HF / RB {r['eval_speedup']:.2f}")


def shape_markdown(res: dict[str, Any]) -> str:
    """The figures of :func:`shape_side_by_side` as Markdown: one table per mesh, then the
    curve over the meshes (wall times, their ratio, J relative difference)."""
    runs = res["runs"]
    head = (f"shape optimisation from the {res['initial']} of height "
            f"{res['initial_height']:g} (uniform-pressure bound "
            f"{res['J_uniform_bound']:.6e}), bundle metric {res['metric']}, one BLAS thread")
    parts = [head, *(_mesh_table(r) for r in runs)]
    if len(runs) > 1:
        rows = [(r["ny"], r["dofs"], f"{r['hf_wall_s']:.1f}", f"{r['rb_wall_s']:.1f}",
                 f"{r['wall_ratio']:.2f}", f"{r['J_rel_diff']:.2e}",
                 f"{r['hf_J'] / r['J_uniform_bound']:.3f}",
                 f"{r['rb_J_hf'] / r['J_uniform_bound']:.3f}",
                 f"{r['hf_evaluations']} / {r['rb_hf_solves']}",
                 f"{r['eval_speedup']:.1f}") for r in runs]
        parts.append(markdown_table(("ny", "dofs", "HF wall (s)", "RB wall (s)", "HF / RB",
                                     "(J_RB - J_HF) / J_HF", "J_HF / bound", "J_RB / bound",
                                     "HF solves HF / RB", "one eval HF / RB"), rows))
    return "\n\n".join(parts)


__getattr__ = deprecated_names(__name__)  # names that left this module (rbbench._compat)

"""HF- and RB-driven shape optimisation side by side (``rbbench studies shape-side-by-side``).

Model B of the talk "On coupling of complementarity with friction in contact shape optimization".

:func:`rbbench.optim.rb_driver.side_by_side` in one process with one BLAS thread: the
bundle trust-region method on the HF ``Theta`` and the trust region of reduced models from
the same initial design, then the per-evaluation times (state + subgradient) of the HF
and of the reduced model at the RB optimum. Rows: the final ``J`` (HF-verified for the
RB driver), its ratio to ``J0`` and to the uniform-pressure lower bound, HF solves, wall
time, stop reasons and the largest constraint residual (raw, > 0 violated).
"""

from __future__ import annotations

from typing import Any

from rbbench._compat import deprecated_names
from rbbench.studies.formatting import markdown_table

__all__ = ["shape_markdown", "shape_side_by_side"]


def shape_side_by_side(scene: str = "shape_coulomb", overrides: dict | None = None,
                       metric: str = "identity", max_iter: int = 100, max_evals: int = 300,
                       eps: float = 1e-6) -> dict[str, Any]:
    """Run both drivers (bundle options ``metric``, ``max_iter``, ``max_evals``, ``eps``
    for the HF run and the RB driver's inner runs); the figures of
    :func:`~rbbench.optim.rb_driver.side_by_side` plus ``J_uniform_bound``."""
    from rbbench.optim.bundle import BundleOptions
    from rbbench.optim.rb_driver import RBOptions, side_by_side
    from rbbench.optim.shape_scene import load_shape_scene

    sc = load_shape_scene(scene, overrides or {})
    hf_opts = BundleOptions(max_iter=max_iter, max_evals=max_evals, eps=eps, metric=metric)
    rb_opts = RBOptions(inner=BundleOptions(max_iter=100, max_evals=200, eps=eps,
                                            metric=metric))
    res = side_by_side(sc, rb_opts, hf_opts)
    res.pop("rb_history", None)
    return {**res, "metric": metric, "initial": sc.initial,
            "initial_height": sc.initial_height,
            "J_uniform_bound": sc.uniform_pressure_bound()}


def shape_markdown(r: dict[str, Any]) -> str:
    """The figures of :func:`shape_side_by_side` as a Markdown table."""
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
    return (f"shape optimisation from the {r['initial']} of height {r['initial_height']:g} "
            f"(J0 = {r['J0']:.6e}, uniform-pressure bound {bound:.6e}), bundle metric "
            f"{r['metric']}, one BLAS thread\n\n"
            + markdown_table(("", "HF-driven", "RB-driven"), rows)
            + f"\n\nwall HF / RB {r['wall_ratio']:.2f}, (J_RB - J_HF) / J_HF "
              f"{r['J_rel_diff']:.2e}, one evaluation HF / RB {r['eval_speedup']:.2f}")


__getattr__ = deprecated_names(__name__)  # names that left this module (rbbench._compat)

"""What ``rbbench solve`` and ``rbbench reduce`` print for a linear scene (issue 18: no
contact field, no dual space). Formatting only, as :mod:`rbbench.cli.console`."""

from __future__ import annotations

from rbbench.cli.console import _fmt

__all__ = ["print_linear_reduce", "print_linear_summary"]

_SOLVE_KEYS = ("physics", "n_dofs", "n_free", "steps", "dt", "stop_reason", "residual_rel",
               "solve_time_s", "u_max", "u_min", "u_integral", "u_norm_X", "u_norm_L2X")
_REDUCE_KEYS = ("N", "hyper", "n_train", "n_valid", "n_hf_dofs", "err_u_max", "err_u_mean",
                "err_est_max", "effectivity_min", "effectivity_max", "alpha_lb_max",
                "energy_err_max", "t_offline_s", "t_offline_hf_s", "n_snapshots_cached",
                "t_online_median_s", "t_hf_median_s", "speedup")


def print_linear_summary(m: dict, mu: dict) -> None:
    """The lines of a linear HF solve (``m``: :func:`rbbench.hf.linear.solve.linear_metrics`)."""
    print("mu: " + ", ".join(f"{k} = {v:g}" for k, v in mu.items()))
    at_t = " (at T)" if "steps" in m else ""
    for k in _SOLVE_KEYS:
        if k in m:
            tail = at_t if k in ("u_max", "u_min", "u_integral", "u_norm_X") else ""
            print(f"  {k:<14} {_fmt(m[k])}{tail}")
    print("  (linear scene, no contact: residual_rel recomputed from the assembled operators; "
          "see summary.json definitions)")


def print_linear_reduce(s: dict, parabolic: bool, inner: str) -> None:
    """The main numbers of a linear reduction (``s``: ``ReduceResult.summary()``;
    ``parabolic``: a ``heat`` scene, errors in L2(0, T; X); ``inner``: X, the scene's
    ``inner_product``)."""
    for k in _REDUCE_KEYS:
        if k in s and s[k] is not None:
            print(f"  {k:<20} {_fmt(s[k])}")
    for w in s.get("warnings", ()):
        print(f"  WARNING: {w}")
    x = {"h1_semi": "H1_0 seminorm |.|_1", "h1": "H1"}.get(inner, inner)
    norm = f"L2(0, T; X) norm, X the {x}" if parabolic else f"X norm, X the {x}"
    print(f"  (linear scene, no contact: err_u = ||u - u_N|| / ||u|| in the {norm}, "
          "err_est = the a posteriori bound / ||u||, effectivity = bound / error (>= 1: "
          "rigorous), max/mean/min over the validation set; no dual space, stabiliser or "
          "contact solver: --dual, --stabilizer, -R, -S, --solver do not apply; see "
          "result.json definitions)")

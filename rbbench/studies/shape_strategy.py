"""The optimiser's strategy against the plain method (``rbbench studies shape-strategy``).

Model B of the talk "On coupling of complementarity with friction in contact shape
optimization". For each driver, ``rbbench optimize`` with ``--strategy none`` (the bundle
trust-region method from the initial design) and with ``--strategy equalise`` (the
load-equalising phase before it, :mod:`rbbench.optim.strategy`), alternately in this
process with one BLAS thread, ``repeats`` times: ``J`` at the returned design (HF), ``J``
over the uniform-pressure bound, HF solves, the strategy's stages and phase solves, the
largest raw constraint residual and its group, the wall time (median over the repeats,
the figures not included) and the stop reasons. The runs are deterministic: ``J`` and the
counts must agree between repeats, which the study checks.
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from statistics import median
from typing import Any

from rbbench.studies.formatting import markdown_table

__all__ = ["strategy_markdown", "strategy_side_by_side"]

_KEEP = ("J_over_bound", "hf_solves", "rb_solves", "constraint_residual_max_opt",
         "constraint_worst_opt", "stop_reason", "J0")


def strategy_side_by_side(scene: str = "shape_coulomb", overrides: dict | None = None,
                          drivers: tuple[str, ...] = ("hf",), repeats: int = 1,
                          max_iter: int = 100, max_evals: int = 300, eps: float = 1e-6,
                          metric: str = "identity", out_dir: Path | None = None
                          ) -> dict[str, Any]:
    """Run both strategies per driver (the options of ``rbbench optimize``); their files go
    to ``out_dir/<driver>_<strategy>_<repeat>`` (a temporary folder if None). Returns
    ``{"runs": {"<driver>/<strategy>": figures}, "J_uniform_bound": ..., ...}``;
    RuntimeError if a repeat's ``J`` or counts differ from the first's."""
    from rbbench.optim.run import OptimizeConfig, run_optimization
    from rbbench.optim.shape_scene import load_shape_scene

    sc = load_shape_scene(scene, overrides or {})
    runs: dict[str, dict[str, Any]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(out_dir) if out_dir is not None else Path(tmp)
        for r in range(repeats):
            for driver in drivers:
                for strategy in ("none", "equalise"):
                    cfg = OptimizeConfig(driver=driver, max_iter=max_iter,
                                         max_evals=max_evals, eps=eps, quiet=True,
                                         metric=metric, strategy=strategy)
                    s = run_optimization(sc, cfg, base / f"{driver}_{strategy}_{r}")
                    _collect(runs.setdefault(f"{driver}/{strategy}", {}), s)
    for fig in runs.values():
        fig["wall_s_median"] = median(fig.pop("wall_s_all"))
    return {"runs": runs, "J_uniform_bound": sc.uniform_pressure_bound(),
            "initial": sc.initial, "initial_height": sc.initial_height, "repeats": repeats,
            "max_iter": max_iter, "max_evals": max_evals, "eps": eps, "metric": metric,
            "n_contact": sc.n_contact, "ny": sc.ny}


def _collect(fig: dict[str, Any], s: dict[str, Any]) -> None:
    J = s.get("J_opt_hf", s["J_opt"])
    cost = s["strategy_cost"]
    now = {"J": J, **{k: s.get(k) for k in _KEEP},
           "outer_stages": cost["outer_stages"],
           "phase_state_solves": cost["phase_state_solves"],
           "local_hf_solves": cost["local_hf_solves"]}
    if "J" in fig:
        same = {k: fig[k] == now[k] for k in ("J", "hf_solves", "rb_solves", "outer_stages")}
        if not all(same.values()):
            raise RuntimeError(f"shape-strategy: a repeat differs from the first ({same})")
    else:
        fig.update(now, wall_s_all=[])
    fig["wall_s_all"].append(s["wall_s"])


def strategy_markdown(r: dict[str, Any]) -> str:
    """The figures of :func:`strategy_side_by_side` as a Markdown table."""
    names = list(r["runs"])
    f = [r["runs"][k] for k in names]
    rows = [("J at the returned design (HF)", *(f"{x['J']:.6e}" for x in f)),
            ("J / uniform-pressure bound", *(f"{x['J_over_bound']:.7f}" for x in f)),
            ("HF solves (phase state solves + local)",
             *(f"{x['hf_solves']} ({x['phase_state_solves']} + {x['local_hf_solves']})"
               for x in f)),
            ("reduced solves", *(x["rb_solves"] if x["rb_solves"] is not None else ""
                                 for x in f)),
            ("outer stages", *(x["outer_stages"] for x in f)),
            (f"wall time (s), median of {r['repeats']}",
             *(f"{x['wall_s_median']:.1f}" for x in f)),
            ("largest constraint residual (raw, group)",
             *(f"{x['constraint_residual_max_opt']:.2e} ({x['constraint_worst_opt']})"
               for x in f)),
            ("stop", *(x["stop_reason"] for x in f))]
    return (f"rbbench optimize from the {r['initial']} of height {r['initial_height']:g} "
            f"(I = {r['n_contact']}, ny = {r['ny']}; J0 = {f[0]['J0']:.6e}, uniform-pressure "
            f"bound {r['J_uniform_bound']:.6e}), max_iter {r['max_iter']}, metric "
            f"{r['metric']}, one BLAS thread, runs alternated in one process\n\n"
            + markdown_table(("", *(n.replace("/", ", strategy ") for n in names)), rows))

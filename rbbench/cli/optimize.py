"""``rbbench optimize``: contact shape optimisation with model B of the talk "On coupling of
complementarity with friction in contact shape optimization"."""
from __future__ import annotations

import argparse
import math
from pathlib import Path

from rbbench.optim.shape_scene import parse_overrides
from rbbench.optim.strategy import STRATEGIES

#: the help of the optimiser's arguments (``rbbench optimize``, ``rbbench studies
#: shape-side-by-side``)
HELP = {
    "scene": "a shape scene in problems/optimize/ or a path",
    "max_iter": "iterations at most",
    "max_evals": "objective evaluations at most",
    "metric": "bundle subproblem metric: identity (Schramm-Zowe BT) or bfgs (damped BFGS at "
              "serious steps, rbbench.optim.bundle_metric)",
    "eps": "stopping tolerance on the predicted decrease, relative to J0",
    "strategy": "equalise: stages of a load-equalising design phase (HF state "
                "solves that set the design carrying the uniform nodal force, "
                "rbbench.optim.strategy) and the local solver from its design; none: the "
                "local solver alone from the initial design (the plain bundle method)",
}


def add_parser(sub) -> argparse.ArgumentParser:
    """Register ``optimize`` on the CLI's subparsers."""
    p = sub.add_parser(
        "optimize", help="contact shape optimisation with slip-dependent Coulomb friction "
        "(model B of the shape-optimisation talk): bundle trust region, HF- or RB-driven; "
        "history.csv, summary.json, PNGs")
    p.add_argument("scene", nargs="?", default="shape_coulomb", help=HELP["scene"])
    p.add_argument("--driver", choices=("hf", "rb"), default="hf",
                   help="state solver along the path: the HF model or the reduced model "
                        "enriched in a trust region")
    p.add_argument("--method", choices=("bundle", "slsqp"), default="bundle",
                   help="bundle trust region or scipy's SLSQP as a smooth baseline")
    p.add_argument("--strategy", choices=STRATEGIES, default="equalise",
                   help=HELP["strategy"])
    p.add_argument("--max-iter", type=int, default=100, help=HELP["max_iter"])
    p.add_argument("--max-evals", type=int, default=300, help=HELP["max_evals"])
    p.add_argument("--metric", choices=("identity", "bfgs"), default="identity",
                   help=HELP["metric"])
    p.add_argument("--eps", type=float, default=1e-6, help=HELP["eps"])
    p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override a scene field, e.g. --set geometry.ny=20")
    p.add_argument("--out", type=Path, default=None,
                   help="output directory (default results/optimize/<scene>_<driver>_<method>, "
                        "with _none appended for --strategy none)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=run)
    return p


def run(args) -> int:
    """Exit 0 when the optimiser stopped by its own rule or budget, 1 when a solve failed."""
    from rbbench.optim.run import OptimizeConfig, run_optimization
    from rbbench.optim.shape_scene import load_shape_scene
    from rbbench.scene.parameters import SceneError

    for flag, v in (("--max-iter", args.max_iter), ("--max-evals", args.max_evals)):
        if v < 1:
            raise SceneError(f"{flag} {v}: must be an integer >= 1")
    if not (math.isfinite(args.eps) and 0 < args.eps <= 1):
        raise SceneError(f"--eps {args.eps:g}: must be a finite number in (0, 1] (relative "
                         "to J0)")
    sc = load_shape_scene(args.scene, parse_overrides(args.set))
    tail = "" if args.strategy == "equalise" else f"_{args.strategy}"
    out = args.out or (Path("results") / "optimize"
                       / f"{sc.name}_{args.driver}_{args.method}{tail}")
    cfg = OptimizeConfig(driver=args.driver, method=args.method, max_iter=args.max_iter,
                         max_evals=args.max_evals, eps=args.eps, quiet=args.quiet,
                         metric=args.metric, strategy=args.strategy)
    print(f"rbbench optimize {sc.name}: driver {cfg.driver}, method {cfg.method}, "
          f"strategy {cfg.strategy}, "
          f"I = {sc.n_contact}, mesh {sc.n_contact - 1} x {sc.ny} Q1 -> {out}")
    s = run_optimization(sc, cfg, out)
    print(f"J0 {s['J0']:.6e}  J_opt {s['J_opt']:.6e}  ratio {s['ratio']:.4e} (published: "
          f"{s['published']['ratio']:.4e})  iterations {s['iterations']}  HF solves "
          f"{s.get('hf_solves')}  wall {s['wall_s']:.1f} s  stop: {s['stop_reason']}\n"
          f"J / uniform-pressure bound {s['J_over_bound']:.8g} (bound {s['J_uniform_bound']:.6e})"
          f"  strategy {s['strategy']}: {s['strategy_cost']['outer_stages']} stage(s), "
          f"{s['strategy_cost']['phase_state_solves']} phase state solves\n"
          f"constraint residuals at the optimum (max, raw): {s['constraint_residual_max_opt']:.2e}"
          f" ({s['constraint_worst_opt']})"
          f"\nwritten: {out}/summary.json, history.csv, designs.png, pressure.png, history.png")
    return 1 if str(s["stop_reason"]).startswith("oracle failed") else 0

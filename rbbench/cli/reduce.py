"""``rbbench reduce`` (offline stage and validation: ``result.json``) and
``rbbench online-scaling``."""

from __future__ import annotations

import json
from pathlib import Path

from rbbench.cli.common import _add_option_args, _backend_options, _resolve_solver
from rbbench.cli.console import _print_reduce_summary, _Progress
from rbbench.runtime import openblas_env as _openblas_env  # noqa: F401  (first: before numpy loads OpenBLAS)
from rbbench.scene.linear import is_linear
from rbbench.scene.loading import SceneError, load_scene


def _reduce_config(args):
    from rbbench.rb.offline import ReduceConfig

    _resolve_solver(args)
    for flag, key in (("-N", "N"), ("-R", "R"), ("-S", "S"), ("--n-train", "n_train"),
                      ("--n-valid", "n_valid"), ("--jobs", "jobs"), ("--m-eim", "m_eim")):
        v = getattr(args, key, None)
        if v is not None and v < 1:
            raise SceneError(f"{flag} {v}: must be an integer >= 1")
    try:
        return ReduceConfig(primal=args.primal, dual=args.dual, stabilizer=args.stabilizer,
                            hyper=args.hyper, N=args.N, R=args.R, S=args.S,
                            n_train=args.n_train,
                            n_valid=args.n_valid, n_jobs=args.jobs, solver=args.solver,
                            backend=args.backend, formulation=args.formulation,
                            tol_eim=args.tol_eim, m_eim=args.m_eim, delta_pga=args.delta_pga,
                            k_pga_max=args.k_pga_max, online_method=args.online_method,
                            gcns_per_iteration=args.gcns_per_iteration,
                            gcns_patience=args.gcns_patience,
                            friction_dual=args.friction_dual,
                            backend_options=_backend_options(args.backend_option),
                            formulation_options=_backend_options(
                                args.formulation_option, "--formulation-option"))
    except ValueError as exc:
        raise SceneError(str(exc)) from None


def cmd_online_scaling(args) -> int:
    from rbbench.studies.scaling import online_scaling, scaling_markdown

    rows = online_scaling(args.scene, _reduce_config(args), tuple(args.levels),
                          tuple(args.set or ()), repeats=args.repeats,
                          progress=_Progress(args.quiet))
    print(scaling_markdown(rows))
    print("(online time: one reduced solve incl. the EIM evaluation; median and IQR over "
          "validation mus x repeats, models interleaved; ratio: median / first level's)")
    return 0


def cmd_reduce(args) -> int:
    from rbbench.rb.offline import reduce

    scene = load_scene(args.scene, overrides=args.set or [])
    if is_linear(scene):
        return _reduce_linear(scene, args)
    _resolve_solver(args, scene)  # a friction scene: the solver declaring its law
    cfg = _reduce_config(args)
    progress = _Progress(args.quiet)
    res = reduce(scene, cfg, progress=progress, snapshot_progress=not args.quiet)
    s = res.summary()
    tag = f"nitsche_{res.hyper}" if cfg.formulation == "nitsche" else \
        f"{args.dual}_{args.stabilizer}"
    if cfg.friction_dual != "seed":
        tag += f"_{cfg.friction_dual}"
    path = _write_result(args, scene, tag, s)
    _print_reduce_summary(s, cfg.formulation)
    print(f"wrote: {path}")
    return 0


def _write_result(args, scene, tag: str, s: dict) -> Path:
    """``result.json`` of ``rbbench reduce`` (``--out``, default results/reduce/<scene>_<tag>)."""
    from rbbench.provenance import _jsonable, provenance

    out = Path(args.out) if args.out else Path("results") / "reduce" / f"{scene.name}_{tag}"
    out.mkdir(parents=True, exist_ok=True)
    (out / "result.json").write_text(json.dumps(_jsonable({**s, "provenance": provenance()}),
                                                indent=2) + "\n")
    return out / "result.json"


def _reduce_linear(scene, args) -> int:
    """``rbbench reduce`` of a linear scene (:func:`rbbench.api.linear_config`)."""
    from rbbench.api import linear_config
    from rbbench.cli.console import print_linear_reduce
    from rbbench.rb.linear.offline import reduce_linear
    from rbbench.scene.linear import is_parabolic

    fields = {"formulation": args.formulation} if args.formulation != "mixed" else {}
    cfg = linear_config(scene, **fields, primal=args.primal, hyper=args.hyper, N=args.N,
                        n_train=args.n_train, n_valid=args.n_valid, backend=args.backend,
                        backend_options=_backend_options(args.backend_option))
    s = reduce_linear(scene, cfg, progress=_Progress(args.quiet)).summary()
    path = _write_result(args, scene, "linear", s)
    print_linear_reduce(s, is_parabolic(scene), scene.data["discretization"]["inner_product"])
    print(f"wrote: {path}")
    return 0


def _add_reduce_args(rd) -> None:
    _add_option_args(rd)
    rd.add_argument("--primal", default="pod")
    rd.add_argument("--dual", default="mcpg", help="pod, cpg, mcpg, eng, nnmf")
    rd.add_argument("--stabilizer", default="pga", help="none, supremizer, pga")
    rd.add_argument("--hyper", default="auto",
                    help="auto (affine if exact, else eim), affine (exact), eim (EIM of "
                         "B(mu) Z and G(mu)), none (plain: HF assembly projected online); "
                         "nitsche: auto = empirical cubature at the contact points, eim = DEIM, "
                         "none = plain; friction: auto = none (plain), eim = the wedge model's "
                         "EIM of its B, g and DEIM of the slip (--friction-dual wedge only)")
    rd.add_argument("--online-method", default="auto",
                    help="reduced solver: auto, nnls, pdas (condensed LCP), daqp (primal QP)")
    rd.add_argument("--tol-eim", type=float, default=1e-4,
                    help="EIM tolerance (relative max-norm training error)")
    rd.add_argument("--m-eim", type=int, default=None, dest="m_eim",
                    help="cap on the number of EIM terms (default: the tolerance decides)")
    rd.add_argument("--delta-pga", type=float, default=None,
                    help="PGA tolerance on sigma_max (default: see result.json pga_delta)")
    rd.add_argument("--k-max", type=int, default=None, dest="k_pga_max",
                    help="cap on the PGA dimension K (online primal size N + K)")
    rd.add_argument("-N", type=int, default=None,
                    help="primal size (default: POD tolerance); clipped to the number of "
                         "training snapshots and to their numerical rank, with a warning "
                         "in result.json 'warnings' and on the console (N in result.json: "
                         "the size built)")
    rd.add_argument("-R", type=int, default=None, help="max dual size (default: tolerance)")
    rd.add_argument("-S", type=int, default=None,
                    help="friction: tangential size (POD of lam_t; default: R)")
    rd.add_argument("--gcns-per-iteration", type=int, default=2,
                    help="friction: GCNS nodes added per iteration (seed: 2)")
    rd.add_argument("--gcns-patience", type=int, default=1,
                    help="friction: GCNS stops after this many increases of e_GCNS, keeping "
                         "the best set (1: the seed's rule e(q) > e(q-1))")
    rd.add_argument("--friction-dual", choices=("seed", "wedge"), default="seed",
                    help="friction: the seed's dual model (normal cone + POD of lam_t + GCNS "
                         "collocation) or 'wedge' (cones of F lam_n +- lam_t, De Saxce's "
                         "fixed point: the Coulomb cone at every node)")
    rd.add_argument("--n-train", type=int, default=None)
    rd.add_argument("--n-valid", type=int, default=None)
    rd.add_argument("--jobs", type=int, default=None, help="processes for HF snapshots")
    rd.add_argument("--backend", default="skfem")
    rd.add_argument("--formulation", default="mixed", help="mixed or nitsche")
    rd.add_argument("--solver", default=None,
                    help="default: the formulation's (ssn for mixed, newton for nitsche)")
    rd.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE")


def _add_reduce_parser(sub) -> None:
    rd = sub.add_parser("reduce", help="offline RB stage + online validation (mixed or "
                        "nitsche formulation): errors, inf-sup constants, timings -> result.json")
    rd.add_argument("scene")
    _add_reduce_args(rd)
    rd.add_argument("--out")
    rd.add_argument("--quiet", action="store_true")
    rd.set_defaults(func=cmd_reduce)


def _add_online_scaling_parser(sub) -> None:
    osc = sub.add_parser("online-scaling",
                         help="online time of one reduction at several mesh levels, timed "
                              "side by side (is it flat in the HF size?)")
    osc.add_argument("scene")
    _add_reduce_args(osc)
    osc.add_argument("--levels", type=int, nargs="+", default=[0, 1])
    osc.add_argument("--repeats", type=int, default=30)
    osc.add_argument("--quiet", action="store_true")
    osc.set_defaults(func=cmd_online_scaling, hyper="eim")

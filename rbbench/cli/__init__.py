"""The ``rbbench`` command line.

``rbbench solve SCENE``: one HF solve with summary and files (``--formulation nitsche``);
``rbbench nitsche-table``: the seed's Alart-Curnier residual table (Nitsche);
``rbbench plugins``: every registered component and whether it is importable;
``rbbench scenes``: the scenes in ``problems/``;
``rbbench run MATRIX``: a run matrix, one results row per case;
``rbbench studies STUDY``: the linear scenes beside pyMOR and the seed (issue 18);
``rbbench report DIR`` / ``rbbench compare A B``: plots, tables, regressions.
Bad input exits with status 2 and a message naming what is wrong.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from rbbench.bench.errors import ResultsError
from rbbench.cli.console import _print_reduce_summary, _Progress, print_summary
from rbbench.cli.optimize import add_parser as _add_optimize_parser
from rbbench.cli.studies import add_parser as _add_studies_parser
from rbbench.registry import NotInstalledError, UnknownComponentError, default_registry
from rbbench.runtime import openblas_env as _openblas_env  # noqa: F401  (first: before numpy loads OpenBLAS)
from rbbench.scene.linear import is_linear
from rbbench.scene.loading import PROBLEMS_DIR, SceneError, load_scene, tomllib


def _backend_options(items: list[str] | None, flag: str = "--backend-option") -> dict:
    """``FLAG KEY=VALUE`` pairs (``--backend-option``, ``--formulation-option``); a value is
    a TOML literal, else a string."""
    options = {}
    for text in items or ():
        key, sep, raw = text.partition("=")
        key, raw = key.strip(), raw.strip()
        if not sep or not key.isidentifier():
            raise SceneError(f"{flag} {text!r}: expected KEY=VALUE, e.g. mesh=skfem or "
                             "gamma0=1.0")
        try:
            options[key] = tomllib.loads(f"v = {raw}")["v"]
        except tomllib.TOMLDecodeError:
            options[key] = raw
    return options


def _resolve_solver(args, scene=None) -> None:
    """``--solver`` not given: the formulation's declared solver (``ssn`` for mixed,
    ``newton`` for Nitsche; for a friction ``scene``, the first declaring its law)."""
    if getattr(args, "solver", None) is None:
        from rbbench.hf.components import default_solver
        from rbbench.scene.friction import friction_of

        law = friction_of(scene).law if scene is not None else "none"
        args.solver = default_solver(args.formulation, law=law)


def _solve_components(scene, args, options: dict, f_options: dict | None = None):
    """Backend (with ``options``), formulation (with ``f_options``) and solver for
    ``rbbench solve``."""
    from rbbench.hf.components import check_names

    reg = default_registry()
    check_names(scene, reg, args.backend, args.formulation, args.solver)  # before any meshing
    try:
        backend = reg.create("backend", args.backend, scene=scene, **options)
    except SceneError:
        raise
    except (TypeError, ValueError) as exc:
        raise SceneError(f"--backend-option: {exc}") from None
    try:
        form = reg.create("formulation", args.formulation, **(f_options or {}))
    except (TypeError, ValueError) as exc:
        raise SceneError(f"--formulation-option: {exc}") from None
    return backend, form, reg.create("solver", args.solver)


def cmd_solve(args) -> int:
    scene = load_scene(args.scene, overrides=args.set or [])
    mu = scene.check_mu(args.mu) if args.mu is not None else scene.default_mu
    options = _backend_options(args.backend_option)
    f_options = _backend_options(args.formulation_option, "--formulation-option")
    _resolve_solver(args, scene)
    if args.out and Path(args.out).exists() and not Path(args.out).is_dir():
        raise SceneError(f"--out {args.out}: exists and is not a directory")
    progress = _Progress(args.quiet)
    if is_linear(scene):
        return _solve_linear(scene, mu, args, options, progress)
    from rbbench.hf.model import solve_hf
    from rbbench.hf.output import write_all

    components = None
    if options or f_options:
        progress("meshing the reference configuration")
        components = _solve_components(scene, args, options, f_options)
    sol = solve_hf(scene, mu, backend=args.backend, formulation=args.formulation,
                   solver=args.solver, progress=progress, components=components)
    out = _solve_out(args, scene, mu)
    progress(f"writing {out}")
    paths = write_all(sol, out, plot=not args.no_plot)
    print_summary(sol.metrics, scene.mu_dict(mu))
    print("wrote: " + ", ".join(str(p) for p in paths))
    return 0 if sol.result.converged else 1


def _solve_out(args, scene, mu) -> Path:
    mu_txt = "_".join(f"{k}{v:g}" for k, v in scene.mu_dict(mu).items())
    return Path(args.out) if args.out else Path("results") / "solve" / f"{scene.name}_{mu_txt}"


def _solve_linear(scene, mu, args, options: dict, progress) -> int:
    """``rbbench solve`` of a linear scene (no contact): :mod:`rbbench.hf.linear.solve`."""
    from rbbench.cli.console_linear import print_linear_summary
    from rbbench.hf.linear.solve import solve_linear_hf, write_linear

    sol = solve_linear_hf(scene, mu, args.backend, args.formulation,
                          backend_options=options, progress=progress)
    out = _solve_out(args, scene, mu)
    progress(f"writing {out}")
    paths = write_linear(sol, out, plot=not args.no_plot)
    print_linear_summary(sol.metrics, scene.mu_dict(mu))
    print("wrote: " + ", ".join(str(p) for p in paths))
    return 0


def cmd_plugins(args) -> int:
    rows = _plugin_rows(default_registry())
    if args.json:
        print(json.dumps(rows, indent=2, default=str))
        return 0
    _print_plugin_table(rows)
    return 0


def _plugin_rows(reg) -> list[dict]:
    """One row per registered component (and per broken plugin) for ``rbbench plugins``."""
    rows = []
    for spec in reg.specs():
        ok, why = reg.availability(spec)
        rows.append({"role": spec.role, "name": spec.name, "package": spec.package,
                     "version": spec.version, "extras": list(spec.extras),
                     "importable": ok, "hint": why, "description": spec.description,
                     "capabilities": spec.capabilities})
    for ep_name, pkg, msg in reg.broken:
        rows.append({"role": "?", "name": ep_name, "package": pkg, "version": "", "extras": [],
                     "importable": False, "hint": msg, "description": "BROKEN plugin",
                     "capabilities": {}})
    return rows


def _print_plugin_table(rows: list[dict]) -> None:
    """The rows of :func:`_plugin_rows` as a table, with a hint under each unimportable one."""
    w = max([len(r["name"]) for r in rows] + [4]) + 2
    print(f"{'role':<12}{'name':<{w}}{'package':<22}{'extras':<10}{'importable':<11}description")
    for r in rows:
        pkg = f"{r['package']} {r['version']}".strip()
        print(f"{r['role']:<12}{r['name']:<{w}}{pkg:<22}{','.join(r['extras']) or '-':<10}"
              f"{'yes' if r['importable'] else 'NO':<11}{r['description']}")
        if not r["importable"]:
            print(f"{'':<12}-> {r['hint']}")


def cmd_scenes(args) -> int:
    for path in sorted(PROBLEMS_DIR.glob("*.toml")):
        sc = load_scene(path)
        params = ", ".join(f"{p.name} in [{p.low:g}, {p.high:g}]" for p in sc.parameters)
        print(f"{sc.name:<22}{params:<44}{sc.data['scene']['description']}")
    return 0


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
    from rbbench.cli.console_linear import print_linear_reduce
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


def cmd_hertz_table(args) -> int:
    from rbbench.studies.hertz import hertz_markdown, hertz_table

    progress = _Progress(args.quiet)
    rows = hertz_table(args.scene, tuple(args.loads), tuple(args.levels), args.mu,
                       tuple(args.set or ()), progress=progress)
    print(hertz_markdown(rows))
    return 0


def cmd_nitsche_table(args) -> int:
    from rbbench.studies.nitsche_eac import NITSCHE_COLUMNS, nitsche_markdown, nitsche_table

    overrides = [f"load.displacement={args.load!r}", f"discretization.degree={args.degree}",
                 f"discretization.quadrature={args.quadrature}",
                 f"discretization.normals={args.normals!r}",
                 f"discretization.contact_integration={args.integration!r}", *(args.set or ())]
    rows = nitsche_table(args.scene, tuple(1e-3 * h for h in args.h), tuple(args.mu),
                         backend=args.backend, theta=args.theta, gamma0=args.gamma0,
                         overrides=tuple(overrides), progress=_Progress(args.quiet))
    print(nitsche_markdown(rows))
    r = rows[0]
    print(f"(Nitsche theta = {r['theta']:g}, gamma = gamma0 E / h with gamma0 = {r['gamma0']:g}; "
          f"backend {args.backend}; overrides {overrides}; 'facet': mean slave facet length "
          "at mu; F mixed: LAC multipliers + ssn on the same mesh)")
    print(f"({NITSCHE_COLUMNS})")
    return 0


def cmd_nitsche_compare(args) -> int:
    from rbbench.studies.nitsche_compare import comparison_markdown, formulation_comparison

    res = formulation_comparison(args.scene, tuple(args.set or ()), n_train=args.n_train,
                                 n_valid=args.n_valid, N=args.N, Rs=tuple(args.R),
                                 progress=_Progress(args.quiet))
    print(comparison_markdown(res))
    print("(J = 1/2 a(u,u) - f(u) of the HF solutions over D_train; reduced errors: max over "
          "the validation set, u in the X norm; mixed: lam in the W norm (mCPG + PGA); "
          "Nitsche: the contact pressure -[P_gamma]_- in L2(Gamma_c))")
    return 0


def cmd_run(args) -> int:
    from rbbench.bench.matrix import MatrixError, load_matrix
    from rbbench.bench.runner import run_matrix

    reg = default_registry()
    try:
        matrix = load_matrix(args.matrix, selectors=args.select or (), sets=args.set or (),
                             registry=reg)
    except MatrixError as exc:
        raise SceneError(str(exc)) from None
    if args.dry_run:
        _print_cases(matrix)
        return 0
    out = Path(args.out) if args.out else Path("results") / matrix.name
    opts = {"address": args.scheduler} if args.scheduler else {}
    retry = [x for x in (args.retry or "").split(",") if x]
    try:
        summary = run_matrix(matrix, out, executor=args.executor, jobs=args.jobs, registry=reg,
                             retry=retry, csv=args.csv, cache_dir=args.cache_dir,
                             progress=not args.quiet, executor_options=opts)
    except KeyboardInterrupt:
        print(f"interrupted: finished cases are kept in {out}; rerun the same command to "
              "resume", file=sys.stderr)
        return 130
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    _print_run_summary(summary, out)
    return 0


def _print_run_summary(summary, out: Path) -> None:
    """``rbbench run``: cases computed and kept, counts per status, wall time, files."""
    print(f"{len(summary.computed)} computed, {len(summary.kept)} kept from before; "
          + ", ".join(f"{v} {k}" for k, v in sorted(summary.counts.items()))
          + f"; {summary.wall_s:.0f} s")
    print(f"wrote: {out / 'results.parquet'} (report: rbbench report {out})")


def _print_cases(matrix) -> None:
    """``rbbench run --dry-run``: one line per case, then the counts per status."""
    counts: dict[str, int] = {}
    for c in matrix.cases:
        print(f"{c.key}  {c.status:<13} {c.label}" + (f"  ({c.reason})" if c.reason else ""))
        counts[c.status] = counts.get(c.status, 0) + 1
    print(f"{len(matrix.cases)} cases: " + ", ".join(f"{v} {k}" for k, v in counts.items()))


def cmd_report(args) -> int:
    from rbbench.bench.report import report

    res = report(args.run_dir, out_dir=args.out, formats=tuple(args.format))
    print(f"wrote: {res}")
    return 0


def cmd_compare(args) -> int:
    from rbbench.bench.report import compare, format_compare

    res = compare(args.a, args.b, threshold=args.threshold, time_threshold=args.time_threshold)
    print(format_compare(res))
    return 1 if res.n_regressions else 0


def _add_run_parsers(sub) -> None:
    r = sub.add_parser("run", help="run a matrix of cases (problems/matrices/*.toml): one "
                                   "results row per case, resumable")
    r.add_argument("matrix", help="matrix file, or a name in problems/matrices/")
    r.add_argument("-s", "--select", action="append", metavar="ROLE=NAME[,NAME]",
                   help="keep only these (globs allowed; roles: scene, backend, formulation, "
                        "solver, primal, dual, stabilizer, hyper, friction_dual, N, R); repeatable")
    r.add_argument("--set", action="append", metavar="FIELD=VALUE",
                   help="override a [reduce] field for every case (repeatable)")
    r.add_argument("--dry-run", action="store_true", help="list the cases and exit")
    r.add_argument("--executor", default="processes", help="serial, processes, dask")
    r.add_argument("--jobs", type=int, default=None, help="concurrent cases (default: CPUs)")
    r.add_argument("--scheduler", help="dask scheduler address (executor dask)")
    r.add_argument("--out", help="run directory (default results/<matrix name>)")
    r.add_argument("--retry", help="recompute finished cases with these statuses, e.g. "
                                   "error,timeout")
    r.add_argument("--csv", action="store_true", help="also write results.csv")
    r.add_argument("--cache-dir", default=".rbbench_cache", help="HF snapshot cache")
    r.add_argument("--quiet", action="store_true")
    r.set_defaults(func=cmd_run)
    rp = sub.add_parser("report", help="plots and HTML / Markdown tables of a run directory")
    rp.add_argument("run_dir")
    rp.add_argument("--out", help="output directory (default RUN_DIR/report)")
    rp.add_argument("--format", nargs="+", default=["png", "svg"], choices=["png", "svg"])
    rp.set_defaults(func=cmd_report)
    cp = sub.add_parser("compare", help="compare two runs; exit code 1 on a regression")
    cp.add_argument("a", help="baseline run directory or results.parquet")
    cp.add_argument("b", help="new run directory or results.parquet")
    cp.add_argument("--threshold", type=float, default=0.1,
                    help="relative growth of an error / drop of a beta counted as a regression")
    cp.add_argument("--time-threshold", type=float, default=0.5,
                    help="relative growth of a time counted as a regression")
    cp.set_defaults(func=cmd_compare)


def _add_option_args(p) -> None:
    p.add_argument("--backend-option", action="append", metavar="KEY=VALUE",
                   help="backend constructor option (repeatable), e.g. mesh=skfem "
                        "(ngsolve: one mesh with skfem)")
    p.add_argument("--formulation-option", action="append", metavar="KEY=VALUE",
                   help="formulation constructor option (repeatable), e.g. gamma0=1.0 "
                        "(nitsche)")


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


def _add_study_tail(p, func) -> None:
    """The last arguments of a study command (``--set``, ``--quiet``) and its function."""
    p.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE")
    p.add_argument("--quiet", action="store_true")
    p.set_defaults(func=func)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="rbbench", description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="command", required=True)
    _add_solve_parser(sub)
    pl = sub.add_parser("plugins", help="registered components and whether they are importable")
    pl.add_argument("--json", action="store_true")
    pl.set_defaults(func=cmd_plugins)
    _add_reduce_parser(sub)
    _add_hertz_table_parser(sub)
    _add_nitsche_table_parser(sub)
    _add_nitsche_compare_parser(sub)
    _add_online_scaling_parser(sub)
    _add_optimize_parser(sub)
    _add_studies_parser(sub)
    _add_run_parsers(sub)
    sc = sub.add_parser("scenes", help="list the scenes in problems/")
    sc.set_defaults(func=cmd_scenes)
    return p


def _add_solve_parser(sub) -> None:
    s = sub.add_parser("solve", help="one HF contact solve: summary, contact.csv, VTU, PNG; "
                       "exit 1 when it did not converge or is flagged (stop_reason 'flagged': "
                       "zero contact force while the bodies overlap, see summary.json "
                       "warnings)")
    s.add_argument("scene", help="scene name in problems/ or path to a .toml file")
    s.add_argument("--mu", type=float, nargs="+", help="parameter value(s) (default: scene's)")
    s.add_argument("--backend", default="skfem")
    _add_option_args(s)
    s.add_argument("--formulation", default="mixed", help="mixed or nitsche")
    s.add_argument("--solver", default=None,
                   help="default: the formulation's (ssn for mixed, newton for nitsche)")
    s.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE",
                   help="override a scene value (repeatable), e.g. load.displacement=0.01")
    s.add_argument("--out", help="output directory (default results/solve/<scene>_<mu>)")
    s.add_argument("--no-plot", action="store_true", help="skip the PNG")
    s.add_argument("--quiet", action="store_true", help="no progress lines")
    s.set_defaults(func=cmd_solve)


def _add_reduce_parser(sub) -> None:
    rd = sub.add_parser("reduce", help="offline RB stage + online validation (mixed or "
                        "nitsche formulation): errors, inf-sup constants, timings -> result.json")
    rd.add_argument("scene")
    _add_reduce_args(rd)
    rd.add_argument("--out")
    rd.add_argument("--quiet", action="store_true")
    rd.set_defaults(func=cmd_reduce)


def _add_hertz_table_parser(sub) -> None:
    ht = sub.add_parser("hertz-table",
                        help="2D Hertz errors against load and mesh level (Markdown table)")
    ht.add_argument("scene", nargs="?", default="hertz_halfdisks")
    ht.add_argument("--loads", type=float, nargs="+", default=[0.05, 0.01],
                    help="imposed displacements d (m)")
    ht.add_argument("--levels", type=int, nargs="+", default=[0, 1, 2],
                    help="uniform refinement levels (sizes divided by 2**level)")
    ht.add_argument("--mu", type=float, default=1.0)
    _add_study_tail(ht, cmd_hertz_table)


def _add_nitsche_table_parser(sub) -> None:
    nt = sub.add_parser("nitsche-table",
                        help="the seed's Alart-Curnier residual e_AC^n of the Nitsche solve "
                             "against h and mu, side by side with the seed (Markdown table)")
    nt.add_argument("scene", nargs="?", default="hertz_halfdisks")
    nt.add_argument("--h", type=float, nargs="+", default=[5.0, 2.5, 1.25],
                    help="the seed's mesh sizes (mm), mapped to discretization.h_contact by "
                         "rbbench.studies.nitsche_eac.seed_h_overrides")
    nt.add_argument("--mu", type=float, nargs="+", default=[0.7, 1.0, 1.3])
    nt.add_argument("--backend", default="skfem")
    nt.add_argument("--theta", type=float, default=1.0)
    nt.add_argument("--gamma0", type=float, default=None, help="default: the formulation's")
    nt.add_argument("--load", type=float, default=0.09,
                    help="imposed displacement d (m); the seed's 0.09 by default")
    nt.add_argument("--degree", type=int, choices=(1, 2), default=2,
                    help="displacement degree (the seed's Hertz setting: P2)")
    nt.add_argument("--quadrature", type=int, default=0,
                    help="Gauss points per contact facet or piece (0: degree + 1)")
    nt.add_argument("--normals", choices=("facet", "smooth"), default="smooth",
                    help="slave normals: per facet, or continuous (vertex-averaged); "
                         "README 'The e_AC table'")
    nt.add_argument("--integration", choices=("gauss", "segmented"), default="segmented",
                    help="contact quadrature per slave facet (GPTS) or per piece between "
                         "master-vertex rays (segment-to-segment)")
    _add_study_tail(nt, cmd_nitsche_table)


def _add_nitsche_compare_parser(sub) -> None:
    nc = sub.add_parser("nitsche-compare",
                        help="Nitsche against mixed: HF energies over D_train and reduced "
                             "errors for several R (Markdown tables)")
    nc.add_argument("scene", nargs="?", default="hertz_halfdisks")
    nc.add_argument("-N", type=int, default=20)
    nc.add_argument("-R", type=int, nargs="+", default=[10, 30, 40])
    nc.add_argument("--n-train", type=int, default=61, help="|D_train| (the seed: 61)")
    nc.add_argument("--n-valid", type=int, default=10)
    _add_study_tail(nc, cmd_nitsche_compare)


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


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (SceneError, UnknownComponentError, NotInstalledError, ResultsError) as exc:
        print(f"rbbench: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # e.g. `rbbench plugins --json | head`
        sys.stderr.close()
        return 0
    except KeyboardInterrupt:
        print("rbbench: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())

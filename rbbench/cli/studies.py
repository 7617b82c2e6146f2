"""The study commands: ``rbbench hertz-table``, ``nitsche-table``, ``nitsche-compare`` and
``rbbench studies STUDY`` (pymor-thermal-block, heat-robin, shape-side-by-side,
shape-strategy, snapshot-workers, bound-greedy, bound-cap); the studies themselves live in
:mod:`rbbench.studies`.

The published figures are those of Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order
reduction methods: parametric variational inequalities" (talk), and of the talk "On
coupling of complementarity with friction in contact shape optimization" (model B).
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

from rbbench.cli.console import _Progress
from rbbench.cli.optimize import HELP as OPTIMIZE_HELP
from rbbench.scene.loading import SceneError
from rbbench.studies.formatting import print_and_dump
from rbbench.studies.published import PUBLISHED_SETTING

#: the scene argument of the Hertz studies
HERTZ_SCENE = "a Hertz scene: name in problems/ or path to a .toml file"


#: integer arguments of the studies: ``dest -> (flag, largest value)``; all must be >= 1
STUDY_INTS = {"N": ("-N", 1000), "R": ("-R", 1000), "n_train": ("--n-train", 10_000),
              "n_valid": ("--n-valid", 10_000), "repeats": ("--repeats", 10_000),
              "n_cells": ("--n-cells", 1024), "P": ("-P", 10_000), "jobs": ("--jobs", 256),
              "rounds": ("--rounds", 1000), "max_iter": ("--max-iter", 100_000),
              "max_evals": ("--max-evals", 100_000), "ny": ("--ny", 100_000),
              "caps": ("--caps", 10_000)}
#: float arguments: ``dest -> (flag, low, high, low included)`` (high included; eps: the
#: stopping tolerance relative to J0, at most 1)
STUDY_FLOATS = {"eps": ("--eps", 0.0, 1.0, False), "pause": ("--pause", 0.0, 60.0, True),
                "tol": ("--tol", 0.0, math.inf, False)}


def check_study_args(args: argparse.Namespace) -> None:
    """Refuse, before any work, a study argument out of its range (naming the flag and the
    range) and a ``--json`` file whose folder does not exist (it was noticed only after the
    whole study had run)."""
    for dest, (flag, high) in STUDY_INTS.items():
        value = getattr(args, dest, None)
        for v in value if isinstance(value, list) else [] if value is None else [value]:
            if not 1 <= v <= high:
                raise SceneError(f"{flag} {v}: must be an integer in [1, {high}]")
    for dest, (flag, low, high, closed) in STUDY_FLOATS.items():
        v = getattr(args, dest, None)
        if v is None:
            continue
        ok = math.isfinite(v) and (low <= v if closed else low < v) and v <= high
        if not ok:
            bound = (f"{'>=' if closed else '>'} {low:g}" if math.isinf(high) else
                     f"in {'[' if closed else '('}{low:g}, {high:g}]")
            raise SceneError(f"{flag} {v:g}: must be a finite number {bound}")
    target = getattr(args, "json", None)
    if target:
        folder = Path(target).resolve().parent
        if not folder.is_dir():
            raise SceneError(f"--json {target}: the folder {folder} does not exist")
        if Path(target).is_dir():
            raise SceneError(f"--json {target}: is a directory; give a file name")
    backend = getattr(args, "backend", None)
    if backend is not None:
        from rbbench.registry import default_registry

        default_registry().get("backend", backend)  # an unknown one: the valid names


def _scene_values(scene: str, base: list[str], values: list[tuple[str, Any, list[str]]]
                  ) -> Any:
    """Load ``scene`` with the overrides ``base`` (its errors as they are), then with each
    ``(flag, value, overrides)`` of ``values``: an error names the flag and its value. The
    scene with ``base`` only is returned."""
    from rbbench.scene.loading import load_scene

    sc = load_scene(scene, base)
    for flag, value, extra in values:
        try:
            load_scene(scene, [*base, *extra])
        except SceneError as exc:
            raise SceneError(f"{flag} {value}: {exc}") from None
    return sc


def _mu_values(sc: Any, flag: str, mus: list[float]) -> None:
    """Each of ``mus`` is a parameter of ``sc`` (one-parameter scenes), else the flag named."""
    for mu in mus:
        try:
            sc.check_mu([mu])
        except SceneError as exc:
            raise SceneError(f"{flag} {mu}: {exc}") from None


def _checked(run: Any) -> Any:
    """``run`` after :func:`check_study_args`."""
    def checked(args: argparse.Namespace) -> int:
        check_study_args(args)
        return run(args)

    checked.__doc__ = run.__doc__
    return checked


def add_parser(sub) -> None:
    """Register ``studies`` and one subcommand per study on the CLI's subparsers."""
    st = sub.add_parser("studies", help="side-by-side studies (pymor-thermal-block, heat-robin, "
                        "shape-side-by-side, shape-strategy, snapshot-workers, bound-greedy, "
                        "bound-cap)")
    group = st.add_subparsers(dest="study", required=True, metavar="STUDY",
                              help="the study (rbbench studies STUDY --help: its arguments)")
    for add, run in ((_add_pymor_thermal_block_parser, cmd_pymor_thermal_block),
                     (_add_heat_robin_parser, cmd_heat_robin),
                     (_add_shape_side_by_side_parser, cmd_shape_side_by_side),
                     (_add_shape_strategy_parser, cmd_shape_strategy),
                     (_add_snapshot_workers_parser, cmd_snapshot_workers),
                     (_add_bound_greedy_parser, cmd_bound_greedy),
                     (_add_bound_cap_parser, cmd_bound_cap)):
        add(group).set_defaults(func=_checked(run))


def cmd_hertz_table(args) -> int:
    from rbbench.studies.hertz import hertz_markdown, hertz_table

    sc = _scene_values(args.scene, list(args.set or ()),
                       [*(("--loads", d, [f"load.displacement={d!r}"]) for d in args.loads),
                        *(("--levels", lv, [f"discretization.level={lv}"])
                          for lv in args.levels)])
    _mu_values(sc, "--mu", [args.mu])

    progress = _Progress(args.quiet)
    rows = hertz_table(args.scene, tuple(args.loads), tuple(args.levels), args.mu,
                       tuple(args.set or ()), progress=progress)
    print(hertz_markdown(rows))
    return 0


def cmd_nitsche_table(args) -> int:
    from rbbench.studies.nitsche_eac import NITSCHE_COLUMNS, nitsche_markdown, nitsche_table

    by_flag = {"--load": (args.load, f"load.displacement={args.load!r}"),
               "--degree": (args.degree, f"discretization.degree={args.degree}"),
               "--quadrature": (args.quadrature, f"discretization.quadrature={args.quadrature}"),
               "--normals": (args.normals, f"discretization.normals={args.normals!r}"),
               "--integration": (args.integration,
                                 f"discretization.contact_integration={args.integration!r}")}
    overrides = [o for _, o in by_flag.values()] + list(args.set or ())
    _check_nitsche_table(args, by_flag)
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


def _check_nitsche_table(args, by_flag: dict[str, tuple[Any, str]]) -> None:
    """nitsche-table's values, before any solve: the scene with each flag's override, the
    mesh sizes, the parameters and the Nitsche options (theta, gamma0)."""
    from rbbench.registry import default_registry
    from rbbench.studies.nitsche_eac import published_h_overrides

    for flag, v in (("--h", h) for h in args.h):
        if not (math.isfinite(v) and v > 0):
            raise SceneError(f"{flag} {v:g}: must be a finite mesh size > 0 (mm)")
    sc = _scene_values(args.scene, list(args.set or ()),
                       [*((flag, v, [o]) for flag, (v, o) in by_flag.items()),
                        *(("--h", h, published_h_overrides(args.backend, 1e-3 * h))
                          for h in args.h)])
    _mu_values(sc, "--mu", args.mu)
    options = {"theta": args.theta, **({} if args.gamma0 is None else {"gamma0": args.gamma0})}
    try:
        default_registry().create("formulation", "nitsche", **options)
    except (TypeError, ValueError) as exc:
        flag = "--gamma0" if "gamma0" in str(exc) else "--theta"
        raise SceneError(f"{flag}: {exc}") from None


def cmd_nitsche_compare(args) -> int:
    from rbbench.scene.loading import load_scene
    from rbbench.studies.nitsche_compare import comparison_markdown, formulation_comparison

    load_scene(args.scene, list(args.set or ()))

    res = formulation_comparison(args.scene, tuple(args.set or ()), n_train=args.n_train,
                                 n_valid=args.n_valid, N=args.N, Rs=tuple(args.R),
                                 progress=_Progress(args.quiet))
    print(comparison_markdown(res))
    print("(J = 1/2 a(u,u) - f(u) of the HF solutions over D_train; reduced errors: max over "
          "the validation set, u in the X norm; mixed: lam in the W norm (mCPG + PGA); "
          "Nitsche: the contact pressure -[P_gamma]_- in L2(Gamma_c))")
    return 0


def _add_study_tail(p, func) -> None:
    """The last arguments of a study command (``--set``, ``--quiet``) and its function."""
    p.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE",
                   help="override a scene value (repeatable), e.g. discretization.degree=1")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.set_defaults(func=_checked(func))


def _add_hertz_table_parser(sub) -> None:
    ht = sub.add_parser("hertz-table",
                        help="2D Hertz errors against load and mesh level (Markdown table)")
    ht.add_argument("scene", nargs="?", default="hertz_halfdisks", help=HERTZ_SCENE)
    ht.add_argument("--loads", type=float, nargs="+", default=[0.05, 0.01],
                    help="imposed displacements d (m)")
    ht.add_argument("--levels", type=int, nargs="+", default=[0, 1, 2],
                    help="uniform refinement levels (sizes divided by 2**level)")
    ht.add_argument("--mu", type=float, default=1.0,
                    help="the scene's parameter (hertz_halfdisks: the radius R1, m)")
    _add_study_tail(ht, cmd_hertz_table)


def _add_nitsche_table_parser(sub) -> None:
    nt = sub.add_parser("nitsche-table",
                        help="the relative Alart-Curnier residual e_AC^n of the Nitsche solve "
                             "against h and mu, side by side with Benaceur et al.'s published "
                             "table (Markdown table)")
    # the defaults are the published setting (rbbench.studies.published.PUBLISHED_SETTING)
    pub = PUBLISHED_SETTING
    nt.add_argument("scene", nargs="?", default="hertz_halfdisks", help=HERTZ_SCENE)
    nt.add_argument("--h", type=float, nargs="+", default=[5.0, 2.5, 1.25],
                    help="the published mesh sizes (mm), mapped to discretization.h_contact "
                         "by rbbench.studies.nitsche_eac.published_h_overrides")
    nt.add_argument("--mu", type=float, nargs="+", default=[0.7, 1.0, 1.3],
                    help="the scene's parameter values (hertz_halfdisks: the radius R1, m)")
    nt.add_argument("--backend", default="skfem",
                    help="HF backend (registered: rbbench plugins, role backend)")
    nt.add_argument("--theta", type=float, default=1.0,
                    help="Nitsche variant: 1 symmetric (the talk's), 0, -1 skew-symmetric")
    nt.add_argument("--gamma0", type=float, default=None,
                    help="Nitsche parameter, gamma = gamma0 E / h (default: the nitsche "
                         "formulation's)")
    nt.add_argument("--load", type=float, default=pub["load.displacement"],
                    help="imposed displacement d (m) (default: %(default)s, the talk's)")
    nt.add_argument("--degree", type=int, choices=(1, 2), default=pub["discretization.degree"],
                    help="displacement degree (the talk's Hertz setting: P2)")
    nt.add_argument("--quadrature", type=int, default=pub["discretization.quadrature"],
                    help="Gauss points per contact facet or piece (0: degree + 1)")
    nt.add_argument("--normals", choices=("facet", "smooth"),
                    default=pub["discretization.normals"],
                    help="slave normals: per facet, or continuous (vertex-averaged)")
    nt.add_argument("--integration", choices=("gauss", "segmented"),
                    default=pub["discretization.contact_integration"],
                    help="contact quadrature per slave facet (GPTS) or per piece between "
                         "master-vertex rays (segment-to-segment)")
    _add_study_tail(nt, cmd_nitsche_table)


def _add_nitsche_compare_parser(sub) -> None:
    nc = sub.add_parser("nitsche-compare",
                        help="Nitsche against mixed: HF energies over D_train and reduced "
                             "errors for several R (Markdown tables)")
    nc.add_argument("scene", nargs="?", default="hertz_halfdisks", help=HERTZ_SCENE)
    nc.add_argument("-N", type=int, default=20, help="primal RB size of both reductions")
    nc.add_argument("-R", type=int, nargs="+", default=[10, 30, 40],
                    help="dual sizes of the mixed reductions (one reduction each)")
    nc.add_argument("--n-train", type=int, default=61,
                    help="training parameters |D_train| (default: %(default)s, the talk's)")
    nc.add_argument("--n-valid", type=int, default=10, help="validation parameters")
    _add_study_tail(nc, cmd_nitsche_compare)


def _add_pymor_thermal_block_parser(sub: Any) -> argparse.ArgumentParser:
    """``rbbench studies pymor-thermal-block`` (``sub``: argparse subparsers)."""
    p = sub.add_parser("pymor-thermal-block", help="rbbench and pyMOR side by side on the "
                       "thermal block (pyMOR: optional, pip install pymor)")
    p.add_argument("--n-cells", type=int, default=64, help="squares per side")
    p.add_argument("--blocks", type=int, default=2, choices=(2, 3), help="b x b blocks")
    p.add_argument("-N", type=int, default=10, help="reduced basis size")
    p.add_argument("--n-train", type=int, default=100, help="training parameters")
    p.add_argument("--n-valid", type=int, default=20, help="validation parameters")
    p.add_argument("--repeats", type=int, default=20, help="online repeats per mu")
    p.add_argument("--backend", default="skfem", help="rbbench backend (skfem, ngsolve)")
    p.add_argument("--json", default=None, help="also write the figures to this JSON file")
    return p

def cmd_pymor_thermal_block(args: argparse.Namespace) -> int:
    """Run the study and print its table (exit 0; pyMOR missing is a row, not an error)."""
    from rbbench.studies.pymor_thermal_block import side_by_side, side_by_side_markdown

    res = side_by_side(args.n_cells, args.blocks, args.N, args.n_train, args.n_valid,
                       args.repeats, args.backend)
    return print_and_dump(side_by_side_markdown(res), res, args.json)

def _add_heat_robin_parser(sub: Any) -> argparse.ArgumentParser:
    """``rbbench studies heat-robin`` (``sub``: argparse subparsers; ``heat-seed``: its
    former name, a deprecated alias)."""
    p = sub.add_parser("heat-robin", aliases=["heat-seed"],
                       help="Benaceur et al.'s heat equation (N = 25) beside their published "
                       "valve figures: HF / RB times, L2(0, T; H1) error (alias heat-seed: "
                       "deprecated)")
    p.add_argument("--n-cells", type=int, default=64, help="squares per side")
    p.add_argument("-N", type=int, default=25,
                   help="reduced basis size (default: %(default)s, the talk's)")
    p.add_argument("--repeats", type=int, default=20, help="online repeats per mu")
    p.add_argument("--backend", default="skfem", help="rbbench backend (skfem, ngsolve)")
    p.add_argument("--json", default=None, help="also write the figures to this JSON file")
    return p

def cmd_heat_robin(args: argparse.Namespace) -> int:
    """Run the study and print its table."""
    from rbbench.studies.heat_robin import heat_robin_markdown, heat_robin_study

    res = heat_robin_study(args.n_cells, args.N, repeats=args.repeats, backend=args.backend)
    return print_and_dump(heat_robin_markdown(res), res, args.json)

def _add_bundle_options(p: argparse.ArgumentParser) -> None:
    """The bundle method's options shared by the shape studies (as ``rbbench optimize``)."""
    p.add_argument("--metric", choices=("identity", "bfgs"), default="identity",
                   help=OPTIMIZE_HELP["metric"])
    p.add_argument("--max-iter", type=int, default=100, help=OPTIMIZE_HELP["max_iter"])
    p.add_argument("--max-evals", type=int, default=300, help=OPTIMIZE_HELP["max_evals"])
    p.add_argument("--eps", type=float, default=1e-6, help=OPTIMIZE_HELP["eps"])


def _add_shape_side_by_side_parser(sub: Any) -> argparse.ArgumentParser:
    """``rbbench studies shape-side-by-side`` (``sub``: argparse subparsers)."""
    p = sub.add_parser("shape-side-by-side", help="shape optimisation (model B of the "
                       "shape-optimisation talk), HF- and RB-driven in one process: J, HF "
                       "solves, wall time")
    p.add_argument("--scene", default="shape_coulomb", help=OPTIMIZE_HELP["scene"])
    _add_bundle_options(p)
    p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override a scene field, e.g. --set design.initial_height=0.005")
    p.add_argument("--ny", type=int, nargs="+", default=None, metavar="NY",
                   help="body meshes: element rows (geometry.ny) of each run, the 81 contact "
                   "nodes kept, e.g. --ny 40 160 640 (6642, 26082, 103842 dofs); default: "
                   "the scene's")
    p.add_argument("--json", default=None, help="also write the figures to this JSON file")
    return p

def cmd_shape_side_by_side(args: argparse.Namespace) -> int:
    """Run the study and print its table."""
    from rbbench.optim.shape_scene import load_shape_scene, parse_overrides
    from rbbench.studies.shape_side_by_side import shape_markdown, shape_side_by_side

    overrides = parse_overrides(args.set)
    load_shape_scene(args.scene, overrides)  # its errors before any solve
    for ny in args.ny or ():
        try:
            load_shape_scene(args.scene, {**overrides, "geometry.ny": ny})
        except SceneError as exc:
            raise SceneError(f"--ny {ny}: {exc}") from None

    res = shape_side_by_side(args.scene, overrides, args.metric, args.max_iter,
                             args.max_evals, args.eps, args.ny, progress=_Progress(False))
    return print_and_dump(shape_markdown(res), res, args.json)

def _add_shape_strategy_parser(sub: Any) -> argparse.ArgumentParser:
    """``rbbench studies shape-strategy`` (``sub``: argparse subparsers)."""
    p = sub.add_parser("shape-strategy", help="rbbench optimize with --strategy none and "
                       "equalise side by side in one process: J, J / uniform-pressure bound, "
                       "HF solves, stages, wall time")
    p.add_argument("--scene", default="shape_coulomb", help=OPTIMIZE_HELP["scene"])
    p.add_argument("--driver", nargs="+", choices=("hf", "rb"), default=["hf"],
                   help="the drivers to run (each with both strategies)")
    p.add_argument("--repeats", type=int, default=1,
                   help="runs of each configuration, alternated (wall time: the median)")
    _add_bundle_options(p)
    p.add_argument("--set", action="append", default=[], metavar="SECTION.KEY=VALUE",
                   help="override a scene field, e.g. --set geometry.ny=20")
    p.add_argument("--out-dir", type=Path, default=None,
                   help="keep each run's files in OUT_DIR/<driver>_<strategy>_<repeat> "
                        "(default: a temporary folder)")
    p.add_argument("--json", default=None, help="also write the figures to this JSON file")
    return p


def cmd_shape_strategy(args: argparse.Namespace) -> int:
    """Run the study and print its table."""
    from rbbench.optim.shape_scene import parse_overrides
    from rbbench.studies.shape_strategy import strategy_markdown, strategy_side_by_side

    res = strategy_side_by_side(args.scene, parse_overrides(args.set), tuple(args.driver),
                                args.repeats, args.max_iter, args.max_evals, args.eps,
                                args.metric, args.out_dir)
    return print_and_dump(strategy_markdown(res), res, args.json)


def _add_snapshot_workers_parser(sub: Any) -> argparse.ArgumentParser:
    """``rbbench studies snapshot-workers`` (``sub``: argparse subparsers)."""
    p = sub.add_parser("snapshot-workers", help="HF snapshots with 1 and n worker "
                       "processes, interleaved: a fresh pool and a kept one")
    p.add_argument("scene", nargs="?", default="hertz_halfdisks",
                   help="scene name in problems/ or path to a .toml file")
    p.add_argument("--set", dest="overrides", action="append", default=[],
                   metavar="KEY=VALUE", help="scene override (repeatable)")
    p.add_argument("-P", type=int, default=8, help="parameters per call (a Latin "
                   "hypercube of the domain)")
    p.add_argument("--jobs", type=int, default=2, help="worker processes")
    p.add_argument("--rounds", type=int, default=15, help="interleaved rounds")
    p.add_argument("--pause", type=float, default=0.5, help="seconds waited, untimed, "
                   "after the serial call, the fresh call and the kept block (long enough "
                   "for the threads a call leaves spinning to stop)")
    p.add_argument("--json", default=None, help="also write the figures to this JSON file")
    return p

def cmd_snapshot_workers(args: argparse.Namespace) -> int:
    """Run the study and print its table."""
    from rbbench.scene.loading import load_scene
    from rbbench.scene.sampling import parameter_set
    from rbbench.studies.snapshot_workers import markdown, snapshot_workers

    scene = load_scene(args.scene, args.overrides)  # the counts: check_study_args
    mus = parameter_set(scene, "valid", n=args.P, kind="lhs")
    out = snapshot_workers(scene, mus, args.jobs, args.rounds, args.pause)
    rows = out["cases"]
    print(f"scene {scene.name}, {len(mus)} parameters per call, {args.rounds} interleaved "
          f"rounds, {args.pause} s untimed pause after the serial call, the fresh call and "
          "the kept block (whose two calls run back to back), one untimed snapshot before "
          "each serial call, medians of wall time per call:")
    print(markdown(rows, args.jobs))
    print(f"untimed snapshot before each serial call: {out['settle_faults']:.0f} minor page "
          "faults (median): the pages a pool call's fork left write-protected here")
    if args.json:
        Path(args.json).write_text(json.dumps({"scene": scene.name, "P": len(mus),
                                               "jobs": args.jobs, "rounds": args.rounds,
                                               "pause_s": args.pause,
                                               "serial_settled": True,
                                               "settle_faults": out["settle_faults"],
                                               "cases": rows}, indent=1))
    return 0


def _add_bound_greedy_parser(sub: Any) -> argparse.ArgumentParser:
    """``rbbench studies bound-greedy`` (``sub``: argparse subparsers)."""
    p = sub.add_parser("bound-greedy", help="weak greedy driven by the certified error bound "
                       "against POD: HF solves to reach the POD's err_u_max")
    p.add_argument("scene", nargs="?", default="membrane_obstacle",
                   help="scene name in problems/ or path to a .toml file (affine operators, "
                   "mu-independent A and B: the online bound's requirements)")
    p.add_argument("--set", dest="overrides", action="append", default=[],
                   metavar="KEY=VALUE", help="scene override (repeatable)")
    p.add_argument("--n-train", dest="n_train", type=int, default=1000,
                   help="the greedy's training set (Latin hypercube)")
    p.add_argument("--tol", type=float, default=1e-3,
                   help="tolerance on max Delta_u / ||u_N||_X over the training set")
    p.add_argument("--max-iter", dest="max_iter", type=int, default=25,
                   help="the most HF solves of the greedy")
    p.add_argument("-N", type=int, default=8, help="POD: primal size")
    p.add_argument("-R", type=int, default=8, help="POD: cone size")
    p.add_argument("--n-valid", dest="n_valid", type=int, default=20,
                   help="validation parameters (the scene's random validation set)")
    p.add_argument("--cache-dir", default=".rbbench_cache", help="HF snapshot cache")
    p.add_argument("--json", default=None, help="also write the figures to this JSON file")
    p.add_argument("--pod-sizes", dest="pod_sizes", type=int, nargs="*", default=[],
                   help="also the POD's curve: its reduction from training grids of these "
                   "sizes (e.g. 4 9 16), on the same validation set")
    return p


def cmd_bound_greedy(args: argparse.Namespace) -> int:
    """Run the study and print its table."""
    from rbbench.scene.loading import load_scene
    from rbbench.studies.bound_greedy import bound_greedy_study, markdown

    scene = load_scene(args.scene, args.overrides)
    out = bound_greedy_study(scene, args.n_train, args.tol, args.max_iter, args.N, args.R,
                             args.n_valid, args.cache_dir, progress=_Progress(False),
                             pod_sizes=tuple(args.pod_sizes))
    return print_and_dump(markdown(out), out, args.json)


def _add_bound_cap_parser(sub: Any) -> argparse.ArgumentParser:
    """``rbbench studies bound-cap`` (``sub``: argparse subparsers)."""
    p = sub.add_parser("bound-cap", help="the two-body online error bound against its number "
                       "of POD modes (--bound-pod-max): time beside the reduced solve, "
                       "effectivity")
    p.add_argument("scene", nargs="?", default="hertz_halfdisks",
                   help="a two-body scene (contact EIM): name in problems/ or path to a .toml")
    p.add_argument("--set", dest="overrides", action="append", default=[],
                   metavar="KEY=VALUE", help="scene override (repeatable)")
    p.add_argument("--caps", type=int, nargs="+", default=[250, 150, 100, 60, 30],
                   help="the caps on the POD modes (one reduction, built with the largest)")
    p.add_argument("-N", type=int, default=20, help="primal size")
    p.add_argument("-R", type=int, default=20, help="cone size")
    p.add_argument("--n-valid", dest="n_valid", type=int, default=20,
                   help="validation parameters (the scene's random validation set)")
    p.add_argument("--repeats", type=int, default=20,
                   help="timed rounds per validation parameter (all caps in each round)")
    p.add_argument("--cache-dir", default=".rbbench_cache", help="HF snapshot cache")
    p.add_argument("--json", default=None, help="also write the figures to this JSON file")
    return p


def cmd_bound_cap(args: argparse.Namespace) -> int:
    """Run the study and print its table."""
    from rbbench.scene.loading import load_scene
    from rbbench.studies.bound_cap import bound_cap_study, markdown

    scene = load_scene(args.scene, args.overrides)
    out = bound_cap_study(scene, tuple(args.caps), args.N, args.R, args.n_valid,
                          args.repeats, args.cache_dir, progress=_Progress(False))
    return print_and_dump(markdown(out), out, args.json)

"""``rbbench solve`` (one HF solve and its files), ``rbbench plugins``, ``rbbench scenes``."""

from __future__ import annotations

import json
import textwrap
from pathlib import Path

from rbbench.cli.choices import component_arg
from rbbench.cli.common import _add_option_args, _backend_options, _resolve_solver
from rbbench.cli.console import _Progress, format_table, print_summary, terminal_width
from rbbench.registry import default_registry
from rbbench.runtime import openblas_env as _openblas_env  # noqa: F401  (first: before numpy loads OpenBLAS)
from rbbench.scene.linear import is_linear
from rbbench.scene.loading import PROBLEMS_DIR, SceneError, load_scene


def _solve_components(scene, args, options: dict, f_options: dict | None = None):
    """Backend (with ``options``), formulation (with ``f_options``) and solver for
    ``rbbench solve``."""
    from rbbench.hf.components import check_names, warm_up

    reg = default_registry()
    check_names(scene, reg, args.backend, args.formulation, args.solver)  # before any meshing
    try:
        backend = reg.create("backend", args.backend, scene=scene, **options)
    except SceneError:
        raise
    except (TypeError, ValueError) as exc:
        raise SceneError(f"--backend-option: {exc}") from None
    warm_up(backend)  # mu-independent operators: setup, not the timed discretisation
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
    print_summary(sol.metrics, scene.mu_dict(mu), _mu_units(scene))
    print("wrote: " + ", ".join(str(p) for p in paths))
    return 0 if sol.result.converged else 1


def _mu_units(scene) -> dict[str, str]:
    """The units of the scene's parameters (``[parameters.NAME] unit``; empty: none)."""
    return {p.name: p.unit for p in scene.parameters}


def _solve_out(args, scene, mu) -> Path:
    mu_txt = "_".join(f"{k}{v:g}" for k, v in scene.mu_dict(mu).items())
    return Path(args.out) if args.out else Path("results") / "solve" / f"{scene.name}_{mu_txt}"


def _solve_linear(scene, mu, args, options: dict, progress) -> int:
    """``rbbench solve`` of a linear scene (no contact): :mod:`rbbench.hf.linear.solve`."""
    from rbbench.cli.console import print_linear_summary
    from rbbench.hf.linear.solve import solve_linear_hf, write_linear

    sol = solve_linear_hf(scene, mu, args.backend, args.formulation,
                          backend_options=options, progress=progress)
    out = _solve_out(args, scene, mu)
    progress(f"writing {out}")
    paths = write_linear(sol, out, plot=not args.no_plot)
    print_linear_summary(sol.metrics, scene.mu_dict(mu), _mu_units(scene))
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
    """The rows of :func:`_plugin_rows` as a table fitting the terminal (the descriptions
    wrapped), with a hint under each unimportable one."""
    width = terminal_width()
    table = [["role", "name", "package", "extras", "importable", "description"]]
    table += [[r["role"], r["name"], f"{r['package']} {r['version']}".strip(),
               ",".join(r["extras"]) or "-", "yes" if r["importable"] else "NO",
               r["description"]] for r in rows]
    header, *blocks = format_table(table, wrap={5}, width=width)
    print("\n".join(header))
    indent = " " * (max(len(r["role"]) for r in rows) + 2)
    for r, block in zip(rows, blocks, strict=True):
        print("\n".join(block))
        if not r["importable"]:
            print(textwrap.fill(f"-> {r['hint']}", width or 10**9, initial_indent=indent,
                                subsequent_indent=indent + "   ", break_long_words=False,
                                break_on_hyphens=False))


def cmd_scenes(args) -> int:
    """The scenes of problems/: name, parameter ranges (with their units), description, as
    a table fitting the terminal (parameters and descriptions wrapped)."""
    table = [["scene", "parameters", "description"]]
    for path in sorted(PROBLEMS_DIR.glob("*.toml")):
        sc = load_scene(path)
        params = [f"{p.name} in [{p.low:g}, {p.high:g}]" + (f" {p.unit}" if p.unit else "")
                  for p in sc.parameters]
        table.append([sc.name, params, sc.data["scene"]["description"]])
    for block in format_table(table, wrap={1, 2}, width=terminal_width()):
        print("\n".join(block))
    return 0


def _add_solve_parser(sub) -> None:
    s = sub.add_parser("solve", help="one HF contact solve: summary, contact.csv, VTU, PNG; "
                       "exit 1 when it did not converge or is flagged (stop_reason 'flagged': "
                       "zero contact force while the bodies overlap, see summary.json "
                       "warnings)")
    s.add_argument("scene", help="scene name in problems/ or path to a .toml file")
    s.add_argument("--mu", type=float, nargs="+", help="parameter value(s) (default: scene's)")
    component_arg(s, "--backend", "backend", "HF backend", default="skfem")
    _add_option_args(s)
    component_arg(s, "--formulation", "formulation", "formulation",
                  default="mixed")
    component_arg(s, "--solver", "solver", "algebraic solver (default: the formulation's: "
                  "ssn for mixed, newton for nitsche)", default=None)
    s.add_argument("--set", action="append", metavar="SECTION.KEY=VALUE",
                   help="override a scene value (repeatable), e.g. load.displacement=0.01")
    s.add_argument("--out", help="output directory (default results/solve/<scene>_<mu>)")
    s.add_argument("--no-plot", action="store_true", help="skip the PNG")
    s.add_argument("--quiet", action="store_true", help="no progress lines")
    s.set_defaults(func=cmd_solve)

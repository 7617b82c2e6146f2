"""The ``rbbench`` command line.

``rbbench solve SCENE``: one HF solve with summary and files (``--formulation nitsche``);
``rbbench nitsche-table``: the relative Alart-Curnier residual table of the Nitsche solve beside
the published one (Benaceur, Drouet, Ehrlacher, Ern & Niakh, "Model order reduction methods:
parametric variational inequalities" (talk));
``rbbench plugins``: every registered component and whether it is importable (``--check``: their
contract suite, without pytest);
``rbbench scenes``: the scenes in ``problems/``;
``rbbench run MATRIX``: a run matrix, one results row per case;
``rbbench studies STUDY``: the linear scenes beside pyMOR and the published figures, the shape
optimisation HF- and RB-driven, HF snapshot workers;
``rbbench report DIR`` / ``rbbench compare A B``: plots, tables, regressions.
Bad input exits with status 2 and a message naming what is wrong.
"""

from __future__ import annotations

from rbbench.runtime import openblas_env  # noqa: F401  (first: before numpy loads OpenBLAS)

# isort: split
import argparse
import sys

from rbbench._compat import deprecated_names
from rbbench._version import __version__
from rbbench.bench.errors import ResultsError
from rbbench.bench.guard import RunLockedError
from rbbench.cli.common import Parser
from rbbench.cli.optimize import add_parser as _add_optimize_parser
from rbbench.cli.plugins import add_plugin_args
from rbbench.cli.reduce import _add_online_scaling_parser, _add_reduce_parser
from rbbench.cli.run import _add_run_parsers
from rbbench.cli.solve import _add_solve_parser, cmd_plugins, cmd_scenes
from rbbench.cli.studies import (
    _add_hertz_table_parser,
    _add_nitsche_compare_parser,
    _add_nitsche_table_parser,
)
from rbbench.cli.studies import add_parser as _add_studies_parser
from rbbench.registry import NotInstalledError, UnknownComponentError
from rbbench.scene.loading import SceneError


def build_parser() -> argparse.ArgumentParser:
    p = Parser(prog="rbbench", description=__doc__.splitlines()[0].replace("``", ""))
    p.add_argument("--version", action="version", version=f"rbbench {__version__}",
                   help="print the version (rbbench VERSION) and exit")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND",
                           help="the command (rbbench COMMAND --help: its arguments)")
    _add_solve_parser(sub)
    pl = sub.add_parser("plugins", help="registered components and whether they are importable")
    pl.add_argument("--json", action="store_true",
                    help="print every field of every component as JSON (package, version, "
                         "extras, install hint, capabilities)")
    pl.set_defaults(func=cmd_plugins)
    add_plugin_args(pl)  # --check, --package, --role
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


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return args.func(args)
    except (SceneError, UnknownComponentError, NotInstalledError, ResultsError,
            RunLockedError) as exc:
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


__getattr__ = deprecated_names(__name__)  # names that left this module (rbbench._compat)

"""``rbbench plugins``: the registered components, or with ``--check`` their contract suite
run without pytest (``--package NAME``: one package's components only).

The check exits 0 when no component failed, 1 when one did (a plugin whose entry point
fails to load counts as failed), 2 on bad input (an unknown ``--package`` names the
packages that have components).
"""

from __future__ import annotations

import json
import sys

from rbbench.cli.solve import _plugin_rows, _print_plugin_table
from rbbench.registry import ROLES, default_registry
from rbbench.scene.loading import SceneError


def add_plugin_args(p) -> None:
    """The options of ``rbbench plugins`` beside ``--json``."""
    p.add_argument("--check", action="store_true",
                   help="run the contract suite (rbbench.testing) on the selected components, "
                        "no pytest needed: one line per component (passed, failed with the "
                        "property that fails, skipped with why), exit 1 if one failed")
    p.add_argument("--package", metavar="NAME",
                   help="only the components of this installed distribution (its pip name, "
                        "e.g. rbbench-plugin-template; 'rbbench' for the built-ins)")
    p.add_argument("--role", choices=ROLES, help="only the components of this role")
    p.set_defaults(func=cmd_plugins)


def cmd_plugins(args) -> int:
    """The table (or JSON) of the selected components, or their contracts (``--check``)."""
    from rbbench.testing.contract_runner import normalise, select_specs

    reg = default_registry()
    package, role = getattr(args, "package", None), getattr(args, "role", None)
    try:
        select_specs(reg, package, role)
    except ValueError as exc:
        raise SceneError(str(exc)) from None
    if getattr(args, "check", False):
        return _check(reg, package, role, args.json)
    rows = [r for r in _plugin_rows(reg)
            if (package is None or normalise(r["package"]) == normalise(package))
            and (role is None or r["role"] == role)]
    if args.json:
        print(json.dumps(rows, indent=2, default=str))
    else:
        _print_plugin_table(rows)
    return 0


def _check(reg, package: str | None, role: str | None, as_json: bool) -> int:
    """Run the contracts, printing each line as it ends (or one JSON list at the end)."""
    from rbbench.testing.contract_runner import format_result, run_contracts, summary_line

    def show(result) -> None:
        if not as_json:
            print(format_result(result), flush=True)

    if not as_json:
        what = f"package {package}" if package else "every installed package"
        print(f"contract suite (rbbench.testing) on {what}"
              + (f", role {role}" if role else "") + ":", flush=True)
    results = run_contracts(reg, package, role, on_result=show)
    if as_json:
        print(json.dumps([r.as_dict() for r in results], indent=2))
    else:
        print(summary_line(results))
    failed = [r for r in results if r.status == "failed"]
    if failed and not as_json:
        print(f"FAILED: {', '.join(f'{r.role} {r.name!r}' for r in failed)}", file=sys.stderr)
    return 1 if failed else 0

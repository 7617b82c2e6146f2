"""Sphinx extension of the rbbench docs: reference pages generated from the code.

At ``builder-inited`` it writes Markdown tables into ``docs/_generated/`` (not in git), which
the user-guide pages include: the scene keys (from :data:`rbbench.scene.schema.SCHEMA` and
the linear schema), the run-matrix keys and fields (their checks and the help of
``rbbench reduce``), the results columns (:data:`rbbench.bench.schema.COLUMNS`), the numbers
of ``summary.json`` (:data:`rbbench.hf.metrics.DEFINITIONS`), the command line (the argparse
parsers themselves) and the registered components. Nothing there is written twice.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import Any

GENERATED = Path(__file__).resolve().parents[1] / "_generated"


def _cell(text: Any) -> str:
    """A Markdown table cell: one line, ``|`` escaped."""
    s = " ".join(str(text).split())
    return s.replace("|", "\\|")


def _table(headers: list[str], rows: list[list[Any]]) -> str:
    out = ["| " + " | ".join(headers) + " |", "|" + "---|" * len(headers)]
    out += ["| " + " | ".join(_cell(c) for c in r) + " |" for r in rows]
    return "\n".join(out) + "\n"


def _default(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, str):
        return f'`"{value}"`' if value else '`""`'
    if isinstance(value, tuple):
        value = list(value)
    return f"`{value}`"


# -- scenes ----------------------------------------------------------------------------------
def _schema_tables(schema: dict[str, dict[str, Any]]) -> str:
    parts = []
    for section, keys in schema.items():
        if not keys:
            continue
        rows = [[f"`{k}`", f.describe() if f.kind != "table" else "a table",
                 "required" if f.required else _default(f.default), f.doc]
                for k, f in keys.items()]
        parts.append(f"**`[{section}]`**\n\n"
                     + _table(["key", "valid values", "default", "meaning"], rows))
    return "\n".join(parts)


def scene_reference() -> str:
    """The keys of contact scenes, of ``[parameters.NAME]``, of friction, of linear scenes."""
    from rbbench.scene import friction
    from rbbench.scene.linear import LINEAR_SCHEMA
    from rbbench.scene.schema import _ELASTIC, _PARAM_FIELDS, REDUCE_SECTION, SCHEMA

    text = ["### Contact scenes\n", _schema_tables(SCHEMA)]
    text.append("**`[material.upper]`, `[material.lower]`** (an elastic body each)\n\n"
                + _table(["key", "valid values", "default", "meaning"],
                         [[f"`{k}`", f.describe(), "required", f.doc]
                          for k, f in _ELASTIC.items()]))
    text.append("**`[parameters.NAME]`** (one table per parameter; NAME an identifier, "
                "referenced as `\"mu.NAME\"`)\n\n"
                + _table(["key", "valid values", "default", "meaning"],
                         [[f"`{k}`", f.describe(), "required" if f.required else
                           _default(f.default), f.doc] for k, f in _PARAM_FIELDS.items()]))
    text.append("**`[friction]`**: `law` one of "
                + ", ".join(f"`{v}`" for v in friction.LAWS)
                + "; `threshold` (Tresca); `coefficient` (Coulomb): "
                + friction._COEFFICIENT_WHAT + ". `[load] load_steps`: a list of tables "
                "with keys " + ", ".join(f"`{k}`" for k in friction.STEP_KEYS)
                + " (fractions of the normal and tangential loads, at most "
                f"{friction.MAX_STEP_FRACTION:g} in magnitude; at most "
                f"{friction.MAX_LOAD_STEPS} steps).\n")
    text.append("**`[reduce]`** (optional, not filled when absent; a scene's own defaults "
                "of reduction options, used where the command or the API gives none; not part "
                "of the snapshot cache key)\n\n"
                + _table(["key", "valid values", "default", "meaning"],
                         [[f"`{k}`", f.describe(), "none", f.doc]
                          for k, f in REDUCE_SECTION.items()]))
    text += ["\n### Linear scenes (no contact)\n", _schema_tables(LINEAR_SCHEMA)]
    return "\n".join(text)


def shipped_scenes() -> str:
    """The scenes shipped in ``problems/``: physics, parameters and domain, description."""
    from rbbench.scene.loading import PROBLEMS_DIR, load_scene

    rows = []
    for path in sorted(PROBLEMS_DIR.glob("*.toml")):
        sc = load_scene(path)
        params = "; ".join(f"{p.name} in [{p.low:g}, {p.high:g}]"
                           + (f" {p.unit}" if getattr(p, "unit", "") else "")
                           for p in sc.parameters)
        rows.append([f"`{sc.name}`", sc.data["scene"]["physics"], params,
                     sc.data["scene"]["description"]])
    return _table(["scene", "physics", "parameters (domain D)", "description"], rows)


def matrix_header() -> str:
    """The keys of a matrix file's ``[matrix]`` table, with the bounds its checks enforce
    (:mod:`rbbench.bench.matrix_checks`)."""
    from rbbench.bench import matrix_checks as c
    from rbbench.scene import limits

    rows = [
        ["`name`", f"matches `{limits.NAME_PATTERN}`", "the file's stem",
         "names the run and its default output directory `results/NAME`"],
        ["`description`", "a string", "", "free text (kept in `manifest.json`)"],
        ["`scenes`", "a non-empty list of scene names (`name@variant`: the scene under its "
         "own `[scene_overrides]` entry)", "required", "the scenes crossed with the rest"],
        ["`repetitions`", f"an integer in [1, {c.MAX_REPETITIONS}]", "`1`",
         "rows per case: each repetition is one row (its own timings)"],
        ["`timeout_s`", f"a number in (0, {c.MAX_TIMEOUT_S:g}]", "none",
         "per-case time limit, enforced (the case's process is killed: status `timeout`)"],
        ["`seed`", "an integer >= 0", "each scene's", "seed of the random parameter sets"],
        ["`mode`", " or ".join(f"`{m}`" for m in c._MODES), '`"rb"`',
         "`hf`: each case is an HF solve only (backend x formulation x solver; "
         "`[params.solver.NAME]`: the solver's options)"],
    ]
    return (_table(["key", "valid values", "default", "meaning"], rows)
            + f"\nA matrix expands to at most {c.MAX_CASES:,} cases; sizes (`[sizes]`, N, R, S) "
            f"are integers in [1, {c.MAX_SIZE:,}].\n")


# -- results -----------------------------------------------------------------------------------
def columns_reference() -> str:
    """Every results column, grouped, with its type, unit and meaning."""
    from rbbench.bench.schema import COLUMNS, STATUSES

    groups: dict[str, list[Any]] = {}
    for c in COLUMNS:
        groups.setdefault(c.group, []).append(c)
    text = ["Statuses: " + ", ".join(f"`{s}`" for s in STATUSES) + ".\n"]
    for group, cols in groups.items():
        text.append(f"**{group}**\n\n" + _table(
            ["column", "type", "unit", "meaning"],
            [[f"`{c.name}`", c.dtype, c.unit, c.doc] for c in cols]))
    return "\n".join(text)


def summary_reference() -> str:
    """The numbers of an HF solve's ``summary.json`` (its ``definitions`` table)."""
    from rbbench.hf.metrics import DEFINITIONS

    return _table(["key", "meaning"], [[f"`{k}`", v] for k, v in DEFINITIONS.items()])


# -- command line ------------------------------------------------------------------------------
def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            seen: dict[int, str] = {}
            out = {}
            for name, sub in action.choices.items():
                if id(sub) in seen:  # an alias
                    continue
                seen[id(sub)] = name
                out[name] = sub
            return out
    return {}


def _option_rows(parser: argparse.ArgumentParser) -> list[list[str]]:
    rows = []
    for a in parser._actions:
        if isinstance(a, (argparse._HelpAction, argparse._SubParsersAction)):
            continue
        flags = ", ".join(f"`{o}`" for o in a.option_strings) or f"`{a.dest}`"
        default = "" if a.default in (None, argparse.SUPPRESS, False) or a.required \
            else _default(a.default)
        choices = ", ".join(map(str, a.choices)) if a.choices else ""
        help_text = (a.help or "") % {"default": a.default, "prog": parser.prog} \
            if a.help and "%(" in a.help else (a.help or "")
        rows.append([flags, help_text + (f" Choices: {choices}." if choices else ""),
                     default])
    return rows


def _command(parser: argparse.ArgumentParser, name: str, level: int) -> list[str]:
    text = [f"{'#' * level} `{name}`\n"]
    if parser.description:
        text.append(parser.description.strip() + "\n")
    rows = _option_rows(parser)
    if rows:
        text.append(_table(["option", "meaning", "default"], rows))
    for sub_name, sub in _subparsers(parser).items():
        text += _command(sub, f"{name} {sub_name}", level + 1)
    return text


def cli_reference() -> str:
    """Every command of ``rbbench``, its options with their help and defaults."""
    from rbbench.cli import build_parser

    os.environ.setdefault("COLUMNS", "100")
    parser = build_parser()
    text = []
    for name, sub in _subparsers(parser).items():
        text += _command(sub, f"rbbench {name}", 2)
    return "\n".join(text)


# -- run matrices ------------------------------------------------------------------------------
def _reduce_help() -> dict[str, str]:
    """``dest -> help`` of ``rbbench reduce``'s options."""
    from rbbench.cli import build_parser

    reduce = _subparsers(build_parser())["reduce"]
    return {a.dest: a.help or "" for a in reduce._actions if a.help}


def matrix_reference() -> str:
    """The ``[reduce]`` / ``[params]`` fields a matrix may set, and the registered
    components a ``[components]`` list may name."""
    from rbbench.bench.matrix_checks import REDUCE_FIELDS
    from rbbench.registry import default_registry

    helps = _reduce_help()
    kinds = {"int": "integer in [{1}, {2}]", "float": "number > {1}", "float>=": "number >= {1}",
             "dict": "a table"}
    rows = []
    for name, spec in sorted(REDUCE_FIELDS.items()):
        kind = spec[0]
        what = (kinds[kind].format(*spec) if kind in kinds
                else "one of " + ", ".join(map(str, spec[1])))
        rows.append([f"`{name}`", what, helps.get(name, "")])
    text = ["**`[reduce]` and `[params.ROLE.NAME]` fields**\n",
            _table(["field", "valid values", "meaning"], rows)]
    reg = default_registry()
    comp_rows = [[f"`{role}`", ", ".join(f"`{n}`" for n in reg.names(role))]
                 for role in ("backend", "formulation", "solver", "primal", "dual",
                              "stabilizer", "hyper", "executor") if reg.names(role)]
    text.append("\n**Registered components** (this build's installation; `rbbench plugins` "
                "lists yours)\n")
    text.append(_table(["role", "names"], comp_rows))
    return "\n".join(text)


GENERATORS = {"scene_reference.md": scene_reference, "columns.md": columns_reference,
              "summary_definitions.md": summary_reference, "cli_reference.md": cli_reference,
              "matrix_reference.md": matrix_reference, "scenes.md": shipped_scenes,
              "matrix_header.md": matrix_header}


def write_references(app: Any = None) -> None:
    """Write every generated page (only when its text changed, so Sphinx rereads only
    what is new)."""
    GENERATED.mkdir(exist_ok=True)
    for name, make in GENERATORS.items():
        text = "<!-- generated by docs/_ext/rbbench_docs.py: do not edit -->\n\n" + make()
        path = GENERATED / name
        if not path.exists() or path.read_text() != text:
            path.write_text(text)


def setup(app: Any) -> dict[str, Any]:
    app.connect("builder-inited", write_references)
    return {"parallel_read_safe": True, "parallel_write_safe": True}

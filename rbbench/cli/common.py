"""Argument helpers shared by the commands."""

from __future__ import annotations

import argparse
from typing import Any

from rbbench.runtime import openblas_env as _openblas_env  # noqa: F401  (first: before numpy loads OpenBLAS)
from rbbench.scene.limits import toml_literal
from rbbench.scene.loading import SceneError


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
            options[key] = toml_literal(raw, f"{flag} {key}")
        except ValueError as exc:
            raise SceneError(str(exc)) from None
    return options


def _resolve_solver(args, scene=None) -> None:
    """``--solver`` not given: the formulation's declared solver (``ssn`` for mixed,
    ``newton`` for Nitsche; for a friction ``scene``, the first declaring its law)."""
    if getattr(args, "solver", None) is None:
        from rbbench.hf.components import default_solver
        from rbbench.scene.friction import friction_of

        law = friction_of(scene).law if scene is not None else "none"
        args.solver = default_solver(args.formulation, law=law)


def _add_option_args(p) -> None:
    p.add_argument("--backend-option", action="append", metavar="KEY=VALUE",
                   help="backend constructor option (repeatable), e.g. mesh=skfem "
                        "(ngsolve: one mesh with skfem)")
    p.add_argument("--formulation-option", action="append", metavar="KEY=VALUE",
                   help="formulation constructor option (repeatable), e.g. gamma0=1.0 "
                        "(nitsche)")


def shown_default(value: Any) -> str:
    """A default as typed on the command line (a list: its items separated by spaces),
    ``%`` escaped for argparse's help formatting."""
    text = " ".join(map(str, value)) if isinstance(value, (list, tuple)) else str(value)
    return text.replace("%", "%%")


class HelpFormatter(argparse.HelpFormatter):
    """Every argument's help ends with its default when it has one: a value (not ``None``,
    ``False``, an empty list or ``argparse.SUPPRESS``; those say in words what happens) on an
    option or an optional positional, unless the help places it with ``%(default)s``."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        value = action.default
        if ("%(default)" in text or value is None or value is False or value == []
                or value is argparse.SUPPRESS
                or (not action.option_strings and action.nargs not in ("?", "*"))):
            return text
        return f"{text} (default: {shown_default(value)})"


class _SubParsers(argparse._SubParsersAction):
    """Subcommands whose ``--help`` opens with the line that lists them (their ``help``)."""

    def add_parser(self, name: str, **kwargs: Any) -> argparse.ArgumentParser:
        if kwargs.get("help"):
            kwargs.setdefault("description", kwargs["help"])
        return super().add_parser(name, **kwargs)


class Parser(argparse.ArgumentParser):
    """The parser of ``rbbench`` and of each of its (sub)commands: :class:`HelpFormatter`,
    and a subcommand's description is its help line."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)
        self.register("action", "parsers", _SubParsers)

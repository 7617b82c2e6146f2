"""``--help`` of every command: every argument (options, positionals, the subcommand lists)
has help, and the help shows the default where there is one.

The walk covers every parser under ``rbbench`` (``rbbench studies STUDY`` too). A default is
"there" when it is a value (not ``None``, ``False``, ``[]`` or ``argparse.SUPPRESS``: those
are rules said in words). The flags of ``rbbench reduce`` / ``online-scaling`` have no
default of their own (``argparse.SUPPRESS``: the formulation's applies): their help shows
the default of the field in the options dataclasses.
"""

from __future__ import annotations

import argparse
import dataclasses

import pytest

from rbbench.cli import build_parser, main
from rbbench.cli.common import shown_default
from rbbench.rb.config import ReduceConfig
from rbbench.rb.friction.options import FrictionOptions
from rbbench.rb.mixed.options import MixedOptions
from rbbench.rb.nitsche.options import NitscheOptions


def _walk(parser: argparse.ArgumentParser, path: tuple[str, ...] = ("rbbench",)):
    """``(command path, parser)`` of ``parser`` and of every subcommand under it (an alias
    once)."""
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            seen = set()
            for name, sub in action.choices.items():
                if id(sub) not in seen:
                    seen.add(id(sub))
                    yield from _walk(sub, (*path, name))


PARSERS = {" ".join(path): p for path, p in _walk(build_parser())}


def _arguments(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    return [a for a in parser._actions if not isinstance(a, argparse._HelpAction)]


def _help(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    """The help of ``action`` as ``--help`` prints it (defaults expanded), on one line."""
    return " ".join(parser._get_formatter()._expand_help(action).split())


def _name(action: argparse.Action) -> str:
    return "/".join(action.option_strings) or action.dest


def _has_value(default) -> bool:
    return not (default is None or default is False or default == []
                or default is argparse.SUPPRESS)


def test_the_walk_reaches_every_command():
    expected = {"rbbench", "rbbench solve", "rbbench plugins", "rbbench scenes",
                "rbbench reduce", "rbbench online-scaling", "rbbench hertz-table",
                "rbbench nitsche-table", "rbbench nitsche-compare", "rbbench optimize",
                "rbbench run", "rbbench report", "rbbench compare", "rbbench studies",
                "rbbench studies pymor-thermal-block", "rbbench studies heat-robin",
                "rbbench studies shape-side-by-side", "rbbench studies shape-strategy",
                "rbbench studies snapshot-workers"}
    assert expected <= set(PARSERS)


@pytest.mark.parametrize("command", sorted(PARSERS))
def test_every_argument_has_help(command):
    parser = PARSERS[command]
    missing = []
    for action in _arguments(parser):
        if not (action.help or "").strip():
            missing.append(_name(action))
        if isinstance(action, argparse._SubParsersAction):
            missing += [f"subcommand {c.dest}" for c in action._choices_actions
                        if not (c.help or "").strip()]
    assert not missing, f"{command}: arguments without help: {missing}"
    parser.format_help()  # no stray % in a help text


@pytest.mark.parametrize("command", sorted(PARSERS))
def test_help_shows_the_default_once(command):
    parser = PARSERS[command]
    wrong = []
    for action in _arguments(parser):
        if not _has_value(action.default) or isinstance(action, argparse._SubParsersAction):
            continue
        text = _help(parser, action)
        shown = shown_default(action.default).replace("%%", "%")
        if f"default: {shown}" not in text or text.lower().count("default") != 1:
            wrong.append(f"{_name(action)} = {action.default!r}: {text!r}")
    assert not wrong, f"{command}: default not shown, or shown twice: {wrong}"


def _declared_defaults(field: str) -> set:
    """The defaults of the reduction field ``field`` in the dataclasses declaring it."""
    return {f.default for cls in (ReduceConfig, MixedOptions, FrictionOptions, NitscheOptions)
            for f in dataclasses.fields(cls) if f.name == field}


@pytest.mark.parametrize("command", ["rbbench reduce", "rbbench online-scaling"])
def test_reduction_flags_show_the_dataclass_defaults(command):
    parser = PARSERS[command]
    checked, wrong = [], []
    for action in _arguments(parser):
        declared = _declared_defaults(action.dest)
        if not declared or action.default is not argparse.SUPPRESS:
            continue
        text = _help(parser, action)
        checked.append(action.dest)
        values = declared - {None, dataclasses.MISSING}
        assert len(values) <= 1, f"{action.dest}: formulations differ: {values}"
        if values and None in declared:  # a value for some formulations, none for others
            v = shown_default(values.pop())
            if not ("(default: " in text and f" {v})" in text and " none" in text):
                wrong.append(f"{_name(action)}: {text!r}")
        elif values and f"(default: {shown_default(values.pop())})" not in text:
            wrong.append(f"{_name(action)}: {text!r}")
        elif not values and "default" not in text:  # a rule (None): said in words
            wrong.append(f"{_name(action)} (default None, no rule given): {text!r}")
    assert {"tol_pod", "dual", "tol_dual", "stabilizer", "exact_max_r", "online_method",
            "friction_dual", "gcns_per_iteration", "gcns_patience", "tol_eim", "R",
            "m_eim"} <= set(checked)
    assert not wrong, f"{command}: {wrong}"


def test_online_scaling_shows_its_own_hyper_default():
    parser = PARSERS["rbbench online-scaling"]
    (hyper,) = [a for a in parser._actions if a.dest == "hyper"]
    assert _help(parser, hyper).endswith("(default: eim)")


def test_reduce_help_prints_the_dataclass_default(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["reduce", "--help"])
    assert exc.value.code == 0
    out = " ".join(capsys.readouterr().out.split())
    assert f"dual compressor tolerance on e_proj (default: {MixedOptions.tol_dual})" in out
    assert f"(default: {FrictionOptions.friction_dual})" in out


def test_subcommand_help_opens_with_its_description(capsys):
    with pytest.raises(SystemExit):
        main(["studies", "snapshot-workers", "--help"])
    assert "HF snapshots with 1 and n worker processes" in capsys.readouterr().out


def test_online_scaling_keeps_its_own_flags_out_of_the_reduction():
    from rbbench.cli.reduce import reduce_fields
    from rbbench.rb.config import make_config

    args = build_parser().parse_args(["online-scaling", "hertz_sphere", "--levels", "0", "1",
                                      "--baseline", "hertz_halfdisks", "--baseline-set",
                                      "discretization.level=0", "-N", "5", "--match-sizes"])
    fields = reduce_fields(args)
    assert args.match_sizes
    assert fields["N"] == 5 and not {"baseline", "baseline_set", "levels",
                                     "match_sizes"} & set(fields)
    make_config(**fields)  # every field left is a reduction field

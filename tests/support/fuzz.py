"""Helpers of the generated hostile-input tests (``tests/system/test_fuzz_*.py``).

Every input runs ``rbbench.cli.main`` (or an API call) in this process, under a hard time
limit (SIGALRM), from an empty working directory inside a fresh temporary tree; what it
wrote outside the output directory is listed, so a test can assert it wrote nothing there.
The bad values are tables (:data:`NOT_NUMBERS`, :data:`NOT_FINITE`, ...) crossed with the
keys and options of a surface, not hand-written one by one.
"""

from __future__ import annotations

import contextlib
import functools
import io
import math
import os
import signal
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

import rbbench.cli as cli
from rbbench.cli import main

#: seconds one input may take before it counts as a hang
LIMIT_S = 20

#: values that are not numbers, as TOML literals (``--set KEY=VALUE``) and as Python values
NOT_NUMBERS = {"string": ('"abc"', "abc"), "bool": ("true", True), "list": ("[1.0]", [1.0]),
               "table": ("{a = 1}", {"a": 1})}
#: non-finite numbers
NOT_FINITE = {"nan": ("nan", math.nan), "inf": ("inf", math.inf),
              "-inf": ("-inf", -math.inf)}
#: numbers that are not integers
NOT_INTEGERS = {"2.5": ("2.5", 2.5), "1e308": ("1e308", 1e308)}
#: integers beyond any size a run can honour
HUGE_INTS = {"10**30": ("1000000000000000000000000000000", 10**30),
             "2**63-1": ("9223372036854775807", 2**63 - 1)}


_build_parser = cli.build_parser


@functools.cache
def _parser() -> Any:
    """One parser for every input (building it takes about 0.1 s; parsing leaves it as
    it was)."""
    return _build_parser()


class Hang(Exception):
    """An input that got no answer within its time limit."""


@contextlib.contextmanager
def hard_limit(seconds: int = LIMIT_S) -> Iterator[None]:
    """Raise :class:`Hang` in the main thread after ``seconds`` (SIGALRM)."""
    def handler(signum: int, frame: Any) -> None:
        raise Hang(f"no answer within {seconds} s")

    old = signal.signal(signal.SIGALRM, handler)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def files_under(root: Path) -> dict[str, int]:
    """``{relative path: size}`` of every file and link under ``root`` (links not followed)."""
    out = {}
    for p in root.rglob("*"):
        if p.is_symlink() or p.is_file():
            out[str(p.relative_to(root))] = p.lstat().st_size
    return out


def run_cli(argv_of: Callable[[Path, Path], list[str]],
            files: dict[str, bytes | str] | None = None,
            prepare: Callable[[Path], None] | None = None,
            limit: int = LIMIT_S) -> tuple[int, str, list[str]]:
    """Run ``main(argv_of(inputs, out))`` in a fresh tree: ``inputs/`` holds ``files``,
    ``prepare(base)`` may add more (links, run directories), the working directory is an
    empty ``work/deep``. Return the exit code, stderr and every file created, changed or
    removed outside ``work/deep/out`` (``inputs/`` included: an input must not change)."""
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp)
        inputs, work = base / "inputs", base / "work" / "deep"
        inputs.mkdir()
        work.mkdir(parents=True)
        out = work / "out"
        for name, content in (files or {}).items():
            p = inputs / name
            p.parent.mkdir(parents=True, exist_ok=True)
            p.write_bytes(content.encode() if isinstance(content, str) else content)
        if prepare is not None:
            prepare(base)
        before = files_under(base)
        err, cwd = io.StringIO(), os.getcwd()
        os.chdir(work)
        try:
            with hard_limit(limit), contextlib.redirect_stderr(err), \
                    contextlib.redirect_stdout(io.StringIO()), \
                    pytest.MonkeyPatch.context() as mp:
                mp.setattr(cli, "build_parser", _parser)
                try:
                    code = main(argv_of(inputs, out))
                except SystemExit as exc:  # argparse
                    code = exc.code
        finally:
            os.chdir(cwd)
        after = files_under(base)
        changed = {f for f in set(before) | set(after) if before.get(f) != after.get(f)}
        outside = sorted(f for f in changed if not (base / f).is_relative_to(out))
        return code, err.getvalue(), outside


def assert_rejected(code: Any, err: str, outside: list[str], *names: str) -> None:
    """Exit 2, no traceback, one ``error:`` line naming every one of ``names``, nothing
    written outside the output directory."""
    assert "Traceback" not in err, err
    assert code == 2, f"exit {code}; stderr: {err}"
    assert err.startswith("rbbench: error:") or "error: argument" in err, err
    for n in names:
        assert n in err, f"{n!r} not named in: {err}"
    assert outside == [], f"written outside the output directory: {outside}"


def refuse_work(monkeypatch: pytest.MonkeyPatch, targets: list[tuple[Any, str]]) -> None:
    """Replace every ``(module, name)`` of ``targets`` by a function that fails the test:
    the input must be refused before that work starts."""
    for module, name in targets:
        def refuse(*a: Any, _what: str = f"{module.__name__}.{name}", **k: Any) -> Any:
            raise AssertionError(f"{_what} ran: the input was not refused before the work")

        monkeypatch.setattr(module, name, refuse)


def hf_work() -> list[tuple[Any, str]]:
    """The entry points of HF work: snapshots of a reduction (contact and linear), one HF
    solve (contact and linear)."""
    import rbbench.hf.linear.solve as linear_solve
    import rbbench.hf.model as hf_model
    import rbbench.rb.linear.offline as linear_offline
    import rbbench.rb.offline as offline

    return [(offline, "training_snapshots"), (linear_offline, "linear_snapshots"),
            (hf_model, "solve_hf"), (linear_solve, "solve_linear_hf")]


def ids(table: list[tuple]) -> list[str]:
    """Readable test ids of a table of ``(key, label, ...)`` rows."""
    return [f"{row[0]}={row[1]}" for row in table]

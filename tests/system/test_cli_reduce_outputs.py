"""``rbbench reduce`` writes its output directory alone and never through a link: a second
writer is refused (exit 2, naming the holder), a lock file that is a link is refused, and a
``result.json`` that is a link is replaced, the file it pointed to untouched."""

from __future__ import annotations

import json

import pytest

from rbbench.bench.guard import LOCK_NAME, RunLock
from rbbench.cli import main

TINY = ["reduce", "membrane_obstacle", "-N", "3", "-R", "3", "--n-train", "4",
        "--n-valid", "2", "--quiet"]


@pytest.fixture
def args(tmp_path):
    return [*TINY, "--cache-dir", str(tmp_path / "cache")]


def test_a_second_writer_is_refused(tmp_path, args, capsys):
    out = tmp_path / "out"
    out.mkdir()
    with RunLock(out):
        assert main([*args, "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "another rbbench run writes to this directory" in err
    assert not (out / "result.json").exists()
    assert main([*args, "--out", str(out)]) == 0  # the lock is free again
    assert json.loads((out / "result.json").read_text())["N"] == 3


def test_links_in_the_output_directory_are_not_followed(tmp_path, args, capsys):
    outside = tmp_path / "outside.txt"
    outside.write_text("precious")
    out = tmp_path / "out"
    out.mkdir()
    (out / LOCK_NAME).symlink_to(outside)
    assert main([*args, "--out", str(out)]) == 2
    assert "symbolic link" in capsys.readouterr().err
    assert outside.read_text() == "precious"
    (out / LOCK_NAME).unlink()
    (out / "result.json").symlink_to(outside)
    assert main([*args, "--out", str(out)]) == 0
    assert outside.read_text() == "precious"
    assert not (out / "result.json").is_symlink()
    assert json.loads((out / "result.json").read_text())["scene"] == "membrane_obstacle"

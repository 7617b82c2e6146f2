"""A wheel built from the project ships every module and the scenes; installed
non-editable into a fresh virtual environment it lists the scenes and solves the membrane.

pip fetches the dependencies (numpy, scipy, scikit-fem, ...; from its cache after the first
time; ``--no-compile``: only what runs is byte-compiled). Without a reachable package index
the tests skip with pip's message. About a minute on an idle machine.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
#: what the build reads: the rest of the checkout (results, caches, .venv) stays out
BUILD_INPUTS = ("pyproject.toml", "README.md", "LICENSE", "rbbench", "plugins", "problems")
#: pip's words when the index cannot be reached (then skip, not fail)
OFFLINE = ("Failed to establish a new connection", "Temporary failure in name resolution",
           "Name or service not known", "Network is unreachable", "Max retries exceeded",
           "Connection refused", "Read timed out", "ProxyError", "Could not fetch URL")


def _run(cmd: list, what: str, timeout: float, cwd: Path | None = None,
         network: bool = False) -> subprocess.CompletedProcess:
    """Run ``cmd`` outside any virtual environment of ours; skip on a network failure when
    ``network``, fail with the output otherwise."""
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "PYTHONHOME", "VIRTUAL_ENV")}
    proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True, cwd=cwd,
                          env=env, timeout=timeout)
    out = proc.stdout + proc.stderr
    if proc.returncode != 0 and network and any(s in out for s in OFFLINE):
        pytest.skip(f"{what}: the package index is not reachable: {out.strip()[-400:]}")
    assert proc.returncode == 0, f"{what} failed ({proc.returncode}):\n{out[-4000:]}"
    return proc


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    """``pip wheel --no-deps`` of a copy of the build inputs (no build/ in the checkout)."""
    src = tmp_path_factory.mktemp("src")
    for name in BUILD_INPUTS:
        p = ROOT / name
        if p.is_dir():
            shutil.copytree(p, src / name,
                            ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        else:
            shutil.copy2(p, src / name)
    out = tmp_path_factory.mktemp("dist")
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w", out, src],
         "building the wheel", timeout=600, network=True)
    (whl,) = out.glob("rbbench-*.whl")
    return whl


def _expected_files() -> set[str]:
    """Every module of rbbench/ and plugins/, and the shipped scenes and matrices, as
    paths inside the wheel."""
    files = {f"rbbench/{p.relative_to(ROOT / 'rbbench').as_posix()}"
             for p in (ROOT / "rbbench").rglob("*.py")}
    files |= {f"rbbench_plugins/{p.relative_to(ROOT / 'plugins').as_posix()}"
              for p in (ROOT / "plugins").rglob("*.py")}
    files |= {f"rbbench/problems/{p.relative_to(ROOT / 'problems').as_posix()}"
              for p in (ROOT / "problems").rglob("*") if p.suffix in (".toml", ".py")}
    return {f for f in files if "__pycache__" not in f}


def test_wheel_ships_every_module_and_the_scenes(wheel):
    """A subpackage missing from pyproject's ``packages`` fails here, not after a release."""
    names = set(zipfile.ZipFile(wheel).namelist())
    missing = sorted(_expected_files() - names)
    assert not missing, f"not in the wheel (pyproject.toml packages / package-data): {missing}"
    assert {"rbbench/problems/membrane_obstacle.toml",
            "rbbench/problems/matrices/quick.toml"} <= names
    assert "rbbench/py.typed" in names  # package data: the typing marker
    assert any(n.endswith(".dist-info/licenses/LICENSE") or n.endswith(".dist-info/LICENSE")
               for n in names), "the licence is not in the wheel's metadata"


def _bin(venv: Path, name: str) -> Path:
    return venv / ("Scripts" if os.name == "nt" else "bin") / name


def test_installed_wheel_lists_scenes_and_solves_membrane(wheel, tmp_path):
    venv = tmp_path / "venv"
    _run([sys.executable, "-m", "venv", venv], "creating a virtual environment", timeout=300)
    _run([_bin(venv, "python"), "-m", "pip", "install", "--quiet", "--no-compile", wheel],
         "installing the wheel and its dependencies", timeout=900, network=True)
    elsewhere = tmp_path / "elsewhere"  # no checkout on the path
    elsewhere.mkdir()
    where = _run([_bin(venv, "python"), "-c",
                  "import rbbench.scene.loading as m; print(m.__file__); print(m.PROBLEMS_DIR)"],
                 "importing rbbench", timeout=300, cwd=elsewhere).stdout.split()
    assert all(Path(w).resolve().is_relative_to(venv.resolve()) for w in where), where

    scenes = _run([_bin(venv, "rbbench"), "scenes"], "rbbench scenes", timeout=300,
                  cwd=elsewhere).stdout
    # the header, then one row per scene (a line starting with a space: a row's wrapped cells)
    listed = [line.split()[0] for line in scenes.splitlines()[1:]
              if line.strip() and not line[0].isspace()]
    shipped = sorted(s.stem for s in (ROOT / "problems").glob("*.toml"))
    assert {"hertz_halfdisks", "membrane_obstacle"} <= set(shipped)
    assert listed == shipped, scenes  # every scene of the source tree, from the wheel

    out = tmp_path / "solve"
    _run([_bin(venv, "rbbench"), "solve", "membrane_obstacle", "--mu", "0.3", "5.0",
          "--out", out], "rbbench solve membrane_obstacle", timeout=600, cwd=elsewhere)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["converged"] is True
    assert summary["stop_reason"] == "converged"

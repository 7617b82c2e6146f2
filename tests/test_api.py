"""The Python face: ``import rbbench`` is cheap and gives load_scene, solve, reduce, run,
load_results; the README's "Python" section runs as written."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

import rbbench
from rbbench import api
from rbbench.scene.loading import PROBLEMS_DIR, Scene, load_scene

ROOT = Path(__file__).resolve().parents[1]
PUBLIC = ["load_results", "load_scene", "reduce", "run", "solve"]


def readme_python_block() -> str:
    """The first ``python`` code block of the README's "## Python" section."""
    text = (ROOT / "README.md").read_text()
    section = text.split("\n## Python\n", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, flags=re.S)
    assert blocks, "README: no ```python block in the Python section"
    return blocks[0]


def test_readme_python_block_is_short():
    lines = [ln for ln in readme_python_block().splitlines() if ln.strip()]
    assert 5 <= len(lines) <= 12
    for name in PUBLIC:
        assert f"rbbench.{name}(" in readme_python_block()


def test_readme_python_section_runs(tmp_path, monkeypatch):
    """Exactly the README's code, in an empty directory (results and cache land there)."""
    monkeypatch.chdir(tmp_path)
    ns: dict = {"__name__": "readme_python"}
    exec(compile(readme_python_block(), "README.md (Python)", "exec"), ns)  # noqa: S102
    assert isinstance(ns["scene"], Scene)
    assert ns["sol"].result.converged
    assert ns["res"].model is not None
    assert ns["res"].N == 6
    df = ns["df"]
    assert isinstance(df, pd.DataFrame)
    assert df["status"].tolist() == ["ok"]
    assert pd.api.types.is_float_dtype(df["err_u_max"])
    assert pd.api.types.is_integer_dtype(df["N"])
    assert (tmp_path / "results" / "api" / "results.parquet").is_file()


def test_public_names():
    assert set(PUBLIC) <= set(rbbench.__all__)
    assert set(PUBLIC) <= set(dir(rbbench))
    assert rbbench.load_scene is load_scene
    for name in ("solve", "reduce", "run", "load_results"):
        assert getattr(rbbench, name) is getattr(api, name)
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        rbbench.nope  # noqa: B018
    assert isinstance(rbbench.__version__, str)


def test_import_is_cheap_and_imports_no_backend():
    """``import rbbench`` and looking the five names up import no backend, no solver
    stack, no pandas (a fresh interpreter: the test process has them all loaded)."""
    code = (
        "import json, sys, rbbench\n"
        "before = sorted(sys.modules)\n"
        "[getattr(rbbench, n) for n in ('load_scene', 'solve', 'reduce', 'run', "
        "'load_results')]\n"
        "print(json.dumps([before, sorted(sys.modules)]))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=ROOT, timeout=120)
    assert proc.returncode == 0, proc.stderr
    before, after = json.loads(proc.stdout)
    heavy = ("skfem", "ngsolve", "petsc4py", "rbbench_plugins", "scipy", "pandas",
             "matplotlib", "rbbench.hf", "rbbench.rb", "rbbench.bench")
    for mods in (before, after):
        loaded = [m for m in mods if m.startswith(heavy)]
        assert not loaded, f"imported too early: {loaded[:10]}"
    assert "numpy" not in before


@pytest.mark.parametrize("how", ["name", "path", "scene"])
def test_a_scene_is_a_name_a_path_or_a_scene(how):
    sc = rbbench.load_scene("membrane_obstacle")
    arg = {"name": "membrane_obstacle", "path": PROBLEMS_DIR / "membrane_obstacle.toml",
           "scene": sc}[how]
    got = api.as_scene(arg)
    assert got.fingerprint() == sc.fingerprint()
    if how == "scene":
        assert got is sc

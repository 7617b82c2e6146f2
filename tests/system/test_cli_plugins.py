"""``rbbench plugins --check --package NAME``: the contract suite on one installed package's
components, in a process where pytest cannot be imported (it is not in the base install)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import pytest

PLUGIN = '''
from rbbench.plugin import ComponentSpec, DualCompressor, hookimpl
from rbbench.rb.compressors import CPG


class Rescaled(CPG):
    """CPG reporting half its last projection error."""

    name = "check-demo-rescaled"

    def compress(self, LAM, W, **kw):
        basis = super().compress(LAM, W, **kw)
        basis.e_proj[-1] *= 0.5
        return basis


@hookimpl
def rbbench_register(registry):
    for name, target in (("check-demo-cpg", "CPG"), ("check-demo-rescaled", "Rescaled")):
        registry.add(ComponentSpec(name=name, role="dual", target=f"rbbench_check_demo:{target}",
                                   capabilities={"cone": True, "nested": True},
                                   description="demo"))
'''

#: run the command line in a process where ``import pytest`` fails
NO_PYTEST = ("import sys; sys.modules['pytest'] = None; from rbbench.cli import main; "
             "sys.exit(main(sys.argv[1:]))")


@pytest.fixture
def env(tmp_path):
    """A process environment in which ``rbbench-check-demo 0.1`` is installed."""
    (tmp_path / "rbbench_check_demo.py").write_text(textwrap.dedent(PLUGIN))
    info = tmp_path / "rbbench_check_demo-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: rbbench-check-demo\n"
                                   "Version: 0.1\n")
    (info / "entry_points.txt").write_text("[rbbench]\ndemo = rbbench_check_demo\n")
    path = [str(tmp_path), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    return {**os.environ, "PYTHONPATH": os.pathsep.join(path)}


def _run(env, *argv):
    return subprocess.run([sys.executable, "-c", NO_PYTEST, "plugins", *argv],
                          capture_output=True, text=True, env=env, timeout=300)


def test_check_of_one_package_reports_each_component_and_fails(env):
    out = _run(env, "--check", "--package", "rbbench-check-demo")
    assert out.returncode == 1, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0] == "contract suite (rbbench.testing) on package rbbench-check-demo:"
    passed = next(ln for ln in lines if "check-demo-cpg" in ln)
    assert passed.startswith("PASSED  dual") and "rbbench-check-demo 0.1" in passed
    i = next(i for i, ln in enumerate(lines) if "check-demo-rescaled" in ln)
    assert lines[i].startswith("FAILED  dual")
    assert "does not match the recomputed projection error" in lines[i + 1]
    assert lines[-1] == "contracts: 1 passed, 1 failed, 0 skipped"
    assert not any(" cpg " in ln for ln in lines)  # the built-ins are not checked
    assert "FAILED: dual 'check-demo-rescaled'" in out.stderr


def test_check_json_and_a_passing_selection(env):
    out = _run(env, "--check", "--package", "rbbench_check_demo", "--role", "dual", "--json")
    rows = json.loads(out.stdout)
    assert {(r["name"], r["status"]) for r in rows} == {("check-demo-cpg", "passed"),
                                                        ("check-demo-rescaled", "failed")}
    ok = _run(env, "--check", "--package", "rbbench", "--role", "dual")
    assert ok.returncode == 0, ok.stdout + ok.stderr
    assert ok.stdout.splitlines()[-1] == "contracts: 5 passed, 0 failed, 0 skipped"


def test_an_unknown_package_exits_2_listing_the_packages(env):
    out = _run(env, "--check", "--package", "nope")
    assert out.returncode == 2
    assert "--package 'nope': no registered component comes from it; packages with " \
           "components: rbbench, rbbench-check-demo" in out.stderr


def test_the_listing_takes_the_same_selection(env):
    out = _run(env, "--package", "rbbench-check-demo", "--json")
    assert out.returncode == 0, out.stderr
    assert sorted(r["name"] for r in json.loads(out.stdout)) == ["check-demo-cpg",
                                                                 "check-demo-rescaled"]


# ---------------------------------------------------------------------------
# the component options read their choices and help from the registry
# ---------------------------------------------------------------------------
def test_a_plugins_component_is_a_choice_with_its_description(env):
    help_ = subprocess.run([sys.executable, "-m", "rbbench.cli", "reduce", "--help"],
                           capture_output=True, text=True, env=env, timeout=120)
    assert help_.returncode == 0, help_.stderr
    text = " ".join(help_.stdout.split()).replace("- ", "-")  # argparse wraps the lines
    assert "--dual DUAL dual compressor of the multiplier cone. Registered " \
           "(rbbench plugins --role dual): check-demo-cpg: demo; check-demo-rescaled: demo; " \
           "cpg: Cone Projected Greedy;" in text
    bad = subprocess.run([sys.executable, "-m", "rbbench.cli", "reduce", "membrane_obstacle",
                          "--dual", "nope"], capture_output=True, text=True, env=env, timeout=120)
    assert bad.returncode == 2
    err = " ".join(bad.stderr.split()).replace("- ", "-").replace("'", "")
    assert "argument --dual: invalid choice: nope (choose from check-demo-cpg, " \
           "check-demo-rescaled, cpg" in err


def test_building_the_parser_imports_no_component():
    code = textwrap.dedent("""
        import sys
        from rbbench.cli import build_parser
        from rbbench.registry import default_registry
        build_parser()
        targets = {s.target.split(":")[0] for s in default_registry().specs()
                   if s.role != "hyper"}  # the hyper declarations module is imported by config
        print(sorted(m for m in targets | {"skfem", "ngsolve", "petsc4py", "dask"}
                     if m in sys.modules))
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize("argv, flag, valid", [
    (["solve", "membrane_obstacle", "--backend", "fenics"], "--backend", "ngsolve, skfem"),
    (["run", "quick", "--executor", "slurm"], "--executor", "dask, processes, serial"),
    (["reduce", "membrane_obstacle", "--hyper", "pod"], "--hyper", "auto, affine"),
])
def test_bad_component_names_exit_2_naming_the_flag_and_the_choices(argv, flag, valid, capsys):
    from rbbench.cli import main

    with pytest.raises(SystemExit) as exc:
        main(argv)
    err = " ".join(capsys.readouterr().err.split()).replace("'", "")  # quoted or not
    assert exc.value.code == 2 and f"argument {flag}: invalid choice" in err and valid in err

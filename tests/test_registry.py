"""Plugin discovery: entry points, unknown and missing components, an out-of-tree plugin."""

from __future__ import annotations

import importlib
import importlib.metadata as md
import json
import os
import subprocess
import sys
import textwrap

import pytest

import rbbench.registry as registry_mod
from rbbench.registry import (
    ComponentSpec,
    NotInstalledError,
    Registry,
    UnknownComponentError,
    default_registry,
    discover,
)
from rbbench.testing import check_solver, check_spec, component_params

BUILTINS = {("backend", "skfem"), ("formulation", "mixed"), ("solver", "ssn"),
            ("solver", "uzawa")}


# ---------------------------------------------------------------------------
# (a) built-ins come through the entry point
# ---------------------------------------------------------------------------
def test_builtins_are_declared_by_the_rbbench_distribution():
    reg = discover()
    found = {(s.role, s.name) for s in reg.specs()}
    assert BUILTINS <= found
    for role, name in BUILTINS:
        spec = reg.get(role, name)
        assert spec.package == "rbbench"
        assert spec.version == md.version("rbbench")
        assert spec.target.startswith("rbbench_plugins.")


def test_builtins_need_the_entry_point(monkeypatch):
    eps = md.entry_points(group="rbbench")
    assert [(ep.name, ep.value) for ep in eps if ep.dist.metadata["Name"] == "rbbench"] == [
        ("builtin", "rbbench_plugins")]
    # nothing is hard-wired: without entry points the registry is empty
    monkeypatch.setattr(registry_mod.md, "entry_points", lambda **kw: [])
    assert discover().specs() == []


def test_default_registry_is_cached_and_refreshable():
    reg = default_registry()
    assert default_registry() is reg
    fresh = default_registry(refresh=True)
    try:
        assert fresh is not reg
        assert [s.__dict__ for s in fresh.specs()] == [s.__dict__ for s in reg.specs()]
    finally:
        registry_mod._DEFAULT = reg


def test_duplicate_declaration_is_an_error():
    reg = Registry()
    spec = ComponentSpec(name="dup", role="solver", target="m:A", description="d")
    reg.add(spec)
    with pytest.raises(ValueError, match="registered twice"):
        reg.add(spec)


@pytest.mark.parametrize("kw, match", [
    (dict(role="smoother", target="m:A"), "role 'smoother' is not one of"),
    (dict(role="solver", target="no_colon"), "must read 'module:attribute'"),
])
def test_bad_spec_is_refused_at_declaration(kw, match):
    with pytest.raises(ValueError, match=match):
        ComponentSpec(name="bad", **kw)


# ---------------------------------------------------------------------------
# (b) unknown names list the valid ones
# ---------------------------------------------------------------------------
def test_unknown_name_lists_valid_names():
    reg = default_registry()
    with pytest.raises(UnknownComponentError) as exc:
        reg.get("solver", "newton-krylov")
    msg = str(exc.value)
    assert "newton-krylov" in msg
    for name in reg.names("solver"):
        assert name in msg
    assert {"ssn", "uzawa"} <= set(reg.names("solver"))
    with pytest.raises(UnknownComponentError, match="skfem"):
        reg.create("backend", "fenics", scene=None)
    with pytest.raises(UnknownComponentError, match="valid roles: backend, formulation"):
        reg.get("smoother", "ssn")
    assert isinstance(exc.value, KeyError)  # callers catching KeyError still work


# ---------------------------------------------------------------------------
# (c) missing extras: not available, install hint, NotInstalledError, skipped
# ---------------------------------------------------------------------------
def test_missing_module_is_not_available_with_install_hint():
    reg = Registry()
    reg._current_package = ("rbbench-ghost", "1.0")
    reg.add(ComponentSpec(name="ghost", role="backend", target="surely_missing_mod_xyz:B",
                          extras=("ghostfem",), modules=("surely_missing_mod_xyz",),
                          description="needs a module that is not installed"))
    reg._current_package = ("", "")
    spec = reg.get("backend", "ghost")
    ok, why = reg.availability(spec)
    assert ok is False
    assert "surely_missing_mod_xyz" in why
    assert "ghostfem" in why and "pip install" in why and "rbbench-ghost" in why
    assert "surely_missing_mod_xyz" not in sys.modules  # checked without importing
    with pytest.raises(NotInstalledError, match="ghostfem") as exc:
        reg.load("backend", "ghost")
    assert isinstance(exc.value, ImportError)
    with pytest.raises(NotInstalledError):
        reg.create("backend", "ghost", scene=None)
    # the contract suite skips it with the hint as the reason
    (param,) = component_params(reg)
    assert param.id == "backend:ghost"
    (mark,) = param.marks
    assert mark.name == "skip" and "ghostfem" in mark.kwargs["reason"]
    assert check_spec(reg, spec) is None  # declaration is fine; nothing to load


# ---------------------------------------------------------------------------
# (d) an out-of-tree plugin, found through a real entry point
# ---------------------------------------------------------------------------
DEMO_PLUGIN = '''
"""rbbench-demo-plugin: a third-party solver declared through the rbbench entry point."""
import numpy as np

from rbbench.hf.solvers import lcp
from rbbench.hookspecs import hookimpl
from rbbench.interfaces import Solver, SolveResult
from rbbench.registry import ComponentSpec
from rbbench.hf.condensation.dense import condense


class ProjectedGradientSolver(Solver):
    """Projected gradient on the dual of the condensed contact LCP, step 1 / ||D||."""

    name = "demo-pgd"

    def __init__(self, max_iter=20000, tol=1e-11):
        self.max_iter, self.tol = int(max_iter), float(tol)

    def solve(self, problem, warm_start=None):
        cond = condense(problem.A, problem.F, problem.B, problem.G)
        D, q = cond.D, cond.q
        step = 1.0 / np.linalg.eigvalsh(D)[-1] if q.size else 1.0
        lam = np.zeros(q.size) if warm_start is None else np.maximum(warm_start, 0.0)
        scale, it = max(np.linalg.norm(q), 1e-300), 0
        while True:
            s = q + D @ lam
            res = np.linalg.norm(np.minimum(lam, step * s)) / (step * scale)
            if not np.isfinite(res) or res <= self.tol or it >= self.max_iter:
                break
            lam, it = np.maximum(lam - step * s, 0.0), it + 1
        reason = ("nan" if not np.isfinite(res) else "converged" if res <= self.tol
                  else "max_iterations")
        return SolveResult(u=problem.expand(cond.displacement(lam)), lam=lam, iterations=it,
                           stop_reason=reason, residuals=[float(res)])


@hookimpl
def rbbench_register(registry):
    registry.add(ComponentSpec(
        name="demo-pgd", role="solver",
        target="rbbench_demo_plugin:ProjectedGradientSolver",
        capabilities={"formulations": ("mixed",)},
        description="projected gradient on the condensed contact LCP (demo plugin)",
    ))
'''


@pytest.fixture
def demo_plugin(tmp_path, monkeypatch):
    """Install ``rbbench-demo-plugin 0.1`` into ``tmp_path`` (package + dist-info)."""
    pkg = tmp_path / "rbbench_demo_plugin"
    pkg.mkdir()
    (pkg / "__init__.py").write_text(textwrap.dedent(DEMO_PLUGIN))
    info = tmp_path / "rbbench_demo_plugin-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: rbbench-demo-plugin\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text("[rbbench]\ndemo = rbbench_demo_plugin\n")
    monkeypatch.syspath_prepend(str(tmp_path))  # also invalidates importlib caches
    importlib.invalidate_caches()
    yield tmp_path
    sys.modules.pop("rbbench_demo_plugin", None)
    importlib.invalidate_caches()


def test_out_of_tree_plugin_is_discovered_and_passes_the_contract(demo_plugin):
    assert "rbbench_demo_plugin" not in sys.modules
    reg = discover()
    # the entry point was read from the dist-info, not imported by name
    assert md.version("rbbench-demo-plugin") == "0.1"
    spec = reg.get("solver", "demo-pgd")
    assert spec.package == "rbbench-demo-plugin"
    assert spec.version == "0.1"
    assert BUILTINS <= {(s.role, s.name) for s in reg.specs()}  # alongside the built-ins
    assert reg.get("solver", "ssn").package == "rbbench"
    assert "demo-pgd" in reg.names("solver")
    cls = reg.load("solver", "demo-pgd")
    assert cls.__module__ == "rbbench_demo_plugin"
    assert sys.modules["rbbench_demo_plugin"].__file__.startswith(str(demo_plugin))
    assert "solver:demo-pgd" in {p.id for p in component_params(reg)}
    # the same contract as the built-ins
    assert check_spec(reg, spec) is cls
    check_solver(cls, name="demo-pgd")
    sol = reg.create("solver", "demo-pgd", max_iter=5)
    assert sol.max_iter == 5


def test_out_of_tree_plugin_that_breaks_the_contract_is_caught(demo_plugin):
    # same plugin, but claiming convergence after max_iter: the contract must say so
    from rbbench.testing import ContractViolation

    cls = discover().load("solver", "demo-pgd")

    class Liar(cls):
        def solve(self, problem, warm_start=None):
            res = super().solve(problem, warm_start)
            res.stop_reason = "converged"
            return res

    with pytest.raises(ContractViolation, match="KKT fails|without solution"):
        check_solver(Liar)


def test_out_of_tree_plugin_in_rbbench_plugins_cli(demo_plugin):
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(demo_plugin)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep)
                              if p])}
    out = subprocess.run([sys.executable, "-m", "rbbench.cli", "plugins", "--json"],
                         capture_output=True, text=True, env=env, timeout=120, check=True)
    rows = {(r["role"], r["name"]): r for r in json.loads(out.stdout)}
    demo = rows[("solver", "demo-pgd")]
    assert demo["package"] == "rbbench-demo-plugin" and demo["version"] == "0.1"
    assert demo["importable"] is True
    assert rows[("backend", "skfem")]["package"] == "rbbench"
    table = subprocess.run([sys.executable, "-m", "rbbench.cli", "plugins"],
                           capture_output=True, text=True, env=env, timeout=120, check=True)
    line = next(ln for ln in table.stdout.splitlines() if "demo-pgd" in ln)
    assert "rbbench-demo-plugin 0.1" in line and "yes" in line


def test_plugin_failing_to_import_is_named(tmp_path, monkeypatch):
    pkg = tmp_path / "rbbench_broken_plugin"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("raise RuntimeError('boom at import')\n")
    info = tmp_path / "rbbench_broken_plugin-0.2.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(
        "Metadata-Version: 2.1\nName: rbbench-broken-plugin\nVersion: 0.2\n")
    (info / "entry_points.txt").write_text("[rbbench]\nbroken = rbbench_broken_plugin\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    try:
        reg = discover()  # the broken plugin is recorded, the others still work
        assert "ssn" in reg.names("solver")
        assert len(reg.broken) == 1
        ep_name, pkg, msg = reg.broken[0]
        assert ep_name == "broken" and pkg == "rbbench-broken-plugin"
        assert "boom at import" in msg
        with pytest.raises(ImportError, match="'broken'.*rbbench-broken-plugin.*boom"):
            discover(strict=True)
    finally:
        sys.modules.pop("rbbench_broken_plugin", None)


# ---------------------------------------------------------------------------
# (e) the core does not import a backend
# ---------------------------------------------------------------------------
def test_core_does_not_import_a_backend():
    code = textwrap.dedent("""
        import sys
        import rbbench, rbbench.registry, rbbench.scene.loading, rbbench.hf.model, rbbench.cli
        import rbbench.testing, rbbench.testing.contract_model
        reg = rbbench.registry.default_registry()
        assert reg.names("backend"), "no backend declared"
        reg.availability(reg.get("backend", "skfem"))
        heavy = sorted(m for m in sys.modules
                       if m == "skfem" or m.startswith("skfem.")
                       or m.startswith("rbbench_plugins.backends"))
        assert not heavy, heavy
        assert "pytest" not in sys.modules, "rbbench.testing must not import pytest"
        print("ok")
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"

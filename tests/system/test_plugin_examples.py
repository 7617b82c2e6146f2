"""The plugin author's guide (``docs/plugins``) against the code: each role's example module
passes its role's contract, each role has a page that includes an existing example, and
each run matrix the pages show loads with the examples and runs every case."""

from __future__ import annotations

import importlib
import re
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.sparse as sp

from rbbench.registry import ROLES, Registry, default_registry
from rbbench.testing import reference_discretization, run_contract

ROOT = Path(__file__).resolve().parents[2]
GUIDE = ROOT / "docs" / "plugins"
EXAMPLES = GUIDE / "examples"
TEMPLATE_SRC = ROOT / "examples" / "plugin_template" / "src"
#: the example module of each role's page (the dual role's is the template's component)
ROLE_EXAMPLE = {
    "backend": "cached_backend", "formulation": "lumped_formulation", "solver": "pgd_solver",
    "primal": "norm_order_primal", "stabilizer": "center_supremizer", "hyper": "declared_hyper",
    "executor": "inline_executor",
}
PACKAGE = "docs-examples"


def _fresh_import(name: str):
    sys.modules.pop(name, None)
    return importlib.import_module(name)


@pytest.fixture
def on_path(monkeypatch):
    """The example modules and the template package importable, as installed plugins are."""
    monkeypatch.syspath_prepend(str(EXAMPLES))
    monkeypatch.syspath_prepend(str(TEMPLATE_SRC))
    yield
    for name in [*ROLE_EXAMPLE.values(), "rbbench_plugin_template"]:
        sys.modules.pop(name, None)


def _registry(modules, with_builtins: bool = True) -> Registry:
    """The built-in components and the declarations of ``modules`` (their hooks called as
    discovery calls them, under the package name ``docs-examples``)."""
    reg = Registry()
    if with_builtins:
        for spec in default_registry().specs():
            if spec.package not in (PACKAGE, "rbbench-plugin-template"):
                reg.add(spec)
    reg._current_package = (PACKAGE, "0")
    for module in modules:
        module.rbbench_register(reg)
    reg._current_package = ("", "")
    return reg


def test_every_example_module_has_a_role():
    assert sorted(p.stem for p in EXAMPLES.glob("*.py")) == sorted(ROLE_EXAMPLE.values())
    assert set(ROLE_EXAMPLE) | {"dual"} == set(ROLES)


@pytest.mark.parametrize("role", sorted(ROLE_EXAMPLE))
def test_the_example_passes_its_roles_contract(role, on_path):
    module = _fresh_import(ROLE_EXAMPLE[role])
    reg = _registry([module])
    specs = [s for s in reg.specs() if s.package == PACKAGE]
    assert [s.role for s in specs] == [role]
    for spec in specs:
        run_contract(spec, reg)  # a violation or a skip fails the test


def test_the_lumped_formulation_lumps_w_and_keeps_the_rest(on_path):
    module = _fresh_import("lumped_formulation")
    disc = reference_discretization("poisson")
    mixed = default_registry().create("formulation", "mixed").build(disc)
    lumped = module.LumpedMixed().build(disc)
    W = sp.csr_matrix(mixed.W)
    assert sp.issparse(lumped.W) and sp.triu(lumped.W, 1).nnz == 0 \
        and sp.tril(lumped.W, -1).nnz == 0
    np.testing.assert_allclose(lumped.W.diagonal(), np.asarray(abs(W).sum(axis=1)).ravel())
    assert (abs(lumped.A - mixed.A)).max() == 0 and (abs(lumped.B - mixed.B)).max() == 0
    np.testing.assert_array_equal(lumped.G, mixed.G)


def test_the_lumped_formulation_is_reduced_by_the_mixed_steps(on_path, tmp_path):
    from rbbench import api
    from rbbench.scene.loading import load_scene

    reg = _registry([_fresh_import("lumped_formulation")])
    scene = load_scene("membrane_obstacle", ["discretization.n_cells=8"])
    res = api.reduce(scene, formulation="mixed-lumped", dual="cpg", stabilizer="none", N=4,
                     R=4, n_train=9, n_valid=3, online_repeats=1, cache_dir=str(tmp_path),
                     registry=reg)
    summary = res.summary()
    assert summary["config"]["formulation"] == "mixed-lumped"
    assert summary["online_stops"] == {"converged": 3}
    assert 0 <= summary["err_u_max"] < 1


# ---------------------------------------------------------------------------------- pages
def _page(role: str) -> str:
    return (GUIDE / f"{role}.md").read_text()


def _includes(text: str, page: Path) -> list[Path]:
    return [(page.parent / p).resolve() for p in re.findall(r"```\{literalinclude\} (\S+)", text)]


@pytest.mark.parametrize("role", ROLES)
def test_each_role_has_a_page_including_its_example(role):
    page = GUIDE / f"{role}.md"
    included = _includes(_page(role), page)
    assert included and all(p.is_file() for p in included)
    if role in ROLE_EXAMPLE:
        assert (EXAMPLES / f"{ROLE_EXAMPLE[role]}.py").resolve() in included
    else:
        assert (TEMPLATE_SRC / "rbbench_plugin_template" / "random_cone.py").resolve() \
            in included


def test_the_index_lists_every_page_and_the_site_reaches_it():
    index = (GUIDE / "index.md").read_text()
    toctree = index.split("```{toctree}")[1].split("```")[0].split()
    assert set(toctree) >= {*ROLES, "template"}
    site = (ROOT / "docs" / "index.md").read_text()
    assert "plugins/index" in site.split("```{toctree}")[1]
    for role in ROLES:  # the group name rbbench reads, and the check command
        assert "[project.entry-points.rbbench]" in _page(role)
        assert "rbbench plugins --check --package" in _page(role)


def _page_matrices() -> list[tuple[str, str]]:
    out = []
    for page in sorted(GUIDE.glob("*.md")):
        for block in re.findall(r"```toml\n(.*?)```", page.read_text(), flags=re.S):
            if "[matrix]" in block:
                out.append((page.stem, block))
    return out


@pytest.mark.parametrize("block", [b for _, b in _page_matrices()],
                         ids=[p for p, _ in _page_matrices()])
def test_the_pages_matrices_run_every_case(block, on_path, tmp_path):
    from rbbench.bench.matrix import load_matrix

    modules = [_fresh_import(m) for m in ROLE_EXAMPLE.values()]
    reg = _registry([*modules, _fresh_import("rbbench_plugin_template")])
    path = tmp_path / "matrix.toml"
    path.write_text(block)
    cases = load_matrix(path, registry=reg).cases
    assert cases and {c.status for c in cases} == {"run"}, \
        [(c.label, c.status, c.reason) for c in cases]

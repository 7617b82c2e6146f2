"""The shape rules of the code base, enforced rather than remembered.

* every module of ``rbbench/`` and ``plugins/`` stays under :data:`MAX_MODULE_LINES`;
* every function or method stays under :data:`MAX_FUNCTION_LINES` (decorators and
  docstring included: the span of the ``def`` statement);
* no import circle between the modules of ``rbbench`` (imports inside functions count:
  a lazy import is still a dependency); ``rbbench/__init__.py`` (the lazy Python face)
  and ``rbbench/_compat.py`` (old paths) are outside the graph;
* the layers import downwards only: scene <- hf <- rb <- bench / studies / cli, and inside
  ``rbbench.hf`` and ``rbbench.rb`` their folders too (:data:`SUBLAYERS`; every folder and
  module there has a place, so a new one must be placed here); the formulations of
  ``rbbench.rb`` are peers that never import each other (:data:`PEERS`);
* no folder holds more than :data:`MAX_FOLDER_MODULES` modules (split it by concept);
* ``tests/`` mirrors the package: every test folder is a folder of ``rbbench/`` (or of
  ``plugins/`` under ``tests/plugins/``), except :data:`TEST_FOLDERS_OUTSIDE` (system-level
  tests, shared helpers, data).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
MAX_MODULE_LINES = 600
MAX_FUNCTION_LINES = 80
MAX_FOLDER_MODULES = 15
SOURCES = sorted([*(ROOT / "rbbench").rglob("*.py"), *(ROOT / "plugins").rglob("*.py")])
OUTSIDE_GRAPH = {"rbbench", "rbbench._compat"}

#: a module of layer k may import modules of layers <= k only (top-level modules such as
#: registry, interfaces, hookspecs, provenance are layer 0: the shared vocabulary; ``plugin``
#: gathers the names plugin authors use from every layer below the Python face)
LAYERS = {"scene": 1, "hf": 2, "rb": 3, "bench": 4, "optim": 4, "studies": 5, "testing": 5,
          "api": 6, "plugin": 6, "cli": 7}

#: inside a layer, its folders and modules in import order: a module may import those of a
#: lower or equal rank only (the data flow: geometry -> condensed problem -> solvers -> one HF
#: solve -> snapshots; shared RB algorithms and compiled kernels -> the offline skeleton ->
#: the formulations)
SUBLAYERS = {
    "rbbench.hf": {"geometry": 1, "references": 1, "condensation": 2, "algebra": 3,
                   "solvers": 4, "components": 5, "metrics": 5, "metrics3d": 5, "model": 6,
                   "output": 7, "output3d": 7, "snapshots": 7, "linear": 8},
    "rbbench.rb": {"algorithms": 1, "online": 1, "hyper": 2, "kernels": 2, "compressors": 2,
                   "config": 3, "validation": 3, "offline": 4, "mixed": 5, "nitsche": 5,
                   "friction": 5, "linear": 5},
}
#: folders of the same rank that must not import each other (one per formulation)
PEERS = {"rbbench.rb": {"mixed", "nitsche", "friction", "linear"}}
#: peer imports that stand for now, each named with its reason (none: what the formulations
#: share lives below them, e.g. the compiled kernels in ``rbbench.rb.kernels``)
PEER_IMPORTS_KEPT: dict[str, set[str]] = {}


def _rel(p: Path) -> str:
    return str(p.relative_to(ROOT))


def _module_name(p: Path) -> str:
    rel = p.relative_to(ROOT).with_suffix("")
    parts = list(rel.parts)
    if parts[0] == "plugins":
        parts[0] = "rbbench_plugins"
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def long_functions(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(), filename=str(path))
    out = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            start = min([node.lineno, *(d.lineno for d in node.decorator_list)])
            n = node.end_lineno - start + 1
            if n > MAX_FUNCTION_LINES:
                out.append(f"{_rel(path)}:{node.lineno} {node.name} ({n} lines)")
    return out


def imports_of(path: Path, modules: set[str]) -> set[str]:
    """The rbbench / rbbench_plugins modules that ``path`` imports (``from a import b``
    counts ``a.b`` when that is a module, else ``a``)."""
    tree = ast.parse(path.read_text(), filename=str(path))
    me = _module_name(path)
    pkg = me if path.name == "__init__.py" else me.rpartition(".")[0]
    found = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                up = pkg.split(".")
                base = ".".join(up[: len(up) - node.level + 1] + ([base] if base else []))
            names = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base
                     for a in node.names]
        else:
            continue
        for name in names:
            while name and name not in modules:
                name = name.rpartition(".")[0]
            if name and name != me:
                found.add(name)
    return found


def import_graph() -> dict[str, set[str]]:
    mods = {_module_name(p): p for p in SOURCES}
    names = set(mods)
    return {m: imports_of(p, names) - OUTSIDE_GRAPH
            for m, p in mods.items() if m not in OUTSIDE_GRAPH}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def _layer(mod: str) -> int | None:
    parts = mod.split(".")
    if parts[0] != "rbbench":
        return None
    return LAYERS.get(parts[1], 0) if len(parts) > 1 else 0


def _sublayer(mod: str) -> tuple[str, str, int] | None:
    """``(layer package, folder or module, rank)`` of a module inside a :data:`SUBLAYERS`
    package (None outside them, or for the package itself)."""
    for pkg, ranks in SUBLAYERS.items():
        if mod.startswith(pkg + "."):
            part = mod[len(pkg) + 1:].split(".")[0]
            return pkg, part, ranks.get(part, -1)
    return None


def test_sources_found():
    assert len(SOURCES) > 40
    assert "rbbench.rb.offline" in import_graph()


def test_module_sizes():
    big = [f"{_rel(p)} ({n} lines)" for p in SOURCES
           if (n := len(p.read_text().splitlines())) > MAX_MODULE_LINES]
    assert not big, f"modules over {MAX_MODULE_LINES} lines: " + "; ".join(big)


def test_function_sizes():
    long_ = [f for p in SOURCES for f in long_functions(p)]
    assert not long_, f"functions over {MAX_FUNCTION_LINES} lines: " + "; ".join(long_)


def test_no_import_circles():
    circles = cycles(import_graph())
    assert not circles, "import circles: " + "; ".join(" <-> ".join(c) for c in circles)


def test_layers_import_downwards():
    bad = []
    for mod, deps in import_graph().items():
        lm = _layer(mod)
        if lm is None:
            continue
        bad += [f"{mod} -> {d}" for d in deps
                if (ld := _layer(d)) is not None and ld > lm]
    assert not bad, "imports from a higher layer: " + "; ".join(sorted(bad))


def test_every_folder_of_a_layer_has_a_place():
    unplaced = sorted({f"{s[0]}.{s[1]}" for mod in import_graph()
                       if (s := _sublayer(mod)) is not None and s[2] < 0})
    assert not unplaced, "folders / modules without a rank in SUBLAYERS: " + ", ".join(unplaced)


def test_folders_inside_a_layer_import_downwards():
    bad = []
    for mod, deps in import_graph().items():
        me = _sublayer(mod)
        if me is None:
            continue
        for d in deps:
            other = _sublayer(d)
            if other is None or other[0] != me[0] or other[1] == me[1]:
                continue
            peers = PEERS.get(me[0], set())
            if d in PEER_IMPORTS_KEPT.get(mod, ()):
                continue
            if other[2] > me[2] or (me[1] in peers and other[1] in peers):
                bad.append(f"{mod} -> {d}")
    assert not bad, "imports against the flow of a layer: " + "; ".join(sorted(bad))


TESTS = ROOT / "tests"
#: test folders that mirror no package folder: CLI, fuzz, install, code shape, published
#: figures, old paths (``system``); helpers shared by test files (``support``); reference data
TEST_FOLDERS_OUTSIDE = {"system", "support", "data"}


def test_tests_mirror_the_package():
    stray = []
    for d in sorted(p.parent for p in TESTS.rglob("test_*.py")):
        rel = d.relative_to(TESTS)
        if not rel.parts or rel.parts[0] in TEST_FOLDERS_OUTSIDE:
            continue
        source = (ROOT / "plugins").joinpath(*rel.parts[1:]) if rel.parts[0] == "plugins" \
            else (ROOT / "rbbench").joinpath(*rel.parts)
        if not source.is_dir():
            stray.append(f"tests/{rel.as_posix()}/ (no {_rel(source)}/)")
    assert not stray, "test folders that mirror no package folder: " + "; ".join(sorted(set(stray)))


def test_folder_sizes():
    big = []
    for d in sorted({p.parent for p in SOURCES}):
        n = len([p for p in d.glob("*.py") if p.name != "__init__.py"])
        if n > MAX_FOLDER_MODULES:
            big.append(f"{_rel(d)}/ ({n} modules)")
    assert not big, f"folders over {MAX_FOLDER_MODULES} modules: " + "; ".join(big)


@pytest.mark.parametrize("src, expected", [
    ({"a": {"b"}, "b": {"a"}}, [["a", "b"]]),
    ({"a": {"b"}, "b": {"c"}, "c": set()}, []),
    ({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}, [["a", "b", "c"]]),
])
def test_cycle_finder(src, expected):
    assert cycles(src) == expected


def test_long_function_finder(tmp_path):
    body = "\n".join(f"    x{i} = {i}" for i in range(MAX_FUNCTION_LINES))
    p = tmp_path / "m.py"
    p.write_text(f"@staticmethod\ndef f():\n{body}\n\n\ndef g():\n    return 1\n")
    found = [s.split(" ", 1)[1] for s in long_functions_at(p)]
    assert found == [f"f ({MAX_FUNCTION_LINES + 2} lines)"]


def long_functions_at(p: Path) -> list[str]:
    """:func:`long_functions` for a file outside the tree (path shown as given)."""
    global ROOT
    root, ROOT = ROOT, p.parent
    try:
        return long_functions(p)
    finally:
        ROOT = root


def test_kept_peer_imports_still_exist():
    """Every kept peer import is still made (a stale entry would hide a new one)."""
    graph = import_graph()
    for mod, deps in PEER_IMPORTS_KEPT.items():
        assert deps <= graph.get(mod, set()), (mod, deps - graph.get(mod, set()))

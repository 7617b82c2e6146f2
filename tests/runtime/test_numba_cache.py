"""numba's cache of the online kernels lives in the user's cache directory (or numba's own
NUMBA_CACHE_DIR), not in the installed package."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("numba")

PROBE = ("from rbbench.rb.mixed import dual_kernels as D; "
         "print(D.online_nnls._cache._cache_path)")


def _cache_path(env: dict[str, str]) -> Path:
    base = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR",
                                                              "XDG_CACHE_HOME")}
    out = subprocess.run([sys.executable, "-c", PROBE], env={**base, **env},
                         capture_output=True, text=True, timeout=300, check=True)
    return Path(out.stdout.strip().splitlines()[-1])


def test_kernels_cache_in_the_users_cache_dir(tmp_path):
    path = _cache_path({"XDG_CACHE_HOME": str(tmp_path)})
    assert path.is_relative_to(tmp_path / "rbbench" / "numba"), path


def test_numba_cache_dir_is_respected(tmp_path):
    path = _cache_path({"NUMBA_CACHE_DIR": str(tmp_path / "mine")})
    assert path.is_relative_to(tmp_path / "mine"), path


def test_dependency_digest_follows_the_contents_not_the_times(tmp_path):
    from rbbench.runtime.numba_cache import dependency_digest

    a, b = tmp_path / "a.py", tmp_path / "b.py"
    a.write_text("x = 1")
    b.write_text("y = 2")
    d = dependency_digest([a, b])
    os.utime(a, (5000, 5000))
    assert dependency_digest([a, b]) == d  # touched, same contents
    assert dependency_digest([b, a]) != d  # in order
    a.write_text("x = 3")
    assert dependency_digest([a, b]) != d
    empty = tmp_path / "empty.py"
    empty.write_text("")
    assert dependency_digest([tmp_path / "missing.py"]) == dependency_digest([empty])


def test_is_stale_compares_the_times():
    import tempfile

    from rbbench.runtime.numba_cache import is_stale

    with tempfile.TemporaryDirectory() as d:
        index, source = Path(d) / "k.nbi", Path(d) / "k.py"
        index.write_text("")
        source.write_text("")
        os.utime(index, (1000, 1000))
        os.utime(source, (2000, 2000))
        assert is_stale(index, source) and not is_stale(source, index)
        assert not is_stale(Path(d) / "missing.nbi", source)


class _Cache:
    """The two numba cache internals drop_stale reads: the index path and flush()."""

    def __init__(self, index: Path) -> None:
        self._cache_file = type("F", (), {"_index_path": str(index)})()
        self.flushed = 0

    def flush(self) -> None:
        self.flushed += 1


def test_drop_stale_flushes_caches_made_with_other_dependencies(tmp_path):
    """numba would keep running a cached kernel after a change to a module whose kernels it
    compiles in (it checks only its own file), and an index's time says nothing of its
    older entries (numba rewrites it with each new one): a cache is kept only when the
    digest beside it is the dependencies' current one."""
    from types import SimpleNamespace

    from rbbench.runtime.numba_cache import drop_stale

    dep = tmp_path / "dep.py"
    dep.write_text("A = 1")
    index = tmp_path / "k.nbi"
    index.write_text("")  # a cache of unknown provenance (no digest beside it)
    kernel = SimpleNamespace(_cache=_Cache(index))
    never = SimpleNamespace(_cache=_Cache(tmp_path / "missing.nbi"))
    uncached = SimpleNamespace(_cache=object())  # inline kernels: no disk cache
    assert drop_stale([kernel, never, uncached], [dep]) is True
    assert kernel._cache.flushed == 1 and never._cache.flushed == 0
    assert drop_stale([kernel, never], [dep]) is False  # digests written: nothing stale
    os.utime(index, (1, 1))  # times do not matter
    assert drop_stale([kernel], [dep]) is False
    dep.write_text("A = 2")  # the dependency changed: flushed once, then kept
    assert drop_stale([kernel], [dep]) is True and kernel._cache.flushed == 2
    assert drop_stale([kernel], [dep]) is False


#: the kernel modules that compile in another module's kernels
def _kernel_modules_calling_other_kernels() -> list[str]:
    """Every rbbench module with cached numba kernels that imports another module's
    kernels (found in the sources, so a new kernel module cannot be forgotten)."""
    import ast

    root = Path(__file__).resolve().parents[2] / "rbbench"
    src = {".".join(f.relative_to(root.parent).with_suffix("").parts)
           .removesuffix(".__init__"): f.read_text() for f in root.rglob("*.py")}
    kernels = {m for m, text in src.items() if "@njit(cache=True" in text}
    out = []
    for m in sorted(kernels):
        for node in ast.walk(ast.parse(src[m])):
            if isinstance(node, ast.ImportFrom) and node.module and node.module in src:
                names = {node.module} | {f"{node.module}.{a.name}" for a in node.names}
                if names & (kernels - {m}):
                    out.append(m)
                    break
    return out


KERNEL_MODULES = _kernel_modules_calling_other_kernels()


def test_the_kernel_modules_are_found():
    assert {"rbbench.rb.kernels.pairing", "rbbench.rb.mixed.kernels",
            "rbbench.rb.mixed.bound_kernels",
            "rbbench.rb.friction.wedge.kernels"} <= set(KERNEL_MODULES)


@pytest.mark.parametrize("name", KERNEL_MODULES)
def test_every_kernel_module_it_imports_is_a_dependency(name):
    """The staleness check of each kernel module names every rbbench module whose numba
    kernels it imports (transitively), and nothing is stale right after the import; the
    numba internals it reads exist in this numba."""
    import ast
    import importlib

    def kernel_imports(mod_name: str) -> set[str]:
        mod = importlib.import_module(mod_name)
        tree = ast.parse(Path(mod.__file__).read_text())
        found = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and \
                    node.module.startswith("rbbench.rb"):
                for alias in node.names:
                    full = f"{node.module}.{alias.name}"
                    found.add(full if _is_module(full) else node.module)
        out = set()
        for dep in found:
            if dep != mod_name and "njit" in Path(
                    importlib.import_module(dep).__file__).read_text():
                out |= {dep} | kernel_imports(dep)
        return out

    mod = importlib.import_module(name)
    deps = {str(Path(f).resolve()) for f in mod.DEPENDENCIES}
    wanted = {str(Path(importlib.import_module(d).__file__).resolve())
              for d in kernel_imports(name)}
    assert wanted and wanted <= deps, sorted(wanted - deps)
    assert mod.drop_stale_cache() is False  # just imported: nothing stale left
    from rbbench.runtime.numba_cache import module_kernels

    cached = {f.name for f in ast.walk(ast.parse(Path(mod.__file__).read_text()))
              if isinstance(f, ast.FunctionDef) and any(
                  isinstance(d, ast.Call) and getattr(d.func, "id", None) == "njit"
                  and any(k.arg == "cache" for k in d.keywords) for d in f.decorator_list)}
    assert cached == {k.py_func.__name__ for k in module_kernels(name)}  # all checked
    kernel = next(v for v in vars(mod).values() if hasattr(v, "_cache")
                  and getattr(v, "py_func", None) is not None
                  and v.py_func.__module__ == name)
    assert str(kernel._cache._cache_file._index_path).endswith(".nbi")


def _is_module(name: str) -> bool:
    import importlib.util

    try:
        return importlib.util.find_spec(name) is not None
    except ModuleNotFoundError:
        return False

"""Where numba keeps the compiled online kernels: the user's cache directory, not the
installed package.

numba caches a ``cache=True`` function beside its source (``__pycache__`` in the package)
unless ``numba.config.CACHE_DIR`` names a directory; a package directory may be read-only,
shared between users or replaced by an upgrade. :func:`use_user_cache` points numba at
``$NUMBA_CACHE_DIR`` when the user set it (numba's own variable), else
``$XDG_CACHE_HOME/rbbench/numba`` (``~/.cache/rbbench/numba``). It must run before the
kernels are decorated: the kernel modules call it first.

numba checks only the source file of a cached function, yet a kernel that calls another
module's kernels compiles them into its own cache entry (numba's documented
cache-invalidation limit): after a change there alone (an editable install updated) the
cache would run the old code. :func:`drop_stale` forgets such entries; every kernel module
that calls another's calls it at import, naming the files it depends on. It keeps, beside
each kernel's cache index, a digest of those files' contents as they were when the cache
was last flushed (the entries compiled since used them): an index's own time says nothing
of its older entries, since numba rewrites it whenever it adds one.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

__all__ = ["cache_dir", "dependency_digest", "drop_stale", "is_stale", "module_kernels",
           "stale_cache_dropper", "use_user_cache"]


def cache_dir() -> Path:
    """The directory for numba's cache: ``$NUMBA_CACHE_DIR``, else
    ``$XDG_CACHE_HOME/rbbench/numba``, else ``~/.cache/rbbench/numba``."""
    if os.environ.get("NUMBA_CACHE_DIR"):
        return Path(os.environ["NUMBA_CACHE_DIR"])
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "rbbench" / "numba"


def use_user_cache() -> str:
    """Set ``numba.config.CACHE_DIR`` to :func:`cache_dir` (unless numba already has one)
    and return it. numba falls back to the package's ``__pycache__`` only when that
    directory cannot be created or written."""
    from numba.core import config

    if not config.CACHE_DIR:
        config.CACHE_DIR = str(cache_dir())
    return config.CACHE_DIR


def module_kernels(name: str) -> list[Any]:
    """The numba dispatchers with a disk cache defined in module ``name`` (all of them: a
    kernel's cached callees in the same module are loaded from their own entries)."""
    import sys

    return [v for v in vars(sys.modules[name]).values()
            if getattr(getattr(v, "py_func", None), "__module__", None) == name
            and getattr(getattr(v, "_cache", None), "_cache_file", None) is not None]


def is_stale(index: str | os.PathLike, dependency: str | os.PathLike) -> bool:
    """Whether the file ``index`` is older than the source file ``dependency`` (kept from
    0.1; :func:`drop_stale` compares contents instead: numba rewrites an index with every
    new entry, so its time says nothing of its older entries)."""
    try:
        return os.path.getmtime(index) < os.path.getmtime(dependency)
    except OSError:  # no index yet (nothing cached) or no source file (frozen install)
        return False


def dependency_digest(dependencies: Iterable[str | os.PathLike]) -> str:
    """SHA-256 of the dependency files' contents, in order (a missing file counts as
    empty: a frozen install without sources)."""
    h = hashlib.sha256()
    for dep in dependencies:
        try:
            h.update(Path(dep).read_bytes())
        except OSError:
            pass
        h.update(b"\0")
    return h.hexdigest()


def drop_stale(kernels: Iterable[Any], dependencies: Iterable[str | os.PathLike]) -> bool:
    """Flush the on-disk cache of every kernel of ``kernels`` (numba dispatchers; those
    without a disk cache are skipped) whose cache was not made with the current contents
    of ``dependencies``, the modules whose kernels it compiles in: its digest file
    (``<index>.deps``, :func:`dependency_digest`) is missing or differs. Then the digest
    file is written. Returns whether it flushed any."""
    digest = dependency_digest(list(dependencies))
    flushed = False
    for kernel in kernels:
        cache = getattr(kernel, "_cache", None)
        cache_file = getattr(cache, "_cache_file", None)
        if cache_file is None:
            continue
        index = Path(cache_file._index_path)
        stamp = index.with_name(index.name + ".deps")
        try:
            known = stamp.read_text()
        except OSError:
            known = None
        if known == digest:
            continue
        if index.exists():
            cache.flush()
            flushed = True
        try:
            stamp.parent.mkdir(parents=True, exist_ok=True)
            stamp.write_text(digest)
        except OSError:
            pass  # a read-only cache: checked again next time
    return flushed


def stale_cache_dropper(module: str, dependencies: Iterable[str | os.PathLike]
                        ) -> Callable[[], bool]:
    """The ``drop_stale_cache()`` of kernel module ``module``: :func:`drop_stale` of all its
    cached kernels (:func:`module_kernels`) against ``dependencies``, the modules whose
    kernels they compile in. Returns whether it flushed; a kernel module calls it once at
    the end of its import."""
    deps = tuple(dependencies)
    return lambda: drop_stale(module_kernels(module), deps)

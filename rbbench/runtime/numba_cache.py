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
that calls another's calls it at import, naming the files it depends on.
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

__all__ = ["cache_dir", "drop_stale", "is_stale", "use_user_cache"]


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


def is_stale(index: str | os.PathLike, dependency: str | os.PathLike) -> bool:
    """Whether numba's cache index ``index`` predates the source file ``dependency``."""
    try:
        return os.path.getmtime(index) < os.path.getmtime(dependency)
    except OSError:  # no index yet (nothing cached) or no source file (frozen install)
        return False


def drop_stale(kernels: Iterable[Any], dependencies: Iterable[str | os.PathLike]) -> bool:
    """Flush the on-disk cache of every kernel of ``kernels`` (numba dispatchers; those
    without a disk cache are skipped) whose cache index predates one of the source files
    ``dependencies``, the modules whose kernels it compiles in. Returns whether it flushed
    any."""
    deps = list(dependencies)
    flushed = False
    for kernel in kernels:
        cache = getattr(kernel, "_cache", None)
        cache_file = getattr(cache, "_cache_file", None)
        if cache_file is None:
            continue
        if any(is_stale(cache_file._index_path, dep) for dep in deps):
            cache.flush()
            flushed = True
    return flushed

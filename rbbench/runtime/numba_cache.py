"""Where numba keeps the compiled online kernels: the user's cache directory, not the
installed package.

numba caches a ``cache=True`` function beside its source (``__pycache__`` in the package)
unless ``numba.config.CACHE_DIR`` names a directory; a package directory may be read-only,
shared between users or replaced by an upgrade. :func:`use_user_cache` points numba at
``$NUMBA_CACHE_DIR`` when the user set it (numba's own variable), else
``$XDG_CACHE_HOME/rbbench/numba`` (``~/.cache/rbbench/numba``). It must run before the
kernels are decorated: the kernel modules call it first.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["cache_dir", "use_user_cache"]


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

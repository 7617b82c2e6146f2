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

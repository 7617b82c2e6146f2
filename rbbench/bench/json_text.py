"""JSON read from a run directory (case records, manifests, locks, table cells), bounded in
depth: a file nested 200,000 levels deep made :func:`json.loads` raise ``RecursionError``
(not ``ValueError``), which crashed ``rbbench report`` and the resume of a run.

:func:`loads` raises ``ValueError`` instead, so every reader's "unreadable: ignored" path
takes such a file, and it refuses documents deeper than :data:`MAX_DEPTH`, so no reader
that walks a document recursively meets one it cannot walk.
"""

from __future__ import annotations

import json
import os
import stat
from pathlib import Path
from typing import Any

__all__ = ["MAX_BYTES", "MAX_DEPTH", "depth", "loads", "read_text"]

#: Deepest nesting of lists and objects accepted (a case record is about 5 deep).
MAX_DEPTH = 100
#: Largest JSON file read from a run directory (a case record with its per-mu details is
#: well under 1 MB)
MAX_BYTES = 64_000_000


def depth(obj: Any) -> int:
    """The nesting depth of lists and dicts in ``obj`` (a scalar: 0), without recursion."""
    deepest, stack = 0, [(obj, 1)]
    while stack:
        node, d = stack.pop()
        if isinstance(node, dict):
            children = node.values()
        elif isinstance(node, list):
            children = node
        else:
            continue
        deepest = max(deepest, d)
        if d > MAX_DEPTH:
            break
        stack.extend((c, d + 1) for c in children if isinstance(c, (dict, list)))
    return deepest


def read_text(path: Path) -> str:
    """The text of a run directory's JSON file: ``OSError`` for what is not a regular file
    (a link to ``/dev/zero`` would never end) or holds more than :data:`MAX_BYTES`,
    ``ValueError`` for text that is not UTF-8."""
    with open(path, "rb") as fh:
        if not stat.S_ISREG(os.fstat(fh.fileno()).st_mode):
            raise OSError(f"{path}: not a regular file")
        raw = fh.read(MAX_BYTES + 1)
    if len(raw) > MAX_BYTES:
        raise OSError(f"{path}: more than {MAX_BYTES} bytes")
    return raw.decode("utf-8")


def loads(text: str | bytes) -> Any:
    """:func:`json.loads`, with ``ValueError`` for a document nested deeper than
    :data:`MAX_DEPTH` (``RecursionError`` of the parser included)."""
    try:
        obj = json.loads(text)
    except RecursionError:
        raise ValueError(f"nested too deeply for the JSON parser (at most {MAX_DEPTH} "
                         "levels)") from None
    if depth(obj) > MAX_DEPTH:
        raise ValueError(f"nested more than {MAX_DEPTH} levels deep") from None
    return obj

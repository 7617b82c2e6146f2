"""JSON read from a run directory (case records, manifests, locks, table cells), bounded in
depth: a file nested 200,000 levels deep made :func:`json.loads` raise ``RecursionError``
(not ``ValueError``), which crashed ``rbbench report`` and the resume of a run.

:func:`loads` raises ``ValueError`` instead, so every reader's "unreadable: ignored" path
takes such a file, and it refuses documents deeper than :data:`MAX_DEPTH`, so no reader
that walks a document recursively meets one it cannot walk.
"""

from __future__ import annotations

import json
from typing import Any

__all__ = ["MAX_DEPTH", "loads"]

#: Deepest nesting of lists and objects accepted (a case record is about 5 deep).
MAX_DEPTH = 100


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

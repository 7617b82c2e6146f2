"""pluggy hook specifications of rbbench.

A plugin package exposes, through the ``rbbench`` entry-point group, a module
(or object) that implements :func:`rbbench_register`. It declares its
components cheaply: name, role, import target, extras, capabilities. Nothing
heavy may be imported inside the hook.
"""

from __future__ import annotations

import pluggy

PROJECT = "rbbench"

hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)


@hookspec
def rbbench_register(registry):  # pragma: no cover - specification only
    """Declare components by calling ``registry.add(ComponentSpec(...))``."""

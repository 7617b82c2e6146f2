"""The start method of a snapshot pool: ``fork`` from the main thread only."""

from __future__ import annotations

import multiprocessing
import threading

import pytest

from rbbench.runtime.workers import start_method

fork_only = pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(),
                               reason="needs the fork start method")


def _in_thread(mp_context):
    out = []
    thread = threading.Thread(target=lambda: out.append(start_method(mp_context)))
    thread.start()
    thread.join(30)
    return out[0]


@fork_only
def test_fork_is_kept_in_the_main_thread_and_replaced_in_another():
    safe = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
    assert start_method("fork") == "fork"
    assert _in_thread("fork") == safe


def test_other_methods_and_the_default_pass_through():
    default = multiprocessing.get_start_method()
    assert start_method(None) == default
    for method in ("spawn", "forkserver"):
        if method in multiprocessing.get_all_start_methods():
            assert start_method(method) == method
            assert _in_thread(method) == method
    assert _in_thread(None) == (default if default != "fork" else _in_thread("fork"))

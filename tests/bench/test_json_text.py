"""JSON of a run directory: bounded depth and size, ``ValueError`` / ``OSError`` instead of
``RecursionError`` or an endless read."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rbbench.bench import json_text


def _nested(depth: int) -> str:
    return "[" * depth + "]" * depth


@given(st.recursive(st.none() | st.integers() | st.text(max_size=3),
                    lambda c: st.lists(c, max_size=3) | st.dictionaries(st.text(max_size=2),
                                                                        c, max_size=3),
                    max_leaves=30))
def test_depth_is_the_nesting_of_lists_and_dicts(obj):
    def brute(o):  # recursion is fine on these small documents
        if isinstance(o, dict):
            return 1 + max(map(brute, o.values()), default=0)
        if isinstance(o, list):
            return 1 + max(map(brute, o), default=0)
        return 0

    assert json_text.depth(obj) == brute(obj)
    assert json_text.loads(json.dumps(obj)) == obj


@pytest.mark.parametrize("depth", [json_text.MAX_DEPTH + 1, 900, 200_000])
def test_too_deep_is_a_value_error(depth):
    with pytest.raises(ValueError, match="nested"):
        json_text.loads(_nested(depth))


def test_the_deepest_accepted_document_loads():
    assert json_text.depth(json_text.loads(_nested(json_text.MAX_DEPTH))) == json_text.MAX_DEPTH


def test_read_text_refuses_what_is_not_a_regular_file(tmp_path):
    link = tmp_path / "x.json"
    link.symlink_to(Path("/dev/zero"))
    with pytest.raises(OSError, match="not a regular file"):
        json_text.read_text(link)
    with pytest.raises(IsADirectoryError):
        json_text.read_text(tmp_path)
    big = tmp_path / "big.json"
    with open(big, "wb") as fh:
        fh.truncate(json_text.MAX_BYTES + 1)  # sparse: no disk used
    with pytest.raises(OSError, match="more than"):
        json_text.read_text(big)

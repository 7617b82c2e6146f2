"""The files of a release beside the code: the licence, the citation and the typing marker.

``LICENSE`` is the BSD-3-Clause text pyproject.toml declares; ``CITATION.cff`` carries the
version by hand, so it is checked against ``rbbench.__version__``; ``py.typed`` is in the
package as installed and declared as package data (the wheel test of
``test_package_install.py`` checks that the built wheel ships both).
"""

from __future__ import annotations

import re
from importlib import resources
from pathlib import Path

import rbbench
from rbbench.scene.loading import tomllib

ROOT = Path(__file__).resolve().parents[2]
PYPROJECT = tomllib.loads((ROOT / "pyproject.toml").read_text())


def _cff_field(name: str) -> str:
    """The value of a top-level scalar ``name:`` of CITATION.cff (quotes stripped): read
    without a YAML parser, which is not a dependency."""
    text = (ROOT / "CITATION.cff").read_text()
    m = re.search(rf"^{re.escape(name)}:[ \t]*(.+?)[ \t]*$", text, re.M)
    assert m, f"CITATION.cff: no top-level {name!r}"
    return m.group(1).strip("\"'")


def test_license_is_the_declared_bsd_3_clause():
    assert PYPROJECT["project"]["license"] == {"text": "BSD-3-Clause"}
    text = (ROOT / "LICENSE").read_text()
    assert text.startswith("BSD 3-Clause License")
    assert "Copyright (c) 2026, the rbbench developers" in text
    assert "Neither the name of the copyright holder" in text  # clause 3


def test_citation_matches_the_package():
    assert _cff_field("cff-version") == "1.2.0"
    assert _cff_field("version") == rbbench.__version__
    assert _cff_field("license") == PYPROJECT["project"]["license"]["text"]
    text = (ROOT / "CITATION.cff").read_text()
    assert 'name: "The rbbench developers"' in text
    for title in ("Model order reduction methods: parametric variational inequalities",
                  "On coupling of complementarity with friction in contact shape optimization"):
        assert f'title: "{title}"' in text, title


def test_py_typed_is_installed_and_declared():
    assert resources.files("rbbench").joinpath("py.typed").is_file()
    assert "py.typed" in PYPROJECT["tool"]["setuptools"]["package-data"]["rbbench"]


def test_metadata_declares_authors_and_classifiers():
    project = PYPROJECT["project"]
    assert project["authors"] == [{"name": "The rbbench developers"}]
    classifiers = set(project["classifiers"])
    assert {"License :: OSI Approved :: BSD License",
            "Development Status :: 3 - Alpha"} <= classifiers
    supported = {c.rsplit(" :: ", 1)[1] for c in classifiers
                 if re.fullmatch(r"Programming Language :: Python :: 3\.\d+", c)}
    low = project["requires-python"].removeprefix(">=")
    assert min(supported, key=lambda v: tuple(map(int, v.split(".")))) == low

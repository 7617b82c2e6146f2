"""Sphinx configuration of the rbbench documentation.

Built with ``python -m sphinx -W -b html docs docs/_build/html`` (warnings are errors). The
pages are MyST Markdown; the examples, the validation and the performance pages are
sphinx-gallery scripts in ``examples/`` executed at build time, so every figure and table
on them comes from the code of this checkout (``RBBENCH_DOCS_FULL=1`` runs the validation
scripts at the published sizes: hours, not for CI).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))

import rbbench  # noqa: E402
import rbbench.plugin  # noqa: E402

project = "rbbench"
author = "the rbbench developers"
copyright = "the rbbench developers (BSD-3-Clause)"
version = release = rbbench.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.intersphinx",
    "sphinx.ext.mathjax",
    "sphinx-mathjax-offline",  # MathJax 3 copied into the build: no network when viewed
    "sphinx.ext.viewcode",
    "numpydoc",
    "sphinx_gallery.gen_gallery",
    "sphinx_copybutton",
    "sphinx_design",
    "rbbench_docs",
    "rbbench_xref",
]

source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
root_doc = "index"
exclude_patterns = ["_build", "_generated", "**/*.ipynb", "**/*.py.md5", "**/*.zip", "**/*.json",
                    "**/sg_execution_times.rst"]
templates_path = ["_templates"]

myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist", "fieldlist",
                          "substitution"]
myst_heading_anchors = 3
myst_dmath_double_inline = True

# -- API reference ------------------------------------------------------------------------
autosummary_generate = True
autodoc_default_options = {"members": True, "show-inheritance": False}
autodoc_typehints = "none"  # numpydoc's parameter lists say the types
numpydoc_show_class_members = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()
# a module gathering names defined elsewhere (template autosummary/public_names.rst) lists
# its __all__, each documented under the gathering module's path
autosummary_context = {"public_names": {"rbbench.plugin": rbbench.plugin.__all__}}

# no network at build time: intersphinx reads nothing remote (the mapping stays empty)
intersphinx_mapping: dict[str, tuple[str, str | None]] = {}

# -- executed examples --------------------------------------------------------------------
sphinx_gallery_conf = {
    "examples_dirs": ["../examples/getting_started", "../examples/gallery",
                      "../examples/validation", "../examples/performance"],
    "gallery_dirs": ["getting_started", "auto_examples", "validation", "performance"],
    "filename_pattern": r"/(plot|run)_",
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "abort_on_example_error": True,
    "only_warn_on_example_error": False,
    "matplotlib_animations": False,
    "image_scrapers": ("matplotlib",),
    "capture_repr": ("_repr_html_", "__repr__"),
    "min_reported_time": 1,
    "show_memory": False,
    "show_signature": False,
    "reset_modules": ("matplotlib",),
    # RBBENCH_DOCS_PLOT=False: pages only, the examples not run (a quick check of the text)
    "plot_gallery": os.environ.get("RBBENCH_DOCS_PLOT", "True"),
}

# -- HTML -----------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"rbbench {release}"
html_static_path = ["_static"]
html_css_files = ["rbbench.css"]
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "secondary_sidebar_items": ["page-toc"],
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_show_sourcelink = False
html_last_updated_fmt = None

# the docs build runs the examples with one BLAS thread and writes their files under the
# build directory, never into the checkout
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("MKL_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

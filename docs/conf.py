"""Sphinx configuration of pointax's documentation site (built by scripts/docs.sh).

Sphinx with the furo theme: autodoc + napoleon read the docstrings (Google style),
myst-parser the Markdown pages (the guides, docs/layout.md, the help texts in
pointax/data/help/), sphinx-gallery runs the examples (docs/gallery/*.py, which run
examples/*.py, cut to a smaller size where they are slow: POINTAX_DOCS_QUICK) and
embeds their output and figures. docs/_ext/pointax_docs.py writes the generated pages
(the API reference from ``pointax.__all__``, the command options from the parser,
the conventions figure) before the build reads them.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
REPO = DOCS.parent
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(DOCS / "_ext"))
os.environ.setdefault("MPLBACKEND", "Agg")
os.environ.setdefault("POINTAX_DOCS_QUICK", "1")  # examples at their build-time size
os.environ.setdefault("POINTAX_JAX_CACHE", "")
# XLA's quicker-compiling CPU options, as the test suite uses (the examples compile a lot).
os.environ["XLA_FLAGS"] = (os.environ.get("XLA_FLAGS", "") + " --xla_cpu_use_fusion_emitters=false --xla_backend_optimization_level=2").strip()

import pointax  # noqa: E402

project = "pointax"
author = "the pointax authors"
copyright = "the pointax authors, MIT licence"
release = version = pointax.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "myst_parser",
    "sphinx_copybutton",
    "sphinx_gallery.gen_gallery",
    "pointax_docs",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "_generated", "**/GALLERY_HEADER.rst", "Thumbs.db", ".DS_Store"]
root_doc = "index"

# Markdown: $...$ maths, ::: fences, definition lists, heading anchors for links.
myst_enable_extensions = ["colon_fence", "deflist", "dollarmath"]
myst_heading_anchors = 3

# The docstrings: Google style; members in source order; type hints in the description.
napoleon_google_docstring = True
napoleon_numpy_docstring = False
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_mock_imports: list[str] = []
add_module_names = False

html_theme = "furo"
html_title = f"pointax {release}"
html_static_path: list[str] = []
html_theme_options = {"navigation_with_keys": True}

sphinx_gallery_conf = {
    "examples_dirs": "gallery",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "ignore_pattern": r"(__init__|_load)\.py",
    "within_subsection_order": "FileNameSortKey",
    "download_all_examples": False,
    "remove_config_comments": True,
    "capture_repr": (),
    "image_scrapers": ("matplotlib",),
    "run_stale_examples": False,
    "show_memory": False,
    "min_reported_time": 1,
    "write_computation_times": False,  # its pages need jQuery, which the theme no longer loads
    "plot_gallery": "True",
    "abort_on_example_error": True,
}

# A warning is an error (scripts/docs.sh passes -W), but one: the commands' page
# (docs/_generated/cli_page.md) is included under docs/cli.md's title, so its headings
# start at level 2, which MyST notes.
suppress_warnings = ["myst.header"]
nitpicky = False

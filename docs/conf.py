"""Sphinx configuration of the mi-npr documentation (``make docs``).

The build imports :mod:`mi_npr` (the API reference and the CLI reference read the code), so it
runs with the project's environment: ``make docs``, i.e. ``.venv/bin/sphinx-build -E -W
--keep-going -b html docs docs/_build/html``. Nothing is fetched from the network (no
intersphinx).
"""

from __future__ import annotations

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "_ext"))

import mi_npr  # noqa: E402  (after sys.path; picks LLVM and the variant like any user)

project = "mi-npr"
author = "the mi-npr authors"
copyright = "the mi-npr authors, BSD-3-Clause"
version = release = mi_npr.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.viewcode",
    "myst_parser",  # the guide pages are Markdown (MyST), the API pages reStructuredText
    "cli_reference",  # docs/_ext: the mi-npr command's flags, read from build_parser()
    "bench_tables",  # docs/_ext: tables from benchmarks/results/*.json
]

root_doc = "index"
# Flags are text here too (in the generated CLI tables): "--lines" must not become an en dash.
smartquotes = False
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
# Links to headings of other pages: [text](lines.md#width-rule).
myst_heading_anchors = 3
exclude_patterns = ["_build"]
templates_path: list[str] = []

# The API pages document what each module exports (``__all__``) or defines; keep the source
# order, which is the order the docstrings explain things in.
autodoc_default_options = {"members": True, "member-order": "bysource"}
autodoc_typehints = "description"
autodoc_class_signature = "separated"
napoleon_google_docstring = True
napoleon_numpy_docstring = True

html_theme = "alabaster"
html_title = f"mi-npr {release}"
html_static_path: list[str] = []
html_theme_options = {
    "description": "Non-photorealistic rendering for Mitsuba 3",
    "fixed_sidebar": True,
    "page_width": "1180px",
    "sidebar_width": "240px",
}
html_sidebars = {"**": ["about.html", "navigation.html", "searchbox.html"]}

# Benchmarks: where the JSON results are (bench_tables reads them at build time).
bench_results_dir = str(DOCS.parent / "benchmarks" / "results")

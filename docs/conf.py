"""Sphinx configuration of the inscal documentation site (``make docs``).

The build is offline and strict: ``-W`` turns every warning into an error and ``-n`` (``nitpicky``)
checks every cross-reference.  References into inscal must resolve; references to other projects
(NumPy, SciPy, h5py, ...) are not checked, since no inventory of theirs is fetched.
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

import inscal
from inscal import SCHEMA_VERSION
from inscal.io.paramfile import PARAM_SCHEMA_VERSION
from inscal.lab.opening import head_revision, revision_number

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "_ext"))

project = "inscal"
author = "the inscal authors"
copyright = "the inscal authors, MIT licence"
release = inscal.__version__
logging.getLogger("alembic").setLevel(logging.WARNING)  # the database module's migrations, imported by autodoc
version = inscal.__version__

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.viewcode",
    "sphinx.ext.mathjax",
    "sphinx_gallery.gen_gallery",
    "inscal_docs",  # docs/_ext: the equation index, the API and CLI coverage checks
    "inscal_site",  # docs/_ext: MathJax served from the site (typeset offline) and checked in Chromium
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "**/README.rst", "sg_execution_times.rst", "examples/README.txt",
                    "reference/generated"]  # tables written by _ext/inscal_docs.py, included by formats.md
templates_path: list[str] = []

# --- MyST: Markdown pages with math, fenced directives and definition lists
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist", "substitution"]
# version numbers the pages state, read from the code ({{ db_schema }} in a page)
myst_substitutions = {"db_schema": revision_number(head_revision()), "record_schema": SCHEMA_VERSION,
                      "param_schema": PARAM_SCHEMA_VERSION}
myst_heading_anchors = 3

# --- strict cross-references: everything of inscal must resolve; other projects' names are not checked
nitpicky = True
nitpick_ignore_regex = [
    (r"py:.*", r"(?!inscal\b).*"),  # numpy.ndarray, pathlib.Path, typing.Any, ... (no inventory offline)
    (r"py:.*", r"inscal\..*\._[A-Za-z].*"),  # private names in a signature's annotations
    (r"py:.*", r"inscal\.cli\..*"),  # the command line's modules: internals, not in the API reference
]

# --- the API reference: one page per module (docs/reference/api/, written by _ext/inscal_docs.py)
# undocumented members too: a public function without a docstring is still listed (tests/test_docstrings.py
# keeps the list of those from growing)
autodoc_default_options = {"members": True, "undoc-members": True, "show-inheritance": True,
                           "member-order": "bysource"}
autodoc_typehints = "signature"
autodoc_preserve_defaults = True
autoclass_content = "class"
napoleon_numpy_docstring = True
napoleon_google_docstring = False
add_module_names = False
python_use_unqualified_type_names = True

# --- executed examples (docs/examples/*.py -> docs/auto_examples/): run as the site builds, kept
# until the script changes (sphinx-gallery compares each script's checksum)
sphinx_gallery_conf = {
    "examples_dirs": ["examples"],
    "gallery_dirs": ["auto_examples"],
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "abort_on_example_error": True,
    "run_stale_examples": False,
    "within_subsection_order": "FileNameSortKey",
    "reset_modules": ("matplotlib",),
    "image_scrapers": ("matplotlib",),
    "min_reported_time": 1,
    "show_memory": False,
    "backreferences_dir": None,
}

# --- HTML
html_theme = "furo"
html_title = f"inscal {release}"
html_static_path = ["_static"]
html_css_files = ["inscal.css"]
html_show_sourcelink = False
html_theme_options = {
    "source_repository": "",
    "navigation_with_keys": True,
}

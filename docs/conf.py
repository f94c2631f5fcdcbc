"""Sphinx configuration of the stageid documentation.

The API pages are generated from each package's ``__all__`` and the CLI page from the click
commands, so neither can drift from the code.  ``STAGEID_DOCS_FAST=1`` runs a subset of the
gallery (the CI mode); ``make docs`` runs it all.
"""

from __future__ import annotations

import importlib
import os
import re
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "src"))
sys.path.insert(0, str(HERE / "_ext"))

import stageid  # noqa: E402

project = "stageid"
author = "the stageid authors"
copyright = "the stageid authors, MIT license"  # noqa: A001
release = stageid.__version__
version = release

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.doctest",
    "sphinx.ext.mathjax",
    "numpydoc",
    "myst_parser",
    "sphinx_click",
    "sphinx_gallery.gen_gallery",
    "api_pages",
    "short_refs",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "examples/README.txt", "auto_examples/*.ipynb", "auto_examples/*.py", "**.zip"]
templates_path = ["_templates"]
nitpicky = True

# --- API reference --------------------------------------------------------------------------------
autosummary_generate = True
autosummary_imported_members = True
autodoc_typehints = "none"  # numpydoc's Parameters sections carry the types, with shapes
autodoc_default_options = {"members": False}
numpydoc_show_class_members = False  # the class template lists them with :members:
numpydoc_show_inherited_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
numpydoc_validation_checks: set[str] = set()

# Names outside stageid that docstrings mention but this offline build cannot link to (no
# intersphinx inventories are fetched): the targets are numpy, scipy, matplotlib, python-control,
# click, dask and the standard library.
nitpick_ignore_regex = [
    (r"py:.*", r"(numpy|np|scipy|matplotlib|control|ct|click|dask|distributed|zarr|h5py|pathlib|os|io|typing)\..*"),
    (r"py:.*", r"(collections\.abc|concurrent|threading|enum|dataclasses|json|numbers)\..*"),
]

# --- prose ------------------------------------------------------------------------------------------
myst_enable_extensions = ["colon_fence", "deflist", "dollarmath"]
myst_heading_anchors = 3

# --- gallery ----------------------------------------------------------------------------------------
FAST = os.environ.get("STAGEID_DOCS_FAST", "") not in ("", "0")
sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "auto_examples",
    "filename_pattern": r"/plot_",
    "ignore_pattern": r"/_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "image_scrapers": ("figure_scraper",),
    "matplotlib_animations": False,
    "show_memory": False,
    "abort_on_example_error": True,
    "only_warn_on_example_error": False,
    "min_reported_time": 1,
    "capture_repr": (),  # printed output only, not the value of a last expression
}
if FAST:
    # CI: the quick examples only; the others are listed but not executed
    sphinx_gallery_conf["filename_pattern"] = r"/plot_(01|02|03|11|12)_"

# --- HTML ------------------------------------------------------------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"stageid {release}"
html_static_path = ["_static"]
html_css_files = ["stageid.css"]
html_theme_options = {
    "navigation_with_keys": False,
    "show_toc_level": 2,
    "header_links_before_dropdown": 7,
    "footer_start": ["copyright"],
    "footer_end": [],
    "secondary_sidebar_items": ["page-toc"],
}
html_sidebars = {"index": [], "matlab": [], "getting-started": [], "cli": [], "**": ["sidebar-nav-bs"]}
html_context = {"default_mode": "auto"}  # without it a first visit logs "invalid theme mode" as an error
html_show_sourcelink = False
html_copy_source = False

# --- doctest --------------------------------------------------------------------------------------
doctest_test_doctest_blocks = ""  # docstring examples run in tests/test_docstring_examples.py, in their module
doctest_global_setup = """
import numpy as np
"""

# --- the generated API pages ----------------------------------------------------------------------
API_PACKAGES = [
    ("stageid", "errors and warnings shared by every sub-package"),
    ("stageid.data", "records: the Experiment container, readers, writers, preprocessing"),
    ("stageid.signals", "excitation signals"),
    ("stageid.models", "LTI models, conversions, the stageid.lti/1 format"),
    ("stageid.subspace", "Hankel-Toeplitz regression, recursive MAP, realisation"),
    ("stageid.closedloop", "closed-loop identification of unstable plants"),
    ("stageid.frf", "frequency-response measurement and FRF fitting"),
    ("stageid.hysteresis", "Prandtl-Ishlinskii, Preisach and stage models, inverses"),
    ("stageid.validation", "fit metrics and residual tests"),
    ("stageid.plots", "figures"),
    ("stageid.report", "HTML reports"),
    ("stageid.display", "notebook display: a short repr and an HTML table with an inline figure"),
    ("stageid.export", "C99 and MATLAB export"),
    ("stageid.batch", "many commands on a Dask cluster"),
    ("stageid.plants", "the reference stages of the papers"),
    ("stageid.demo", "the three workflows on the reference stages"),
    ("stageid.base", "the estimator contract"),
    ("stageid.atomic", "atomic file writes and transactions"),
]


def public_names(package: str) -> list[str]:
    """The names a package exports (its ``__all__``), documented one page each."""
    module = importlib.import_module(package)
    return [name for name in getattr(module, "__all__", []) if not name.startswith("__")]


api_packages = API_PACKAGES
api_public_names = public_names


def escape_help_underscores(app, ctx, lines) -> None:
    """Option help such as ``re_/im_<out>_<in>`` is plain text to click; to reST ``re_`` is a link."""
    for i, line in enumerate(lines):
        lines[i] = re.sub(r"(?<=[a-z])_(?=[/<,)])", r"\\_", line)


def setup(app):
    app.connect("sphinx-click-process-options", escape_help_underscores)
    app.connect("sphinx-click-process-description", escape_help_underscores)

"""Sphinx configuration of the workbench documentation (``make docs``).

Why this stack: Sphinx with numpydoc, sphinx-gallery and the pydata theme is scikit-learn's,
and the workbench's docstrings follow scikit-learn's numpydoc layout, so autodoc renders them
as its users know them; sphinx-gallery runs the examples at build time (a stale example fails
the build); MyST lets the user guide stay Markdown (the README it came from). Material for
MkDocs with mkdocstrings (MAPIE's newer stack) renders numpydoc less faithfully and its gallery
plug-in is younger.

The build is offline: no intersphinx inventory, no web font (the pydata theme ships its
fonts and icons), no CDN script except MathJax, which the browser (not the build) loads for
the formulas. The config and CLI references are generated at build time from the typed
schemas and the argparse parser (``_ext/configref.py``, ``_ext/cliref.py``).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
# The checkout's package, not an installed copy (a worktree's docs document its own code).
sys.path.insert(0, str(HERE.parent))
os.environ.setdefault("MLFLOW_DISABLE_TELEMETRY", "true")

import workbench  # noqa: E402

project = "workbench"
author = "workbench contributors"
copyright = "2026, workbench contributors"
release = version = workbench.__version__

extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.mathjax",
    "sphinx.ext.viewcode",
    "numpydoc",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
    "configref",
    "cliref",
]

source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
exclude_patterns = ["_build", "README.md", "examples/README.txt", "**/GALLERY_HEADER.rst"]
templates_path = ["_templates"]
root_doc = "index"

# --- API reference: autosummary pages from the numpydoc docstrings ---------------------------
autosummary_generate = True
autosummary_imported_members = True
autosummary_ignore_module_all = False  # a module page lists its __all__, nothing else
autodoc_default_options = {"members": True, "inherited-members": False}
autodoc_typehints = "none"  # numpydoc's Parameters sections carry the types
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False

# --- MyST ----------------------------------------------------------------------------------
myst_enable_extensions = ["dollarmath", "amsmath", "colon_fence", "deflist"]
myst_heading_anchors = 3

# --- the gallery: examples run at build time (``-D plot_gallery=0`` skips running them) -----
sphinx_gallery_conf = {
    "examples_dirs": ["examples"],
    "gallery_dirs": ["auto_examples"],
    "filename_pattern": r"/plot_",
    "download_all_examples": False,
    "remove_config_comments": True,
    "within_subsection_order": "FileNameSortKey",
    "reset_modules": ("matplotlib",),
    "show_memory": False,
    "min_reported_time": 1e9,  # no timings in the pages: they would change on every build
    "write_computation_times": False,
}

# --- HTML: pydata theme, nothing fetched from the web -----------------------------------------
html_theme = "pydata_sphinx_theme"
html_title = f"workbench {version}"
html_static_path: list[str] = []
html_theme_options = {
    "navbar_align": "left",
    "show_toc_level": 2,
    "navigation_with_keys": False,
    "icon_links": [],
    "use_edit_page_button": False,
    "check_switcher": False,
    "footer_start": ["copyright"],
    "footer_end": ["sphinx-version"],
}
html_show_sourcelink = False
html_last_updated_fmt = None


def _skip_member(app, what, name, obj, skip, options):  # noqa: ANN001, ANN202 (Sphinx hook)
    # scikit-learn's metadata-routing setters (set_fit_request, ...): its docstrings link
    # into scikit-learn's own glossary, and they are not the workbench's API.
    if name.startswith("set_") and name.endswith("_request"):
        return True
    return skip


def setup(app):  # noqa: ANN001, ANN201 (Sphinx hook)
    """Leave scikit-learn's metadata-routing setters out of the API pages."""
    app.connect("autodoc-skip-member", _skip_member)

"""Sphinx configuration of the documentation site (``.ci/docs``: built with -W, no warnings).

The user guide and the notes are Markdown pages (MyST), the API reference is generated from the docstrings
(``api/``), and the gallery is ``examples/*.py``, each script executed by sphinx-gallery at every build, its
output rendered below its code, so no example can go stale (a failing example fails the build)."""

import re
from pathlib import Path

project = "exo-bench"
author = "exo-bench"
extensions = [
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "myst_parser",
    "sphinx_gallery.gen_gallery",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
autosummary_generate = True
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True, "ignore-module-all": True}
autodoc_typehints = "description"
autodoc_member_order = "bysource"
napoleon_google_docstring = False
napoleon_numpy_docstring = False
default_role = "literal"
html_theme = "alabaster"
exclude_patterns = ["_build", "examples"]  # the gallery reads examples/ itself
templates_path = ["_templates"]
# Headings get anchors, so the pages' [text](#section) links resolve.
myst_heading_anchors = 3
myst_enable_extensions = ["dollarmath"]
sphinx_gallery_conf = {
    "examples_dirs": "examples",
    "gallery_dirs": "gallery",
    "filename_pattern": r".*\.py$",  # execute every example, not only plot_*.py
    "abort_on_example_error": True,
    "download_all_examples": False,
    "show_memory": False,
    "show_signature": False,
    "min_reported_time": 1e9,  # no per-example timing lines in the pages (sg_execution_times has them)
}

# A Markdown page's link to a Markdown file outside docs/ (a report, the README) would be read as a page of
# this site, which it is not: it becomes a download of that file, so a link to a file that does not exist still
# fails the build ("download file not readable"), and the page stays as it is for GitHub.
_OUTSIDE_MD = re.compile(r"\]\(((?:\.\./)+[^)#\s]+\.md)(?:#[^)\s]*)?\)")


def _outside_links_as_downloads(app, docname, source):
    """``source-read``: rewrite the links of ``docname`` to Markdown files outside the source folder."""
    folder = Path(app.env.doc2path(docname)).parent
    srcdir = Path(app.srcdir).resolve()

    def download(m: re.Match) -> str:
        target = (folder / m.group(1)).resolve()
        return f"](path:{m.group(1)})" if not target.is_relative_to(srcdir) else m.group(0)

    source[0] = _OUTSIDE_MD.sub(download, source[0])


def setup(app):
    app.connect("source-read", _outside_links_as_downloads)

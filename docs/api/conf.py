"""Sphinx configuration of the API reference, built from the docstrings (``.ci/docs``: no warnings)."""

project = "exo-bench"
author = "exo-bench"
extensions = ["sphinx.ext.autodoc", "sphinx.ext.autosummary", "sphinx.ext.napoleon"]
autosummary_generate = True
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": True, "ignore-module-all": True}
autodoc_typehints = "description"
autodoc_member_order = "bysource"
napoleon_google_docstring = False
napoleon_numpy_docstring = False
default_role = "literal"
html_theme = "alabaster"
exclude_patterns = ["_build"]
templates_path = ["_templates"]

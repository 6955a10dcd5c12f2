"""Sphinx configuration of akd_ros's documentation site (scripts/docs.sh builds it; scripts/test.sh builds it with
warnings as errors). Pages are MyST Markdown; the reference of parameters, topics, services and messages and the tools'
help are generated from the code at each build (`_ext/akd_reference.py`), the Python API from its docstrings."""

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
sys.path.insert(0, str(DOCS / "_ext"))

project = "akd_ros"
author = "the akd_ros authors"
copyright = "2026, the akd_ros authors"  # noqa: A001 (Sphinx reads this name)

extensions = ["myst_parser", "sphinx.ext.autodoc", "akd_reference"]
source_suffix = {".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "_generated/*.md"]
# Links in pages to a heading of another page ([text](page.md#a-heading)) are checked too.
myst_heading_anchors = 3
# A code block's marks for the tests (tests/support/docs_pages.py) follow its language in the fence's info string,
# which MyST, like GitHub, does not show; no block attribute syntax, which GitHub would show as text.
myst_enable_extensions = ["colon_fence"]
# Broken references fail the build (-W); the crate's rustdoc is copied beside the pages by scripts/docs.sh.
nitpicky = False
suppress_warnings = []

autodoc_member_order = "bysource"
autodoc_typehints = "none"
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": False}

html_theme = "furo"
html_title = "akd_ros"
html_static_path = ["_static"]
html_css_files = ["akd.css"]

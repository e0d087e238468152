"""Sphinx configuration: the guides (Markdown, MyST) and the API reference (autodoc + numpydoc).

Build: ``pip install '.[docs]' && python -m sphinx -W --keep-going -b html docs docs/_build/html``
(``.ci/run`` builds it so, warnings as errors).
"""

from __future__ import annotations

import ottag_db

project = "ottag-db"
author = "ottag-db developers"
release = version = ottag_db.__version__

extensions = [
    "myst_parser",  # the guides are Markdown, as the README
    "sphinx.ext.autodoc",
    "numpydoc",  # the package's docstrings are numpydoc (Parameters / Returns / Raises)
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
exclude_patterns = ["_build", "img/*.txt"]
myst_heading_anchors = 3

# numpydoc: one page per module, no autosummary tables of class members (they would need stub pages)
numpydoc_show_class_members = False
numpydoc_class_members_toctree = False
numpydoc_xref_param_type = False
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": False}
autodoc_member_order = "bysource"
autodoc_typehints = "none"  # the numpydoc sections give the types

html_theme = "furo"
html_title = f"ottag-db {release}"
html_static_path: list[str] = []

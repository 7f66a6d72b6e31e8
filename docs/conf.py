"""Sphinx configuration of the mmlearn documentation (MyST markdown, API by autodoc).

Build: ``pip install -e '.[docs]' && python -m sphinx -W -b html docs build/docs``.
"""

import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "_ext"))
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

project = "mmlearn"
author = "the mmlearn authors"
copyright = "mmlearn authors; BSD-3-Clause"
release = "0.1.0"

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "mmlearn_docs",
]
source_suffix = {".rst": "restructuredtext", ".md": "markdown"}
root_doc = "index"
# results/tables/*.md are fragments included by the capability pages; images/ holds pictures
exclude_patterns = ["_build", "results/tables/*", "images/*", "_ext/*", "README.md"]

myst_enable_extensions = ["colon_fence", "dollarmath"]
myst_heading_anchors = 3

autodoc_default_options = {"members": True, "show-inheritance": False}
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_format = "short"
autodoc_preserve_defaults = True

try:
    import furo  # noqa: F401
    html_theme = "furo"
except ImportError:
    html_theme = "alabaster"
html_title = "mmlearn"

# Google-style docstrings ("Args:", "Attributes:", ...) and the sections the systems use
napoleon_google_docstring = True
napoleon_numpy_docstring = False
napoleon_use_ivar = True
napoleon_custom_sections = [("Outputs", "params_style"), ("Inputs", "params_style"),
                            ("Input ports", "params_style"), ("Output ports", "params_style"),
                            ("Ports", "params_style"), ("State", "params_style"),
                            ("Fields", "params_style"), ("Columns", "params_style")]

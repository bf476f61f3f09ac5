"""Sphinx configuration of planarcal's documentation site.

Build it strictly and offline (a broken link or reference fails; nothing is fetched):
``python -m sphinx -W -n --keep-going -b html docs /tmp/planarcal-site``.
"""

import importlib
import sys
from pathlib import Path

import planarcal

DOCS = Path(__file__).resolve().parent

project = "planarcal"
author = "the planarcal authors"
copyright = "planarcal's authors"
version = release = planarcal.__version__
html_title = "planarcal"
html_theme = "furo"

source_suffix = {".md": "markdown"}
# _build is where a local build goes; docs/*.py besides conf.py are the scripts that draw
# docs/images, not pages.
exclude_patterns = ["_build", "_ext", "**/.ipynb_checkpoints"]

# Local extensions: every module in docs/_ext with a setup() is loaded, so a helper adds one
# by adding its file.
sys.path.insert(0, str(DOCS / "_ext"))
_LOCAL_EXTENSIONS = sorted(
    path.stem
    for path in (DOCS / "_ext").glob("*.py")
    if hasattr(importlib.import_module(path.stem), "setup")
)

extensions = [
    "myst_parser",
    "sphinx.ext.autodoc",
    *_LOCAL_EXTENSIONS,
]

# Pages are Markdown: ## headings get anchors (page.md#a-heading), ::: fences hold directives.
myst_heading_anchors = 3
myst_enable_extensions = ["colon_fence", "deflist"]

# The API reference: members in the source's order, type hints shown once, in the
# description, where they read as prose (the signatures stay short).
autodoc_member_order = "bysource"
autodoc_typehints = "description"
autodoc_typehints_format = "short"
# numpy's ArrayLike by its name, not the union of a dozen protocols it stands for.
autodoc_type_aliases = {"ArrayLike": "numpy.typing.ArrayLike"}
# A constant's value is left out: some are long tables (the synthetic corpora).
autodoc_default_options = {"members": True, "no-value": True}

# Strict: every cross-reference must resolve (-n), except to the libraries whose own
# documentation is not linked (no intersphinx: the build fetches nothing).
nitpicky = True
nitpick_ignore_regex = [
    (r"py:.*", r"(numpy|np|npt|cv2|scipy|matplotlib|starlette|uvicorn)(\..*)?"),
    (r"py:.*", r"(NDArray|ArrayLike|DTypeLike|MatLike)(\[.*\])?"),
    # The standard library's types.
    (r"py:.*", r"(collections\.abc|os|pathlib|typing|types)\..*"),
    # Private names (planarcal._core, a _Base class): not part of the documented API.
    (r"py:.*", r"(.*\.)?_[A-Za-z]\w*(\..*)?"),
    # planarcal's alias of NDArray[np.float64], named as such where hints stay unevaluated.
    ("py:class", "F64"),
]

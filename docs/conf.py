"""Sphinx configuration of the documentation site (``sphinx-build -W --keep-going -b html docs docs/_build/html``).

The pages stay Markdown (MyST), so they read on GitHub as they do in the site. Section titles become anchors
(``myst_heading_anchors``), so a link to ``page.md#a-title`` is checked at build time, and the build runs with
warnings as errors: a broken link, a missing anchor or an unknown page fails it.
"""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the API pages document the checkout being built, installed or not

from vesicle_core import __version__  # noqa: E402

project = "vesicle-wrinkling"
author = "vesicle-wrinkling maintainers"
release = __version__
extensions = [
    "myst_nb",  # Markdown (MyST) pages and the quickstart notebook
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "sphinx.ext.napoleon",
    "sphinx.ext.mathjax",
    "sphinxarg.ext",  # the CLI reference from the argument parser itself
]
source_suffix = {".md": "myst-nb", ".ipynb": "myst-nb"}
myst_enable_extensions = ["dollarmath", "colon_fence", "deflist"]
myst_heading_anchors = 4
# the tutorial notebook needs the tiny workflow's results; CI executes it on them (.ci/run), the site shows its code
nb_execution_mode = "off"
# validation_morphology.md is a section of validation.md (included there), not a page of its own
exclude_patterns = ["_build", "README.md", "**/.ipynb_checkpoints", "validation_morphology.md"]
autosummary_generate = True
autodoc_default_options = {"members": True}
autodoc_typehints = "description"
html_theme = "furo"
html_title = "vesicle-wrinkling"
nitpicky = False

"""Sphinx configuration of the documentation site.

Build it from the repository root with ``python -m sphinx -W -b html docs docs/_build/html``
(warnings are errors; CI runs exactly that). The Markdown pages are read by MyST, the notebooks
are shown with the outputs stored in them (never executed here), the API reference is generated
from the numpy-style docstrings (autosummary, autodoc, napoleon) and the command-line reference
from the argument parsers (``_ext/clihelp.py``).
"""

from __future__ import annotations

import sys
from pathlib import Path

DOCS = Path(__file__).resolve().parent
ROOT = DOCS.parent
sys.path[:0] = [str(ROOT), str(DOCS / "_ext")]

from labrig import __version__  # noqa: E402

project = "nanodisorder"
author = "the nanodisorder authors"
copyright = "the nanodisorder authors, MIT licence"
release = version = __version__

extensions = [
    "myst_nb",                  # Markdown pages (MyST) and the notebooks with their stored outputs
    "sphinx.ext.autodoc",
    "sphinx.ext.autosummary",
    "numpystyle",               # the numpy-style docstrings: napoleon, constants left as prose
    "clihelp",                  # the command-line reference, from the argument parsers
    "sitepages",                # the pages' links to repository files, as the site has them
]

source_suffix = {".rst": "restructuredtext", ".md": "myst-nb", ".ipynb": "myst-nb"}
root_doc = "index"
templates_path = ["_templates"]
exclude_patterns = ["_build", "**/.ipynb_checkpoints", "Thumbs.db", ".DS_Store"]

# --- MyST ---------------------------------------------------------------------------------------
# GitHub-style anchors for headings down to level 4: the pages link to each other's sections
# (guide.md#notebooks, reproduction.md#engines) as they do when read on the forge.
myst_heading_anchors = 4
# attrs_block: the reports' section anchors become heading ids (``_ext/sitepages.py``).
myst_enable_extensions = ["attrs_block", "colon_fence"]

# --- notebooks (myst-nb) -----------------------------------------------------------------------
nb_execution_mode = "off"       # shown with their stored outputs: several take minutes to run
nb_merge_streams = True
nb_ipywidgets_js = {}           # no widget scripts from the network: stored widgets (progress bars) are not drawn

# --- API reference --------------------------------------------------------------------------------
autosummary_generate = True
autosummary_ignore_module_all = True   # each object is documented once, in the module that defines it
autodoc_default_options = {"ignore-module-all": True}
autodoc_member_order = "bysource"
autodoc_typehints = "signature"
# In the docstrings `name` is an object of the code: a link where it is documented, code where not.
default_role = "py:obj"
# The packages' ``__main__`` modules run the command line when imported: autosummary's module walk
# would import them, so they are mocked (their content is the CLI, documented from its parsers).
autodoc_mock_imports = ["qdots.__main__", "planarize.__main__",
                        # the napari plugin's Qt and napari imports: its pages build without the napari extra
                        "qtpy", "napari"]
napoleon_google_docstring = False
napoleon_numpy_docstring = True
napoleon_use_ivar = True        # "Attributes" sections as fields, not second descriptions of the members

# --- HTML ---------------------------------------------------------------------------------------
html_theme = "furo"
html_title = f"nanodisorder {release}"


def copy_notebooks() -> None:
    """Put the notebooks beside the pages, in ``docs/notebooks/`` (not kept in git).

    Sphinx reads pages only under ``docs/``. The copies are written only when their text changed (a
    rebuild stays incremental), and their links to ``../docs/PAGE.md`` point at the same pages
    from their new place; a copy whose notebook is gone is removed.
    """
    source, target = ROOT / "notebooks", DOCS / "notebooks"
    target.mkdir(exist_ok=True)
    names = set()
    for notebook in sorted(source.glob("*.ipynb")):
        names.add(notebook.name)
        text = notebook.read_text(encoding="utf-8").replace("](../docs/", "](../")
        copy = target / notebook.name
        if not copy.exists() or copy.read_text(encoding="utf-8") != text:
            copy.write_text(text, encoding="utf-8")
    for stale in target.glob("*.ipynb"):
        if stale.name not in names:
            stale.unlink()


copy_notebooks()

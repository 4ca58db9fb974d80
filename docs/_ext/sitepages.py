"""Read the Markdown pages of ``docs/`` as the site needs them, without changing the files.

The pages are also read on the forge, where their links go to files of the repository. In the
site, a link to ``../notebooks/NAME.ipynb`` goes to the notebook's page (``notebooks/NAME``, the
copy that ``conf.py`` makes) and one to ``../README.md`` to the landing page. The generated
reports (``python -m reproduce``, ``python -m benchmarks``) mark their sections with HTML anchors,
``<a id="KEY"></a>`` before a heading, and link to them as ``#KEY``: the site gives the heading
that id instead (MyST's ``{#KEY}`` attribute), so that the links resolve and Sphinx checks them.
"""

from __future__ import annotations

import re

#: Links of the top-level pages to repository files outside ``docs/``, and where they go in the site.
LINKS = [(re.compile(r"\]\(\.\./notebooks/([\w.-]+\.ipynb)\)"), r"](notebooks/\1)"),
         (re.compile(r"\]\(\.\./README\.md\)"), "](index.md)")]
ANCHOR = re.compile(r'^<a id="([\w.-]+)"></a>$', re.MULTILINE)


def site_text(text: str) -> str:
    """The Markdown of a top-level page as the site reads it (see the module's docstring)."""
    for pattern, replacement in LINKS:
        text = pattern.sub(replacement, text)
    return ANCHOR.sub(r"{#\1}", text)


def rewrite(app, docname: str, source: list[str]) -> None:
    """``source-read``: `site_text` for the Markdown pages directly in ``docs/``."""
    if "/" not in docname and str(app.env.doc2path(docname)).endswith(".md"):
        source[0] = site_text(source[0])


def setup(app):
    app.connect("source-read", rewrite)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}

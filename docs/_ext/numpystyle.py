"""Napoleon for the numpy-style docstrings, except on constants, attributes and properties.

Napoleon reads the first line of a constant's, attribute's or property's docstring as
``type: description``. In this project those docstrings (the ``#:`` comments above module
constants, the properties' one-liners) are prose in which a colon is punctuation ("Settings the
forces read: changing one empties their caches"): they are left as written, plain reStructuredText.
Functions, classes and methods go through napoleon as usual.
"""

from __future__ import annotations

from sphinx.ext import napoleon

#: Objects whose docstring stays as written.
PROSE = ("data", "attribute", "property")


def process_docstring(app, what, name, obj, options, lines) -> None:
    """``autodoc-process-docstring``: napoleon's, for everything but `PROSE`."""
    if what not in PROSE:
        napoleon._process_docstring(app, what, name, obj, options, lines)


def setup(app):
    app.setup_extension("sphinx.ext.napoleon")
    for listener in list(app.events.listeners["autodoc-process-docstring"]):
        if listener.handler is napoleon._process_docstring:
            app.disconnect(listener.id)
    app.connect("autodoc-process-docstring", process_docstring)
    return {"version": "1", "parallel_read_safe": True, "parallel_write_safe": True}

"""Notebook widgets on matplotlib: ipympl canvases without pyplot state, and a clear error without them.

The widgets extra (ipywidgets, ipympl) is optional; `require_widgets` imports it or says how to
install it.
"""

from __future__ import annotations

import warnings

from matplotlib.figure import Figure


def require_widgets(what: str = "this widget"):
    """Import ipywidgets and ipympl, or raise an ImportError that names the ``widgets`` extra."""
    try:
        import ipympl.backend_nbagg  # noqa: F401
        import ipywidgets
    except ImportError as exc:
        raise ImportError(f"{what} needs the 'widgets' extra (ipywidgets, ipympl): "
                          f"pip install \"nanodisorder[widgets]\" ({exc})") from exc
    return ipywidgets


def widget_figure(figsize: tuple[float, float]) -> Figure:
    """A matplotlib Figure whose ``canvas`` is an ipympl widget (no pyplot state involved)."""
    require_widgets("a widget figure")
    from ipympl.backend_nbagg import Canvas, FigureManager

    figure = Figure(figsize=figsize)
    canvas = Canvas(figure)
    with warnings.catch_warnings():  # ipympl's own Toolbar call trips a traitlets DeprecationWarning
        warnings.simplefilter("ignore", DeprecationWarning)
        FigureManager(canvas, 0)
    canvas.header_visible = False
    canvas.toolbar_position = "bottom"
    return figure

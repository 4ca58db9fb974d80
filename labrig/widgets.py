"""Notebook widgets on matplotlib: ipympl canvases without pyplot state, and a clear error without them.

The widgets extra (ipywidgets, ipympl) is optional; `require_widgets` imports it or says how to
install it.

A canvas made by `widget_figure` is meant to sit inside an ipywidgets ``Box`` next to controls,
and to show in a real browser (JupyterLab, Chromium), not only headless:

* Widgets here do not call ``canvas.draw()`` while they are built: the front end asks for the
  first picture itself once the canvas is shown (ipympl's ``refresh`` / ``draw`` messages), and
  ``canvas.draw_idle()`` is all a widget needs until then.
* A ``draw()`` that happens before the canvas is shown anyway (a user's code, a test) is made
  harmless. ipympl (0.10 and its main branch; its issue #472) sends such an early picture to the
  browser as raw RGBA pixels labelled PNG, and keeps it in ``_data_url`` as bare base64: the
  browser's image is broken, resizing the canvas then fails (console: ``Error setting state:
  Failed to execute 'drawImage' ... 'broken' state``) and the canvas stays blank. The canvas
  class here sends the PNG and keeps a ``data:`` URL.
"""

from __future__ import annotations

import io
import warnings
from base64 import b64encode

import numpy as np
from matplotlib.figure import Figure
from PIL import Image

_PNG_URL = "data:image/png;base64,"
_canvas_class = None


def require_widgets(what: str = "this widget"):
    """Import ipywidgets and ipympl, or raise an ImportError that names the ``widgets`` extra."""
    try:
        import ipympl.backend_nbagg  # noqa: F401
        import ipywidgets
    except ImportError as exc:
        raise ImportError(f"{what} needs the 'widgets' extra (ipywidgets, ipympl): "
                          f"pip install \"nanodisorder[widgets]\" ({exc})") from exc
    return ipywidgets


def widget_canvas_class():
    """The ipympl ``Canvas`` subclass that `widget_figure` uses (made on first use: ipympl is optional).

    It differs from ipympl's in what it does with a picture drawn before a front end is there
    (see `labrig.widgets`): the browser gets the PNG, and ``_data_url`` (the picture a saved or
    embedded widget starts with) is a ``data:image/png;base64,...`` URL.
    """
    global _canvas_class
    if _canvas_class is None:
        require_widgets("a widget canvas")
        from ipympl.backend_nbagg import Canvas

        class WidgetCanvas(Canvas):
            """An ipympl canvas whose early pictures reach the browser intact (see `labrig.widgets`)."""

            def send_binary(self, data):
                # ``data`` is the PNG (full or diff) made by matplotlib's get_diff_image; ipympl's own
                # method replaces it by raw pixels when it keeps the full picture for _data_url.
                if self.syncing_data_url:
                    pixels = self._last_buff.view(dtype=np.uint8).reshape((*self._last_buff.shape, 4))
                    with io.BytesIO() as png:
                        Image.fromarray(pixels).save(png, format="png")
                        self._data_url = _PNG_URL + b64encode(png.getvalue()).decode("ascii")
                self.send({"data": '{"type": "binary"}'}, buffers=[data])

        _canvas_class = WidgetCanvas
    return _canvas_class


def widget_figure(figsize: tuple[float, float]) -> Figure:
    """A matplotlib Figure whose ``canvas`` is an ipympl widget (no pyplot state involved).

    Build the picture with ``canvas.draw_idle()``, not ``canvas.draw()``: the front end draws the
    canvas when it is shown (see `labrig.widgets`).
    """
    canvas_class = widget_canvas_class()
    from ipympl.backend_nbagg import FigureManager

    figure = Figure(figsize=figsize)
    canvas = canvas_class(figure)
    with warnings.catch_warnings():  # ipympl's own Toolbar call trips a traitlets DeprecationWarning
        warnings.simplefilter("ignore", DeprecationWarning)
        FigureManager(canvas, 0)
    canvas.header_visible = False
    canvas.toolbar_position = "bottom"
    return figure

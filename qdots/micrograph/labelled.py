"""Synthetic micrographs as microscopes write them: a data strip along a side (black or white, with the
instrument's text and magnification), and a scale bar drawn solid, ruled (divided by ticks), checkered
(blocks in an outline) or as a ruler line, boxed or not, its length written under, over or beside it.

Everything is drawn with matplotlib on a canvas of the image's own pixels (`label_micrograph`): the
text is its anti-aliased text, the bars are pixel-exact rectangles, as acquisition software draws them.
The truth comes back with the picture: where the film is, where the bar is and how long. `not_a_film`
draws pictures that a measurement must refuse: a plot, a page of text, a drawing.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from labrig.validate import InputError, choice, count, real

#: Sides a data strip can run along, its colours, the scale-bar styles and where its label goes.
SIDES = ("bottom", "top", "left", "right")
COLOURS = ("black", "white")
BAR_STYLES = ("solid", "ruled", "checkered", "ruler")
LABEL_PLACES = ("under", "over", "beside")
#: Largest canvas side, px.
MAX_CANVAS = 8192
#: Pictures that are not films (`not_a_film`).
NOT_FILMS = ("plot", "text", "drawing")


@dataclass(frozen=True)
class Labelled:
    """A labelled synthetic micrograph and its truth.

    Attributes
    ----------
    image : ndarray (H, W), float
        Grey values in [0, 1].
    window : (int, int, int, int)
        ``(x0, y0, x1, y1)`` of the film in ``image``, px.
    bar_box : (int, int, int, int)
        ``(x0, y0, x1, y1)`` of the whole scale bar (its ticks and outline included), px.
    bar_px : int
        The bar's length, px (from its first end to its last).
    """

    image: np.ndarray
    window: tuple[int, int, int, int]
    bar_box: tuple[int, int, int, int]
    bar_px: int


def bar_rectangles(x: int, y: int, length: int, thick: int, style: str, segments: int = 5) -> list:
    """The bar's pixel rectangles ``(x0, y0, x1, y1, ink)`` with its left end at ``x`` and its top at ``y``:
    ``ink`` True for the bar's colour, False for the background's (drawn after, over it)."""
    style = choice("style", style, BAR_STYLES)
    step = length / segments
    if style == "solid":
        return [(x, y, x + length, y + thick, True)]
    if style == "ruled":  # a solid bar cut into segments by thin gaps, its ends ticked above and below
        out = [(x, y, x + length, y + thick, True)]
        out += [(round(x + k * step) - 1, y, round(x + k * step) + 1, y + thick, False) for k in range(1, segments)]
        out += [(x, y - thick, x + 2, y + 2 * thick, True), (x + length - 2, y - thick, x + length, y + 2 * thick, True)]
        return out
    if style == "checkered":  # blocks, alternately filled, in an outline of the bar's colour
        out = [(x, y, x + length, y + thick, True), (x + 1, y + 1, x + length - 1, y + thick - 1, False)]
        out += [(round(x + k * step), y, round(x + (k + 1) * step), y + thick, True) for k in range(0, segments, 2)]
        return out
    line = max(2, thick // 3)  # ruler: a line with a tick at each division, the ends taller
    out = [(x, y + thick - line, x + length, y + thick, True)]
    for k in range(segments + 1):
        tick = min(x + length - 2, round(x + k * step))
        out.append((tick, y - (thick if k in (0, segments) else 0), tick + 2, y + thick, True))
    return out


def label_micrograph(film, nm_per_px: float, *, bar_nm: float = 100.0, strip: str | None = "bottom",
                     colour: str = "black", strip_px: int | None = None, style: str = "solid", boxed: bool = False,
                     label: str = "under", text: tuple[str, ...] = ("HV=200.0kV", "Mag = 88000x", "Direct Mag"),
                     bar_thick: int | None = None) -> Labelled:
    """Lay a film out as an acquisition program writes it: a data strip along ``strip`` (or none: the bar and its
    label drawn over the film's corner, boxed or not), the instrument's ``text`` in it, and a scale bar ``bar_nm``
    long at ``nm_per_px``.

    Parameters
    ----------
    film : ndarray (h, w)
        The picture, grey values in about [0, 1] (`qdots.micrograph.synthetic.render_micrograph`).
    nm_per_px : float
        The film's scale.
    bar_nm : float
        The scale bar's length, nm (its label reads it, in nm or µm).
    strip : {"bottom", "top", "left", "right"} or None
        Side of the data strip.
    colour : {"black", "white"}
        The strip's colour (its text and bar take the other); with no strip, the colour the bar is drawn on (its
        box's, if boxed; else the bar itself takes the other colour, over the film).
    strip_px : int, optional
        The strip's width across its side, px (default: a tenth of the film's height, at least 40 px).
    style : {"solid", "ruled", "checkered", "ruler"}
        How the bar is drawn (`bar_rectangles`).
    boxed : bool
        Whether the bar and its label sit in an outlined box: of the strip's other colour in a strip, of
        ``colour`` over the film.
    label : {"under", "over", "beside"}
        Where the bar's length is written.
    text : tuple of str
        The strip's other text.
    bar_thick : int, optional
        The bar's thickness, px.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    film = np.asarray(film, dtype=float)
    h, w = film.shape
    real("nm_per_px", nm_per_px, 0.0, 1e6, low_open=True)
    bar_px = round(real("bar_nm", bar_nm, 0.0, 1e9, low_open=True) / nm_per_px)
    colour = choice("colour", colour, COLOURS)
    label = choice("label", label, LABEL_PLACES)
    if strip is not None:
        strip = choice("strip", strip, SIDES)
    band = count("strip_px", strip_px if strip_px is not None else max(40, h // 10), 10, MAX_CANVAS)
    thick = count("bar_thick", bar_thick if bar_thick is not None else max(4, min(band // 8, h // 60)), 2, band)
    H = count("canvas height", h + (band if strip in ("bottom", "top") else 0), 2, MAX_CANVAS)
    W = count("canvas width", w + (band if strip in ("left", "right") else 0), 2, MAX_CANVAS)
    x0 = band if strip == "left" else 0
    y0 = band if strip == "top" else 0
    canvas = np.full((H, W), 0.0 if colour == "black" else 1.0)
    canvas[y0:y0 + h, x0:x0 + w] = np.clip(film, 0.0, 1.0)
    if strip is None:  # over the film's lower right corner
        area = (x0 + w - bar_px - 6 * thick, y0 + h - 12 * thick, x0 + w - 2 * thick, y0 + h - 2 * thick)
    elif strip in ("bottom", "top"):
        top = y0 + h if strip == "bottom" else 0
        area = (W - bar_px - (16 if label == "beside" else 6) * thick, top + 2, W - 4, top + band - 2)
    else:
        left = x0 + w if strip == "right" else 0
        area = (left + 4, H // 2, left + band - 4, H - 4)
    if bar_px + 4 * thick > area[2] - area[0] or area[0] < 0 or area[1] < 0:
        raise InputError(f"a {bar_px} px scale bar does not fit where it is to be drawn; shorten it or widen the picture")
    # the colour the bar is drawn on: the strip's, or its box's (the other, in a strip; `colour`, on the film)
    strip_value = 0.0 if colour == "black" else 1.0
    field = (1.0 - strip_value if strip is not None else strip_value) if boxed else strip_value
    mark = 1.0 - field
    fig = Figure(figsize=(W / 100.0, H / 100.0), dpi=100)
    agg = FigureCanvasAgg(fig)  # becomes fig.canvas
    ax = fig.add_axes((0, 0, 1, 1))
    ax.imshow(canvas, cmap="gray", vmin=0.0, vmax=1.0, extent=(0, W, H, 0), interpolation="nearest")
    ax.set_xlim(0, W)
    ax.set_ylim(H, 0)
    ax.set_axis_off()
    bx = area[2] - bar_px - 2 * thick
    by = {"under": area[1] + 3 * thick, "over": area[3] - 4 * thick,
          "beside": (area[1] + area[3]) // 2 - thick // 2}[label]  # end ticks reach a thickness beyond the bar
    if boxed:
        ax.add_patch(Rectangle((area[0], area[1]), area[2] - area[0], area[3] - area[1], facecolor=str(field),
                               edgecolor=str(mark), lw=1.0, antialiased=False))
    pieces = bar_rectangles(bx, by, bar_px, thick, style)
    for a, b, c, d, on in pieces:
        ax.add_patch(Rectangle((a, b), c - a, d - b, facecolor=str(mark if on else field), lw=0, antialiased=False))
    written = f"{bar_nm:g} nm" if bar_nm < 1000 else f"{bar_nm / 1000:g} µm"
    font = 3.0 * thick * 72.0 / 100.0
    if label == "under":
        ax.text(bx + bar_px / 2, by + 2.2 * thick, written, color=str(mark), ha="center", va="top", fontsize=font)
    elif label == "over":
        ax.text(bx + bar_px / 2, by - 1.6 * thick, written, color=str(mark), ha="center", va="bottom", fontsize=font)
    else:
        ax.text(bx - 2 * thick, by + thick / 2, written, color=str(mark), ha="right", va="center", fontsize=font)
    if strip in ("bottom", "top"):
        ax.text(8, (area[1] + area[3]) / 2, "   ".join(text), color=str(1.0 - strip_value), ha="left",
                va="center", fontsize=min(0.28 * band, 2.0 * (area[0] - 16) / max(1, len("   ".join(text))))
                * 72.0 / 100.0)
    elif strip is not None:
        for k, line in enumerate(text):
            ax.text(area[0] + 2, 12 + k * 2.2 * thick, line, color=str(1.0 - strip_value), ha="left", va="top",
                    fontsize=font * 0.8)
    agg.draw()
    pixels = np.asarray(agg.buffer_rgba(), dtype=float)[..., :3].mean(axis=-1) / 255.0
    top_of_bar = min(b for _, b, _, _, _ in pieces)
    bottom_of_bar = max(d for _, _, _, d, _ in pieces)
    return Labelled(pixels[:H, :W], (x0, y0, x0 + w, y0 + h), (bx, top_of_bar, bx + bar_px, bottom_of_bar), bar_px)


def not_a_film(kind: str, shape: tuple[int, int] = (480, 640), seed: int = 0) -> np.ndarray:
    """A picture that is not a micrograph of a film, grey values in [0, 1], as matplotlib draws it: a line
    ``"plot"`` with its title, axes and legend, a page of ``"text"``, or a ``"drawing"`` (outlined and filled
    shapes, circles among them)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle, Rectangle

    kind = choice("kind", kind, NOT_FILMS)
    h, w = (count("shape", v, 16, MAX_CANVAS) for v in shape)
    rng = np.random.default_rng(seed)
    fig = Figure(figsize=(w / 100.0, h / 100.0), dpi=100)
    agg = FigureCanvasAgg(fig)  # becomes fig.canvas
    if kind == "plot":
        ax = fig.add_subplot()
        x = np.linspace(0, 10, 200)
        ax.plot(x, np.sin(x) * np.exp(-x / 5), label="decay")
        ax.plot(x, np.cos(x), "--", label="reference")
        ax.set_title("Photoluminescence lifetime")
        ax.set_xlabel("time (ns)")
        ax.set_ylabel("intensity (a.u.)")
        ax.legend()
    elif kind == "text":
        words = "the quantum dots form a film whose order depends on the size spread and the rate of arrival".split()
        for line in range(int(h / 22)):
            fig.text(0.05, 1.0 - (line + 1) * 22 / h, " ".join(rng.choice(words, 9)), fontsize=11)
    else:
        ax = fig.add_axes((0, 0, 1, 1))
        ax.set_xlim(0, w)
        ax.set_ylim(0, h)
        ax.set_axis_off()
        for _ in range(25):
            cx, cy, r = rng.uniform(0, w), rng.uniform(0, h), rng.uniform(8, 40)
            shade = str(rng.uniform(0.2, 0.8))
            patch = Circle((cx, cy), r) if rng.random() < 0.6 else Rectangle((cx, cy), 2 * r, r)
            patch.set(facecolor=shade if rng.random() < 0.5 else "none", edgecolor="black", linewidth=1.5)
            ax.add_patch(patch)
    agg.draw()
    return np.asarray(agg.buffer_rgba(), dtype=float)[:h, :w, :3].mean(axis=-1) / 255.0

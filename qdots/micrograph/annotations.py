"""What acquisition programs draw on a micrograph, found so that it is left out: a frame or data strips
along the sides (black or white, with text, the magnification and often the scale bar), label boxes over
the film, and the scale bar with its label.

A **strip** (`find_strips`) is a band along a side whose lines are drawn: mostly black or white (the
strip's colour, its text's and its bar's; JPEG's ringing stays near them), until the film begins (lines
that hardly hold either). A frame is a band of lines of one colour only (whatever follows: a film may hold
that colour too, in saturated dots). The picture is what the strips leave (`Annotations.window`).

A **box** over the film (`find_boxes`) is a flat rectangle of one colour, at least `MIN_BOX` px, holding
something else (text or a bar): a flat dot core holds nothing, a label box does.

The **scale bar** is `qdots.micrograph.scale.find_scale_bar`'s; the label next to a bar drawn over the
film without a box (thin strokes of the bar's colour around it, `label_strokes`) is left out with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from .scale import ScaleBar, find_scale_bar

#: Sides, in the order strips are looked for.
SIDES = ("top", "bottom", "left", "right")
#: Drawn pixels are within EXTREME of the image's range of its darkest or lightest value (a strip is black or
#: white, its text and bar the other). A strip's outermost line is at least STRIP_START drawn, its lines on
#: average STRIP_SHARE; the film's first lines (FILM_LINES of them) less than FILM_SHARE; a strip takes at most
#: MAX_STRIP of the image's height or width.
EXTREME, STRIP_START, STRIP_SHARE, FILM_SHARE, FILM_LINES, MAX_STRIP = 0.1, 0.9, 0.7, 0.3, 3, 0.4
#: Lines of at least FRAME_SHARE of one colour from the edge inward are a frame, whatever follows.
FRAME_SHARE = 0.99
#: Pixels within FLAT of the image's range of a colour are that colour (a drawn strip is flat; a film is not).
FLAT = 0.01
#: A label box over the film: a flat rectangle of at least MIN_BOX px a side, filling BOX_FILL of its bounding
#: box once its holes (its text, its bar) are filled, holding at least BOX_HOLES of its area in them.
MIN_BOX, BOX_FILL, BOX_HOLES = 8, 0.9, 0.02
#: The smallest stroke of a label's text, px.
MIN_STROKE = 8


@dataclass(frozen=True)
class Strip:
    """A data strip (or frame) along a side of the image: ``side``, its ``width`` across the side (px) and its
    ``value`` (grey value of its colour)."""

    side: str
    width: int
    value: float


@dataclass(frozen=True)
class Annotations:
    """What was found drawn on an image.

    Attributes
    ----------
    window : (int, int, int, int)
        ``(x0, y0, x1, y1)`` of the picture, px: the image less its strips.
    strips : tuple of Strip
    boxes : tuple of (int, int, int, int)
        Label boxes over the film, ``(x0, y0, x1, y1)``.
    bar : ScaleBar or None
        The scale bar.
    ignore : ndarray of bool
        Pixels of the picture to leave out: boxes, the bar and its label, each with a margin of 2 px.
    """

    window: tuple[int, int, int, int]
    strips: tuple = ()
    boxes: tuple = ()
    bar: ScaleBar | None = None
    ignore: np.ndarray | None = field(default=None, repr=False)

    def describe(self, low: float, high: float) -> str:
        """What is left out, in words (``low`` and ``high`` the image's darkest and lightest values)."""
        parts = []
        for s in self.strips:
            colour = "black" if abs(s.value - low) <= abs(s.value - high) else "white"
            parts.append(f"a {colour} {'frame' if s.width <= 4 else 'data strip'} {s.width} px wide along the {s.side}")
        parts += [f"a label box at x {x0}-{x1}, y {y0}-{y1} px" for x0, y0, x1, y1 in self.boxes]
        if self.bar is not None:
            parts.append("the scale bar and its label")
        return ", ".join(parts) if parts else "nothing"


def line_shares(mask: np.ndarray, side: str, depth: int) -> np.ndarray:
    """Share of each of the ``depth`` lines of ``mask`` from ``side`` inward that is set."""
    if side == "top":
        return mask[:depth].mean(axis=1)
    if side == "bottom":
        return mask[::-1][:depth].mean(axis=1)
    if side == "left":
        return mask[:, :depth].mean(axis=0)
    return mask[:, ::-1][:, :depth].mean(axis=0)


def find_strips(image: np.ndarray) -> tuple[tuple[int, int, int, int], tuple[Strip, ...]]:
    """The picture's window ``(x0, y0, x1, y1)`` and the strips along its sides (see the module)."""
    image = np.asarray(image, dtype=float)
    h, w = image.shape
    low, high = float(image.min()), float(image.max())
    span = high - low
    drawn = (image <= low + EXTREME * span) | (image >= high - EXTREME * span)
    cut = {"top": 0, "bottom": 0, "left": 0, "right": 0}
    strips = []
    for side in SIDES:
        extent = h if side in ("top", "bottom") else w
        outer = {"top": image[0], "bottom": image[-1], "left": image[:, 0], "right": image[:, -1]}[side]
        value = low if np.mean(outer <= low + EXTREME * span) >= np.mean(outer >= high - EXTREME * span) else high
        depth = max(1, int(MAX_STRIP * extent))
        frame_shares = line_shares(np.abs(image - float(np.median(outer))) <= FLAT * span, side, depth)
        frame = int(np.argmin(frame_shares >= FRAME_SHARE)) if frame_shares[-1] < FRAME_SHARE else 0
        shares = line_shares(drawn, side, depth + FILM_LINES)
        width = 0
        if shares[0] >= STRIP_START:
            film = np.convolve(shares < FILM_SHARE, np.ones(FILM_LINES), mode="valid") == FILM_LINES
            starts = np.flatnonzero(film[:depth + 1])
            if starts.size and shares[:max(1, int(starts[0]))].mean() >= STRIP_SHARE:
                width = int(starts[0])
        width = max(width, frame)
        if width >= 1:
            cut[side] = width
            strips.append(Strip(side, width, float(np.median(outer)) if width == frame else value))
    window = (cut["left"], cut["top"], w - cut["right"], h - cut["bottom"])
    return window, tuple(strips)


def flatness(image: np.ndarray, tolerance: float) -> np.ndarray:
    """Pixels whose 3 x 3 neighbourhood spans at most ``tolerance``: flat colour, as drawn."""
    return ndimage.maximum_filter(image, 3) - ndimage.minimum_filter(image, 3) <= tolerance


def find_boxes(image: np.ndarray, window) -> tuple[tuple[int, int, int, int], ...]:
    """Label boxes over the film (see the module), in image px."""
    x0, y0, x1, y1 = window
    picture = np.asarray(image, dtype=float)[y0:y1, x0:x1]
    span = float(picture.max() - picture.min())
    labels, _ = ndimage.label(flatness(picture, FLAT * span))
    boxes = []
    for k, box in enumerate(ndimage.find_objects(labels), start=1):
        if box is None:
            continue
        rows, cols = box
        bh, bw = rows.stop - rows.start, cols.stop - cols.start
        if min(bh, bw) < MIN_BOX or bh * bw >= 0.5 * picture.size:
            continue
        own = labels[box] == k
        filled = ndimage.binary_fill_holes(own)
        if filled.sum() >= BOX_FILL * bh * bw and (filled.sum() - own.sum()) >= BOX_HOLES * filled.sum():
            boxes.append((cols.start + x0, rows.start + y0, cols.stop + x0, rows.stop + y0))
    return tuple(boxes)


def label_strokes(image: np.ndarray, bar: ScaleBar) -> np.ndarray:
    """The bar's label where the bar is drawn over the film: strokes of the bar's colour within one bar length of
    it, thin (inscribed radius at most half the bar's thickness: not a dot's core), of at least `MIN_STROKE` px (not
    a noise speck), not touching the image's edge (a frame) nor taller than half the bar. Boolean image."""
    image = np.asarray(image, dtype=float)
    low, high = float(image.min()), float(image.max())
    x0, y0, x1, y1 = bar.box
    length = int(math.ceil(bar.length_px))
    near = np.zeros(image.shape, dtype=bool)
    near[max(0, y0 - length):y1 + length, max(0, x0 - length):x1 + length] = True
    ink = (image <= low + 0.3 * (high - low)) if bar.dark else (image >= high - 0.3 * (high - low))
    labels, n = ndimage.label(ink & near)
    if n == 0:
        return np.zeros(image.shape, dtype=bool)
    thick = max(1.0, float(bar.thickness))
    index = np.arange(1, n + 1)
    deepest = np.asarray(ndimage.maximum(ndimage.distance_transform_edt(labels > 0), labels, index))
    area = np.bincount(labels.ravel(), minlength=n + 1)[1:]
    edge = np.zeros(n + 1, dtype=bool)
    edge[np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])] = True
    tall = np.array([sl[0].stop - sl[0].start > 0.5 * length for sl in ndimage.find_objects(labels)])
    stroke = (deepest <= max(2.0, 0.5 * thick)) & (area >= MIN_STROKE) & ~edge[1:] & ~tall
    return np.concatenate([[False], stroke])[labels]


def find_annotations(image: np.ndarray) -> Annotations:
    """Strips, boxes and the scale bar of ``image`` (see the module), and the pixels to leave out."""
    image = np.asarray(image, dtype=float)
    window, strips = find_strips(image)
    boxes = find_boxes(image, window)
    bar = find_scale_bar(image)
    ignore = np.zeros(image.shape, dtype=bool)
    for x0, y0, x1, y1 in boxes:
        ignore[max(0, y0 - 2):y1 + 2, max(0, x0 - 2):x1 + 2] = True
    if bar is not None:
        ignore |= bar.mask(image.shape)
        bx0, by0, bx1, by1 = bar.box
        inside = window[0] <= bx0 and window[1] <= by0 and bx1 <= window[2] and by1 <= window[3]
        boxed = any(x0 <= bx0 and y0 <= by0 and bx1 <= x1 and by1 <= y1 for x0, y0, x1, y1 in boxes)
        if inside and not boxed:  # drawn over the film: its label too
            ignore |= ndimage.binary_dilation(label_strokes(image, bar), iterations=2)
    return Annotations(window, strips, boxes, bar, ignore)

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

from labrig.compiled import jit
from labrig.threads import run_tasks

from .bar import ScaleBar
from .scale import find_scale_bar

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
#: The smallest stroke of a label's text, px; a letter's strokes fill under GLYPH_FILL of its bounding box; a label is
#: drawn within LABEL_INK of the image's range of the bar's colour.
MIN_STROKE, GLYPH_FILL, LABEL_INK = 8, 0.6, 0.15
#: A bar's label's letters are at most LABEL_SIZE of the bar long. A panel letter lies within PANEL_CORNER of the
#: picture's width and height from a corner, at most PANEL_SIZE of its shorter side across; drawn flat, PANEL_FLAT of
#: its pixels lie within 1 % of the range of the extreme.
LABEL_SIZE, PANEL_CORNER, PANEL_SIZE, PANEL_FLAT = 0.35, 0.12, 0.15, 0.7
#: The flat box a panel letter is printed on lies within PANEL_BOX of the picture's width and height from a corner.
PANEL_BOX = 0.25


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


def side_lines(array: np.ndarray, side: str, depth: int) -> np.ndarray:
    """The ``depth`` lines of ``array`` from ``side`` inward, as rows (the side's own line first)."""
    if side == "top":
        return array[:depth]
    if side == "bottom":
        return array[::-1][:depth]
    if side == "left":
        return array[:, :depth].T
    return array[:, ::-1][:, :depth].T


def line_shares(mask: np.ndarray, side: str, depth: int) -> np.ndarray:
    """Share of each of the ``depth`` lines of ``mask`` from ``side`` inward that is set."""
    return side_lines(mask, side, depth).mean(axis=1)


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
        frame_shares = (np.abs(side_lines(image, side, depth) - float(np.median(outer))) <= FLAT * span).mean(axis=1)
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
    """Pixels whose 3 x 3 neighbourhood (within the image) spans at most ``tolerance``: flat colour, as drawn."""
    out = np.empty(np.shape(image), dtype=np.bool_)
    _flat3(np.ascontiguousarray(image, dtype=np.float64), float(tolerance), out)
    return out


@jit
def _flat3(image, tolerance, out):
    h, w = image.shape
    low = np.empty((h, w))  # each pixel's least and greatest value over its row's three, then over three rows
    high = np.empty((h, w))
    for row in range(h):
        for col in range(w):
            a = b = image[row, col]
            for c in range(max(0, col - 1), min(w, col + 2)):
                a = min(a, image[row, c])
                b = max(b, image[row, c])
            low[row, col] = a
            high[row, col] = b
    for row in range(h):
        for col in range(w):
            a = low[row, col]
            b = high[row, col]
            for r in range(max(0, row - 1), min(h, row + 2)):
                a = min(a, low[r, col])
                b = max(b, high[r, col])
            out[row, col] = b - a <= tolerance


def picture_flatness(image: np.ndarray, window) -> np.ndarray:
    """`flatness` of the picture in ``window`` (x0, y0, x1, y1) within `FLAT` of its range: what `find_boxes` and
    `corner_boxes` read."""
    x0, y0, x1, y1 = window
    picture = np.asarray(image, dtype=float)[y0:y1, x0:x1]
    return flatness(picture, FLAT * float(picture.max() - picture.min()))


def find_boxes(image: np.ndarray, window, flat: np.ndarray | None = None) -> tuple[tuple[int, int, int, int], ...]:
    """Label boxes over the film (see the module), in image px; ``flat``: the `picture_flatness`, if known."""
    x0, y0, x1, y1 = window
    picture = np.asarray(image, dtype=float)[y0:y1, x0:x1]
    labels, _ = ndimage.label(picture_flatness(image, window) if flat is None else flat)
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


def glyphs(labels: np.ndarray, n: int, thick: float) -> np.ndarray:
    """Which of the components 1 .. ``n`` of ``labels`` are letters rather than dots: thin strokes (inscribed radius at
    most ``max(2, thick / 2)`` px), or open shapes that fill under `GLYPH_FILL` of their bounding box ("0", "5", "n",
    "m", "(": a dot, even a faceted one, fills three quarters of it), of at least `MIN_STROKE` px, not touching the
    image's edge (a frame). Boolean array over the labels 0 .. n (0, the background, False)."""
    index = np.arange(1, n + 1)
    deepest = np.asarray(ndimage.maximum(ndimage.distance_transform_edt(labels > 0), labels, index))
    area = np.bincount(labels.ravel(), minlength=n + 1)[1:]
    boxes = ndimage.find_objects(labels)
    box_area = np.array([(b[0].stop - b[0].start) * (b[1].stop - b[1].start) if b is not None else 1 for b in boxes])
    edge = np.zeros(n + 1, dtype=bool)
    edge[np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])] = True
    letter = ((deepest <= max(2.0, 0.5 * thick)) | (area < GLYPH_FILL * box_area)) & (area >= MIN_STROKE) & ~edge[1:]
    return np.concatenate([[False], letter])


def label_strokes(image: np.ndarray, bar: ScaleBar) -> np.ndarray:
    """The bar's label where the bar is drawn over the film: letters (`glyphs`) in the bar's colour (within
    `LABEL_INK` of the image's range of it), beside it (within half its length along it and across), none longer than
    `LABEL_SIZE` of the bar. Boolean image."""
    image = np.asarray(image, dtype=float)
    low, high = float(image.min()), float(image.max())
    x0, y0, x1, y1 = bar.found_box
    length = int(math.ceil(bar.length_px))
    along, across = length // 2, length // 2
    horizontal = x1 - x0 >= y1 - y0
    reach_x, reach_y = (along, across) if horizontal else (across, along)
    h, w = image.shape
    rows = slice(max(0, y0 - reach_y), min(h, y1 + reach_y))
    cols = slice(max(0, x0 - reach_x), min(w, x1 + reach_x))
    part = image[rows, cols]
    ink = (part <= low + LABEL_INK * (high - low)) if bar.dark else (part >= high - LABEL_INK * (high - low))
    # only the box beside the bar is searched: cut out, with a row or column of background on each side that is not
    # the image's edge, it gives the letters the whole image would (their depth is measured to that background, and
    # only the image's own edge marks a frame)
    pad = ((int(rows.start > 0), int(rows.stop < h)), (int(cols.start > 0), int(cols.stop < w)))
    labels, n = ndimage.label(np.pad(ink, pad))
    out = np.zeros(image.shape, dtype=bool)
    if n == 0:
        return out
    big = np.array([max(sl[0].stop - sl[0].start, sl[1].stop - sl[1].start) > LABEL_SIZE * length
                    for sl in ndimage.find_objects(labels)])
    letter = glyphs(labels, n, max(1.0, float(bar.thickness)))
    letter[1:] &= ~big
    found = letter[labels]
    out[rows, cols] = found[pad[0][0]:found.shape[0] - pad[0][1], pad[1][0]:found.shape[1] - pad[1][1]]
    return out


def same_line(labels: np.ndarray, letter: np.ndarray) -> np.ndarray:
    """``letter`` (over the components 1 .. n of ``labels``) and the components set in a line with a letter: as tall
    as it within a factor 2, overlapping its rows by half its height, and at most three of its heights from it
    along the line (the rest of a word whose other letters are not thin or open: "(b)" once its "(" is found)."""
    boxes = ndimage.find_objects(labels)
    out = letter.copy()
    for k in np.flatnonzero(letter):
        rows, cols = boxes[k]
        height = rows.stop - rows.start
        for j, other in enumerate(boxes):
            if out[j] or other is None:
                continue
            h = other[0].stop - other[0].start
            shared = min(rows.stop, other[0].stop) - max(rows.start, other[0].start)
            gap = max(other[1].start - cols.stop, cols.start - other[1].stop)
            if 0.5 * height <= h <= 2.0 * height and shared >= 0.5 * height and gap <= 3 * height:
                out[j] = True
    return out


def panel_letters(image: np.ndarray, window: tuple[int, int, int, int]) -> np.ndarray:
    """A journal figure's panel letter ("a", "(b)", "C") in a corner of the picture: letters (`glyphs`) drawn flat
    (`PANEL_FLAT` of their pixels within 1 % of the image's range of its darkest or lightest value) in either extreme
    colour (within `LABEL_INK` of the range), within `PANEL_CORNER` of the picture's width and height from a corner,
    at most `PANEL_SIZE` of its shorter side across, and what is set in a line with them (`same_line`). Boolean
    image."""
    image = np.asarray(image, dtype=float)
    x0, y0, x1, y1 = window
    low, high = float(image.min()), float(image.max())
    span = high - low
    out = np.zeros(image.shape, dtype=bool)
    cw, ch = int(PANEL_CORNER * (x1 - x0)), int(PANEL_CORNER * (y1 - y0))
    largest = PANEL_SIZE * min(x1 - x0, y1 - y0)
    for xa, ya in ((x0, y0), (x1 - cw, y0), (x0, y1 - ch), (x1 - cw, y1 - ch)):
        corner = (slice(ya, ya + ch), slice(xa, xa + cw))
        part = image[corner]
        for value, sign in ((low, 1.0), (high, -1.0)):
            ink = sign * (part - value) <= LABEL_INK * span
            labels, n = ndimage.label(ink)
            if n == 0:
                continue
            flat = np.bincount(labels.ravel(), (sign * (part - value) <= 0.01 * span).ravel(), n + 1)[1:]
            area = np.bincount(labels.ravel(), minlength=n + 1)[1:]
            small = np.array([max(b[0].stop - b[0].start, b[1].stop - b[1].start) <= largest
                              for b in ndimage.find_objects(labels)])
            letter = glyphs(np.pad(labels, 1), n, 2.0)[1:] & (flat >= PANEL_FLAT * area) & small
            out[corner] |= np.concatenate([[False], same_line(labels, letter & (area >= MIN_STROKE)) & small])[labels]
    return out


def corner_boxes(image: np.ndarray, window: tuple[int, int, int, int],
                 flat: np.ndarray | None = None) -> tuple[tuple[int, int, int, int], ...]:
    """Boxes in a corner of the picture ("(a)" on a white box in a journal figure's panel): a piece of flat colour
    (`flatness`, within `FLAT` of the picture's range) in either extreme colour (within `LABEL_INK` of the range),
    whose bounding box starts at a corner of the picture and lies within `PANEL_BOX` of its width and height, and
    holds only the two extremes (at least `BOX_FILL` of its pixels, counting those within 2 px of the other: the
    letters' anti-aliasing), of which at least `BOX_HOLES` the other (the ink). The letters may cut the box into pieces; each such piece is one (their union is
    left out). ``(x0, y0, x1, y1)`` in image px; ``flat``: the `picture_flatness`, if known."""
    x0, y0, x1, y1 = window
    picture = np.asarray(image, dtype=float)[y0:y1, x0:x1]
    h, w = picture.shape
    low, high = float(picture.min()), float(picture.max())
    span = high - low
    dark, light = picture <= low + LABEL_INK * span, picture >= high - LABEL_INK * span
    flat = picture_flatness(image, window) if flat is None else flat
    boxes = []
    for colour, ink in ((dark, light), (light, dark)):
        labels, _ = ndimage.label(flat & colour)
        for rows, cols in (b for b in ndimage.find_objects(labels) if b is not None):
            corner = (rows.start == 0 or rows.stop == h) and (cols.start == 0 or cols.stop == w)
            small = rows.stop - rows.start <= PANEL_BOX * h and cols.stop - cols.start <= PANEL_BOX * w
            if corner and small and min(rows.stop - rows.start, cols.stop - cols.start) >= MIN_BOX:
                inked = ink[rows, cols]
                drawn = colour[rows, cols] | ndimage.binary_dilation(inked, iterations=2)
                if drawn.mean() >= BOX_FILL and inked.mean() >= BOX_HOLES:
                    boxes.append((cols.start + x0, rows.start + y0, cols.stop + x0, rows.stop + y0))
    return tuple(boxes)


def boxes_and_letters(image: np.ndarray, window) -> tuple[tuple, np.ndarray]:
    """The label boxes over the film and in its corners (`find_boxes`, `corner_boxes`: the flatness read once) and the
    panel letters (`panel_letters`)."""
    flat = picture_flatness(image, window)
    return find_boxes(image, window, flat) + corner_boxes(image, window, flat), panel_letters(image, window)


def find_annotations(image: np.ndarray) -> Annotations:
    """Strips, boxes and the scale bar of ``image`` (see the module), and the pixels to leave out."""
    image = np.asarray(image, dtype=float)
    window, strips = find_strips(image)
    # the bar beside the boxes and letters, in a second thread (each is numpy's and scipy's filters, which release the GIL)
    bar, (boxes, letters) = run_tasks([
        lambda: find_scale_bar(image),
        lambda: boxes_and_letters(image, window)])
    ignore = np.zeros(image.shape, dtype=bool)
    for x0, y0, x1, y1 in boxes:
        ignore[max(0, y0 - 2):y1 + 2, max(0, x0 - 2):x1 + 2] = True
    ignore |= ndimage.binary_dilation(letters, iterations=2)
    if bar is not None:
        ignore |= bar.mask(image.shape)
        bx0, by0, bx1, by1 = bar.found_box
        inside = window[0] <= bx0 and window[1] <= by0 and bx1 <= window[2] and by1 <= window[3]
        boxed = any(x0 <= bx0 and y0 <= by0 and bx1 <= x1 and by1 <= y1 for x0, y0, x1, y1 in boxes)
        if inside and not boxed:  # drawn over the film: its label too
            ignore |= ndimage.binary_dilation(label_strokes(image, bar), iterations=2)
    return Annotations(window, strips, boxes, bar, ignore)

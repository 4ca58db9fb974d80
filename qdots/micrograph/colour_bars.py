"""Scale bars drawn in one colour: the picture's darkest or lightest (`colour_bar`), drawn askew (`tilted_bar`), or a
flat grey (`grey_bar`), each measured between its ends at half contrast
(`qdots.micrograph.bar_profile.half_contrast_length`)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy import ndimage

from labrig.compiled import jit

from .bar import MIN_BAR, ScaleBar
from .bar_profile import (
    BAR_SURROUNDINGS,
    MIN_CONTRAST,
    MIN_SHARE,
    bar_contrast,
    half_contrast_length,
    stands_out_both_sides,
)

#: A scale bar is at least this many times longer than it is thick (a journal figure's solid "1 um" bar of 72 x 16 px,
#: 4.5 times, was missed at 5; no other object on the 88 pictures of the development halves, the real micrographs'
#: and EMPS's, is taken at 4 that was not at 5).
BAR_ASPECT = 4.0
#: A stubbier bar, down to STUBBY_ASPECT times longer than thick, is taken where it is drawn as a solid rectangle: at
#: least SOLID of its spine's rows and columns in the bar colour (`solid_rectangle`). On the second EMPS development
#: batch, a solid black bar of 59 x 20 px (2.95 times) under its label; the same search at 2.5 without that test took
#: the black gap between four touching discs of a segmentation (43 x 15 px) for a bar, 0.86 of it in the colour; drawn
#: stubby bars on the EMPS pictures in no batch, 0.987-1.0.
STUBBY_ASPECT, SOLID = 2.5, 0.95
#: ... and stands free: under EDGE_ROW of the row just above its spine, and of the row just below, in the bar colour
#: (that bar: 0.05, a "µ"'s tail touching it; the gap between discs: 0.42 and 0.47).
EDGE_ROW = 0.25
#: Cuts in a ruled bar up to this many px wide are closed; holes in a bar of fewer px are specks of noise.
BAR_GAP, MIN_HOLE = 3, 4
#: A bar drawn askew (`tilted_bar`): its top and bottom edges, fitted over the middle SKEW_MIDDLE of its columns, each
#: within SKEW_STRAIGHT px of a line, their slopes within SKEW_PARALLEL of each other, climbing at most MAX_SKEW rows a
#: px (1.7 degrees). On two EMPS pictures in no batch, scanned figures, bars climbing 2 and 2.8 rows over 259 and 99 px
#: (edges within 0.71-0.88 px of their lines); without the straight and parallel edges, a data strip's frame with its
#: table's cells, 142 px, was taken on a third.
SKEW_MIDDLE, SKEW_STRAIGHT, SKEW_PARALLEL, MAX_SKEW = 0.8, 1.0, 0.01, 0.03
#: A bar holds at most OFF_SPINE times as many pixels off its spine as on it (its ticks, end caps, or its label's
#: letters where they touch it: a cropped journal figure's bold "20 nm" set on its bar, 0.96 times).
OFF_SPINE = 2.0
#: Nor does it taper to its long side: at most one row on either side of its spine is TAPER of the spine's length or
#: more (a bar's edge blurred by JPEG). On the EMPS development half, a ZEISS logo's swoosh (a white arc whose rows
#: widen to 12, 22, 29 and 34 px) and a trapezoid were taken for bars; the bars drawn there have at most one such row.
TAPER = 0.5
#: Pixels within this share of the image's range of its darkest (or lightest) value are bar colour.
BAR_TOLERANCE = 0.05
#: A piece of a bar's component off its spine at least GLYPH_SIDE px wide and tall, its middle more than GLYPH_AWAY of
#: the spine's length from either end, is a letter of its label that touches it, not the bar's (`bar_rows`): on the
#: bars found on 614 EMPS and real pictures, the tails of "µ"s touching a bar were 4-35 px wide and 6-51 tall, 0.5-0.57
#: of the way along; end caps lie within 0.05 of an end and ruler ticks are 1-2 px wide.
GLYPH_SIDE, GLYPH_AWAY = 4, 0.1

#: A bar drawn in a flat grey, neither the picture's darkest colour nor its lightest (`grey_bar`): its inside is flat,
#: each pixel within FLAT_STEP of the picture's range of its four neighbours, in runs along its rows at least as long
#: as the colour search looks at. On the EMPS pictures in no batch where no bar was found, a light grey bar (223 of
#: 69-255) under its label where cubes' rims are lighter, and a grey one (84 of 7-255) in a white box whose letters
#: are as dark: their insides vary by 1 and 3 levels; a film's noise by far more.
FLAT_STEP = 0.02
#: The MAX_GREY longest flat runs are looked at (a picture drawn flat throughout holds many).
MAX_GREY = 10

def colour_bar(image: np.ndarray, shortest: float, polarity: bool | None = None,
               askew: bool = True) -> ScaleBar | None:
    """`qdots.micrograph.scale.find_scale_bar`'s search by colour: the longest bar at least ``shortest`` px long in ``image``'s darkest or
    lightest colour (only the darkest where ``polarity`` is True, the lightest where False), a component that is no
    bar as it lies measured sheared upright where it is one drawn askew (`tilted_bar`, where ``askew``), or None."""
    low, high = float(image.min()), float(image.max())
    span = high - low
    if not span > 0:
        return None
    best = None
    for dark, value in ((True, low), (False, high)):
        if polarity is not None and dark != polarity:
            continue
        found = bar_of_colour(image, np.abs(image - value) <= BAR_TOLERANCE * span, value, dark, shortest, span, askew)
        if found is not None and (best is None or found.length_px > best.length_px):
            best = found
    return best


def bar_of_colour(image: np.ndarray, colour: np.ndarray, level: float, dark: bool, shortest: float, span: float,
                  askew: bool = True, holding: tuple[slice, slice] | None = None) -> ScaleBar | None:
    """The longest bar at least ``shortest`` px long drawn in ``colour`` (a boolean mask of ``image``: the pixels of
    the bar's colour, within `BAR_TOLERANCE` of ``span``, the picture's range of values, of ``level``; ``dark``
    whether it is darker than what surrounds it), of a component whose box holds ``holding`` (rows, columns) where
    given, or None: the tests are `qdots.micrograph.scale.find_scale_bar`'s."""
    best = None
    h_img, w_img = image.shape
    labels, _n = ndimage.label(closed_lines(colour, BAR_GAP))
    for k, box in enumerate(ndimage.find_objects(labels), start=1):
        if box is None:
            continue
        rows, cols = box
        h, w = rows.stop - rows.start, cols.stop - cols.start
        across = (rows.start == 0 and rows.stop == h_img) or (cols.start == 0 and cols.stop == w_img)
        corner = (rows.start == 0 or rows.stop == h_img) and (cols.start == 0 or cols.stop == w_img)
        if across or corner or h > w or 1.5 * w < shortest or w < STUBBY_ASPECT * h / 4:
            continue
        if holding is not None and not (rows.start <= holding[0].start and holding[0].stop <= rows.stop
                                        and cols.start <= holding[1].start and holding[1].stop <= cols.stop):
            continue
        own = labels[box] == k
        filled = ndimage.binary_fill_holes(own)
        holes = filled & ~own
        if (holes & (labels[box] != k) & (labels[box] > 0)).any():
            continue  # a box around a bar or text, not a bar
        found = bar_candidate(filled, holes)
        if found is None and askew:
            tilted = tilted_bar(image, (cols.start, rows.start, cols.stop, rows.stop), filled, level, dark, shortest,
                                span)
            if tilted is not None and (best is None or tilted.length_px > best.length_px):
                best = tilted
            continue
        if found is None or (found[0] < BAR_ASPECT * found[1] and not solid_rectangle(colour[box], found)):
            continue
        plain, noise, outline = bar_contrast(image, (cols.start, rows.start, cols.stop, rows.stop),
                                             colour[box] & own)
        contrast = max(plain, outline)
        if contrast < MIN_SHARE * span or contrast < MIN_CONTRAST * noise:
            continue  # noise pixels, or a bright edge of the picture's own, joined into a bar
        top, bottom = spine_rows(filled)  # its line's rows: a ruler's end caps may reach its label box's edge
        if not stands_out_both_sides(image, (cols.start, rows.start + top, cols.stop, rows.start + bottom),
                                     (colour[box] & own)[top:bottom], plain):
            continue  # the dark fringe along a dark particle's edge
        edge = rows.start == 0 or cols.start == 0 or rows.stop == h_img or cols.stop == w_img
        ends = (cols.start + found[4], rows.start, cols.start + found[4] + found[0], rows.stop)
        length = half_contrast_length(image, ends, found[1], float(found[0]), rows.start + found[3])
        if length < shortest:
            continue
        if best is None or length > best.length_px:
            top, bottom = bar_rows(filled, found)
            extent = (cols.start, rows.start, cols.stop, rows.stop)
            best = ScaleBar(length, (cols.start, rows.start + top, cols.stop, rows.start + bottom), dark,
                            ruled=bool(holes.any() or found[2] > 0 or (own & ~colour[box]).any()),
                            thickness=found[1], at_edge=bool(edge),
                            extent=None if (top, bottom) == (0, rows.stop - rows.start) else extent)
    return best


def grey_bar(image: np.ndarray, shortest: float) -> ScaleBar | None:
    """The longest bar at least ``shortest`` px long drawn in a flat grey (`FLAT_STEP`): where the pixels of ``image``
    that are flat among their four neighbours (`flat_runs`) make a component that lies along the rows (`STUBBY_ASPECT`
    times wider than tall at least; the `MAX_GREY` widest), the pixels around it within `BAR_TOLERANCE` of the
    picture's range of its median are searched as a colour (`bar_of_colour`, with its tests), darker than its
    surroundings (within `BAR_SURROUNDINGS` px) or lighter; only the component of that colour that holds the flat
    inside is looked at (a longer line of the same grey elsewhere, a frame's or a table's, is not this bar), and the
    whole of it, not what lies around the flat inside (a strip's band cut by a letter is not a bar from the picture's
    edge to the letter). The darkest and lightest colours are `colour_bar`'s. None where no such bar is drawn."""
    image = np.asarray(image, dtype=float)
    low, high = float(image.min()), float(image.max())
    span = high - low
    if not span > 0:
        return None
    flat = flat_runs(image, FLAT_STEP * span, max(1, int(shortest / 1.5)))
    if not flat.any():
        return None
    labels, _n = ndimage.label(flat)
    runs = []
    for k, box in enumerate(ndimage.find_objects(labels), start=1):
        if box is not None and STUBBY_ASPECT * (box[0].stop - box[0].start) <= box[1].stop - box[1].start:
            runs.append((box[1].stop - box[1].start, k, box))
    best = None
    for _w, k, (rows, cols) in sorted(runs, reverse=True)[:MAX_GREY]:
        level = float(np.median(image[rows, cols][labels[rows, cols] == k]))
        if min(level - low, high - level) <= BAR_TOLERANCE * span:
            continue  # the darkest or the lightest colour: `colour_bar`'s
        colour = np.abs(image - level) <= BAR_TOLERANCE * span
        m = BAR_SURROUNDINGS
        around = image[max(0, rows.start - m):rows.stop + m, max(0, cols.start - m):cols.stop + m]
        found = bar_of_colour(image, colour, level, level < float(np.median(around)), shortest, span,
                              holding=(rows, cols))
        if found is not None and (best is None or found.length_px > best.length_px):
            best = found
    return best


def flat_runs(image: np.ndarray, step: float, run: int) -> np.ndarray:
    """The pixels of ``image`` within ``step`` of each of their four neighbours, in runs along a row of at least
    ``run`` of them (a boolean mask; the picture's outer rows and columns are never set), in one compiled pass."""
    image = np.ascontiguousarray(image, dtype=np.float64)
    out = np.zeros(image.shape, dtype=np.bool_)
    _flat_runs(image, float(step), int(run), out)
    return out


@jit
def _flat_runs(image, step, run, out):
    """`flat_runs` into ``out`` (all False)."""
    h, w = image.shape
    for row in range(1, h - 1):
        start = -1
        for col in range(1, w):
            flat = False
            if col < w - 1:
                v = image[row, col]
                flat = (abs(image[row, col - 1] - v) <= step and abs(image[row, col + 1] - v) <= step
                        and abs(image[row - 1, col] - v) <= step and abs(image[row + 1, col] - v) <= step)
            if flat and start < 0:
                start = col
            elif not flat and start >= 0:
                if col - start >= run:
                    for k in range(start, col):
                        out[row, k] = True
                start = -1


def tilted_bar(image: np.ndarray, box: tuple[int, int, int, int], component: np.ndarray, level: float, dark: bool,
               shortest: float, span: float) -> ScaleBar | None:
    """A bar drawn a little askew (a figure scanned or rotated: its rows climb 2 rows over its 260 px on an EMPS
    picture, so that no row runs its length), ``component`` (a boolean crop of ``box``, holes filled) drawn at
    ``level`` of ``image`` (dark or light on its ground, ``dark``; ``span`` the picture's range): where its top and
    bottom edges are straight (each within `SKEW_STRAIGHT` px of a line fitted over its middle, `SKEW_MIDDLE` of its
    columns) and parallel (their slopes within `SKEW_PARALLEL`), climbing between one row over its length and
    `MAX_SKEW` rows a px, the picture around it (`BAR_SURROUNDINGS` px and the climb more) is sheared upright, column
    by column, and its pixels within `BAR_TOLERANCE` of ``level`` searched for a bar (`bar_of_colour`, not askew
    again); its length is that bar's over the cosine of the slope, its box that of the component. None otherwise."""
    x0, y0, x1, y1 = box
    w = x1 - x0
    columns = np.flatnonzero(component.any(axis=0))
    if w < shortest or columns.size < SKEW_MIDDLE * w:
        return None
    middle = columns[int(0.5 * (1 - SKEW_MIDDLE) * columns.size):int(0.5 * (1 + SKEW_MIDDLE) * columns.size)]
    if middle.size < 3:
        return None
    top = np.argmax(component[:, middle], axis=0)
    bottom = component.shape[0] - 1 - np.argmax(component[::-1, middle], axis=0)
    slopes = []
    for edge in (top, bottom):
        slope, intercept = np.polyfit(middle, edge, 1)
        if np.abs(edge - (slope * middle + intercept)).max() > SKEW_STRAIGHT:
            return None  # an edge that is not straight: a particle's rim, not a bar
        slopes.append(float(slope))
    slope = 0.5 * (slopes[0] + slopes[1])
    if abs(slopes[0] - slopes[1]) > SKEW_PARALLEL or not 1.0 / w <= abs(slope) <= MAX_SKEW:
        return None
    h_img, w_img = image.shape
    climb = int(np.ceil(abs(slope) * w)) + 1
    margin = BAR_SURROUNDINGS + climb
    rx0, ry0, rx1, ry1 = max(0, x0 - margin), max(0, y0 - margin), min(w_img, x1 + margin), min(h_img, y1 + margin)
    shifts = np.round(slope * (np.arange(rx0, rx1) - 0.5 * (x0 + x1))).astype(int)
    rows = np.clip(np.arange(ry0, ry1)[:, None] + shifts[None, :], 0, h_img - 1)
    upright = image[rows, np.arange(rx0, rx1)[None, :]]  # each column moved by its climb: the bar along the rows
    bar = bar_of_colour(upright, np.abs(upright - level) <= BAR_TOLERANCE * span, level, dark, shortest, span,
                        askew=False)
    if bar is None:
        return None
    bx0, by0, bx1, by1 = bar.box
    centre = 0.5 * (by0 + by1) + ry0
    if not (bx0 + rx0 < x1 and x0 < bx1 + rx0 and y0 <= centre <= y1):
        return None  # a bar elsewhere in the region, not this component sheared
    return replace(bar, length_px=bar.length_px * float(np.hypot(1.0, slope)), box=box, extent=None,
                   measured=f"at half contrast, drawn askew ({slope * w:+.1f} rows over its length) and sheared upright")


def spine(component: np.ndarray) -> tuple[int, int, int, int, int] | None:
    """The spine of a horizontal bar-like component (a boolean crop, its holes filled): ``(length, thickness,
    off, middle, start)`` where the spine's rows are those whose longest run of pixels is at least 0.9 of the longest
    of any row (``thickness`` of them, ``middle`` the middle one), ``off`` the pixels outside those rows (ticks, end
    caps), and ``length`` the longest run of columns set on at least half of those rows, from column ``start``: one
    row's run reaching further (a bright edge of the picture touching the bar) does not lengthen it; None when the
    spine does not span the component (text, a chain of dots)."""
    runs = np.array([longest_run(row) for row in component], dtype=int)
    longest = int(runs.max())
    if longest < 0.9 * component.shape[1]:
        return None
    rows = runs >= 0.9 * longest
    on = np.flatnonzero(rows)
    wide = runs >= TAPER * longest
    if max(int(wide[:on[0]].sum()), int(wide[on[-1] + 1:].sum())) > 1:
        return None  # it tapers to its long side, over rows: a logo's swoosh, a disc cut by the picture's edge
    thickness = int(rows.sum())
    columns = np.pad(2 * component[rows].sum(axis=0) >= thickness, 1).astype(np.int8)
    starts, stops = np.flatnonzero(np.diff(columns) == 1), np.flatnonzero(np.diff(columns) == -1)
    best = int(np.argmax(stops - starts))
    return int(stops[best] - starts[best]), thickness, int(component[~rows].sum()), int(on[len(on) // 2]), \
        int(starts[best])


def bar_candidate(component: np.ndarray, holes: np.ndarray) -> tuple[int, int, int, int, int] | None:
    """(length, thickness, pixels off the spine, the spine's middle row, its first column; `spine`) when
    ``component`` (a boolean crop, holes filled) is a scale bar, solid, ruled or in an outline: a spine at least
    `qdots.micrograph.bar.MIN_BAR` px long and `STUBBY_ASPECT` times its thickness, at most `OFF_SPINE` times as much of it off the spine as on
    it (ticks, end caps, a label whose letters touch the bar), and its holes (the empty blocks of a checkered bar;
    ``holes`` the filled-in pixels) as tall as half the spine (a box holding text and a smaller bar has low holes)."""
    found = spine(component)
    if found is None:
        return None
    length, thickness, off, _middle, _start = found
    if length < MIN_BAR or length < STUBBY_ASPECT * thickness or off > OFF_SPINE * length * thickness:
        return None
    if holes.any():
        hole_labels, _ = ndimage.label(holes)
        sizes = np.bincount(hole_labels.ravel())[1:]
        for (rows, _cols), size in zip(ndimage.find_objects(hole_labels), sizes):
            if size >= MIN_HOLE and rows.stop - rows.start < 0.5 * thickness:
                return None  # a hole of its own, low: text or a smaller bar in a box (specks of noise aside)
    return found


def solid_rectangle(colour: np.ndarray, found: tuple[int, int, int, int, int]) -> bool:
    """Whether a bar's spine (``found``, `spine`) is drawn as a solid rectangle standing free: at least `SOLID` of the
    rectangle of its rows and columns in the bar colour (``colour``, a boolean crop of the component's box, before any
    closing), and under `EDGE_ROW` of the row just above it and of the row just below it (where the crop has them):
    a letter's tail may touch a drawn bar, where the gap between touching discs narrows row by row."""
    length, thickness, _off, middle, start = found
    top = max(0, middle - thickness // 2)
    block = colour[top:top + thickness, start:start + length]
    if block.size == 0 or float(block.mean()) < SOLID:
        return False
    beside = [colour[row, start:start + length] for row in (top - 1, top + thickness) if 0 <= row < colour.shape[0]]
    return all(float(row.mean()) < EDGE_ROW for row in beside)


def bar_rows(component: np.ndarray, found: tuple[int, int, int, int, int]) -> tuple[int, int]:
    """The rows of a bar's ``component`` (a boolean crop, holes filled; ``found`` its `spine`) that are the bar's own,
    ``(top, bottom)``, bottom exclusive: its spine's and its blurred edges' (rows at least `TAPER` of its longest run),
    and those of what stands off them (end caps, ticks), less a letter of its label that touches it: a piece off the spine at least `GLYPH_SIDE` px
    wide and tall, away from its ends (its middle more than `GLYPH_AWAY` of the spine's length from either). On the
    second EMPS development batch a "µ"'s tail touching its bar made the bar's box hold its label (rows 456-483 for a
    bar on rows 480-484)."""
    length, _thickness, _off, middle, start = found
    top, bottom = spine_rows(component)
    on = np.zeros(len(component), dtype=bool)
    on[top:bottom] = True
    off = component & ~on[:, None]
    labels, _n = ndimage.label(off)
    for piece in ndimage.find_objects(labels):
        if piece is None:
            continue
        rs, cs = piece
        centre = 0.5 * (cs.start + cs.stop) - start
        glyph = (rs.stop - rs.start >= GLYPH_SIDE and cs.stop - cs.start >= GLYPH_SIDE
                 and GLYPH_AWAY * length < centre < (1.0 - GLYPH_AWAY) * length)
        if not glyph:
            top, bottom = min(top, rs.start), max(bottom, rs.stop)
    return top, bottom


def spine_rows(component: np.ndarray) -> tuple[int, int]:
    """The rows of a bar's ``component`` (a boolean crop, holes filled) that hold its line: its spine and its blurred
    edges, the rows whose longest run is at least `TAPER` of the longest, ``(top, bottom)``, bottom exclusive."""
    runs = np.array([longest_run(row) for row in component], dtype=int)
    rows = np.flatnonzero(runs >= TAPER * runs.max())
    return int(rows[0]), int(rows[-1]) + 1


def longest_run(row: np.ndarray) -> int:
    """The longest run of set pixels in ``row`` (boolean)."""
    edges = np.diff(np.pad(row, 1).astype(np.int8))
    starts, stops = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    return int((stops - starts).max()) if starts.size else 0


def closed_lines(mask: np.ndarray, length: int) -> np.ndarray:
    """``mask`` with the gaps of its rows and of its columns closed by a line of ``length`` px (odd): ``mask |
    binary_closing(mask, ones((1, length))) | binary_closing(mask, ones((length, 1)))``, scipy's closings (the pixels
    beyond the edge unset), in one compiled pass."""
    if length < 1 or length % 2 == 0:
        raise ValueError(f"length must be an odd number of px >= 1, got {length}")
    mask = np.ascontiguousarray(mask, dtype=np.bool_)
    out = mask.copy()
    _close_lines(mask, length // 2, out)
    return out


@jit
def _close_lines(mask, half, out):
    """`closed_lines` into ``out`` (a copy of ``mask``): rows, then columns."""
    h, w = mask.shape
    grown = np.zeros(w, dtype=np.bool_)
    for row in range(h):  # a row's dilation, then its erosion (False within ``half`` of either end)
        for col in range(w):
            grown[col] = False
            for k in range(max(0, col - half), min(w, col + half + 1)):
                if mask[row, k]:
                    grown[col] = True
                    break
        for col in range(half, w - half):
            if not out[row, col]:
                closed = True
                for k in range(col - half, col + half + 1):
                    if not grown[k]:
                        closed = False
                        break
                out[row, col] = closed
    down = np.zeros((h, w), dtype=np.bool_)  # each column's dilation
    for row in range(h):
        for k in range(max(0, row - half), min(h, row + half + 1)):
            for col in range(w):
                if mask[k, col]:
                    down[row, col] = True
    for row in range(half, h - half):
        for col in range(w):
            if not out[row, col]:
                closed = True
                for k in range(row - half, row + half + 1):
                    if not down[k, col]:
                        closed = False
                        break
                out[row, col] = closed

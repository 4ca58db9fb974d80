"""The scale of a micrograph: given in nm per pixel, or read off the scale bar drawn on it."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage

from labrig.threads import run_tasks
from labrig.validate import InputError, real

from .choices import MAX_NM_PER_PX, MIN_NM_PER_PX
from .read import UNIT_NM

#: A scale bar is at least this many times longer than it is thick (a journal figure's solid "1 um" bar of 72 x 16 px,
#: 4.5 times, was missed at 5; no other object on the 88 pictures of the development halves, the real micrographs'
#: and EMPS's, is taken at 4 that was not at 5).
BAR_ASPECT = 4.0
#: Cuts in a ruled bar up to this many px wide are closed; holes in a bar of fewer px are specks of noise.
BAR_GAP, MIN_HOLE = 3, 4
#: Shortest scale bar, px; a bar's surroundings are read within BAR_SURROUNDINGS px of its ends.
MIN_BAR, BAR_SURROUNDINGS = 10, 12
#: A scale bar is drawn to be read: at least MIN_BAR_SHARE of the picture's longer side (`shortest_bar`). On the
#: development half of the real micrographs, the bars drawn measure 0.10-0.25 of it; what was taken for a bar on two
#: pictures without one, 0.018 (a 10 px run of a sphere's bright rim) and 0.041 (a bright particle cut by the
#: picture's lower edge).
MIN_BAR_SHARE = 0.05
#: A bar holds at most OFF_SPINE times as many pixels off its spine as on it (its ticks, end caps, or its label's
#: letters where they touch it: a cropped journal figure's bold "20 nm" set on its bar, 0.96 times).
OFF_SPINE = 2.0
#: Nor does it taper to its long side: at most one row on either side of its spine is TAPER of the spine's length or
#: more (a bar's edge blurred by JPEG). On the EMPS development half, a ZEISS logo's swoosh (a white arc whose rows
#: widen to 12, 22, 29 and 34 px) and a trapezoid were taken for bars; the bars drawn there have at most one such row.
TAPER = 0.5
#: Pixels within this share of the image's range of its darkest (or lightest) value are bar colour.
BAR_TOLERANCE = 0.05
#: A bar stands out of what surrounds it (within `BAR_SURROUNDINGS` px) by at least MIN_CONTRAST times the pixel noise
#: there and MIN_SHARE of the image's range (`bar_contrast`). Measured on the development half of the real
#: micrographs: drawn bars 6.2-97 noise deviations (infinitely many in noiseless graphics) and 0.37-1 of the range;
#: what was taken for a bar on pictures without one: bright noise pixels joined by the closing, 1.5 and 2.9 deviations
#: (0.05 and 0.01 of the range), a bright crystal's edge and a stain's, 14 and 5.5 deviations (0.12 of the range).
MIN_CONTRAST, MIN_SHARE = 4.0, 0.2
#: A bar in an outline (a white bar edged in black on a light picture) is measured against its outline, the OUTLINE px
#: around it (`bar_contrast`).
OUTLINE = 2
#: And it stands out of the rows on each side of it by at least SIDE_SHARE of that (`stands_out_both_sides`): on the
#: EMPS development half, a dark particle's edge fringe taken for a bar, 0.29 on the particle's side.
SIDE_SHARE = 0.5
#: A thin bar (`thin_bar`: an instrument's data strip draws its bar as a line a few px thick with a mark at each end,
#: grey after JPEG, not the picture's darkest or lightest) is a line at most THIN_LINE px thick that stands out of the
#: pixels above and below it by LINE_CONTRAST of the image's range (a black top-hat over LINE_REACH rows), lies on a
#: flat ground (the rows beside it vary by at most LINE_GROUND of the range: a strip or a label's ground, not a film),
#: and ends at each end in a mark (cap or tick) crossing it: at least END_MARK px above it and as many below (within
#: MARK_ROWS rows of it; its label's letters lie further), within END_REACH px of its end, that stand MARK_SHARE of
#: the line's own contrast out of its ground (a label box drawn as an outline has lines whose ends turn one way only).
#: On the EMPS development pictures, ZEISS strips' bars: lines 1-3 px thick, 0.49-0.58 of the range out of a ground
#: varying by 0.003-0.014 of it, their caps after JPEG 0.41 of the line's contrast; a ZEISS logo's swoosh in the same
#: strips is such a line without end marks. The distance between the marks' middles was within 0.4 % of line profiles
#: read by hand across the marks on four of them (ZEISS and FEI bars of 60-244 px).
THIN_LINE, LINE_REACH, LINE_CONTRAST, LINE_GROUND = 4, 9, 0.25, 0.05
END_MARK, END_REACH, MARK_SHARE, MARK_ROWS = 3, 3, 1.0 / 3.0, 7
#: A ruler of ticks (`band_ruler`) has at least MIN_TICKS ticks at most TICK_WIDTH px wide, its gaps within TICK_EVEN
#: of a whole number of its first gap, and at most MAX_HIDDEN ticks hidden (by a particle where the ruler is drawn over
#: the film). A Hitachi data strip's ruler has 11 ticks, 4-5 px wide at a quarter of the picture's range.
MIN_TICKS, TICK_EVEN, TICK_WIDTH, MAX_HIDDEN = 5, 0.1, 6, 1
#: A ruler's ticks stand at least TICK_APART of their width apart (Hitachi's: 21.5 px apart, 4-5 px wide; a word's
#: letters, 1.2-1.6 of theirs).
TICK_APART = 3.0
#: Lengths a scale bar can state, nm: 0.01 nm to 1 cm.
MIN_BAR_NM, MAX_BAR_NM = 1e-2, 1e7


@dataclass(frozen=True)
class ScaleBar:
    """A scale bar found on an image.

    Attributes
    ----------
    length_px : float
        Its length, px (along its long side), as ``measured`` says.
    box : (int, int, int, int)
        ``(x0, y0, x1, y1)`` of the bar, px (x the column, y the row; ``x1``, ``y1`` exclusive).
    dark : bool
        Whether it is drawn in the image's darkest colour (else its lightest).
    ruled : bool
        Whether it is divided or ticked (cuts, blocks in an outline, ticks, end caps) rather than a plain bar.
    thickness : int
        The thickness of its spine, px (ticks and end caps aside).
    at_edge : bool
        Whether it reaches the picture's edge (its length may then be cut, and is that of what is shown).
    measured : str
        How its length was measured: between its ends' half-contrast points (`half_contrast_length`), between the
        middles of its end marks (`band_bar`), or from its first tick to its last (`band_ruler`).
    """

    length_px: float
    box: tuple[int, int, int, int]
    dark: bool
    ruled: bool = False
    thickness: int = 0
    at_edge: bool = False
    measured: str = "at half contrast"

    def mask(self, shape: tuple[int, int], margin: int = 2) -> np.ndarray:
        """The bar's pixels and ``margin`` px around it, as a boolean image of ``shape``."""
        out = np.zeros(shape, dtype=bool)
        x0, y0, x1, y1 = self.box
        out[max(0, y0 - margin):y1 + margin, max(0, x0 - margin):x1 + margin] = True
        return out


def check_nm_per_px(value, name: str = "nm_per_px") -> float:
    """A scale in nm per pixel: a finite number in [`MIN_NM_PER_PX`, `MAX_NM_PER_PX`]."""
    return real(name, value, MIN_NM_PER_PX, MAX_NM_PER_PX, unit="nm per px")


def parse_length(text: str, name: str = "scale_bar") -> float:
    """A length such as ``"200nm"``, ``"0.5 um"`` or ``"2 µm"``, in nm, within [`MIN_BAR_NM`, `MAX_BAR_NM`]."""
    match = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*([A-Za-z\u00b5\u03bc\u00c5]+)\s*", str(text))
    if not match:
        raise InputError(f"{name} must be a length with its unit, such as 200nm or 0.5um, got {text!r}")
    value, unit = float(match.group(1)), match.group(2).replace("\u03bc", "\u00b5")
    per_unit = UNIT_NM.get(unit.lower())
    if per_unit is None:
        raise InputError(f"{name}: unknown length unit {unit!r} (use nm, um, µm, mm, pm or A)")
    nm = value * per_unit
    if not (math.isfinite(nm) and MIN_BAR_NM <= nm <= MAX_BAR_NM):
        raise InputError(f"{name} must be a length in [{MIN_BAR_NM:g} nm, {MAX_BAR_NM / 1e6:g} mm], got {text!r}")
    return nm


def spine(component: np.ndarray) -> tuple[int, int, int, int, int] | None:
    """The spine of a horizontal bar-like component (a boolean crop, its holes filled): ``(length, thickness,
    off, middle, start)`` where the spine's rows are those whose longest run of pixels is at least 0.9 of the longest
    of any row (``thickness`` of them, ``middle`` the middle one), ``off`` the pixels outside those rows (ticks, end
    caps), and ``length`` the longest run of columns set on at least half of those rows, from column ``start``: one
    row's run reaching further (a bright edge of the picture touching the bar) does not lengthen it; None when the
    spine does not span the component (text, a chain of dots)."""
    padded = np.pad(component, ((0, 0), (1, 1)))
    edges = np.diff(padded.astype(np.int8), axis=1)
    runs = np.zeros(component.shape[0], dtype=int)
    for row in range(component.shape[0]):
        starts, stops = np.flatnonzero(edges[row] == 1), np.flatnonzero(edges[row] == -1)
        if starts.size:
            runs[row] = int((stops - starts).max())
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
    `MIN_BAR` px long and `BAR_ASPECT` times its thickness, at most `OFF_SPINE` times as much of it off the spine as on
    it (ticks, end caps, a label whose letters touch the bar), and its holes (the empty blocks of a checkered bar;
    ``holes`` the filled-in pixels) as tall as half the spine (a box holding text and a smaller bar has low holes)."""
    found = spine(component)
    if found is None:
        return None
    length, thickness, off, _middle, _start = found
    if length < MIN_BAR or length < BAR_ASPECT * thickness or off > OFF_SPINE * length * thickness:
        return None
    if holes.any():
        hole_labels, _ = ndimage.label(holes)
        sizes = np.bincount(hole_labels.ravel())[1:]
        for (rows, _cols), size in zip(ndimage.find_objects(hole_labels), sizes):
            if size >= MIN_HOLE and rows.stop - rows.start < 0.5 * thickness:
                return None  # a hole of its own, low: text or a smaller bar in a box (specks of noise aside)
    return found


def shortest_bar(shape: tuple[int, int]) -> float:
    """The shortest scale bar taken on a picture of ``shape``, px: `MIN_BAR`, or `MIN_BAR_SHARE` of its longer
    side where that is more."""
    return max(float(MIN_BAR), MIN_BAR_SHARE * max(shape))


def find_scale_bar(image: np.ndarray) -> ScaleBar | None:
    """The longest scale bar drawn on ``image`` in its darkest or lightest colour, or None.

    The pixels within `BAR_TOLERANCE` of the image's darkest (or lightest) value are closed along rows and
    columns by `BAR_GAP` px (the thin cuts of a ruled bar) and their holes filled (the blocks of a checkered
    bar in its outline); a component is a bar when it is one horizontally or vertically (`bar_candidate`), and not a
    box: its holes hold nothing of its colour (a label box drawn as an outline holds its bar and its text). A
    component that spans the image from side to side is a frame, not a bar; one that reaches a side with one end
    only is a bar cut by the picture's edge, which cropped figures often show (`ScaleBar.at_edge`). A bar is drawn
    along the picture's rows: a component longer down than across is not one (on the development halves of the real
    micrographs and of EMPS, 88 pictures, every drawn bar is horizontal, and the three upright "bars" taken before were
    a panel label's "1" and two dark gaps between touching particles). Its length is
    measured at half contrast (`half_contrast_length`), and is at least `shortest_bar`. Dots are never that flat in
    colour, nor that long; a bar stands out of what surrounds it (`bar_contrast`; or of its outline, where it is drawn
    in one), where noise pixels joined into a bar do not, and out of the rows on both of its sides
    (`stands_out_both_sides`), where the darkest fringe along a dark particle's edge does not. The thin bars and the
    rulers of ticks of instruments' data strips are found by `thin_bar`.
    """
    image = np.asarray(image, dtype=float)
    low, high = float(image.min()), float(image.max())
    span = high - low
    if not span > 0:
        return None
    best = None
    h_img, w_img = image.shape
    shortest = shortest_bar(image.shape)
    colours = [np.abs(image - value) <= BAR_TOLERANCE * span for value in (low, high)]
    closings = run_tasks([lambda colour=colour, line=line: ndimage.binary_closing(colour, np.ones(line))
                          for colour in colours for line in ((1, BAR_GAP), (BAR_GAP, 1))])  # side by side in threads
    for dark, colour, along, across in zip((True, False), colours, closings[::2], closings[1::2]):
        closed = colour | along | across
        labels, _n = ndimage.label(closed)
        for k, box in enumerate(ndimage.find_objects(labels), start=1):
            if box is None:
                continue
            rows, cols = box
            h, w = rows.stop - rows.start, cols.stop - cols.start
            across = (rows.start == 0 and rows.stop == h_img) or (cols.start == 0 and cols.stop == w_img)
            corner = (rows.start == 0 or rows.stop == h_img) and (cols.start == 0 or cols.stop == w_img)
            if across or corner or h > w or w < shortest or w < BAR_ASPECT * h / 4:
                continue
            own = labels[box] == k
            filled = ndimage.binary_fill_holes(own)
            holes = filled & ~own
            if (holes & (labels[box] != k) & (labels[box] > 0)).any():
                continue  # a box around a bar or text, not a bar
            found = bar_candidate(filled, holes)
            if found is None:
                continue
            plain, noise, outline = bar_contrast(image, (cols.start, rows.start, cols.stop, rows.stop),
                                                 colour[box] & own)
            contrast = max(plain, outline)
            if contrast < MIN_SHARE * span or contrast < MIN_CONTRAST * noise:
                continue  # noise pixels, or a bright edge of the picture's own, joined into a bar
            if not stands_out_both_sides(image, (cols.start, rows.start, cols.stop, rows.stop), colour[box] & own,
                                         plain):
                continue  # the dark fringe along a dark particle's edge
            edge = rows.start == 0 or cols.start == 0 or rows.stop == h_img or cols.stop == w_img
            ends = (cols.start + found[4], rows.start, cols.start + found[4] + found[0], rows.stop)
            length = half_contrast_length(image, ends, found[1], float(found[0]), rows.start + found[3])
            if length < shortest:
                continue
            if best is None or length > best.length_px:
                best = ScaleBar(length, (cols.start, rows.start, cols.stop, rows.stop), dark,
                                ruled=bool(holes.any() or found[2] > 0 or (own & ~colour[box]).any()),
                                thickness=found[1], at_edge=bool(edge))
    thin = thin_bar(image, shortest)
    return thin if thin is not None and (best is None or thin.length_px > best.length_px) else best


def thin_bar(image: np.ndarray, shortest: float) -> ScaleBar | None:
    """The longest thin bar with a mark at each end on ``image`` (see `THIN_LINE`), at least ``shortest`` px between
    its marks, or None: the bar of an instrument's data strip, a line a few px thick, grey after JPEG, with end caps or
    ticks; or two such lines on one row with the label between them and a mark at each outer end (FEI's). Its length
    is the distance between the middles of its end marks. Only the bands of rows near a flat run of a quarter of
    ``shortest`` or more (a strip's or a label's ground) are searched: on a film, none."""
    image = np.asarray(image, dtype=float)
    span = float(np.ptp(image))
    if not span > 0:
        return None
    flat = (np.abs(np.diff(image, axis=1)) <= LINE_GROUND * span).view(np.uint8)
    ground = ndimage.minimum_filter1d(flat, max(MIN_BAR, int(0.25 * shortest)), axis=1).any(axis=1)
    bands, _n = ndimage.label(ndimage.binary_dilation(ground, iterations=LINE_REACH + MARK_ROWS))
    best = None
    for (rows,) in ndimage.find_objects(bands):
        for found in (band_bar(image[rows], span, shortest), band_ruler(image[rows], span, shortest)):
            if found is not None and (best is None or found.length_px > best.length_px):
                x0, y0, x1, y1 = found.box
                best = replace(found, box=(x0, y0 + rows.start, x1, y1 + rows.start))
    return best


def band_ruler(image: np.ndarray, span: float, shortest: float) -> ScaleBar | None:
    """The longest ruler of ticks on a band of rows ``image`` of a picture whose range is ``span``, at least
    ``shortest`` px from its first tick to its last, or None: at least `MIN_TICKS` marks (`tick_marks`) on the same
    rows, evenly spaced (`tick_chains`) with at most `MAX_HIDDEN` missing, `TICK_APART` of their width apart or more,
    on a flat ground between them
    (varying by at most `LINE_GROUND` of the range). A Hitachi data strip draws its scale so: 11 ticks, the label
    giving the length from the first to the last. Its length is the distance between the first and the last tick's
    middles. A ruler that goes on past its ends (`ruler_goes_on`) is not taken: a piece of it would give a wrong
    scale."""
    best = None
    for dark in (True, False):
        signed = -image if dark else image  # the ticks stand up out of their ground
        # a white top-hat along the rows keeps what is narrower than LINE_REACH px: ticks, and letters' strokes
        narrow = signed - ndimage.maximum_filter1d(ndimage.minimum_filter1d(signed, LINE_REACH, axis=1), LINE_REACH,
                                                   axis=1)
        for chain in tick_chains(tick_marks(narrow, LINE_CONTRAST * span)):
            first, last = chain[0], chain[-1]
            if len(chain) < MIN_TICKS or last[0] - first[0] < shortest:
                continue
            if round((last[0] - first[0]) / (chain[1][0] - first[0])) + 1 - len(chain) > MAX_HIDDEN:
                continue  # more ticks hidden than a ruler over a film hides
            if chain[1][0] - first[0] < TICK_APART * max(t[4] - t[3] for t in chain):
                continue  # letters set in a line (a ruler's ticks stand far apart: their ground shows between)
            top, bottom = min(t[1] for t in chain), max(t[2] for t in chain)
            if ruler_goes_on(narrow[top:bottom], [t[0] for t in chain]):
                continue  # a ruler whose ticks go on is taken whole or not at all
            between = np.ones(last[4] - first[3], dtype=bool)
            for tick in chain:
                between[max(0, tick[3] - 1 - first[3]):tick[4] + 1 - first[3]] = False
            ground = signed[(top + bottom) // 2, first[3]:last[4]][between]
            if ground.size == 0 or float(ground.std()) > LINE_GROUND * span:
                continue
            if best is None or last[0] - first[0] > best.length_px:
                best = ScaleBar(last[0] - first[0], (first[3], top, last[4], bottom), dark, ruled=True,
                                at_edge=first[3] == 0 or last[4] == image.shape[1],
                                measured=f"from the first to the last of its {len(chain)} ticks")
    return best


def tick_marks(narrow: np.ndarray, contrast: float) -> list[tuple[float, int, int, int, int]]:
    """The marks on ``narrow`` (a top-hat along the rows) that may be a ruler's ticks: components of pixels at least
    ``contrast`` deep, at most `TICK_WIDTH` px wide and taller than wide (and than `END_MARK` px), as ``(middle, top,
    bottom, first column, last column + 1)``, sorted by their middles (px: the depth-weighted column, pixel centres
    at +0.5)."""
    labels, _n = ndimage.label(narrow >= contrast)
    ticks = []
    for k, (rows, cols) in enumerate(ndimage.find_objects(labels), start=1):
        height, width = rows.stop - rows.start, cols.stop - cols.start
        if width > TICK_WIDTH or height <= max(END_MARK, width):
            continue
        weights = np.where(labels[rows, cols] == k, narrow[rows, cols], 0.0).sum(axis=0)
        middle = cols.start + float(np.sum(np.arange(width) * weights) / weights.sum()) + 0.5
        ticks.append((middle, rows.start, rows.stop, cols.start, cols.stop))
    return sorted(ticks)


def tick_chains(ticks: list[tuple[float, int, int, int, int]]) -> list[list[tuple[float, int, int, int, int]]]:
    """``ticks`` (`tick_marks`) in chains of ticks on the same rows (tops and bottoms within 1 px of the first's),
    evenly spaced: each gap within `TICK_EVEN` of the first gap, or of a whole number of it up to 1 + `MAX_HIDDEN`
    where ticks are hidden (under a particle, where the ruler is drawn over the film). Every tick is in one chain; a
    chain starts at the first tick not yet in one, so that no ruler is taken from one of its own ticks on."""
    chains, taken = [], set()
    for i, first in enumerate(ticks):
        if i in taken:
            continue
        chain = [i]
        for j in range(i + 1, len(ticks)):
            tick, previous = ticks[j], ticks[chain[-1]]
            if abs(tick[1] - first[1]) > 1 or abs(tick[2] - first[2]) > 1:
                continue  # on other rows: letters of its label, or another ruler
            if len(chain) > 1:
                step = ticks[chain[1]][0] - first[0]
                gap = (tick[0] - previous[0]) / step  # in steps
                if gap < 1 - TICK_EVEN:
                    continue  # a speck between two ticks
                if abs(gap - round(gap)) > TICK_EVEN or round(gap) > 1 + MAX_HIDDEN:
                    break
            chain.append(j)
        taken.update(chain)
        chains.append([ticks[j] for j in chain])
    return chains


def band_bar(image: np.ndarray, span: float, shortest: float) -> ScaleBar | None:
    """`thin_bar` on a band of rows ``image`` of a picture whose range is ``span``."""
    best = None
    # a closing along the columns (a running maximum, then minimum) fills the dark lines thinner than LINE_REACH, an
    # opening the light ones; on the transposed image, whose columns are contiguous (twice as fast)
    across = np.ascontiguousarray(image.T)
    fills = {True: lambda: ndimage.minimum_filter1d(ndimage.maximum_filter1d(across, LINE_REACH), LINE_REACH) - across,
             False: lambda: across - ndimage.maximum_filter1d(ndimage.minimum_filter1d(across, LINE_REACH), LINE_REACH)}
    for dark in (True, False):
        signed = image if dark else -image
        labels, _n = ndimage.label(fills[dark]().T >= LINE_CONTRAST * span, structure=np.ones((3, 3)))
        lines = []  # (row, thickness, start, stop, mark at the start, mark at the stop)
        for k, (rows, cols) in enumerate(ndimage.find_objects(labels), start=1):
            if cols.stop - cols.start < MIN_BAR:  # a film's gaps and edges, most of what is found
                continue
            runs = (labels[rows, cols] == k).sum(axis=1)
            spine = np.flatnonzero(runs >= 0.9 * runs.max())  # its rows; their middle row is its spine
            top, bottom = rows.start + int(spine[0]), rows.start + int(spine[-1]) + 1
            if runs.max() < max(MIN_BAR, 0.9 * (cols.stop - cols.start)) or bottom - top > THIN_LINE:
                continue
            ground = flat_ground(signed, span, top, bottom, cols.start, cols.stop)
            if ground is None:
                continue
            contrast = ground - float(np.median(signed[(top + bottom) // 2, cols.start:cols.stop]))
            if contrast >= LINE_CONTRAST * span:  # a line on a flat ground, standing out of it along its spine
                lines.append((top, bottom, cols.start, cols.stop,
                              end_mark(signed, ground, MARK_SHARE * contrast, top, bottom, cols.start),
                              end_mark(signed, ground, MARK_SHARE * contrast, top, bottom, cols.stop - 1)))
        bars = [(first[4], last[5], first, last) for first in lines for last in lines
                if first is last or (abs(first[0] + first[1] - last[0] - last[1]) <= 2 and first[3] < last[2]
                                     and last[2] - first[3] <= 0.5 * (last[3] - first[2]))]
        for left, right, first, last in bars:
            if left is None or right is None or right - left < shortest:
                continue
            if best is None or right - left > best.length_px:
                top, bottom = min(first[0], last[0]), max(first[1], last[1])
                best = ScaleBar(right - left, (first[2], top, last[3], bottom), dark, ruled=True,
                                thickness=bottom - top, at_edge=first[2] == 0 or last[3] == image.shape[1],
                                measured="between the middles of its end marks")
    return best


def ruler_goes_on(narrow: np.ndarray, middles: list[float]) -> bool:
    """Whether a ruler of ticks at columns ``middles`` (px, evenly spaced) goes on past its first or last tick: a mark
    at least half as deep as its ticks' median depth, on its rows (``narrow``, the top-hat of `band_ruler`), one gap on
    from either end (within `TICK_EVEN` of it), where a tick is missing, over a film or under a letter."""
    depth = narrow.max(axis=0)
    step = (middles[-1] - middles[0]) / (len(middles) - 1)
    reach = max(1, int(math.ceil(TICK_EVEN * step)))
    median = float(np.median([depth[int(m)] for m in middles]))
    for beyond in (middles[0] - step, middles[-1] + step):
        at = int(beyond)
        near = depth[max(0, at - reach):max(0, at + reach + 1)]
        if near.size and float(near.max()) >= 0.5 * median:
            return True
    return False


def flat_ground(signed: np.ndarray, span: float, top: int, bottom: int, start: int, stop: int) -> float | None:
    """The level of the ground a thin line lies on (rows ``top`` to ``bottom``, exclusive, columns ``start`` to
    ``stop``, on ``signed``): the median of the rows just above and below its middle half, 1 px off it (its blur), or
    None where they vary by more than `LINE_GROUND` of the image's range ``span`` (a film, not a strip or a label's
    ground)."""
    middle = slice(start + (stop - start) // 4, stop - (stop - start) // 4)
    above = signed[max(0, top - LINE_REACH // 2 - 2):max(0, top - 1), middle]
    below = signed[bottom + 1:bottom + LINE_REACH // 2 + 2, middle]
    if above.size == 0 or below.size == 0 or max(float(above.std()), float(below.std())) > LINE_GROUND * span:
        return None
    return float(np.median(np.concatenate([above.ravel(), below.ravel()])))


def end_mark(signed: np.ndarray, ground: float, contrast: float, top: int, bottom: int, end: int) -> float | None:
    """The middle (column, px) of the mark (cap, tick) that crosses a thin line on ``signed`` (the image, negated for
    a light line; rows ``top`` to ``bottom``, exclusive, on a ``ground`` level) at its ``end`` column: the columns within
    `END_REACH` px of it weighted by the depth below the ground of their pixels ``contrast`` out of it, from 1 px to
    `MARK_ROWS` px above and below the line; None unless a column holds `END_MARK` such pixels above the line and one
    as many below it."""
    h, w = signed.shape
    columns = np.arange(max(0, end - END_REACH), min(w, end + END_REACH + 1))
    # the rows of a mark: 1 px off the line (its blur) to MARK_ROWS px, above it and below it
    depth = ground - np.concatenate([signed[max(0, top - MARK_ROWS):max(0, top - 1), columns],
                                     signed[min(h, bottom + 1):min(h, bottom + MARK_ROWS), columns]])
    split = max(0, top - 1) - max(0, top - MARK_ROWS)  # rows above the line, then below it
    ink = depth >= contrast
    if ink[:split].sum(axis=0).max(initial=0) < END_MARK or ink[split:].sum(axis=0).max(initial=0) < END_MARK:
        return None
    weights = np.where(ink, depth, 0.0).sum(axis=0)  # as a line profile across the mark: its depth
    return float(np.sum(columns * weights) / weights.sum()) + 0.5 if weights.sum() > 0 else None


def bar_contrast(image: np.ndarray, box: tuple[int, int, int, int],
                 colour: np.ndarray) -> tuple[float, float, float]:
    """How far a bar in ``box`` (x0, y0, x1, y1) stands out of its surroundings, the pixel noise there, and how far it
    stands out of its outline: the median of its pixels in the bar colour (``colour``, a mask of the box) against the
    median of the pixels within `BAR_SURROUNDINGS` px around the box, and against the `OUTLINE` px around the box
    where that stands further out by `MIN_CONTRAST` times the noise (a white bar in a dark outline on a light picture;
    else 0); the noise of that window, 1.4826 times the median absolute deviation of
    neighbouring pixels' differences over sqrt 2 (texture and edges hardly move it). A drawn bar stands out by
    tens of deviations (infinitely many in noiseless graphics); noise pixels joined into a bar, by a few."""
    x0, y0, x1, y1 = box
    m = BAR_SURROUNDINGS
    window = np.asarray(image[max(0, y0 - m):y1 + m, max(0, x0 - m):x1 + m], dtype=float)
    inside = np.zeros(window.shape, dtype=bool)
    inside[y0 - max(0, y0 - m):y1 - max(0, y0 - m), x0 - max(0, x0 - m):x1 - max(0, x0 - m)] = True
    bar = np.asarray(image[y0:y1, x0:x1], dtype=float)[colour]
    if bar.size == 0 or inside.all():
        return math.inf, 0.0, 0.0
    level = float(np.median(bar))
    contrast = abs(level - float(np.median(window[~inside])))
    diffs = np.concatenate([np.diff(window, axis=1).ravel(), np.diff(window, axis=0).ravel()])
    noise = 1.4826 * float(np.median(np.abs(diffs - np.median(diffs)))) / math.sqrt(2.0)
    ring = ndimage.binary_dilation(inside, iterations=OUTLINE) & ~inside
    outline = abs(level - float(np.median(window[ring]))) if ring.any() else 0.0
    # a bar drawn in an outline stands further out of it than out of the picture beside it
    return contrast, noise, outline if outline >= contrast + MIN_CONTRAST * noise else 0.0


def stands_out_both_sides(image: np.ndarray, box: tuple[int, int, int, int], colour: np.ndarray,
                          contrast: float) -> bool:
    """Whether a bar in ``box`` (x0, y0, x1, y1; its pixels in the bar colour ``colour``, a mask of the box) stands
    out of the rows above it and of those below it, each by at least `SIDE_SHARE` of its ``contrast`` with its
    surroundings (`bar_contrast`): the level of the rows within `BAR_SURROUNDINGS` px of it, each row's median across
    its columns, read outward as `surroundings` reads them off its ends (a label box's frame ends them); a side at
    the picture's edge (under 3 rows) is not asked. A drawn bar lies on its ground; a fringe along an object's edge
    has the object on one side."""
    x0, y0, x1, y1 = box
    level = float(np.median(np.asarray(image[y0:y1, x0:x1], dtype=float)[colour]))
    top = max(0, y0 - BAR_SURROUNDINGS)
    rows = np.median(np.asarray(image[top:y1 + BAR_SURROUNDINGS, x0:x1], dtype=float), axis=1)  # each row's level
    for near in (rows[:y0 - top][::-1], rows[y1 - top:]):
        if near.size > 2 and abs(surroundings(near, level) - level) < SIDE_SHARE * contrast:
            return False
    return True


def surroundings(near: np.ndarray, level: float) -> float:
    """The level around a bar's end, from the profile ``near`` it (from the end outward, `BAR_SURROUNDINGS` px): the
    median of the values from 2 px on, up to the first that turns back toward the bar's ``level`` (under half the
    largest distance from it so far: a label box's frame, another mark). A blurred end's ramp is mostly in the first
    2 px and weighs little in the median; noise is not picked as an extreme."""
    far = np.abs(near - level)
    start = min(2, len(near) - 1)
    kept, peak = [], 0.0
    for value, distance in zip(near[start:], far[start:]):
        peak = max(peak, float(distance))
        if distance < 0.5 * peak:
            break
        kept.append(float(value))
    return float(np.median(kept)) if kept else float(near[-1])


def half_contrast_length(image: np.ndarray, box: tuple[int, int, int, int], thickness: int, solid: float,
                         middle: int) -> float:
    """The length of the bar in ``box`` (x0, y0, x1, y1) between the points where its ends cross half contrast, px:
    a blurred bar (a journal figure's, a JPEG's) is measured as drawn, not at its solid core (``solid`` px). The
    profile along the bar is the mean of the ``thickness`` rows around its spine's ``middle`` one; the bar's level is
    the median of its middle
    half, the background's what surrounds each solid end (`surroundings`: the picture, or a label box); from each solid
    end outward, the first pixel under half
    contrast and the one before it give the crossing, interpolated. An end at the image's edge stays where the bar
    stops; ``solid`` when the profile does not show both levels."""
    x0, _, x1, _ = box
    rows = slice(max(0, middle - max(1, thickness) // 2), min(image.shape[0], middle + max(1, thickness) // 2 + 1))
    profile = np.asarray(image[rows], dtype=float).mean(axis=0)
    inner = profile[x0 + (x1 - x0) // 4:x1 - (x1 - x0) // 4]
    if inner.size == 0:
        return solid
    level = float(np.median(inner))
    ends = []
    for start, step in ((x0, -1), (x1 - 1, 1)):
        near = profile[start + step::step][:BAR_SURROUNDINGS] if step > 0 else \
            profile[max(0, start - BAR_SURROUNDINGS):start][::-1]
        if near.size < 2:  # the picture's edge: the end shown is where the bar stops
            ends.append(float(start) + (1.0 if step > 0 else 0.0))
            continue
        background = surroundings(near, level)
        if abs(level - background) < 0.25 * float(np.ptp(profile)) or np.ptp(profile) <= 0:
            return solid  # bar colour on both sides: not an end
        t = (profile - background) / (level - background)  # 0 at the background, 1 on the bar
        i = start
        while 0 <= i + step < len(t) and t[i + step] >= 0.5:
            i += step
        if not (0 <= i + step < len(t)) or t[i] < 0.5:
            return solid
        frac = (t[i] - 0.5) / (t[i] - t[i + step])  # from pixel i's centre toward the next one
        ends.append(i + 0.5 + step * frac)
    length = ends[1] - ends[0]
    return float(length) if 0.5 * solid <= length <= 1.5 * solid else solid


def scale_from_bar(bar: ScaleBar | None, length: str) -> float:
    """nm per px from the scale ``bar`` found on an image (`find_scale_bar`) that is ``length`` long (``"200nm"``)."""
    nm = parse_length(length)
    if bar is None:
        raise InputError(f"scale_bar: no scale bar found on the image (a horizontal bar, solid or ruled, in its darkest or "
                         f"lightest colour, at least {MIN_BAR} px long and {MIN_BAR_SHARE:g} of the picture's longer side, "
                         f"and {BAR_ASPECT:g} times longer than thick); "
                         "give the scale with --nm-per-px instead")
    return check_nm_per_px(nm / bar.length_px, "scale from the scale bar")

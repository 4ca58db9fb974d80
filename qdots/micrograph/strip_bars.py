"""The scale bars of instruments' data strips: thin lines with a mark at each end (ZEISS, FEI), and rulers of
separate ticks (Hitachi). After JPEG they are grey, neither the picture's darkest nor its lightest colour, so
`qdots.micrograph.scale.find_scale_bar`'s search by colour does not see them; it takes the longer of its own bar and
`thin_bar`'s.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy import ndimage

from .bar import MIN_BAR, ScaleBar

#: A thin bar (`thin_bar`: an instrument's data strip draws its bar as a line a few px thick with a mark at each end,
#: grey after JPEG, not the picture's darkest or lightest) is a line at most THIN_LINE px thick that stands out of the
#: pixels above and below it by LINE_CONTRAST of the image's range (a black top-hat over LINE_REACH rows), lies on a
#: flat ground (each row beside it varies along it by at most LINE_GROUND of the range: a strip or a label's ground,
#: not a film; rows of other levels, a table's border 5 px under an FEI strip's bar, are a strip's too),
#: and ends at each end in a mark (cap or tick) crossing it: at least END_MARK px above it and as many below (within
#: MARK_ROWS rows of it; its label's letters lie further), within END_REACH px of its end, that stand MARK_SHARE of
#: the line's own contrast out of its ground (a label box drawn as an outline has lines whose ends turn one way only).
#: On the EMPS development pictures, ZEISS strips' bars: lines 1-3 px thick, 0.49-0.58 of the range out of a ground
#: varying by 0.003-0.014 of it, their caps after JPEG 0.41 of the line's contrast; a ZEISS logo's swoosh in the same
#: strips is such a line without end marks. The distance between the marks' middles was within 0.4 % of line profiles
#: read by hand across the marks on four of them (ZEISS and FEI bars of 60-244 px).
THIN_LINE, LINE_REACH, LINE_CONTRAST, LINE_GROUND = 4, 9, 0.25, 0.05
END_MARK, END_REACH, MARK_SHARE, MARK_ROWS = 3, 3, 1.0 / 3.0, 7
#: A line broken by its label without end marks (FEI's and others' "-- 5 um --", its ends plain or round): two thin
#: lines on one row (`band_bar`), the shorter at least HALVES_EQUAL of the longer (the label is set in the middle),
#: with ink between them on at least LABEL_INK of the gap's columns (the label; within `MARK_ROWS` rows of the line),
#: measured between the lines' outer ends at half of their contrast (`line_end`). On the second EMPS development batch,
#: three such bars (FEI, two other instruments): halves of 51 and 53, 74 and 75, 76 and 78 px, 0.65-0.90 of the range
#: out of their ground, none with a mark at either end.
#: Each half is straight: its pixels (of the top-hat) off its spine's rows are at most HALF_OFF times those on them (those
#: halves 0.00-0.04; the bottoms of two letters "0" on one row of a label, taken as such a pair on a test picture,
#: 0.53-0.55).
HALVES_EQUAL, LABEL_INK, HALF_OFF = 0.8, 0.3, 0.2
#: A plain line without end marks is a bar (`plain_bar`) where its ends are free, FREE_ROWS px above and below it,
#: and its label lies within LABEL_ROWS px above or below it.
FREE_ROWS, LABEL_ROWS = 3, 15
#: A scale drawn as a double-headed arrow is measured between its tips (`arrow_tip`): its top-hat line stops where the
#: arrowheads' arms meet it, and those arms, taken as end marks, lie inside the tips. An arm is sought within
#: ARROW_ARM px of the line's rows, and the tip within twice that past the line's end (an EMPS development picture's
#: arrow: arms 11 px long across, the tip 11 px past where its line stops).
ARROW_ARM = 12
#: A ruler of ticks (`band_ruler`) has at least MIN_TICKS ticks at most TICK_WIDTH px wide, its gaps within TICK_EVEN
#: of a whole number of its first gap, and at most MAX_HIDDEN ticks hidden (by a particle where the ruler is drawn over
#: the film). A Hitachi data strip's ruler has 11 ticks, 4-5 px wide at a quarter of the picture's range.
MIN_TICKS, TICK_EVEN, TICK_WIDTH, MAX_HIDDEN = 5, 0.1, 6, 1
#: A ruler's ticks stand at least TICK_APART of their width apart (Hitachi's: 21.5 px apart, 4-5 px wide; a word's
#: letters, 1.2-1.6 of theirs).
TICK_APART = 3.0


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
    on a flat ground between them (varying by at most `LINE_GROUND` of the range, each tick's blurred sides as wide
    as it and the place of a tick not seen left out), out of which they stand by `LINE_CONTRAST` of the range (the
    holes of a word's "0"s do not: what lies between them is as deep), and they end: the rows just past their tops
    and bottoms are nearer the ground than the ticks (the light gaps between a cluster's particles in a row go on
    between its rows). A Hitachi data strip draws its scale so: 11
    ticks, the label giving the length from the first to the last. Its length is the distance between the first and
    the last tick's middles. A ruler that goes on past its ends (`ruler_goes_on`) is not taken: a piece of it would
    give a wrong scale."""
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
            step = chain[1][0] - first[0]
            for tick, after in zip(chain, chain[1:] + [last]):  # each tick and its blurred sides as wide as it, and
                reach = tick[4] - tick[3] + 1  # where one is hidden (under a particle, or not seen), as much
                for k in range(max(1, round((after[0] - tick[0]) / step))):
                    x0, x1 = tick[3] + round(k * step), tick[4] + round(k * step)
                    between[max(0, x0 - reach - first[3]):max(0, x1 + reach - first[3])] = False
            ground = signed[(top + bottom) // 2, first[3]:last[4]][between]
            if ground.size == 0 or float(ground.std()) > LINE_GROUND * span:
                continue  # no flat ground between them
            level = float(np.median(ground))
            peak = float(np.median([signed[tick[1]:tick[2], tick[3]:tick[4]].max() for tick in chain]))
            if peak - level < LINE_CONTRAST * span:
                continue  # marks as deep as what lies between them: the holes of a word's letters, not ticks
            ends = [float(signed[row, tick[3]:tick[4]].mean()) for tick in chain for row in (tick[1] - 2, tick[2] + 1)
                    if 0 <= row < signed.shape[0]]
            if ends and float(np.median(ends)) >= 0.5 * (level + peak):
                continue  # marks that go on up or down: the gaps between a cluster's particles, not ticks
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
    """``ticks`` (`tick_marks`) in chains of ticks on the same rows (their tops or their bottoms within 1 px of the
    first's: a Hitachi SU strip draws its first, middle and last ticks taller, on the others' baseline), evenly
    spaced: each gap within `TICK_EVEN` of the first gap, or of a whole number of it up to 1 + `MAX_HIDDEN`
    where ticks are hidden (under a particle, where the ruler is drawn over the film). Every tick is in one chain; a
    chain starts at the first tick not yet in one, so that no ruler is taken from one of its own ticks on."""
    chains, taken = [], set()
    for i, first in enumerate(ticks):
        if i in taken:
            continue
        chain = [i]
        for j in range(i + 1, len(ticks)):
            tick, previous = ticks[j], ticks[chain[-1]]
            if abs(tick[1] - first[1]) > 1 and abs(tick[2] - first[2]) > 1:
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
        # (top, bottom, start, stop, mark at the start, mark at the stop, pixels off the spine's rows / on, ground)
        lines = []
        for k, (rows, cols) in enumerate(ndimage.find_objects(labels), start=1):
            if cols.stop - cols.start < MIN_BAR:  # a film's gaps and edges, most of what is found
                continue
            runs = (labels[rows, cols] == k).sum(axis=1)
            spine = np.flatnonzero(runs >= 0.9 * runs.max())  # its rows; their middle row is its spine
            off = 1.0 - float(runs[spine].sum()) / float(runs.sum())
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
                              end_mark(signed, ground, MARK_SHARE * contrast, top, bottom, cols.stop - 1),
                              off / (1.0 - off) if off < 1.0 else math.inf, ground))
        bars = [(first[4], last[5], first, last) for first in lines for last in lines
                if first is last or (abs(first[0] + first[1] - last[0] - last[1]) <= 2 and first[3] < last[2]
                                     and last[2] - first[3] <= 0.5 * (last[3] - first[2]))]
        measured = "between the middles of its end marks"
        for left, right, first, last in bars:
            how = measured
            if left is not None and right is not None:
                contrast = first[7] - float(np.median(signed[(first[0] + first[1]) // 2, first[2]:first[3]]))
                tip_left, tip_right = arrow_tip(signed, first, -1, contrast), arrow_tip(signed, last, 1, contrast)
                if tip_left is not None and tip_right is not None:
                    (left, arms_left), (right, arms_right) = tip_left, tip_right
                    how = "between the tips of its arrowheads, at half contrast"
            if (left is None or right is None) and first is not last and label_between(signed, first, last):
                left, right, how = line_end(signed, first, -1, first[7]), line_end(signed, last, 1, last[7]), \
                    "between the outer ends of its two halves, at half contrast"
            elif left is None and right is None and first is last and plain_bar(signed, first):
                left, right, how = line_end(signed, first, -1, first[7]), line_end(signed, first, 1, first[7]), \
                    "between its plain ends, at half contrast"
            if left is None or right is None or right - left < shortest:
                continue
            if best is None or right - left > best.length_px:
                top, bottom = min(first[0], last[0]), max(first[1], last[1])
                box = (first[2], top, last[3], bottom)
                if how.startswith("between the tips"):  # the arrowheads, tips and arms, are the bar's too
                    box = (int(left), top - max(arms_left[0], arms_right[0]), int(math.ceil(right)),
                           bottom + max(arms_left[1], arms_right[1]))
                best = ScaleBar(right - left, box, dark, ruled=True,
                                thickness=bottom - top, at_edge=first[2] == 0 or last[3] == image.shape[1],
                                measured=how)
    return best


def arrow_tip(signed: np.ndarray, line: tuple, side: int, contrast: float) -> tuple[float, tuple[int, int]] | None:
    """Where a thin line of `band_bar` (``(top, bottom, start, stop, ..., ground)`` on ``signed``, standing
    ``contrast`` out of its ground) ends on its ``side`` (-1 its left, 1 its right) in an arrowhead's tip: the column,
    px (a pixel's edge), where its rows' depth below the ground falls to half of ``contrast``, interpolated, when that
    is more than `END_REACH` px past the line's end and the ink beside its rows closes in on them towards the tip (the
    two arms of an open or filled arrowhead pointing outward: on each side, the farthest pixel half as deep within
    `ARROW_ARM` px of the rows comes no farther out, column by column towards the tip, and is at least `END_MARK` px
    out at the line's end), with how far the arms reach above and below the line's rows there, px; None otherwise (a
    cap's or a tick's edge, or a plain end).

    The arrows of a double-headed arrow drawn as the scale, whose top-hat line stops where its arms meet it."""
    top, bottom, start, stop, ground = line[0], line[1], line[2], line[3], line[7]
    h, w = signed.shape
    end = start if side < 0 else stop - 1
    half = 0.5 * contrast
    rows = slice(max(0, top - ARROW_ARM), min(h, bottom + ARROW_ARM))
    ink = ground - signed[rows] >= half
    spine = ink[top - rows.start:bottom - rows.start]
    # the farthest ink above and below the line's rows, column by column (0: none)
    above = np.where(ink[:top - rows.start].any(axis=0),
                     top - rows.start - np.argmax(ink[:top - rows.start], axis=0), 0)
    below = np.where(ink[bottom - rows.start:].any(axis=0),
                     ink.shape[0] - (bottom - rows.start) - np.argmax(ink[::-1][:ink.shape[0] - (bottom - rows.start)],
                                                                     axis=0), 0)
    at = end
    while 0 <= at + side < w and spine[:, at + side].any() and abs(at + side - end) <= ARROW_ARM * 2:
        at += side
    if abs(at - end) <= END_REACH or min(above[end], below[end]) < END_MARK:
        return None
    reach = range(end, at + side, side)
    if any(above[c + side] > above[c] or below[c + side] > below[c] for c in reach[:-1]):
        return None  # the ink beside the line does not close in on it towards the tip
    depth = ground - signed[top:bottom].min(axis=0)
    beyond = at + side
    if not 0 <= beyond < w or depth[beyond] >= half:
        return None
    return float(at + 0.5 + side * (depth[at] - half) / (depth[at] - depth[beyond])), (int(above[end]),
                                                                                         int(below[end]))


def plain_bar(signed: np.ndarray, line: tuple) -> bool:
    """Whether a thin line of `band_bar` (``(top, bottom, start, stop, ..., off, ground)`` on ``signed``) without end
    marks is a plain bar under or over its label: straight (`HALF_OFF`), its ends free (no ink, half its contrast out
    of its ground, `FREE_ROWS` px above or below its rows 1 px off them, within `END_REACH` px of either end: a box's
    frame turns there), and its label's ink on `LABEL_INK` of its middle half's columns within `LABEL_ROWS` px above
    it or below it."""
    top, bottom, start, stop, off, ground = line[0], line[1], line[2], line[3], line[6], line[7]
    if off > HALF_OFF:
        return False
    h, w = signed.shape
    half = 0.5 * (ground - float(np.median(signed[(top + bottom) // 2, start:stop])))
    for end in (start, stop - 1):
        columns = slice(max(0, end - END_REACH), min(w, end + END_REACH + 1))
        near = np.concatenate([signed[max(0, top - 1 - FREE_ROWS):max(0, top - 1), columns].ravel(),
                               signed[min(h, bottom + 1):min(h, bottom + 1 + FREE_ROWS), columns].ravel()])
        if (ground - near >= half).any():
            return False
    middle = slice(start + (stop - start) // 4, stop - (stop - start) // 4)
    for rows in (slice(max(0, top - LABEL_ROWS), max(0, top - 1)), slice(min(h, bottom + 1), bottom + LABEL_ROWS)):
        if signed[rows, middle].size and float(np.mean((ground - signed[rows, middle] >= half).any(axis=0))) >= LABEL_INK:
            return True
    return False


def label_between(signed: np.ndarray, first: tuple, last: tuple) -> bool:
    """Whether two thin lines of `band_bar` (``(top, bottom, start, stop, ...)`` on ``signed``, the first to the left)
    are the halves of one bar broken by its label: straight (`HALF_OFF`), of lengths within `HALVES_EQUAL` of each
    other, with ink (half the lines' contrast out of their ground) on `LABEL_INK` of the columns between them, within
    `MARK_ROWS` rows of them."""
    lengths = (first[3] - first[2], last[3] - last[2])
    if min(lengths) < HALVES_EQUAL * max(lengths) or max(first[6], last[6]) > HALF_OFF:
        return False
    top, bottom = min(first[0], last[0]), max(first[1], last[1])
    rows = slice(max(0, top - MARK_ROWS), bottom + MARK_ROWS)
    ground = 0.5 * (first[7] + last[7])
    line = float(np.median(np.concatenate([signed[top:bottom, first[2]:first[3]].ravel(),
                                           signed[top:bottom, last[2]:last[3]].ravel()])))
    gap = signed[rows, first[3]:last[2]]
    return gap.size > 0 and float(np.mean((ground - gap >= 0.5 * (ground - line)).any(axis=0))) >= LABEL_INK


def line_end(signed: np.ndarray, line: tuple, side: int, ground: float) -> float | None:
    """Where a thin line of `band_bar` (``(top, bottom, start, stop, ...)`` on ``signed``, lying on ``ground``) ends on
    its ``side`` (-1 its left, 1 its right): the column, px (a pixel's edge), where the depth below the ground of its
    rows' darkest pixel falls to half of its depth along the line, interpolated between pixels, sought outwards from
    `END_REACH` px inside the line to as far beyond its end; None where it does not fall there."""
    top, bottom, start, stop = line[:4]
    depth = ground - signed[top:bottom].min(axis=0)
    half = 0.5 * float(np.median(depth[start:stop]))
    if side > 0:
        reach = range(max(start, stop - 1 - END_REACH), min(signed.shape[1] - 1, stop + END_REACH))
    else:
        reach = range(min(stop - 1, start + END_REACH), max(0, start - END_REACH - 1), -1)
    for at in reach:
        beyond = at + side
        if depth[beyond] < half <= depth[at]:  # the half-depth point between the centres of pixels at and beyond
            centre = at + 0.5 + side * (depth[at] - half) / (depth[at] - depth[beyond])
            return float(centre)
    return None


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
    None where one of those rows varies along the line by more than `LINE_GROUND` of the image's range ``span`` (a
    film, not a strip or a label's ground; a table's border among those rows is flat along them)."""
    middle = slice(start + (stop - start) // 4, stop - (stop - start) // 4)
    above = signed[max(0, top - LINE_REACH // 2 - 2):max(0, top - 1), middle]
    below = signed[bottom + 1:bottom + LINE_REACH // 2 + 2, middle]
    if above.size == 0 or below.size == 0 or max(float(above.std(axis=1).max()), float(below.std(axis=1).max())) > \
            LINE_GROUND * span:
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

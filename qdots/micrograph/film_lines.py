"""Faint scale bars drawn over the film: a thin line a little lighter (or darker) than the film it lies on, under or
over its label, neither the picture's darkest nor its lightest colour and on no flat ground, so that neither
`qdots.micrograph.scale.find_scale_bar`'s search by colour nor `qdots.micrograph.strip_bars.thin_bar`'s search of
strips and label boxes sees it. It is looked for only where neither finds a bar.

A line is found where, on each of its columns, its rows stand out of the rows on both sides of it (`stand_out`): a film's
texture does that on some columns, a drawn line on nearly all of them, however faint.
"""

from __future__ import annotations

import numpy as np
from scipy import ndimage

from labrig.compiled import jit
from labrig.threads import run_tasks

from .bar import ScaleBar
from .strip_bars import LABEL_INK, LABEL_ROWS, THIN_LINE

#: A line's rows stand out of the rows beside it (SIDE_ROWS of them, 1 px off its rows: its blur) on at least
#: ALONG_SHARE of its columns; it is sought in windows of SEED_WINDOW of the shortest bar's length where SEED_SHARE of
#: the columns do. On the EMPS development pictures and those in no batch, the faint lines drawn as bars: 0.958-0.967
#: of their columns; a film's texture reaches 0.9 over a short bar's length here and there, never 0.95 over a longer
#: one with the rest of these tests. Windows as long as the shortest bar missed lines little longer than it, or broken
#: by noise near an end (their seeds widened by half a window overshot their ends): five white lines 37.7-117.3 px
#: long on EMPS pictures in no batch, found in windows of half its length (0.4 found the same and took a piece of
#: film on two pictures; 0.6 missed one and took a piece of film on one).
ALONG_SHARE, SEED_SHARE, SIDE_ROWS, SEED_WINDOW = 0.95, 0.9, 3, 0.5
#: Its median contrast is at least NOISE_RATIO times the spread (SD) of the quieter of the bands beside it
#: (NEAR_ROWS rows each; the label's ink left out): those faint lines 3.0-10.5 times. A band that varies by less than
#: MIN_TEXTURE of the picture's range is a flat ground, a strip's or a box's: its lines are `thin_bar`'s.
NOISE_RATIO, NEAR_ROWS, MIN_TEXTURE = 2.0, 8, 0.015
#: The film is the same on both sides of a bar: their levels differ by at most SIDES_EVEN of the line's contrast (a
#: bright rim along a particle's edge, or the border between a strip and the film, has a different side each way).
SIDES_EVEN = 0.5
#: A bar is one line: on no row PARALLEL_ROWS rows from it do the rows stand out (`stand_out`) on PARALLEL_SHARE of
#: its columns (the gaps between the rows of particles in a superlattice are lines side by side).
PARALLEL_SHARE, PARALLEL_ROWS = 0.8, (5, 20)
#: Its label's ink (within EXTREME of the picture's range of its darkest or lightest value) lies within
#: `qdots.micrograph.strip_bars.LABEL_ROWS` px above or below it, on `qdots.micrograph.strip_bars.LABEL_INK` of its
#: columns or more, of LABEL_SPAN times `LABEL_ROWS` columns at most (a long bar's label may be short: "0.5 um" over
#: 27 % of a 210 px line on a picture in no batch). A line along the edge of a flat box or strip (flat ink: within FLAT of the range across 3 x 3 px,
#: on half its columns within HUG_ROWS rows of it) is the box's edge, and a line of flat ink is a letter's or a
#: box's, not faint.
EXTREME, FLAT, HUG_ROWS = 0.1, 0.04, 4
LABEL_SPAN = 4
#: It ends: beyond each end that is not the picture's edge, its rows stand out on at most FREE_SHARE of the columns
#: (over half its length, from END_GAP px out); and no mark as strong as half its contrast goes CORNER_ROWS
#: px up or down within 2 px of an end (a box's frame turns there).
FREE_SHARE, END_GAP, CORNER_ROWS = 0.7, 3, 5


def stand_out(image: np.ndarray, window: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """For each thickness 1 to `THIN_LINE` px: where the rows ``r`` to ``r + thickness`` (exclusive) of ``image``
    stand out, column by column, of both bands of `SIDE_ROWS` rows beside them, 1 px off: lighter than both, darker
    than both (at row ``r``; False where a band leaves the picture); and the runs of columns where they may be a line,
    as rows ``(dark, row, start, stop)``: each run of the columns whose ``window`` columns centred on them (from
    ``window // 2`` before; columns beyond the picture do not) stand out on `SEED_SHARE` of them, widened by
    ``window // 2`` on each side (within the picture), where they stand out on `ALONG_SHARE` of its columns.
    Compiled passes over the columns' running sums."""
    image = np.ascontiguousarray(image, dtype=float)
    h, w = image.shape
    total = np.zeros((h + 1, w))
    _running_sums(image, total)

    def one(thickness: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        light, dark = np.zeros(image.shape, dtype=bool), np.zeros(image.shape, dtype=bool)
        runs = np.empty((2 * h * (w // max(1, window) + 2), 4), dtype=np.int64)  # the first n are written
        n = _stand_out(total, thickness, SIDE_ROWS, int(window), SEED_SHARE, ALONG_SHARE, light, dark, runs)
        return light, dark, runs[:n]

    return run_tasks([lambda thickness=thickness: one(thickness) for thickness in range(1, THIN_LINE + 1)])


@jit
def _running_sums(image, total):
    """Each column's running sum of ``image`` down its rows into ``total`` (one row more, the first 0)."""
    h, w = image.shape
    for row in range(h):
        for col in range(w):
            total[row + 1, col] = total[row, col] + image[row, col]


@jit
def _stand_out(total, thickness, side, window, seed_share, along_share, light, dark, runs):
    """`stand_out` for one thickness into ``light``, ``dark`` and ``runs``; returns how many runs it wrote."""
    h, w = light.shape
    need = seed_share * window
    half = window // 2
    counted = np.zeros(w + 1, dtype=np.int64)
    n = 0
    for row in range(side + 1, h - thickness - side):
        for col in range(w):
            core = (total[row + thickness, col] - total[row, col]) / thickness
            above = (total[row - 1, col] - total[row - 1 - side, col]) / side
            below = (total[row + thickness + 1 + side, col] - total[row + thickness + 1, col]) / side
            light[row, col] = core > max(above, below)
            dark[row, col] = core < min(above, below)
        for polarity in range(2):
            out = dark if polarity == 1 else light
            for col in range(w):
                counted[col + 1] = counted[col] + out[row, col]
            first = -1  # the first column of the current run of seeds
            for col in range(w + 1):
                seed = False
                if col < w:
                    seed = counted[min(w, col + window - half)] - counted[max(0, col - half)] >= need
                if seed and first < 0:
                    first = col
                elif not seed and first >= 0:
                    start, stop = max(0, first - half), min(w, col + half)
                    if counted[stop] - counted[start] >= along_share * (stop - start):
                        runs[n, 0], runs[n, 1], runs[n, 2], runs[n, 3] = polarity, row, start, stop
                        n += 1
                    first = -1
    return n


def faint_line(image: np.ndarray, shortest: float) -> ScaleBar | None:
    """The longest faint line drawn over the film as a scale bar on ``image`` (see the module), at least ``shortest``
    px between its ends at half contrast, or None."""
    image = np.asarray(image, dtype=float)
    h, w = image.shape
    low, high = float(image.min()), float(image.max())
    span = high - low
    window = int(SEED_WINDOW * shortest)
    if not span > 0 or window < 2 or h < 2 * (SIDE_ROWS + 1) + THIN_LINE or w <= window:
        return None
    ink = (image <= low + EXTREME * span) | (image >= high - EXTREME * span)
    lines = []
    negative = -image
    for thickness, (light, dark_, runs) in enumerate(stand_out(image, window), start=1):
        for polarity, row, start, stop in runs.tolist():
            dark, out = bool(polarity), dark_ if polarity else light
            signed = negative if dark else image
            found = None if stop - start < shortest else faint(signed, out, ink, span, (row, row + thickness, start, stop))
            if found is None:
                continue
            ends = line_ends(signed[row:row + thickness].mean(axis=0), found[0], start, stop)
            if ends is not None and ends[1] - ends[0] >= shortest:
                left, right = ends
                lines.append((found[1], ScaleBar(right - left, (int(left), row, int(np.ceil(right)), row + thickness),
                                                 dark, thickness=thickness, at_edge=left <= 0 or right >= w,
                                                 measured="between its ends at half contrast, a faint line over the film")))
    # a line is found at several rows and thicknesses: each is read where it stands out most, then the longest is taken
    kept: list[ScaleBar] = []
    for _score, bar in sorted(lines, key=lambda found: -found[0]):
        if not any(overlap(bar.box, other.box) for other in kept):
            kept.append(bar)
    return max(kept, key=lambda bar: bar.length_px, default=None)


def overlap(box: tuple[int, int, int, int], other: tuple[int, int, int, int]) -> bool:
    """Whether two boxes ``(x0, y0, x1, y1)`` share a pixel or touch."""
    return box[0] <= other[2] and other[0] <= box[2] and box[1] <= other[3] and other[1] <= box[3]


def faint(signed: np.ndarray, out: np.ndarray, ink: np.ndarray, span: float,
          line: tuple) -> tuple[float, float] | None:
    """Whether the rows ``line`` = ``(top, bottom, start, stop)`` of ``signed`` (``out``: where they stand out of both
    sides, row by row; ``ink``: the picture's darkest and lightest `EXTREME`; ``span``: its range) are a faint bar
    drawn over the film under or over its label (see the module's constants): if so, the level of the film beside it
    and how far the line stands out of it in its quieter side's SDs, else None."""
    top, bottom, start, stop = line
    h, w = signed.shape
    columns = slice(start, stop)
    if (start == 0 and stop == w) or out[top, columns].mean() < ALONG_SHARE:
        return None
    beside = [top + offset for offset in range(-PARALLEL_ROWS[1], PARALLEL_ROWS[1] + 1)
              if abs(offset) >= PARALLEL_ROWS[0] and 0 <= top + offset < h]
    if beside and float(out[beside, columns].mean(axis=1).max()) >= PARALLEL_SHARE:
        return None
    bands = (slice(max(0, top - NEAR_ROWS - 1), max(0, top - 1)), slice(bottom + 1, bottom + NEAR_ROWS + 1))
    sides = [signed[rows, columns][~ink[rows, columns]] for rows in bands]
    if min(side.size for side in sides) <= NEAR_ROWS:
        return None
    quiet = min(float(side.std()) for side in sides)
    levels = [float(np.median(side)) for side in sides]
    line_level = float(np.median(signed[top:bottom, columns].mean(axis=0)))
    contrast = line_level - max(levels)
    if quiet < MIN_TEXTURE * span or contrast < NOISE_RATIO * quiet or abs(levels[0] - levels[1]) > SIDES_EVEN * contrast:
        return None
    # flat ink (within FLAT of the range over 3 x 3 px) on the line's rows and HUG_ROWS rows beside them
    first, wide = max(0, top - HUG_ROWS - 1), slice(max(0, start - 1), min(w, stop + 1))
    near = signed[first:bottom + HUG_ROWS + 1, wide]
    flat = ink[first:bottom + HUG_ROWS + 1, wide] & (ndimage.maximum_filter(near, 3) - ndimage.minimum_filter(near, 3)
                                                       <= FLAT * span)
    flat = flat[:, start - wide.start:stop - wide.start]
    if flat[top - first:bottom - first].mean() > 0.5:
        return None
    hug = max(flat[max(0, top - HUG_ROWS) - first:top - first].any(axis=0).mean(),
              flat[bottom - first:bottom + HUG_ROWS - first].any(axis=0).mean())
    if hug >= 0.5:
        return None
    label = max(int(ink[max(0, top - LABEL_ROWS):max(0, top - 1), columns].any(axis=0).sum()),
                int(ink[bottom + 1:bottom + LABEL_ROWS, columns].any(axis=0).sum()))
    if label < LABEL_INK * min(stop - start, LABEL_SPAN * LABEL_ROWS):
        return None
    reach = (stop - start) // 2
    level = 0.5 * (levels[0] + levels[1])
    for end, beyond in ((start, slice(max(0, start - END_GAP - reach), max(0, start - END_GAP))),
                        (stop - 1, slice(min(w, stop + END_GAP), min(w, stop + END_GAP + reach)))):
        if end in (0, w - 1):
            continue
        if beyond.stop - beyond.start > 0 and float(out[max(0, top - 1):top + 2, beyond].mean(axis=1).max()) > FREE_SHARE:
            return None  # the line goes on: a film's or a picture's line, not a bar
        near_end = slice(max(0, end - 2), min(w, end + 3))
        for rows in (slice(max(0, top - NEAR_ROWS), top), slice(bottom, bottom + NEAR_ROWS)):
            strong = signed[rows, near_end] >= level + 0.5 * contrast
            if strong.size and (strong.sum(axis=0) >= CORNER_ROWS).any():
                return None  # a box's frame turning up or down at the end
    return level, contrast / quiet


def line_ends(profile: np.ndarray, ground: float, start: int, stop: int) -> tuple[float, float] | None:
    """Where a faint line found between columns ``start`` and ``stop`` ends on each side (px, pixels' edges), at half
    contrast: where its rows' mean (``profile``, column by column, smoothed over 3 px) falls halfway from its median
    inside to the level past that end (`END_GAP` to twice that px past where it falls halfway to ``ground``, the level
    of the film beside it: a bar in a dark outline ends on the outline), and stays there for `END_GAP` px (a faint
    line's noise dips under it here and there), interpolated, sought outwards from a quarter of its length in; the
    picture's edge where it reaches it. None where it does not fall within half its length beyond an end."""
    w = profile.size
    smooth = ndimage.uniform_filter1d(profile, 3)
    quarter = (stop - start) // 4
    level = float(np.median(smooth[start + quarter:stop - quarter]))
    if not level > ground:
        return None
    ends = []
    for side, first in ((-1, start + quarter), (1, stop - 1 - quarter)):
        limit = first + side * (3 * quarter + (stop - start) // 2)
        end = crossing(smooth, first, limit, side, 0.5 * (level + ground))
        if end is None:
            return None
        past = smooth[int(end) + side * END_GAP:int(end) + side * 2 * END_GAP:side] if side > 0 else \
            smooth[max(0, int(end) - 2 * END_GAP):max(0, int(end) - END_GAP)]
        if 0 < end < w and past.size == END_GAP and float(np.median(past)) < level:
            end = crossing(smooth, first, limit, side, 0.5 * (level + float(np.median(past))))
            if end is None:
                return None
        ends.append(end)
    return ends[0], ends[1]


def crossing(smooth: np.ndarray, first: int, limit: int, side: int, half: float) -> float | None:
    """`line_ends`' end on its ``side`` (-1 left, 1 right) at the level ``half``, walking from column ``first`` to at
    most ``limit``: px, a pixel's edge; the picture's edge where it gets there; None where it reaches ``limit``."""
    w = smooth.size
    at = first
    while 0 <= at + side < w and at != limit and (smooth[at + side] >= half or goes_on(smooth, at + side, side, half)):
        at += side
    if at == limit:
        return None
    if not 0 <= at + side < w:
        return 0.0 if side < 0 else float(w)
    beyond = at + side
    return at + 0.5 + side * (smooth[at] - half) / (smooth[at] - smooth[beyond])


def goes_on(height: np.ndarray, at: int, side: int, half: float) -> bool:
    """Whether ``height`` reaches ``half`` again within `END_GAP` px past column ``at`` on its ``side`` (-1 left, 1
    right)."""
    beyond = height[at + side:at + side * (END_GAP + 1):side] if side > 0 else height[max(0, at - END_GAP):at][::-1]
    return bool((beyond >= half).any())

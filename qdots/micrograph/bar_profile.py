"""How a scale bar found stands out of the picture and where its ends are, read from the pixels across and along it:
its contrast with its surroundings and with an outline drawn around it (`bar_contrast`), whether it stands out of both
its sides (`stands_out_both_sides`), and its length between its ends at half contrast (`half_contrast_length`)."""

from __future__ import annotations

import math

import numpy as np

#: A bar's surroundings are read within BAR_SURROUNDINGS px of its ends.
BAR_SURROUNDINGS = 12
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


def bar_contrast(image: np.ndarray, box: tuple[int, int, int, int],
                 colour: np.ndarray) -> tuple[float, float, float]:
    """How far a bar in ``box`` (x0, y0, x1, y1) stands out of its surroundings, the pixel noise there, and how far it
    stands out of its outline: the median of its pixels in the bar colour (``colour``, a mask of the box) against the
    median of the pixels within `BAR_SURROUNDINGS` px around the box, and against the `OUTLINE` px above the box and
    those below it, the less of the two (a light line along a table's dark border stands out of one side only), where
    that stands further out by `MIN_CONTRAST` times the noise (a white bar in a dark outline on a light picture;
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
    # its outline: the OUTLINE px above it and those below it (with its corners); a bar in an outline stands out of
    # both, a light line along a dark border (a data strip's table) out of one only
    top, left = y0 - max(0, y0 - m), x0 - max(0, x0 - m)
    columns = slice(max(0, left - OUTLINE), left + (x1 - x0) + OUTLINE)
    sides = [window[max(0, top - OUTLINE):top, columns], window[top + y1 - y0:top + y1 - y0 + OUTLINE, columns]]
    sides = [side for side in sides if side.size]
    outline = min(abs(level - float(np.median(side))) for side in sides) if sides else 0.0
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

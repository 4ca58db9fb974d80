"""The scale of a micrograph: given in nm per pixel, or read off the scale bar drawn on it."""

from __future__ import annotations

import math
import re

import numpy as np

from labrig.lazy import moved_names
from labrig.validate import InputError, real

from .bar import MIN_BAR, ScaleBar
from .choices import MAX_NM_PER_PX, MIN_NM_PER_PX
from .colour_bars import BAR_ASPECT, BAR_TOLERANCE, STUBBY_ASPECT, colour_bar, grey_bar
from .film_lines import faint_line
from .read import UNIT_NM
from .strip_bars import thin_bar

#: A scale bar is drawn to be read: at least MIN_BAR_SHARE of the picture's longer side (`shortest_bar`). On the
#: development half of the real micrographs, the bars drawn measure 0.10-0.25 of it; what was taken for a bar on two
#: pictures without one, 0.018 (a 10 px run of a sphere's bright rim) and 0.041 (a bright particle cut by the
#: picture's lower edge).
MIN_BAR_SHARE = 0.05
#: Lengths a scale bar can state, nm: 0.01 nm to 1 cm.
MIN_BAR_NM, MAX_BAR_NM = 1e-2, 1e7


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


def shortest_bar(shape: tuple[int, int]) -> float:
    """The shortest scale bar taken on a picture of ``shape``, px: `qdots.micrograph.bar.MIN_BAR`, or `MIN_BAR_SHARE` of its longer
    side where that is more."""
    return max(float(MIN_BAR), MIN_BAR_SHARE * max(shape))


def find_scale_bar(image: np.ndarray) -> ScaleBar | None:
    """The longest scale bar drawn on ``image``, or None.

    The pixels within `qdots.micrograph.colour_bars.BAR_TOLERANCE` of the image's darkest (or lightest) value are
    closed along rows and columns by `qdots.micrograph.colour_bars.BAR_GAP` px (the thin cuts of a ruled bar) and
    their holes filled (the blocks of a checkered bar in its outline); a component is a bar when it is one
    horizontally or vertically (`qdots.micrograph.colour_bars.bar_candidate`), and not a box: its holes hold nothing
    of its colour (a label box drawn as an outline holds its bar and its text); one under
    `qdots.micrograph.colour_bars.BAR_ASPECT` times longer than thick is a bar only where drawn as a solid rectangle
    (`qdots.micrograph.colour_bars.solid_rectangle`). A component that spans the image from side to side is a frame,
    not a bar; one that reaches a side with one end only is a bar cut by the picture's edge, which cropped figures
    often show (`qdots.micrograph.bar.ScaleBar.at_edge`). A bar is drawn along the picture's rows: a component longer
    down than across is not one (on the development halves of the real micrographs and of EMPS, 88 pictures, every
    drawn bar is horizontal, and the three upright "bars" taken before were a panel label's "1" and two dark gaps
    between touching particles). Its length is measured at half contrast
    (`qdots.micrograph.bar_profile.half_contrast_length`), and is at least `shortest_bar`. Dots are never that flat in
    colour, nor that long; a bar stands out of what surrounds it (`qdots.micrograph.bar_profile.bar_contrast`; or of
    its outline, where it is drawn in one), where noise pixels joined into a bar do not, and out of the rows on both
    of its sides (`qdots.micrograph.bar_profile.stands_out_both_sides`), where the darkest fringe along a dark
    particle's edge does not. The thin bars and the rulers of ticks of instruments' data strips, and grey lines under
    their labels, are found by `qdots.micrograph.strip_bars.thin_bar`; the longer of the two searches' bars is taken,
    but a bar both find (`same_bar`) is measured as its colour shows it. Where neither finds one, a bar drawn in a
    flat grey, neither the picture's darkest colour nor its lightest, is looked for
    (`qdots.micrograph.colour_bars.grey_bar`), and where there is none, a faint line drawn over the film under its
    label (`qdots.micrograph.film_lines.faint_line`). A bar drawn a little askew (a scanned figure) is measured on the
    picture around it sheared upright (`qdots.micrograph.colour_bars.tilted_bar`).
    """
    image = np.asarray(image, dtype=float)
    if not float(np.ptp(image)) > 0:
        return None
    shortest = shortest_bar(image.shape)
    best = colour_bar(image, shortest)
    thin = thin_bar(image, shortest)
    if thin is None and best is None:
        grey = grey_bar(image, shortest)
        return grey if grey is not None else faint_line(image, shortest)
    if thin is None or (best is not None and (thin.length_px <= best.length_px or same_bar(thin, best))):
        return best
    return thin


def same_bar(bar: ScaleBar, other: ScaleBar) -> bool:
    """Whether two bars found by `find_scale_bar`'s two searches are one (their boxes share a pixel, their lengths
    within `qdots.micrograph.colour_bars.BAR_TOLERANCE` of each other): it is measured as its colour shows it, the thin bars' search reading its
    ends off its darkest pixels (up to 0.8 % longer on the EMPS pictures), not the whole bar's profile."""
    box, near = bar.box, other.box
    return (box[0] < near[2] and near[0] < box[2] and box[1] < near[3] and near[1] < box[3]
            and abs(bar.length_px - other.length_px) <= BAR_TOLERANCE * other.length_px)


def scale_from_bar(bar: ScaleBar | None, length: str) -> float:
    """nm per px from the scale ``bar`` found on an image (`find_scale_bar`) that is ``length`` long (``"200nm"``)."""
    nm = parse_length(length)
    if bar is None:
        raise InputError(f"scale_bar: no scale bar found on the image (a horizontal bar, solid or ruled, in its darkest or "
                         f"lightest colour, at least {MIN_BAR} px long and {MIN_BAR_SHARE:g} of the picture's longer side, "
                         f"and {BAR_ASPECT:g} times longer than thick, or {STUBBY_ASPECT:g} times if drawn solid); "
                         "give the scale with --nm-per-px instead")
    return check_nm_per_px(nm / bar.length_px, "scale from the scale bar")


#: The search by colour's functions and constants are `qdots.micrograph.colour_bars`'s since 0.3, and how a bar stands
#: out and where its ends are `qdots.micrograph.bar_profile`'s (here until 0.4).
__getattr__ = moved_names(__name__, {
    **dict.fromkeys(("EDGE_ROW", "BAR_GAP", "MIN_HOLE", "SKEW_MIDDLE", "SKEW_STRAIGHT", "SKEW_PARALLEL", "MAX_SKEW",
                     "OFF_SPINE", "TAPER", "GLYPH_SIDE", "GLYPH_AWAY", "SOLID", "tilted_bar", "spine", "bar_candidate",
                     "solid_rectangle", "bar_rows", "spine_rows", "longest_run", "closed_lines"),
                    "qdots.micrograph.colour_bars"),
    **dict.fromkeys(("BAR_SURROUNDINGS", "MIN_CONTRAST", "MIN_SHARE", "OUTLINE", "SIDE_SHARE", "bar_contrast",
                     "stands_out_both_sides", "surroundings", "half_contrast_length"), "qdots.micrograph.bar_profile"),
}, "0.3", "0.4")

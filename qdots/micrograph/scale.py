"""The scale of a micrograph: given in nm per pixel, or read off the scale bar drawn on it."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from labrig.validate import InputError, real

from .read import UNIT_NM

#: A scale bar is at least this many times longer than it is thick, and fills this share of its box.
BAR_ASPECT, BAR_FILL = 5.0, 0.85
#: Shortest scale bar, px.
MIN_BAR = 10
#: Pixels within this share of the image's range of its darkest (or lightest) value are bar colour.
BAR_TOLERANCE = 0.02
#: Largest scale, nm per px (1 mm per pixel).
MAX_NM_PER_PX = 1e6


@dataclass(frozen=True)
class ScaleBar:
    """A scale bar found on an image.

    Attributes
    ----------
    length_px : int
        Its length, px (along its long side).
    box : (int, int, int, int)
        ``(x0, y0, x1, y1)`` of the bar, px (x the column, y the row; ``x1``, ``y1`` exclusive).
    dark : bool
        Whether it is drawn in the image's darkest colour (else its lightest).
    """

    length_px: int
    box: tuple[int, int, int, int]
    dark: bool

    def mask(self, shape: tuple[int, int], margin: int = 2) -> np.ndarray:
        """The bar's pixels and ``margin`` px around it, as a boolean image of ``shape``."""
        out = np.zeros(shape, dtype=bool)
        x0, y0, x1, y1 = self.box
        out[max(0, y0 - margin):y1 + margin, max(0, x0 - margin):x1 + margin] = True
        return out


def check_nm_per_px(value, name: str = "nm_per_px") -> float:
    """A scale in nm per pixel: a finite number in (0, `MAX_NM_PER_PX`]."""
    return real(name, value, 0.0, MAX_NM_PER_PX, low_open=True, unit="nm per px")


def parse_length(text: str, name: str = "scale_bar") -> float:
    """A length such as ``"200nm"``, ``"0.5 um"`` or ``"2 µm"``, in nm."""
    match = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*([A-Za-z\u00b5\u03bc\u00c5]+)\s*", str(text))
    if not match:
        raise InputError(f"{name} must be a length with its unit, such as 200nm or 0.5um, got {text!r}")
    value, unit = float(match.group(1)), match.group(2).replace("\u03bc", "\u00b5")
    per_unit = UNIT_NM.get(unit.lower())
    if per_unit is None:
        raise InputError(f"{name}: unknown length unit {unit!r} (use nm, um, µm, mm, pm or A)")
    if not (math.isfinite(value) and value > 0):
        raise InputError(f"{name} must be a length > 0, got {text!r}")
    return value * per_unit


def find_scale_bar(image: np.ndarray) -> ScaleBar | None:
    """The longest solid bar drawn on ``image`` in its darkest or lightest colour, or None.

    A bar is a connected patch of pixels within `BAR_TOLERANCE` of the image's extreme value, not
    touching the image's edge (a frame is not a bar), at least `MIN_BAR` px long, `BAR_ASPECT` times
    longer than thick and filling `BAR_FILL` of its bounding box. Dots are never that flat in colour.
    """
    image = np.asarray(image, dtype=float)
    low, high = float(image.min()), float(image.max())
    span = high - low
    if not span > 0:
        return None
    best = None
    for dark, value in ((True, low), (False, high)):
        labels, _n = ndimage.label(np.abs(image - value) <= BAR_TOLERANCE * span)
        for k, box in enumerate(ndimage.find_objects(labels), start=1):
            if box is None:
                continue
            rows, cols = box
            h, w = rows.stop - rows.start, cols.stop - cols.start
            if rows.start == 0 or cols.start == 0 or rows.stop == image.shape[0] or cols.stop == image.shape[1]:
                continue
            long, thick = max(h, w), min(h, w)
            if long < MIN_BAR or long < BAR_ASPECT * thick:
                continue
            if np.count_nonzero(labels[box] == k) < BAR_FILL * h * w:
                continue
            if best is None or long > best.length_px:
                best = ScaleBar(int(long), (cols.start, rows.start, cols.stop, rows.stop), dark)
    return best


def scale_from_bar(image: np.ndarray, length: str) -> tuple[float, ScaleBar]:
    """nm per px from the scale bar on ``image`` that is ``length`` long (``"200nm"``), and the bar."""
    nm = parse_length(length)
    bar = find_scale_bar(image)
    if bar is None:
        raise InputError(f"scale_bar: no scale bar found on the image (a solid bar in its darkest or lightest "
                         f"colour, at least {MIN_BAR} px long and {BAR_ASPECT:g} times longer than thick); "
                         "give the scale with --nm-per-px instead")
    return check_nm_per_px(nm / bar.length_px, "scale from the scale bar"), bar

"""Levelling a measured height map, and the scanning artefacts it removes, as AFM users know them.

An AFM map as the instrument writes it holds more than the surface: the sample's tilt, the scanner's bow,
an offset between scan lines, scars (a stretch of one line where the tip jumped) and spikes (a few pixels of
noise). Gwyddion's and TopoStats' operations are the reference for each correction here:

``"lines"``
    Scan-line alignment by the median of differences (Gwyddion's *Align rows*, "median of differences";
    TopoStats' median flattening): each scan line is shifted so that the median of its differences to the
    line before is 0. It is found when the steps from line to line, less their running median over 5 lines
    (a shape's lines change smoothly, offsets jump), exceed 3 standard errors of a median of the lines'
    differences; its size is the RMS of the shifts the correction makes, less their linear trend (a tilt).
    The median of a line's differences is itself uncertain where the surface's own relief dominates, and the
    shifts add those errors up from line to line: on the rendered Ta film of `benchmarks.afm_map` (4.9 nm RMS,
    0.3 nm offsets independent from line to line), aligning leaves 1.1 nm RMS of slow error against the film
    where leaving the offsets leaves 0.3 nm. On scans of particles on a flat substrate, where Gwyddion and
    TopoStats use it, it is what removes drift between lines (4.2 nm on the WSxM sample scan). On a rough
    film with small offsets, ask for ``"spikes,scars,plane"`` instead of ``"auto"``. A pattern whose
    lines differ in their median (a grating along the slow axis, a checkerboard) is itself taken for
    offsets by this correction: do not ask for it on such maps.
``"spikes"``
    Clusters of at most `MAX_SPIKE_PIXELS` pixels that lie farther from the median of their 5 x 5 window
    than 3 times that window's spread (its 20th to 80th percentile) and than 8 robust standard deviations of
    the whole map's such residuals; each is replaced by its window's median. The spread test keeps a cone's
    tip and a step's edge (measured on the thesis's surfaces: none is marked); a ridge one pixel wide is a
    long cluster, not a spike.
``"scars"``
    Stretches of 1 to `MAX_SCAR_LINES` scan lines, at least `MIN_SCAR_PIXELS` pixels and `SCAR_ASPECT`
    times their width long, that lie above (or below) the lines on either side by more than 4 robust
    standard deviations of the line-to-line differences (Gwyddion's *Remove scars*); replaced by the
    straight line between those two lines.
``"plane"``
    The least-squares plane's tilt (`planarize.io.level_plane`); found as its angle and its height change
    across the map.
``"poly2"``, ``"poly3"``
    A polynomial background of that order in x and y (scanner bow) with its plane part, least squares.
    Found as the peak-to-valley of its part beyond the plane. A real curved sample cannot be told from bow,
    so ``"auto"`` reports it and never removes it.

The detectors are made for measured maps. On a designed shape they can mistake geometry for an artefact (a
pyramid's crease along the scan direction, one line wide, looks like a scar; a checkerboard's rows like line
offsets), which is why files that hold computed maps (``.npy``, text) are not levelled unless asked.

The corrections run in the order of `CORRECTIONS` whatever order they are asked in (robust ones first, so
that a spike or an offset line never pulls a least-squares fit). ``"auto"`` applies each of lines, spikes,
scars and plane that `detect` finds; ``"none"`` applies nothing. A map's scan lines are its rows: the x axis
of a `planarize.Surface` is the fast scan direction, one line per y (AFM files are read that way).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from labrig.validate import InputError

from .heightfield import Surface

#: The corrections, in the order they are applied.
CORRECTIONS = ("lines", "spikes", "scars", "plane", "poly2", "poly3")
#: What ``"auto"`` may apply (where `detect` finds the artefact).
AUTO = ("lines", "spikes", "scars", "plane")
#: Largest cluster of pixels counted as a spike (a larger one is a feature).
MAX_SPIKE_PIXELS = 4
#: Shortest stretch of a scan line counted as a scar, pixels.
MIN_SCAR_PIXELS = 4
#: Widest scar, scan lines (a wider band is a feature, or a change of the tip).
MAX_SCAR_LINES = 4
#: A scar is at least this many times longer (along its line) than it is wide (a square bump is a feature).
SCAR_ASPECT = 4
#: The robust deviation of line-to-line differences is taken as at least this fraction of their RMS (on a map
#: mostly flat, the median absolute deviation is 0 and every crest would be a scar).
SIGMA_FLOOR = 0.1
#: Thresholds: spike residual against its window's spread and against the map's robust deviation; scar step
#: against the robust deviation of line-to-line differences; line steps against a median's standard error.
SPIKE_SPREADS, SPIKE_SIGMAS, SCAR_SIGMAS, LINE_ERRORS = 3.0, 8.0, 4.0, 3.0
#: A tilt is reported as found when its plane's RMS exceeds this fraction of the levelled map's RMS.
TILT_FRACTION = 0.05
#: A bow is reported as found when its RMS beyond the plane exceeds this fraction of the remaining RMS.
BOW_FRACTION = 0.1
#: A tilt or bow smaller than this fraction of the map's z-range is rounding, not found.
ROUNDING = 1e-9
#: 1.4826 x the median absolute deviation estimates a normal distribution's standard deviation.
MAD_TO_SIGMA = 1.4826


@dataclass(frozen=True)
class Artefact:
    """One artefact of a height map: what it is, its size in words, and whether it was removed.

    Attributes
    ----------
    name : str
        ``"tilt"``, ``"bow"``, ``"line offsets"``, ``"spikes"`` or ``"scars"``.
    correction : str
        The correction that removes it (a member of `CORRECTIONS`).
    size : float
        Its size, nm: the tilt's and bow's height change across the map, the offsets' RMS, the largest
        spike's height, the scars' largest step.
    count : int
        Spikes or scars found (1 for the others when found, else 0).
    detail : str
        The size in words (``"2.1 deg, 73 nm across the map"``).
    found : bool
        The size is above its detection threshold (see the module docstring).
    applied : bool
        The correction was applied.
    """

    name: str
    correction: str
    size: float
    count: int
    detail: str
    found: bool
    applied: bool = False

    def sentence(self) -> str:
        """``"tilt 2.1 deg (73 nm across the map): removed"``."""
        if not self.found:
            state = "none found" + (", corrected as asked" if self.applied and self.count == 0 and self.size > 0
                                    and self.name in ("line offsets", "tilt", "bow") else "")
        elif self.applied:
            state = "removed"
        else:
            state = f"kept (level {self.correction!r} removes it)"
        return f"{self.name} {self.detail}: {state}"


def parse_corrections(level, default: str = "none") -> tuple[str, ...] | str:
    """The corrections ``level`` asks for: ``"auto"``, or a tuple of `CORRECTIONS` in their order.

    ``level`` is None (``default``), a bool (True: ``("plane",)``, the old ``level`` switch), ``"auto"``,
    ``"none"``, or corrections separated by commas (``"lines,plane"``) or a sequence of them.
    """
    if level is None:
        level = default
    if isinstance(level, (bool, np.bool_)):
        return ("plane",) if level else ()
    if isinstance(level, str):
        words = [w.strip() for w in level.split(",") if w.strip()]
    elif isinstance(level, (list, tuple)) and all(isinstance(w, str) for w in level):
        words = [w.strip() for w in level]
    else:
        raise InputError(f"level must be \"auto\", \"none\" or corrections ({', '.join(CORRECTIONS)}), got {level!r}")
    if words == ["auto"]:
        return "auto"
    if words in ([], ["none"]):
        return ()
    unknown = [w for w in words if w not in CORRECTIONS]
    if unknown:
        raise InputError(f"level: unknown correction {unknown[0]!r}; corrections: {', '.join(CORRECTIONS)} "
                         "(or \"auto\", \"none\")")
    if "poly2" in words and "poly3" in words:
        raise InputError("level: poly2 and poly3 are alternatives (poly3 includes poly2's terms)")
    return tuple(c for c in CORRECTIONS if c in words)


# -- the corrections, on arrays (z[i, j]: x_i along a scan line, y_j the line) --------------------------

def line_steps(z: np.ndarray) -> np.ndarray:
    """The median of the differences of each scan line to the line before (0 for the first line), nm."""
    steps = np.zeros(z.shape[1])
    steps[1:] = np.median(np.diff(z, axis=1), axis=0)
    return steps


def align_lines(z: np.ndarray) -> np.ndarray:
    """``z`` with each scan line shifted by the median of differences (module docstring); mean kept."""
    offsets = np.cumsum(line_steps(z))
    return z - (offsets - offsets.mean())[None, :]


def spike_mask(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pixels of spikes (module docstring), and the 5 x 5 median that replaces them."""
    median = ndimage.median_filter(z, size=5, mode="reflect")
    residual = z - median
    spread = (ndimage.percentile_filter(z, 80, size=5, mode="reflect")
              - ndimage.percentile_filter(z, 20, size=5, mode="reflect"))
    sigma = MAD_TO_SIGMA * float(np.median(np.abs(residual - np.median(residual))))
    outlier = (np.abs(residual) > SPIKE_SPREADS * spread) & (np.abs(residual) > SPIKE_SIGMAS * sigma)
    if not outlier.any():
        return outlier, median
    labels, n = ndimage.label(outlier, structure=np.ones((3, 3)))
    sizes = np.bincount(labels.ravel(), minlength=n + 1)
    small = sizes <= MAX_SPIKE_PIXELS
    small[0] = False
    return small[labels], median


def scar_mask(z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pixels of scars (module docstring), and ``z`` with them replaced by the straight line between the
    scan lines on either side. Scars 1 to `MAX_SCAR_LINES` lines wide are found, narrowest first."""
    mask = np.zeros(z.shape, dtype=bool)
    z = np.array(z, dtype=float)
    if z.shape[1] < 3 or z.shape[0] < MIN_SCAR_PIXELS:
        return mask, z
    differences = np.diff(z, axis=1)
    sigma = MAD_TO_SIGMA * float(np.median(np.abs(differences - np.median(differences))))
    floor = SIGMA_FLOOR * float(np.sqrt(np.mean(differences ** 2)))  # (a map mostly flat has a MAD of 0)
    threshold = SCAR_SIGMAS * max(sigma, floor)
    for width in range(1, min(MAX_SCAR_LINES, z.shape[1] - 2) + 1):
        run = np.ones((max(MIN_SCAR_PIXELS, SCAR_ASPECT * width), 1), dtype=bool)
        n = z.shape[1] - width - 1  # blocks of `width` lines with a line on either side
        below, above = z[:, :n], z[:, width + 1:width + 1 + n]
        block = np.stack([z[:, 1 + k:1 + k + n] for k in range(width)])
        high = block.min(axis=0) - np.maximum(below, above) > threshold
        low = block.max(axis=0) - np.minimum(below, above) < -threshold
        found = ndimage.binary_opening(high | low, structure=run)  # runs along the scan line
        if not found.any():
            continue
        for k in range(width):
            t = (k + 1) / (width + 1)
            lines = slice(1 + k, 1 + k + n)
            z[:, lines] = np.where(found, (1 - t) * below + t * above, z[:, lines])
            mask[:, lines] |= found
    return mask, z


def polynomial_background(surface: Surface, order: int) -> np.ndarray:
    """The least-squares polynomial of ``order`` in x and y (terms x^a y^b, a + b <= order) without its mean,
    nm, on ``surface``'s grid. Coordinates are scaled to [-1, 1] for a well-conditioned fit."""
    x, y = np.meshgrid(_unit_axis(surface.x), _unit_axis(surface.y), indexing="ij")
    terms = [x ** a * y ** b for a in range(order + 1) for b in range(order + 1 - a) if a + b > 0]
    design = np.column_stack([np.ones(x.size)] + [t.ravel() for t in terms])
    coefficients, *_ = np.linalg.lstsq(design, surface.z.ravel(), rcond=None)
    return (design[:, 1:] @ coefficients[1:]).reshape(surface.shape) - float(np.mean(design[:, 1:] @ coefficients[1:]))


def _unit_axis(values: np.ndarray) -> np.ndarray:
    span = float(values[-1] - values[0])
    return (values - values.mean()) / (span / 2 if span > 0 else 1.0)


# -- detection and levelling ---------------------------------------------------------------------------

def level_surface(surface: Surface, corrections="auto") -> tuple[Surface, list[Artefact]]:
    """``surface`` with ``corrections`` applied (`parse_corrections`), and every artefact found on the way.

    Each artefact is measured on the map as the corrections before it left it (the order of `CORRECTIONS`),
    so its size is what its own correction removes. The mean height is kept. With no correction asked
    (``"none"``) nothing is measured and the list is empty: `detect` measures without changing the map.

    Examples
    --------
    >>> import numpy as np
    >>> from planarize import Surface
    >>> z = np.random.default_rng(0).normal(0.0, 1.0, (64, 64)) + 0.5 * np.arange(64)[None, :]
    >>> levelled, found = level_surface(Surface(z, 10.0), "plane")
    >>> [a.name for a in found if a.applied]
    ['tilt']
    >>> round(float(np.std(levelled.z)), 1)
    1.0
    """
    chosen = parse_corrections(corrections)
    if chosen == ():
        return surface, []  # (nothing asked: nothing measured; `detect` measures)
    auto = chosen == "auto"
    z = np.array(surface.z, dtype=float)
    found: list[Artefact] = []

    artefact = _line_offsets(z, surface)
    apply = artefact.found if auto else "lines" in chosen
    if apply:
        z = align_lines(z)
    found.append(_applied(artefact, apply))

    for name, find in (("spikes", spike_mask), ("scars", scar_mask)):
        mask, replacement = find(z)
        artefact = _clusters(name, name, mask, np.abs(z - replacement))
        apply = artefact.found if auto else name in chosen
        if apply:
            z = np.where(mask, replacement, z)
        found.append(_applied(artefact, apply))

    current = surface.with_heights(z)
    plane = polynomial_background(current, 1)
    artefact = _tilt(plane, current)
    apply = artefact.found if auto else "plane" in chosen or "poly2" in chosen or "poly3" in chosen
    if apply:
        z = z - plane
    found.append(_applied(artefact, apply))

    order = 3 if not auto and "poly3" in chosen else 2
    current = surface.with_heights(z if apply else z - plane)
    bow = polynomial_background(current, order)
    bow = bow - polynomial_background(current.with_heights(bow), 1)  # its part beyond a plane
    artefact = _bow(bow, current, order)
    apply = not auto and f"poly{order}" in chosen
    if apply:
        z = z - bow
    found.append(_applied(artefact, apply))
    return surface.with_heights(z), found


def detect(surface: Surface) -> list[Artefact]:
    """Every artefact `level_surface` finds on ``surface`` with ``"auto"``, marked as not applied (the
    sizes are those ``"auto"`` measures, each after the corrections before it)."""
    return [_applied(a, False) for a in level_surface(surface, "auto")[1]]


def _applied(artefact: Artefact, applied: bool) -> Artefact:
    return Artefact(artefact.name, artefact.correction, artefact.size, artefact.count, artefact.detail,
                    artefact.found, bool(applied))


def _line_offsets(z: np.ndarray, surface: Surface) -> Artefact:
    steps = line_steps(z)
    if z.shape[1] < 3:
        return Artefact("line offsets", "lines", 0.0, 0, "(too few lines)", False)
    differences = np.diff(z, axis=1)
    spread = MAD_TO_SIGMA * np.median(np.abs(differences - np.median(differences, axis=0)), axis=0)
    error = math.sqrt(math.pi / 2) * spread / math.sqrt(z.shape[0])  # a median's standard error
    # offsets jump from line to line; a shape's lines change smoothly: only the steps' part that a running
    # median over 5 lines does not follow counts
    jumps = steps[1:] - ndimage.median_filter(steps[1:], size=5, mode="nearest")
    found = bool(np.sqrt(np.mean(jumps ** 2)) > LINE_ERRORS * max(float(np.sqrt(np.mean(error ** 2))), 1e-300))
    offsets = np.cumsum(steps)
    j = np.arange(z.shape[1])
    rms = float(np.sqrt(np.mean((offsets - np.polyval(np.polyfit(j, offsets, 1), j)) ** 2)))
    return Artefact("line offsets", "lines", rms, int(found), f"RMS {rms:.3g} nm", found)


def _clusters(name: str, correction: str, mask: np.ndarray, height: np.ndarray) -> Artefact:
    _, n = ndimage.label(mask, structure=np.ones((3, 3)))
    size = float(height[mask].max()) if n else 0.0
    pixels = int(mask.sum())
    detail = f"{n} ({pixels} pixels, up to {size:.3g} nm)" if n else "0"
    return Artefact(name, correction, size, n, detail, n > 0)


def _tilt(plane: np.ndarray, surface: Surface) -> Artefact:
    (nx, ny), (dx, dy) = surface.shape, surface.spacing
    gx = float(plane[-1, 0] - plane[0, 0]) / max((nx - 1) * dx, 1e-300)
    gy = float(plane[0, -1] - plane[0, 0]) / max((ny - 1) * dy, 1e-300)
    across = abs(gx) * (nx - 1) * dx + abs(gy) * (ny - 1) * dy
    degrees = math.degrees(math.atan(math.hypot(gx, gy)))
    rest = float(np.std(surface.z - plane))
    found = float(np.std(plane)) > TILT_FRACTION * rest and across > ROUNDING * float(np.ptp(surface.z))
    return Artefact("tilt", "plane", across, int(found), f"{degrees:.3g} deg ({across:.3g} nm across the map)", found)


def _bow(bow: np.ndarray, surface: Surface, order: int) -> Artefact:
    size = float(bow.max() - bow.min())
    rest = float(np.std(surface.z - bow))
    found = float(np.std(bow)) > BOW_FRACTION * rest and size > ROUNDING * float(np.ptp(surface.z))
    return Artefact("bow", f"poly{order}", size, int(found), f"{size:.3g} nm peak to valley (order {order})", found)


def report_rows(found: list[Artefact]) -> list[tuple[str, str]]:
    """``(name, sentence)`` rows of the artefacts worth a line: those found, and corrections asked for that
    changed the map though their artefact was not found (line offsets, tilt, bow under its threshold)."""
    return [(a.name, a.sentence()[len(a.name) + 1:]) for a in found
            if a.found or (a.applied and a.name in ("line offsets", "tilt", "bow") and a.size > 0)]


def applied_corrections(found: list[Artefact]) -> tuple[str, ...]:
    """The corrections that were applied, in their order: what reproduces the levelling explicitly."""
    applied = {a.correction for a in found if a.applied}
    return tuple(c for c in CORRECTIONS if c in applied)


__all__ = ["Artefact", "level_surface", "detect", "parse_corrections", "align_lines", "line_steps", "spike_mask",
           "scar_mask", "polynomial_background", "applied_corrections", "report_rows", "CORRECTIONS", "AUTO"]

"""Whether a picture is a micrograph of a film of round particles, or something else that must be refused
in one line: a plot, text, a drawing, a rendered board.

Two looks. Before the dots are sought (`check_picture`): a micrograph has noise in every pixel, while
drawn pictures are mostly flat colour (`FLAT_SHARE` of the picture with 3 x 3 neighbourhoods of one value;
micrographs: under 2 %; plots, text, drawings and qdots' own board pictures: 65-95 %). After (`check_film`),
for noisy pictures of the same (a scan, a photo of a screen): a film has many dots the picture's edge does not cut
(`MIN_FILM_DOTS`: its sizes and spread are measured on them), big
enough to be particles rather than strokes of text or lines (`MIN_FILM_DIAMETER`), alike in size (their
spread from the interquartile range under `MAX_FILM_SPREAD`), and measured the same twice
(`MAX_REPEAT_ERROR`: the repeated measurement of `qdots.micrograph.refine.repeat_errors`; letters and
lines fitted as discs do not repeat), and not set in lines of text (`text_lines`: enlarged text passes every
other look).
"""

from __future__ import annotations

import numpy as np

from labrig.validate import InputError

from .annotations import Annotations, flatness
from .film import size_spread

#: Share of the picture (within 0.2 % of its range) in flat 3 x 3 neighbourhoods above which it is drawn.
FLAT_SHARE, FLAT_TOLERANCE = 0.3, 0.002
#: A film: at least MIN_FILM_DOTS dots the edge does not cut (with fewer, the spread is uncertain by over a fifth of
#: itself; a noisy drawing of 14 filled and outlined shapes of 17-83 px has 8, which vary 33 % in size), a median
#: diameter of MIN_FILM_DIAMETER px, a spread (interquartile range over 1.349, over the median) under MAX_FILM_SPREAD,
#: and a median repeat error under MAX_REPEAT_ERROR of the diameter (measured: synthetic films and the shared TEM
#: image 0.1-1.0 %, noisy text, plots and drawings 2.4-4 %).
#: The spread's bound, measured on noisy plots, text and drawings drawn at 1-5x: 0.18-0.48, and every one under
#: 0.35 is refused by another check; a film's own spread reaches 0.3 at the simulations' widest sigma (0.25).
MIN_FILM_DOTS, MIN_FILM_DIAMETER, MAX_FILM_SPREAD, MAX_REPEAT_ERROR = 10, 5.0, 0.35, 0.02
#: Text: at least LINE_DOTS whole objects, whose rows, in bands LINE_BAND median diameters high, leave at least
#: LINE_GAPS of the bands between the outermost (2nd and 98th percentiles) empty, while their columns leave at most
#: LINE_FILLED (or the same across). Measured: scanned text at 1, 3 and 5x, 0.25-0.36 of the rows' bands empty and
#: none of the columns'; films (dense, sparse, square and hexagonal superlattices with 1-3 px gaps, 6-30 px dots, and
#: the shared TEM image) at most 0.04 of either, but for sparse films of 16-41 dots (under LINE_DOTS), which
#: leave 0.16-0.42 of both empty by chance.
LINE_DOTS, LINE_BAND, LINE_GAPS, LINE_FILLED = 50, 1.6, 0.2, 0.05


def empty_bands(positions: np.ndarray, band: float) -> float:
    """The share of the bands ``band`` wide, between the 2nd and 98th percentiles of ``positions``, that hold
    none of them (0 over fewer than 4 bands)."""
    low, high = np.percentile(positions, [2, 98])
    edges = np.arange(low, high + band, band)
    if len(edges) < 5:
        return 0.0
    return float(np.mean(np.histogram(positions, edges)[0] == 0))


def text_lines(centres: np.ndarray, diameter: float) -> tuple[float, float]:
    """Whether objects at ``centres`` (x, y), px, of median ``diameter`` px lie in lines of text: the share of
    empty bands along the lines' direction, rows or columns, that the other direction leaves filled (see
    `LINE_BAND`), and that of the other direction."""
    rows, cols = (empty_bands(centres[:, k], LINE_BAND * diameter) for k in (1, 0))
    return (rows, cols) if rows >= cols else (cols, rows)


def check_picture(image: np.ndarray, found: Annotations, source: str) -> None:
    """Refuse, in one line, a picture that is mostly flat colour (see the module)."""
    x0, y0, x1, y1 = found.window
    picture = np.asarray(image, dtype=float)[y0:y1, x0:x1]
    keep = ~found.ignore[y0:y1, x0:x1] if found.ignore is not None else np.ones(picture.shape, dtype=bool)
    span = float(picture.max() - picture.min())
    share = float(flatness(picture, FLAT_TOLERANCE * span)[keep].mean()) if keep.any() else 1.0
    if share > FLAT_SHARE:
        raise InputError(f"{source}: not a micrograph: {100 * share:.0f} % of the picture is flat colour, as in a "
                         f"plot, text, a drawing or a rendered board (a micrograph has noise everywhere, under "
                         f"{100 * FLAT_SHARE:.0f} %); nothing written")


def check_film(detection, source: str) -> None:
    """Refuse, in one line, a detection that is not a film of round particles (see the module)."""
    whole = ~detection.cut
    n = int(np.count_nonzero(whole))
    if n < MIN_FILM_DOTS:
        raise InputError(f"{source}: not a film of particles: {n} round objects found whole (the edge cuts "
                         f"{int(detection.n_dots) - n} more), fewer than {MIN_FILM_DOTS}; nothing written")
    d = float(np.median(detection.diameters))
    if d < MIN_FILM_DIAMETER:
        raise InputError(f"{source}: not a film of particles: the round objects found are {d:.1f} px across, "
                         f"under {MIN_FILM_DIAMETER:g} px (strokes of text or lines?); nothing written")
    spread = size_spread(detection.diameters[whole] if whole.sum() > 1 else detection.diameters)["size_spread_robust"]
    if spread > MAX_FILM_SPREAD:
        raise InputError(f"{source}: not a film of particles: the round objects found vary {100 * spread:.0f} % in "
                         f"size (interquartile range), over {100 * MAX_FILM_SPREAD:.0f} % (text, lines or a "
                         "drawing?); nothing written")
    if n >= LINE_DOTS:
        lines, across = text_lines(detection.centres[whole], d)
        if lines >= LINE_GAPS and across <= LINE_FILLED:
            raise InputError(f"{source}: not a film of particles: the round objects found lie in lines, as text does "
                             f"({100 * lines:.0f} % of the bands between them empty, {100 * across:.0f} % across; a "
                             f"film leaves under {100 * LINE_GAPS:.0f} % empty); nothing written")
    repeat = float(np.nanmedian(detection.errors / detection.diameters))
    if repeat > MAX_REPEAT_ERROR:
        raise InputError(f"{source}: not a film of round particles: the objects found measure {100 * repeat:.1f} % "
                         f"differently each time (round particles: under {100 * MAX_REPEAT_ERROR:.0f} %); "
                         "nothing written")

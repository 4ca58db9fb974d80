"""Whether a picture is a micrograph of a film of round particles, or something else that must be refused
in one line: a plot, text, a drawing, a rendered board, rods, cubes, plates, cells.

Two looks. Before the dots are sought (`check_picture`): a micrograph has noise in every pixel, while
drawn pictures are mostly flat colour (`FLAT_SHARE` of the picture with 3 x 3 neighbourhoods of one value;
micrographs: under 2 %; plots, text, drawings and qdots' own board pictures: 65-95 %). After (`film_verdict`), what
was found: a film has many dots the picture's edge does not cut (`MIN_FILM_DOTS`), big enough to be particles rather
than strokes of text or lines (`MIN_FILM_DIAMETER`), not set in lines of text (`text_lines`), round (the outlines they
show the background do not wander far from one radius, `MAX_OUTLINE`; they are not elongated, `MAX_ELONGATION`) and
whole (a rod or a plate that the detection cut into pieces leaves dots far closer than a diameter to their nearest
neighbour, `PIECES`; the region shapes are `qdots.micrograph.shapes`'). What is refused is said with its numbers.

Other signs make a measurement doubtful without making the picture something else: sizes that vary over
`MAX_FILM_SPREAD` (two populations, or false detections), diameters that repeat worse than `MAX_REPEAT_ERROR` (a noisy
or textured picture), discs that overlap their neighbours (`OVERLAP`: the diameters may be too large). They are
reported beside the measurement (`film_verdict`'s doubts).
"""

from __future__ import annotations

import numpy as np

from labrig.validate import InputError

from ..geometry import nearest_ratio
from .annotations import Annotations, flatness
from .film import size_spread
from .shapes import OVERLAP, OVERLAP_SHARE, STACKED, overlap_share

#: Share of the picture (within 0.2 % of its range) in flat 3 x 3 neighbourhoods above which it is drawn.
FLAT_SHARE, FLAT_TOLERANCE = 0.3, 0.002
#: A film: at least MIN_FILM_DOTS dots the edge does not cut (with fewer, the spread is uncertain by over a fifth of
#: itself) and a median diameter of MIN_FILM_DIAMETER px. Doubtful: a spread (interquartile range over 1.349, over the
#: median) over MAX_FILM_SPREAD, or a median repeat error over MAX_REPEAT_ERROR of the diameter (synthetic films and
#: clean real ones 0.1-1.2 %; real films on a grainy support or with pores 2-5 %).
MIN_FILM_DOTS, MIN_FILM_DIAMETER, MAX_FILM_SPREAD, MAX_REPEAT_ERROR = 10, 5.0, 0.35, 0.02
#: Text: at least LINE_DOTS whole objects, whose rows, in bands LINE_BAND median diameters high, leave at least
#: LINE_GAPS of the bands between the outermost (2nd and 98th percentiles) empty, in at least LINE_RUNS lines (runs
#: of filled bands between empty ones), while their columns leave at most LINE_FILLED (or the same across).
#: Measured: scanned text at 1, 3 and 5x, 0.25-0.36 of the rows' bands empty in 10 lines, and none of the columns';
#: films (dense, sparse, square and hexagonal superlattices with 1-3 px gaps, 6-30 px dots, and the shared TEM image)
#: at most 0.04 of either, but for sparse films of 16-41 dots (under LINE_DOTS), which leave 0.16-0.42 of both empty
#: by chance, and sparse clustered films of 150 dots (coverage 0.05-0.16, as the thesis's), whose few clusters leave
#: up to 0.33 of the rows' bands empty but in 1-4 runs.
LINE_DOTS, LINE_BAND, LINE_GAPS, LINE_FILLED, LINE_RUNS = 50, 1.6, 0.2, 0.05, 6
#: Round: the median outline (`qdots.micrograph.shapes`: the spread of the free boundary's distances to the centroid
#: over their mean) at most MAX_OUTLINE, over at least MIN_OUTLINES dots that show one (faint dots found in the fit's
#: residual show none: the blood cells of the development half showed 8 outlines among 17 whole dots, median 0.19,
#: where each film of the half showed one for all but 0-35 of its whole dots); the median elongation at most
#: MAX_ELONGATION where the outlines are not round either (over ROUND_OUTLINE). Measured on the development half of the
#: real micrographs: films of round and faceted particles 0.02-0.10 and 1.02-1.22; triangular plates, blood cells 0.19-
#: 0.20 and 1.33-1.41; rods cut into pieces 0.11 and 1.36 (a square's outline is 0.11, a hexagon's 0.06, a disc's on
#: the pixel grid 0.02-0.08).
MAX_OUTLINE, MAX_ELONGATION, ROUND_OUTLINE, MIN_OUTLINES = 0.13, 1.3, 0.1, 5
#: Pieces: at least PIECES of the whole dots are stacked on a neighbour (`qdots.micrograph.shapes.STACKED`: its centre
#: closer than 0.7 of their mean diameter). Measured on the development half: films 0-0.35, rods 0.65.
PIECES = 0.5


def empty_bands(positions: np.ndarray, band: float) -> tuple[float, int]:
    """The share of the bands ``band`` wide, between the 2nd and 98th percentiles of ``positions``, that hold
    none of them (0 over fewer than 4 bands), and the number of runs of filled bands between the empty ones."""
    low, high = np.percentile(positions, [2, 98])
    edges = np.arange(low, high + band, band)
    if len(edges) < 5:
        return 0.0, 1
    filled = np.histogram(positions, edges)[0] > 0
    runs = int(np.count_nonzero(filled[1:] & ~filled[:-1])) + int(filled[0])
    return float(np.mean(~filled)), runs


def text_lines(centres: np.ndarray, diameter: float) -> tuple[float, float, int]:
    """Whether objects at ``centres`` (x, y), px, of median ``diameter`` px lie in lines of text: the share of
    empty bands along the lines' direction, rows or columns, that the other direction leaves filled (see
    `LINE_BAND`), that of the other direction, and the number of lines (runs of filled bands) along the first."""
    (rows, row_runs), (cols, col_runs) = (empty_bands(centres[:, k], LINE_BAND * diameter) for k in (1, 0))
    return (rows, cols, row_runs) if rows >= cols else (cols, rows, col_runs)


def check_picture(image: np.ndarray, found: Annotations, source: str) -> None:
    """Refuse, in one line, a picture that is mostly flat colour (see the module)."""
    x0, y0, x1, y1 = found.window
    picture = np.asarray(image, dtype=float)[y0:y1, x0:x1]
    keep = ~found.ignore[y0:y1, x0:x1] if found.ignore is not None else np.ones(picture.shape, dtype=bool)
    span = float(picture.max() - picture.min())
    share = float(flatness(picture, FLAT_TOLERANCE * span)[keep].mean()) if keep.any() else 1.0
    if share > FLAT_SHARE:
        reason = (f"{100 * share:.0f} % of the picture is flat colour, as in a plot, text, a drawing or a rendered "
                  f"board (a micrograph has noise everywhere, under {100 * FLAT_SHARE:.0f} %)")
        raise NotAFilm(f"{source}: not a micrograph: {reason}", [reason])


def film_verdict(detection, max_outline: float = MAX_OUTLINE) -> tuple[list[str], list[str]]:
    """Why the dots found are not a film of round particles (empty when they are), and what makes their measurement
    doubtful (see the module), each in words with its numbers. ``max_outline``: the largest median outline of round
    objects (`MAX_OUTLINE`; stricter where the picture was smoothed, which rounds every outline)."""
    whole = ~detection.cut
    n = int(np.count_nonzero(whole))
    if n < MIN_FILM_DOTS:
        cut = int(detection.n_dots) - n
        return [f"only {n} round object{'' if n == 1 else 's'} stand{'s' if n == 1 else ''} out of the background"
                + (f" ({cut} more cut by the edge)" if cut else "")
                + f": this does not look like a film of particles (a film shows at least {MIN_FILM_DOTS} whole)"], []
    d = float(np.median(detection.diameters))
    if d < MIN_FILM_DIAMETER:
        return [f"the round objects found are {d:.1f} px across, under {MIN_FILM_DIAMETER:g} px (strokes of text or "
                "lines?)"], []
    refusals, doubts = [], []
    if n >= LINE_DOTS:
        lines, across, runs = text_lines(detection.centres[whole], d)
        if lines >= LINE_GAPS and across <= LINE_FILLED and runs >= LINE_RUNS:
            refusals.append(f"the round objects found lie in lines, as text does ({runs} lines, {100 * lines:.0f} % "
                            f"of the bands between them empty, {100 * across:.0f} % across; a film leaves under "
                            f"{100 * LINE_GAPS:.0f} % empty, or lies in fewer than {LINE_RUNS} clusters)")
    shapes = detection.shapes[whole]
    outline = shapes[np.isfinite(shapes[:, 1]), 1]
    if outline.size >= MIN_OUTLINES:
        wander, elongation = float(np.median(outline)), float(np.nanmedian(shapes[:, 0]))
        if wander > max_outline:
            refusals.append(f"the objects are not round: their outlines wander {100 * wander:.0f} % from one radius "
                            f"(median; round and faceted particles: under {100 * max_outline:.0f} %; a square's is 11 %, "
                            "a triangle's 17 %): plates, cubes, cells?")
        elif elongation > MAX_ELONGATION and wander > ROUND_OUTLINE:
            refusals.append(f"the objects are elongated: their long axis is {elongation:.2f} times the short one "
                            f"(median; round particles: under {MAX_ELONGATION:g}): rods, wires, cells?")
    ratio = nearest_ratio(detection.centres[whole], detection.diameters[whole])
    pieces = float(np.mean(ratio < STACKED))
    if pieces >= PIECES:
        refusals.append(f"{100 * pieces:.0f} % of the dots found lie closer than {STACKED:g} diameters to their "
                        "nearest neighbour: larger objects cut into pieces (rods, plates, wires?), not particles")
    spread = size_spread(detection.diameters[whole])["size_spread_robust"]
    if spread > MAX_FILM_SPREAD:
        doubts.append(f"the sizes vary {100 * spread:.0f} % (interquartile range): two populations, or false "
                      "detections? (see the size populations)")
    repeat = float(np.nanmedian(detection.errors / detection.diameters))
    if repeat > MAX_REPEAT_ERROR:
        doubts.append(f"the diameters measure {100 * repeat:.1f} % differently each time (clean films: under "
                      f"{100 * MAX_REPEAT_ERROR:.0f} %): a noisy or textured picture")
    overlapping = overlap_share(ratio)
    if overlapping > OVERLAP_SHARE:
        doubts.append(f"{100 * overlapping:.0f} % of the dots with a close neighbour overlap it (centres closer than "
                      f"{OVERLAP:g} of their mean diameter): hard particles in one layer do not")
    return refusals, doubts


class NotAFilm(InputError):
    """A picture that is not a film of round particles; ``reasons`` say why and ``found`` holds what was found (a
    `qdots.micrograph.measure.MeasuredFilm`, or None when nothing was), for an overlay that shows it."""

    def __init__(self, message: str, reasons: list[str], found=None):
        super().__init__(message)
        self.reasons = reasons
        self.found = found

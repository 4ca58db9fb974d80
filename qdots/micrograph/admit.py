"""Whether a picture is a micrograph of a film of round particles, or something else that must be refused
in one line: a plot, text, a drawing, a rendered board, rods, cubes, plates, cells.

Two looks. Before the dots are sought (`check_picture`): a micrograph has noise in every pixel, while
drawn pictures are mostly flat colour (`FLAT_SHARE` of the picture with 3 x 3 neighbourhoods of one value;
micrographs: mostly under 30 %; plots, text, drawings and qdots' own board pictures: 65-95 %), and what is not flat
in them is strokes and edges (`MIN_TEXTURED`): a micrograph whose background is clipped to one value, flat, still has
particles with noise or texture inside them. After (`film_verdict`), what
was found: a film has many dots the picture's edge does not cut (`MIN_FILM_DOTS`), big enough to be particles rather
than strokes of text or lines (`MIN_FILM_DIAMETER`), not set in lines of text (`text_lines`), round (the outlines they
show the background do not wander far from one radius, `MAX_OUTLINE`; they are not elongated, `MAX_ELONGATION`) and
whole (a rod or a plate that the detection cut into pieces leaves dots far closer than a diameter to their nearest
neighbour, `PIECES`, or slices that meet their neighbours along their whole width, `MAX_NECK`; the region shapes are
`qdots.micrograph.shapes`'). A film found on a smoothed picture must also be round in the picture as taken, where
its necks are read too (`as_taken`): smoothing rounds every outline and widens every contact. What is refused is said
with its numbers.

Other signs make a measurement doubtful without making the picture something else: sizes that vary over
`MAX_FILM_SPREAD` (two populations, or false detections), diameters that repeat worse than `MAX_REPEAT_ERROR` (a noisy
or textured picture), discs that overlap their neighbours (`OVERLAP`: the diameters may be too large). They are
reported beside the measurement (`film_verdict`'s doubts).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy import ndimage

from labrig.validate import InputError

from ..geometry import nearest_ratio
from .annotations import Annotations, flatness
from .cells import flattened
from .film import size_spread
from .shapes import OVERLAP, OVERLAP_SHARE, STACKED, elongation_within, necks_within, overlap_share

#: Share of the picture (within 0.2 % of its range) in flat 3 x 3 neighbourhoods above which it may be drawn.
FLAT_SHARE, FLAT_TOLERANCE = 0.3, 0.002
#: It is drawn unless at least MIN_TEXTURED of it lies TEXTURED_REACH px or more from any flat pixel (inside
#: something with noise or texture, not a stroke or an edge). Drawn pictures (`qdots.micrograph.labelled.not_a_film`:
#: plots, pages of text, drawings) 0.000-0.011; real micrographs with a clipped, flat background (of 254 EMPS and real
#: pictures, the five with over 30 % flat, among them two films refused as drawings before) 0.11-0.43.
MIN_TEXTURED, TEXTURED_REACH = 0.05, 4
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
#: Slices: the median neck (`qdots.micrograph.shapes`: a region's widest contact with one neighbour over its
#: area-equivalent diameter) of the whole dots' regions at least MAX_NECK. Round particles in one layer meet along a
#: chord shorter than that (two discs cut where their centres are half a diameter apart, far closer than hard particles
#: lie: 0.97; a hexagonal lattice's cells 0.55, a square lattice's 0.89); a rod, a wire or a plate cut across into
#: pieces shorter than wide leaves slices that meet along their whole width. Measured on the development halves (real
#: micrographs and EMPS): films of round particles 0-0.89; rods and dumbbells cut into pieces 1.10-1.23, triangular
#: plates 0.95, cells 0.98-1.17.
MAX_NECK = 1.0
#: The clearest dots: where the whole dots' contrasts, sorted, fall CONTRAST_GAP times or more from one to the next with
#: at least MIN_FILM_DOTS above, the dots above stand apart from a crowd of faint objects (`clearest_dots`). Measured on
#: the development halves, over the pictures refused by every other attempt (the largest such fall, with 10 or more
#: above): a few small particles on an SEM support speckled with faint, irregular features (EMPS 50a4901372: 11 clear
#: dots, 3.5 times the contrast of the 225 faint ones); every other picture 1.04-1.47 (rods, plates, cells, cubes,
#: textured or fragmented particles), but 2.5 (particles labelled not round), 3.3 (a drawing, refused before as flat
#: colour) and 15 (SEM silica spheres), whose clearest dots are not a film of round particles either.
CONTRAST_GAP = 3.0
#: Round as taken: a film found on a smoothed picture, whose outlines smoothing rounded, is one where the particles'
#: phase of the picture as taken (cut at Otsu's threshold, `qdots.micrograph.cells.flattened`) within TAKEN_REACH radii
#: of each whole dot has a median elongation at most MAX_TAKEN_ELONGATION. Measured on the development halves: films
#: found smoothed (textured, fragmented or faint particles) 1.01-1.42; sparse rods of aspect 2.3 that smoothing had
#: made round 1.92, cubes 1.87.
TAKEN_REACH, MAX_TAKEN_ELONGATION = 1.5, 1.6


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
    flat = flatness(picture, FLAT_TOLERANCE * span)
    share = float(flat[keep].mean()) if keep.any() else 1.0
    if share <= FLAT_SHARE:
        return
    # the pixels whose (2 TEXTURED_REACH + 1)-wide square holds no flat pixel: inside a textured object
    textured = ndimage.minimum_filter(~flat, size=2 * TEXTURED_REACH + 1, mode="constant", cval=True)
    inside = float(textured[keep].mean()) if keep.any() else 0.0
    if inside < MIN_TEXTURED:
        reason = (f"{100 * share:.0f} % of the picture is flat colour and {100 * inside:.1f} % lies inside anything "
                  "with noise or texture, as in a plot, text, a drawing or a rendered board (a micrograph has noise "
                  f"in its objects: over {100 * MIN_TEXTURED:.0f} % lies {TEXTURED_REACH} px or more inside them)")
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
    regions = shapes[np.isfinite(shapes[:, 0])]
    neck = float(np.median(regions[:, 2])) if len(regions) >= MIN_OUTLINES else 0.0
    if neck >= MAX_NECK:
        refusals.append(f"the objects found meet their neighbours along their whole width (median neck {neck:.2f}; "
                        f"round particles in one layer: under {MAX_NECK:g}): slices of larger objects (rods, wires, "
                        "plates?), not particles")
    ratio = nearest_ratio(detection.centres[whole], detection.diameters[whole])
    pieces = float(np.mean(ratio < STACKED))
    if pieces >= PIECES:
        refusals.append(f"{100 * pieces:.0f} % of the dots found lie closer than {STACKED:g} diameters to their "
                        "nearest neighbour: larger objects cut into pieces (rods, plates, wires?), not particles")
    spread = size_spread(detection.diameters[whole])["size_spread_robust"]
    if spread > MAX_FILM_SPREAD:
        doubts.append(f"the sizes vary {100 * spread:.0f} % (interquartile range): two populations, or false "
                      "detections? (see the size populations)")
    relative = detection.errors / detection.diameters
    repeat = float(np.nanmedian(relative)) if np.isfinite(relative).any() else 0.0  # (none: dots not yet fitted)
    if repeat > MAX_REPEAT_ERROR:
        doubts.append(f"the diameters measure {100 * repeat:.1f} % differently each time (clean films: under "
                      f"{100 * MAX_REPEAT_ERROR:.0f} %): a noisy or textured picture")
    overlapping = overlap_share(ratio)
    if overlapping > OVERLAP_SHARE:
        doubts.append(f"{100 * overlapping:.0f} % of the dots with a close neighbour overlap it (centres closer than "
                      f"{OVERLAP:g} of their mean diameter): hard particles in one layer do not")
    return refusals, doubts


def clearest_dots(detection) -> tuple[np.ndarray, float] | None:
    """The dots that stand apart from a crowd of fainter ones: where ``detection``'s whole dots' contrasts, sorted, fall
    `CONTRAST_GAP` times or more from one to the next with at least `MIN_FILM_DOTS` above, which dots (the cut ones
    too) lie above the largest such fall, and its ratio; None where there is none."""
    whole = np.sort(np.asarray(detection.contrast, dtype=float)[~detection.cut])[::-1]
    whole = whole[np.isfinite(whole)]
    if whole.size <= MIN_FILM_DOTS:
        return None
    ratios = whole[MIN_FILM_DOTS - 1:-1] / np.maximum(whole[MIN_FILM_DOTS:], 1e-12)
    k = int(np.argmax(ratios))
    if not ratios[k] >= CONTRAST_GAP:
        return None
    level = math.sqrt(max(whole[MIN_FILM_DOTS - 1 + k], 0.0) * max(whole[MIN_FILM_DOTS + k], 1e-12))
    return np.asarray(detection.contrast, dtype=float) >= level, float(ratios[k])


def as_taken(pixels: np.ndarray, detection, ignore: np.ndarray | None):
    """A film found on a smoothed picture, seen in ``pixels``, the picture as taken (``ignore``: pixels left out),
    cut at Otsu's threshold: the median elongation of the particles' phase within `TAKEN_REACH` radii of each of
    ``detection``'s whole dots (`qdots.micrograph.shapes.elongation_within`; NaN where no dot shows one), and
    ``detection`` with the necks of its regions read there (`qdots.micrograph.shapes.necks_within`: the phase within
    `TAKEN_REACH` radii of each dot, nearer to it than to any other), where smoothing had widened them."""
    from skimage.filters import threshold_otsu

    x0, y0 = detection.window[:2]
    _, _, flat, left_out = flattened(pixels, ignore, detection.window, detection.dark)
    if not (~left_out).any() or float(np.ptp(flat[~left_out])) <= 0:
        return math.nan, detection
    phase = (flat < threshold_otsu(flat[~left_out])) & ~left_out
    centres = detection.centres - [x0, y0]
    whole = ~detection.cut
    found = elongation_within(phase, centres[whole], detection.diameters[whole], TAKEN_REACH)
    shapes = detection.shapes.copy()
    shapes[:, 2] = necks_within(phase, centres, detection.diameters, TAKEN_REACH)
    return (float(np.nanmedian(found)) if np.isfinite(found).any() else math.nan), replace(detection, shapes=shapes)


class NotAFilm(InputError):
    """A picture that is not a film of round particles; ``reasons`` say why and ``found`` holds what was found (a
    `qdots.micrograph.measure.MeasuredFilm`, or None when nothing was), for an overlay that shows it."""

    def __init__(self, message: str, reasons: list[str], found=None):
        super().__init__(message)
        self.reasons = reasons
        self.found = found

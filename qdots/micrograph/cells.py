"""Particles as the cells of a network: films whose particles the dot search cuts into pieces.

Where particles touch, the film's other phase (the gaps between them, and their shadows and rims in SEM) forms one
connected network, and each particle is a cell it encloses; on a sparse film the background is that network. When
the dots found in both phases are refused, and the smoothed retry finds no film either (`qdots.micrograph.measure`),
the picture is cut at Otsu's threshold after its broad fall of light is taken out, as
`qdots.micrograph.detect.first_look` does. Two routes follow:

* **a network**: where one phase is a network (at least `NETWORK_SHARE` of its pixels in one piece), the cells it
  encloses are the particles (two or three fused where the cut missed their gap are split, `split_merged`);
* **touching in a lattice**: where no phase is, as in a close-packed monolayer whose gaps break at every contact, the
  lattice's spacing (`lattice_spacing`) sets a top-hat that finds the thin gaps, and a watershed of the distance from
  them parts the particles (`touching_cells`).

Each cell is made whole (`whole_outlines`: a darker core or a rim-lit crescent) and measured by the disc of its area
at the threshold: halfway between the network's level and the particle's, as a line profile's half depth. No profile
is fitted: the sizes are a threshold's, and the measurement says so.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from .detection import Detection
from .segment import broad_blur, pixel_noise, region_properties, scaled, split_fused
from .shapes import region_shapes

#: One phase is a network when at least NETWORK_SHARE of its pixels lie in one connected piece. On the EMPS development
#: half's close-packed films whose particles the dot search cut into pieces, 0.94-0.98; where the phase was not a
#: network (sparse SEM spheres' shadows, a close-packed film whose gaps the threshold breaks), 0.25-0.65.
NETWORK_SHARE = 0.9
#: The cells are measured at a threshold, which moves each edge by up to a pixel: they are taken only where their
#: median is MIN_CELL px across or more (a bias under a tenth). On the EMPS development half, cells of 6.7 px read
#: 0.67 of the labels' diameter where cells of 37-47 px read 0.93-0.94.
MIN_CELL = 20.0
#: Cells of fewer pixels are specks, not particles; cells of MERGED times the median whole cell's area or more are
#: particles whose gap the threshold missed (`split_merged`), up to CLUMP times: a larger cell is a clump the cut did
#: not open (on the EMPS development half, one of 18 cells' area, which k-means cut into 20 pieces that were not
#: round), left whole (its size is an outlier, kept out of the sizes).
MIN_CELL_PIXELS, MERGED, CLUMP = 20, 1.6, 4.0
#: A cell of solidity under CONCAVE is a particle's lit part (`whole_outlines`). On the EMPS development half: 13 of the
#: 116 cells of rim-lit SEM spheres (their crescents); 6 of the 144 cells of a close-packed film, whose median is 0.97.
CONCAVE = 0.8
#: Touching particles in a lattice (a close-packed monolayer of spheres): their gaps are broken at every contact, so
#: no phase is a network. The lattice's spacing is the highest peak of the picture's autocorrelation beyond its
#: central lobe, taken where it stands LATTICE_CONTRAST (of the autocorrelation at zero) above the lobe's first
#: minimum (on the EMPS development half's close-packed SEM monolayer of 50 px spheres, 0.09).
LATTICE_CONTRAST = 0.05
#: The gaps are the thin lines and interstices a top-hat of GAP_RADIUS spacings (at least GAP_RADIUS_MIN px) finds;
#: each particle is one peak of the distance from them, peaks at least MARKER_SPACING spacings apart.
GAP_RADIUS, GAP_RADIUS_MIN, MARKER_SPACING = 1.0 / 16.0, 2, 0.35


def network_cells(pixels: np.ndarray, ignore: np.ndarray | None, window: tuple[int, int, int, int],
                  dark: bool) -> Detection | None:
    """The particles of ``pixels`` as the cells of a network, or touching in a lattice where no phase is a network
    (see the module), darker than the network where ``dark``; None where neither route finds cells (no network and no
    lattice) or its cells are under `MIN_CELL` px.

    Parameters
    ----------
    pixels : ndarray, shape (H, W)
        The picture.
    ignore : ndarray of bool, shape (H, W), or None
        Pixels left out (a data strip, a label box, the scale bar).
    window : (int, int, int, int)
        ``(x0, y0, x1, y1)``: the part of the image that is picture, px.
    dark : bool
        Whether the particles are the darker phase.

    Returns
    -------
    Detection or None
        Each cell's centroid and the diameter of the disc of its area; ``cut`` where it touches the window's edge or
        a pixel left out; ``errors`` how far each diameter moves when the threshold moves by the pixel noise;
        ``shape`` NaN (no profile fitted); ``widths`` the diameters (a network's threshold is the half depth; in a
        lattice, the width between the gaps: there, and on rim-lit SEM spheres, a line profile's half depth is no
        particle's edge).
    """
    from skimage.filters import threshold_otsu
    from skimage.morphology import disk, white_tophat
    from skimage.segmentation import expand_labels

    x0, y0, x1, y1 = window
    unit, smooth, flat, left_out = flattened(pixels, ignore, window, dark)
    if not (~left_out).any() or float(np.ptp(flat[~left_out])) <= 0:
        return None
    threshold = threshold_otsu(flat[~left_out])
    network = (flat >= threshold) & ~left_out
    share = largest_share(network)
    field = flat
    if share >= NETWORK_SHARE:
        cells, rejected = enclosed_cells(network, left_out)
        how = (f"{'dark' if dark else 'light'} particles as the cells of the {'light' if dark else 'dark'} network "
               f"({100 * share:.0f} % of its pixels in one piece), cut at Otsu's threshold")
    else:  # particles touching in a lattice: their gaps are broken at every contact
        spacing = lattice_spacing(flat, left_out)
        if spacing is None or spacing < MIN_CELL:
            return None
        field = white_tophat(smooth, disk(max(GAP_RADIUS_MIN, round(spacing * GAP_RADIUS))))
        threshold = threshold_otsu(field[~left_out])
        network = (field >= threshold) & ~left_out
        cells, rejected = touching_cells(network, left_out, spacing)
        how = (f"{'dark' if dark else 'light'} particles touching in a lattice, parted along their "
               f"{'light' if dark else 'dark'} gaps (thin lines and interstices, a top-hat cut at Otsu's threshold)")
    if not cells.any():
        return None
    props = region_properties(cells)
    diameters = 2.0 * np.sqrt(props["area"] / math.pi)
    touching = np.zeros(len(diameters) + 1, dtype=bool)
    touching[np.unique(cells[ndimage.binary_dilation(left_out)])] = True
    cut = props["edge"] | touching[1:]
    whole = ~cut
    if not whole.any() or float(np.median(diameters[whole])) < MIN_CELL:
        return None
    # each diameter at thresholds one pixel noise (of the smoothed picture) either side: its measurement error
    noise = pixel_noise(smooth, left_out)
    grown = expand_labels(cells, 2)
    larger = np.bincount(grown[field < threshold + noise], minlength=len(diameters) + 1)[1:]
    smaller = np.bincount(cells[field < threshold - noise], minlength=len(diameters) + 1)[1:]
    errors = np.sqrt(larger / math.pi) - np.sqrt(smaller / math.pi)
    level = np.asarray(ndimage.median(unit, cells, np.arange(1, len(diameters) + 1)))
    ground = float(np.median(unit[network]))
    contrast = (ground - level) / max(ground, 1e-9)
    centres = np.column_stack([props["centroid-1"] + 0.5 + x0, props["centroid-0"] + 0.5 + y0])
    return Detection(centres, diameters, cut, contrast, dark, how, math.nan,
                     "none fitted: each cell's area at the threshold (its half depth)", math.nan, rejected,
                     tuple(np.shape(pixels)), (x0, y0, x1, y1), errors, region_shapes(cells), diameters.copy())


def flattened(pixels: np.ndarray, ignore: np.ndarray | None, window: tuple[int, int, int, int],
              dark: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The part of ``pixels`` inside ``window`` as the cut at Otsu's threshold sees it (see the module): mapped to
    [0, 1] with the particles dark (``unit``; ``dark``: they are the darker phase), smoothed by 1 px (``smooth``), its
    broad fall of light taken out (``flat``), and the pixels left out (``ignore`` inside the window)."""
    x0, y0, x1, y1 = window
    inner = (slice(y0, y1), slice(x0, x1))
    left_out = np.zeros(np.shape(pixels), dtype=bool) if ignore is None else np.asarray(ignore, dtype=bool)
    left_out = left_out[inner]
    unit = scaled(np.asarray(pixels, dtype=float)[inner], left_out)
    unit = unit if dark else 1.0 - unit  # particles dark, the network light
    smooth = ndimage.gaussian_filter(unit, 1.0)
    return unit, smooth, smooth - broad_blur(smooth, max(unit.shape) / 12.0), left_out


def largest_share(mask: np.ndarray) -> float:
    """The share of ``mask``'s pixels in its largest connected piece (0 where it is empty)."""
    pieces, n = ndimage.label(mask)
    return float(np.bincount(pieces.ravel())[1:].max() / mask.sum()) if n else 0.0


def without_specks(cells: np.ndarray) -> tuple[np.ndarray, int]:
    """``cells`` (labels 1 .. n) without those of under `MIN_CELL_PIXELS` pixels, relabelled 1 .. m; and n - m."""
    n = int(cells.max())
    keep = np.bincount(cells.ravel(), minlength=n + 1) >= MIN_CELL_PIXELS
    keep[0] = False
    relabel = np.zeros(n + 1, dtype=np.int64)
    relabel[keep] = np.arange(1, int(keep.sum()) + 1)
    return relabel[cells], int(n - keep[1:].sum())


def enclosed_cells(network: np.ndarray, left_out: np.ndarray) -> tuple[np.ndarray, int]:
    """The cells ``network`` encloses (outside ``left_out``), specks dropped, each whole (`whole_outlines`) and fused
    ones split (`split_merged`), and the number of specks."""
    cells, rejected = without_specks(ndimage.label(~network & ~left_out)[0])
    return (split_merged(whole_outlines(cells)) if cells.any() else cells), rejected


def whole_outlines(cells: np.ndarray) -> np.ndarray:
    """``cells`` with what each one's outline encloses: the holes only it surrounds (a particle's darker core, its
    texture), and, for a cell of solidity under `CONCAVE`, its convex hull where no other cell lies (an SEM sphere lit
    on one side shows a crescent, its lit rim): a particle is convex. Other cells (the polygons of a close packing)
    are left as they are."""
    from skimage.measure import regionprops

    mask = cells > 0
    holes = ndimage.binary_fill_holes(mask) & ~mask
    pieces, n = ndimage.label(holes)
    out = cells.copy()
    if n:
        rim = ndimage.binary_dilation(holes, np.ones((3, 3), dtype=bool)) & mask
        pairs = np.unique(np.stack([ndimage.grey_dilation(pieces, size=(3, 3))[rim], cells[rim]]), axis=1)
        owners = np.bincount(pairs[0], minlength=n + 1)
        owner = np.zeros(n + 1, dtype=cells.dtype)
        owner[pairs[0]] = pairs[1]
        owner[owners != 1] = 0
        owner[0] = 0
        out = np.where(holes, owner[pieces], out)
    for region in regionprops(out):
        if region.solidity < CONCAVE:
            r0, c0, r1, c1 = region.bbox
            part = out[r0:r1, c0:c1]
            part[region.image_convex & (part == 0)] = region.label
    return out


def touching_cells(gaps: np.ndarray, left_out: np.ndarray, spacing: float) -> tuple[np.ndarray, int]:
    """Touching particles ``spacing`` px apart parted along their broken ``gaps``: one particle at each peak of the
    (smoothed) distance from the gaps, peaks at least `MARKER_SPACING` spacings apart, the picture between them cut
    by a watershed of that distance, each particle the part of its cell outside the gaps; specks dropped. Returns
    the labels and the number of specks."""
    from skimage.feature import peak_local_max
    from skimage.segmentation import watershed

    distance = ndimage.gaussian_filter(ndimage.distance_transform_edt(~gaps & ~left_out), 2.0)
    peaks = peak_local_max(distance, min_distance=max(1, int(MARKER_SPACING * spacing)), exclude_border=False)
    markers = np.zeros(gaps.shape, dtype=np.int64)
    markers[tuple(peaks.T)] = np.arange(1, len(peaks) + 1)
    parted = watershed(-distance, markers, mask=~left_out)
    return without_specks(np.where(gaps, 0, parted))


def lattice_spacing(image: np.ndarray, left_out: np.ndarray) -> float | None:
    """The spacing of the lattice ``image`` shows, px: the highest peak of its autocorrelation's radial profile
    beyond the central lobe (out to a third of its shorter side; ``left_out`` pixels carry no weight), refined by a
    parabola; None where it stands less than `LATTICE_CONTRAST` above the lobe's first minimum."""
    inside = ~left_out
    values = np.where(inside, image - image[inside].mean(), 0.0)
    pad = (2 * image.shape[0], 2 * image.shape[1])
    products = np.fft.irfft2(np.abs(np.fft.rfft2(values, s=pad)) ** 2, s=pad)
    pairs = np.fft.irfft2(np.abs(np.fft.rfft2(inside.astype(float), s=pad)) ** 2, s=pad)
    reach = min(image.shape) // 3
    rows = np.minimum(np.arange(pad[0]), pad[0] - np.arange(pad[0]))[:, None]
    cols = np.minimum(np.arange(pad[1]), pad[1] - np.arange(pad[1]))[None, :]
    radius = np.rint(np.hypot(rows, cols)).astype(np.int64)
    near = radius <= reach + 1
    correlation = np.where(pairs > 0.5, products / np.maximum(pairs, 1.0), 0.0)[near]
    profile = np.bincount(radius[near], correlation) / np.maximum(np.bincount(radius[near]), 1)
    if profile[0] <= 0:
        return None
    profile = profile / profile[0]
    rising = np.flatnonzero(profile[1:reach] <= profile[2:reach + 1])
    if rising.size == 0:
        return None
    first_minimum = int(rising[0]) + 1
    peak = first_minimum + int(np.argmax(profile[first_minimum:reach]))
    if peak <= first_minimum or profile[peak] - profile[first_minimum] < LATTICE_CONTRAST:
        return None
    left, middle, right = profile[peak - 1:peak + 2]
    bend = left - 2.0 * middle + right
    return float(peak + (0.5 * (left - right) / bend if bend < 0 else 0.0))


def split_merged(cells: np.ndarray) -> np.ndarray:
    """``cells`` (labels 1 .. n) with those of `MERGED` to `CLUMP` times the median whole cell's area, two or more
    particles whose gap the threshold missed, split into as many as their area holds median cells
    (`qdots.micrograph.segment.split_fused`; the other cells, polygons in a close packing that it would cut, are left
    whole). Returns labels 1 .. m."""
    from skimage.segmentation import relabel_sequential

    area = np.bincount(cells.ravel())[1:]
    edge = np.zeros(len(area) + 1, dtype=bool)
    edge[np.concatenate([cells[0], cells[-1], cells[:, 0], cells[:, -1]])] = True
    whole = area[~edge[1:]] if (~edge[1:]).any() else area  # cells the picture's edge cuts are smaller
    unit = float(np.median(whole))
    merged = np.flatnonzero((area >= MERGED * unit) & (area <= CLUMP * unit)) + 1
    if merged.size == 0:
        return cells
    only = np.where(np.isin(cells, merged), cells, 0)
    parts = split_fused(only, ndimage.distance_transform_edt(only > 0), unit_area=unit)
    return relabel_sequential(np.where(only > 0, parts + int(cells.max()), cells))[0]

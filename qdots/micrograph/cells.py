"""Particles as the cells of a network: films whose particles the dot search cuts into pieces.

Where particles touch, the film's other phase (the gaps between them, and their shadows and rims in SEM) forms one
connected network, and each particle is a cell it encloses; on a sparse film the background is that network. When
the dots found in both phases are refused, and the smoothed retry finds no film either (`qdots.micrograph.measure`),
the picture is cut at Otsu's threshold after its broad fall of light is taken out, as
`qdots.micrograph.detect.first_look` does; where one phase is a network (at least `NETWORK_SHARE` of its pixels in one
piece), the cells it encloses are the particles (two or three fused where the cut missed their gap are split,
`split_merged`), each measured by the disc of its area at that threshold: halfway between the network's level and the
particle's, as a line profile's half depth. No profile is fitted: the sizes are a threshold's, and the measurement
says so.
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


def network_cells(pixels: np.ndarray, ignore: np.ndarray | None, window: tuple[int, int, int, int],
                  dark: bool) -> Detection | None:
    """The particles of ``pixels`` as the cells of a network (see the module), darker than the network where ``dark``,
    or None where that phase's complement is no network or its cells are under `MIN_CELL` px.

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
        ``shape`` NaN (no profile fitted); ``widths`` the diameters (the threshold is the half depth).
    """
    from skimage.filters import threshold_otsu
    from skimage.segmentation import expand_labels

    x0, y0, x1, y1 = window
    inner = (slice(y0, y1), slice(x0, x1))
    left_out = np.zeros(np.shape(pixels), dtype=bool) if ignore is None else np.asarray(ignore, dtype=bool)
    left_out = left_out[inner]
    unit = scaled(np.asarray(pixels, dtype=float)[inner], left_out)
    unit = unit if dark else 1.0 - unit  # particles dark, the network light
    smooth = ndimage.gaussian_filter(unit, 1.0)
    flat = smooth - broad_blur(smooth, max(unit.shape) / 12.0)
    if not (~left_out).any() or float(np.ptp(flat[~left_out])) <= 0:
        return None
    threshold = threshold_otsu(flat[~left_out])
    network = (flat >= threshold) & ~left_out
    pieces, n = ndimage.label(network)
    if n == 0:
        return None
    sizes = np.bincount(pieces.ravel())[1:]
    if sizes.max() < NETWORK_SHARE * network.sum():
        return None
    cells, n = ndimage.label(~network & ~left_out)
    area = np.bincount(cells.ravel(), minlength=n + 1)
    keep = area >= MIN_CELL_PIXELS
    keep[0] = False
    relabel = np.zeros(n + 1, dtype=np.int64)
    relabel[keep] = np.arange(1, int(keep.sum()) + 1)
    cells = relabel[cells]
    rejected = int(n - keep[1:].sum())
    if not cells.any():
        return None
    cells = split_merged(cells)
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
    larger = np.bincount(grown[flat < threshold + noise], minlength=len(diameters) + 1)[1:]
    smaller = np.bincount(cells[flat < threshold - noise], minlength=len(diameters) + 1)[1:]
    errors = np.sqrt(larger / math.pi) - np.sqrt(smaller / math.pi)
    level = np.asarray(ndimage.median(unit, cells, np.arange(1, len(diameters) + 1)))
    ground = float(np.median(unit[network]))
    contrast = (ground - level) / max(ground, 1e-9)
    centres = np.column_stack([props["centroid-1"] + 0.5 + x0, props["centroid-0"] + 0.5 + y0])
    share = float(sizes.max() / network.sum())
    how = (f"{'dark' if dark else 'light'} particles as the cells of the {'light' if dark else 'dark'} network "
           f"({100 * share:.0f} % of its pixels in one piece), cut at Otsu's threshold")
    return Detection(centres, diameters, cut, contrast, dark, how, math.nan,
                     "none fitted: each cell's area at the threshold (its half depth)", math.nan, rejected,
                     tuple(np.shape(pixels)), (x0, y0, x1, y1), errors, region_shapes(cells), diameters.copy())


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

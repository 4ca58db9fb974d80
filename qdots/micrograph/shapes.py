"""The shapes of the objects a micrograph's dots were found in: are they round particles?

A watershed cuts any object into dot-sized regions: a rod becomes a row of discs, a cube a square, a cell a blob.
Three measures of each region (`region_shapes`) tell round particles from other things:

* **elongation**: the square root of the ratio of its second moments, long axis over short (a disc 1, a rod of
  aspect 3 about 3);
* **outline**: how far the outline it shows to the background (its free boundary, not the cuts between it and its
  neighbours) wanders from one distance to its centroid: the coefficient of variation of those distances (a disc
  about 0.03 on the pixel grid, a hexagon seen face-on 0.04, a square 0.08, a triangle 0.17);
* **neck**: its widest contact with one neighbour (pixels along the cut between them) over its area-equivalent
  diameter: touching spheres meet at a narrow waist (0.2-0.6 once blurred), two pieces of one rod or two cubes
  face to face along their whole width (about 1).

And one of the discs fitted to the dots (`qdots.geometry.nearest_ratio`, `overlap_share`): hard particles in one layer do not
overlap, so discs that overlap their nearest neighbours are larger than the particles (or larger objects were cut into
pieces).
"""

from __future__ import annotations

import math

import numpy as np

from labrig.compiled import jit

from .segment import label_moments

#: Dots overlap when their centres are closer than OVERLAP times their mean diameter; a film whose dots with a close
#: neighbour (within 1.5 diameters) overlap it over OVERLAP_SHARE of the time has discs larger than its particles. A dot
#: whose nearest neighbour is closer than STACKED times their mean diameter overlaps it by over a third: in one layer no
#: particle can, so it lies on another (a second layer), or it is a piece of something larger, or not a particle.
OVERLAP, OVERLAP_SHARE, STACKED = 0.95, 0.2, 0.7


@jit
def _boundaries(labels, cx, cy):
    """Per region (1 .. n): the sum and the sum of squares of the distances of its free-boundary pixels (a 4-neighbour
    is background) to (cx, cy), their count; and the (region, neighbour) pairs of its pixels that touch another region."""
    h, w = labels.shape
    n = cx.shape[0]
    s1 = np.zeros(n)
    s2 = np.zeros(n)
    count = np.zeros(n)
    first = np.empty(4 * h * w // 2 + 4, dtype=np.int64)
    second = np.empty(4 * h * w // 2 + 4, dtype=np.int64)
    m = 0
    for row in range(h):
        for col in range(w):
            k = labels[row, col]
            if k <= 0:
                continue
            free = False
            for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)):
                r2 = row + dr
                c2 = col + dc
                if r2 < 0 or r2 >= h or c2 < 0 or c2 >= w:
                    continue
                j = labels[r2, c2]
                if j == 0:
                    free = True
                elif j != k and m < first.shape[0]:
                    first[m] = k
                    second[m] = j
                    m += 1
            if free:
                d = math.sqrt((col + 0.5 - cx[k - 1]) ** 2 + (row + 0.5 - cy[k - 1]) ** 2)
                s1[k - 1] += d
                s2[k - 1] += d * d
                count[k - 1] += 1.0
    return s1, s2, count, first[:m], second[:m]


def region_shapes(labels: np.ndarray) -> np.ndarray:
    """Elongation, outline and neck (see the module) of each region 1 .. n of ``labels`` (0: background), as an
    array of shape (n, 3); the outline is NaN for a region with fewer than 8 free-boundary pixels (it shows the
    background too little to tell its shape), the neck 0 for a region that touches no other."""
    labels = np.ascontiguousarray(labels, dtype=np.int64)
    n = int(labels.max())
    if n == 0:
        return np.zeros((0, 3))
    sums = label_moments(labels, n, 0.5)
    area = sums[0]
    safe = np.maximum(area, 1.0)
    y, x = sums[1] / safe, sums[2] / safe
    yy, xx, xy = sums[3] / safe - y * y, sums[4] / safe - x * x, sums[5] / safe - x * y
    middle, half = 0.5 * (xx + yy), np.sqrt(0.25 * (xx - yy) ** 2 + xy * xy)
    elongation = np.sqrt((middle + half + 1.0 / 12.0) / np.maximum(middle - half + 1.0 / 12.0, 1e-12))
    s1, s2, count, first, second = _boundaries(labels, x, y)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = s1 / count
        outline = np.where(count >= 8, np.sqrt(np.maximum(s2 / count - mean * mean, 0.0)) / mean, np.nan)
    neck = np.zeros(n)
    if first.size:
        pairs, contacts = np.unique(first * (n + 1) + second, return_counts=True)
        np.maximum.at(neck, pairs // (n + 1) - 1, contacts.astype(float))
    neck /= 2.0 * np.sqrt(safe / math.pi)
    return np.column_stack([elongation, outline, neck])


def elongation_within(mask: np.ndarray, centres: np.ndarray, diameters: np.ndarray, reach: float) -> np.ndarray:
    """The elongation (as `region_shapes`') of the pixels of ``mask`` within ``reach`` radii of each centre (``centres``
    (x, y), px, of discs of ``diameters`` px, in ``mask``'s pixels); NaN where fewer than 5 pixels are."""
    mask = np.asarray(mask, dtype=bool)
    h, w = mask.shape
    out = np.full(len(diameters), np.nan)
    for k, ((x, y), d) in enumerate(zip(np.asarray(centres, dtype=float), np.asarray(diameters, dtype=float))):
        r = reach * 0.5 * d
        top, left = max(0, int(y - r)), max(0, int(x - r))
        rows, cols = np.mgrid[top:min(h, int(y + r) + 2), left:min(w, int(x + r) + 2)]
        inside = mask[rows, cols] & ((cols + 0.5 - x) ** 2 + (rows + 0.5 - y) ** 2 <= r * r)
        if np.count_nonzero(inside) < 5:
            continue
        spread = np.cov(np.vstack([cols[inside], rows[inside]]).astype(float), bias=True) + np.eye(2) / 12.0
        low, high = np.linalg.eigvalsh(spread)
        out[k] = math.sqrt(high / max(low, 1e-12))
    return out


def necks_within(mask: np.ndarray, centres: np.ndarray, diameters: np.ndarray, reach: float) -> np.ndarray:
    """The neck (as `region_shapes`') of each disc's region in ``mask``: its pixels within ``reach`` radii of the disc's
    centre that lie nearer to it than to any other centre (``centres`` (x, y), px, of discs of ``diameters`` px, in
    ``mask``'s pixels); 0 for a disc whose centre lies outside ``mask``."""
    from scipy import ndimage

    mask = np.asarray(mask, dtype=bool)
    h, w = mask.shape
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    n = len(centres)
    cols, rows = np.floor(centres[:, 0]).astype(np.int64), np.floor(centres[:, 1]).astype(np.int64)
    inside = (cols >= 0) & (cols < w) & (rows >= 0) & (rows < h)
    if n == 0 or not inside.any():
        return np.zeros(n)
    seeds = np.zeros((h, w), dtype=np.int64)
    seeds[rows[inside], cols[inside]] = np.flatnonzero(inside) + 1
    distance, (near_row, near_col) = ndimage.distance_transform_edt(seeds == 0, return_indices=True)
    labels = seeds[near_row, near_col]
    reach_px = reach * 0.5 * np.asarray(diameters, dtype=float)
    labels[~mask | (distance > reach_px[labels - 1])] = 0
    necks = np.zeros(n)
    found = region_shapes(labels)[:, 2]
    necks[:len(found)] = found
    return necks


def overlap_share(ratio: np.ndarray) -> float:
    """Of the dots with a close neighbour (`qdots.geometry.nearest_ratio` under 1.5), the share that overlap it (under `OVERLAP`)."""
    ratio = np.asarray(ratio, dtype=float)
    close = ratio < 1.5
    return float(np.mean(ratio[close] < OVERLAP)) if close.any() else 0.0

"""Dot pixels from a grey image: scaling, illumination, threshold phases, splitting, the regions and noise.

The building blocks of `qdots.micrograph.detect`; each works on whole arrays (scipy.ndimage, scikit-image)
or, where a library would sort or loop in Python, in a compiled loop.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from scipy import ndimage

from labrig.compiled import jit
from labrig.threads import BAND_ROWS, by_rows, run_tasks

from ..geometry import pairs_within
from .profiles import BIN

#: A dot must stand this clearly out of the noise (`signal_to_noise`: its darkness over the noise of its mean, which
#: falls as the square root of its pixels). Noise alone, measured over 63,696 candidate dots that the detection finds
#: in 24 images of white, clipped 8-bit and Poisson noise (64-400 px): median 1.3, 99th percentile 3.4, 99.9th 4.1,
#: largest 5.0; the tail falls tenfold per about 0.8, so about one noise candidate in 1e8 scores 8. Films of 10-24 px
#: dots at noise 0.3 of the background score 8-23 (median), clipped 8-bit or not.
MIN_SIGNAL = 8.0
#: A dot must stand GRAIN_SIGNAL deviations of its mean out of the support's grain (`grain_noise`, measured on the
#: picture: a deviation, not the extreme of many candidates as `MIN_SIGNAL` is). Synthetic sparse films on grain of 5 %
#: and 10 % of the background (16 and 8 px dots, contrast 0.4), recall / precision: at 8 deviations 1.00 / 1.00, 0.68
#: / 1.00 and 0.03 / 1.00, 0.10 / 0.98; at 5, 1.00 / 1.00, 0.99 / 0.99 and 0.74 / 0.69, 0.75 / 0.81.
GRAIN_SIGNAL = 5.0
#: Image-wide statistics (percentiles, noise) use every SUBSAMPLE-th pixel.
SUBSAMPLE = 3
#: The support's grain (`grain_noise`) is read on the pixels at least GRAIN_CLEAR radii from every dot, when they are
#: GRAIN_SHARE of the picture, against its average over GRAIN_BROAD radii.
GRAIN_CLEAR, GRAIN_SHARE, GRAIN_BROAD = 2.0, 0.05, 6.0
#: Dot sizes, in typical radii, at which the grain is read (`grain_noise`); a dot's own is interpolated between them.
GRAIN_SIZES = (0.5, 0.7, 1.0, 1.4, 2.0)
#: An object is a dot when its inscribed radius is at least this share of the typical radius.
MIN_INSCRIBED = 1.0 / 3.0
#: A region whose area is more than this many times the disc of its inscribed radius, and whose long axis is
#: this many times its short one (square root of the ratio of its second moments), is fused dots (`split_fused`).
#: Two discs of radius r with centres r apart: area 1.61 pi r^2, elongation 1.41 (1.2 r: 1.72 and 1.56).
FUSED_AREA, FUSED_ELONGATION = 1.6, 1.4


def scaled(image: np.ndarray, ignore: np.ndarray | None = None, clip: bool = True) -> np.ndarray:
    """``image`` mapped to [0, 1] by its 0.5 and 99.5 percentiles (outside ``ignore``), clipped (or not)."""
    values = image[~ignore] if ignore is not None else image.ravel()
    low, high = np.percentile(values[::SUBSAMPLE], [0.5, 99.5])
    if high <= low:
        low, high = float(values.min()), float(values.max())
    if high <= low:  # one grey value: no structure to scale
        return np.zeros(image.shape)
    out = (image - low) / (high - low)
    return np.clip(out, 0.0, 1.0) if clip else out


def broad_blur(image: np.ndarray, sigma: float, mode: str = "nearest") -> np.ndarray:
    """``image`` blurred by a Gaussian of ``sigma`` px, for a broad ``sigma``, its edges extended as
    `scipy.ndimage.gaussian_filter`'s ``mode`` (``"nearest"``: the edge pixels repeated; ``"reflect"``: mirrored): the
    image extended as far as the kernel reaches (4 ``sigma``), averaged over blocks of ``sigma / 8`` px, blurred, then
    interpolated back (the blurred image varies over ``sigma``; the direct filter costs in proportion to it, a
    2048 px image's at 170 px about a second). Within 1 % of the image's range of the direct filter, edges included
    (an edge column repeated as far as the kernel reaches weighs as much here as there)."""
    pad_mode: Literal["edge", "symmetric"] = "edge" if mode == "nearest" else "symmetric"
    if mode not in ("nearest", "reflect"):
        raise ValueError(f"mode must be 'nearest' or 'reflect', got {mode!r}")
    block = max(1, int(sigma / 8.0))
    if block == 1:
        return ndimage.gaussian_filter(image, sigma, mode=mode)
    h, w = image.shape
    pad = -(-int(4.0 * sigma + 0.5) // block) * block
    hb, wb = -(-(h + 2 * pad) // block), -(-(w + 2 * pad) // block)
    padded = np.pad(image, ((pad, hb * block - h - pad), (pad, wb * block - w - pad)), mode=pad_mode)
    small = padded.reshape(hb, block, wb, block).mean(axis=(1, 3))
    small = ndimage.gaussian_filter(small, sigma / block, mode="nearest")
    return stretch(small, (np.arange(h) + pad + 0.5) / block - 0.5, (np.arange(w) + pad + 0.5) / block - 0.5)


def stretch(coarse: np.ndarray, rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
    """``coarse`` interpolated linearly at every pair of fractional ``rows`` and ``cols`` (its own px; clipped to it):
    an image ``len(rows)`` x ``len(cols)``. The same values as `scipy.ndimage.map_coordinates` at order 1 on the grid
    of those pairs, in two passes of one axis each (a 2048 px image in a tenth of the time)."""
    rows = np.asarray(rows, dtype=float)
    if len(rows) >= 2 * BAND_ROWS:  # bands of rows side by side in threads: each output row is its own
        return np.concatenate(run_tasks([lambda part=part: stretch(coarse, part, cols)
                                         for part in np.array_split(rows, 2)]))
    out = np.asarray(coarse, dtype=float)
    for axis, where in ((0, rows), (1, cols)):
        where = np.clip(np.asarray(where, dtype=float), 0, out.shape[axis] - 1)
        low = np.minimum(where.astype(int), max(out.shape[axis] - 2, 0))
        high = np.minimum(low + 1, out.shape[axis] - 1)
        t = where - low
        shape = (-1, 1) if axis == 0 else (1, -1)
        out = (np.take(out, low, axis=axis) * (1.0 - t).reshape(shape)
               + np.take(out, high, axis=axis) * t.reshape(shape))
    return out


def background_level(image: np.ndarray, background: np.ndarray, width: float) -> np.ndarray:
    """The background level everywhere: a Gaussian (``width`` px) average of ``image`` over the ``background``
    pixels only (normalised convolution); where none is near, the median of all of them. Computed on a grid
    coarser by ``width / 4`` (the level varies over ``width``) and interpolated back."""
    step = max(1, int(width / 4))
    small = (slice(None, None, step), slice(None, None, step))
    weight = ndimage.gaussian_filter(background[small].astype(float), width / step, mode="nearest")
    level = ndimage.gaussian_filter(np.where(background, image, 0.0)[small], width / step, mode="nearest")
    fallback = float(np.median(image[background])) if background.any() else float(np.median(image))
    with np.errstate(invalid="ignore", divide="ignore"):
        coarse = np.where(weight > 1e-3, level / weight, fallback)
    if step == 1:
        return coarse
    return stretch(coarse, np.arange(image.shape[0]) / step, np.arange(image.shape[1]) / step)


def inside_distance(mask: np.ndarray, reach: float) -> np.ndarray:
    """The Euclidean distance of each pixel of ``mask`` to the nearest pixel outside it (0 outside), as
    `scipy.ndimage.distance_transform_edt` gives, computed on bands of rows side by side (`labrig.threads.by_rows`,
    ``reach`` rows of margin). A band's distance is never shorter than the true one, and equal to it where it is
    under ``reach``; where any reaches ``reach``, the whole image is computed at once."""
    margin = math.ceil(reach)
    distance = by_rows(ndimage.distance_transform_edt, mask, margin)
    return distance if distance.max(initial=0.0) < margin else ndimage.distance_transform_edt(mask)


def grow_labels(labels: np.ndarray, grow: float) -> np.ndarray:
    """Each labelled region grown by up to ``grow`` px into the unlabelled pixels, each such pixel taking the label of
    the nearest labelled one (`skimage.segmentation.expand_labels`), on bands of rows side by side
    (`labrig.threads.by_rows`; exact, as a band's distances under its margin are)."""
    from skimage.segmentation import expand_labels

    return by_rows(lambda part: expand_labels(part, distance=grow), labels, math.ceil(grow) + 2)


def typical_radius(distance: np.ndarray) -> float:
    """The radius of a typical object, from the distance transform of the objects' pixels: the median of
    its maxima (over 5 x 5 px) that reach half the 90th percentile of them (text strokes and noise fall
    below), px."""
    peaks = distance[(distance >= 1.0) & (distance == by_rows(lambda part: ndimage.maximum_filter(part, size=5),
                                                               distance, 2))]
    if peaks.size == 0:
        return 0.0
    high = np.percentile(peaks, 90)
    return float(np.median(peaks[peaks >= 0.5 * high]))


def pixel_noise(image: np.ndarray, ignore: np.ndarray) -> float:
    """Standard deviation of the pixel noise of ``image``: the median absolute deviation of its convolution with
    Immerkaer's mask ``[[1, -2, 1], [-2, 4, -2], [1, -2, 1]]`` (the difference of two Laplacians, which white noise
    passes with 6 times its deviation and smooth structure, dots of 5 px included, hardly at all), robust to edges;
    on bands of rows side by side (`labrig.threads.by_rows`: exact).
    (J. Immerkaer, Fast noise variance estimation, Computer Vision and Image Understanding 64, 300-302, 1996.)"""
    mask = np.array([[1.0, -2.0, 1.0], [-2.0, 4.0, -2.0], [1.0, -2.0, 1.0]])
    residual = by_rows(lambda part: ndimage.convolve(part, mask, mode="nearest"), image, 1)[~ignore][::SUBSAMPLE]
    return 1.4826 * float(np.median(np.abs(residual - np.median(residual)))) / 6.0


def signal_to_noise(sums, counts, radius, background, noise: float, mean_noise=0.0) -> np.ndarray:
    """How clearly each dot stands out of the noise: its background less its mean within 0.7 radii, over the
    noise of that mean, ``noise / sqrt(pixels)`` for white noise (a matched filter whose score grows with the dot's
    area; blobs of noise alone score about 1, `MIN_SIGNAL`); or, where it says more, over the deviation of that mean
    that the support shows (``mean_noise``, one value or one per dot, `grain_noise`: a grain correlated over pixels
    averages out more slowly), scaled so that `GRAIN_SIGNAL` of those deviations scores `MIN_SIGNAL`."""
    rho = (np.arange(sums.shape[1]) + 0.5) * BIN
    inner = rho[None, :] < 0.7 * radius[:, None]
    n = (counts * inner).sum(axis=1)
    mean = (sums * inner).sum(axis=1) / np.maximum(n, 1)
    grain = np.asarray(mean_noise, dtype=float) * GRAIN_SIGNAL / MIN_SIGNAL
    return (background - mean) / np.maximum(max(noise, 1e-12) / np.sqrt(np.maximum(n, 1)), grain)


def grain_noise(image: np.ndarray, dots: np.ndarray, radius: float, sizes=(1.0,)) -> np.ndarray:
    """The noise of a dot's mean as the picture's own background shows it, whatever its correlation, for dots of
    ``sizes`` times ``radius`` (the typical radius, px): the robust deviation (1.4826 MAD) of ``image`` averaged by a
    Gaussian of 0.35 of the dot's radius (as a disc of 0.7 radii averages white noise), less its average over
    `GRAIN_BROAD` typical radii (the illumination's slow change; both with the edges mirrored: an edge row repeated
    as far as the broad kernel reaches would be read as grain), over the pixels at least `GRAIN_CLEAR` typical radii
    from every pixel of the ``dots`` (a boolean image). A grain averages out less over a smaller dot: a dot half the
    typical size must stand out of a deviation about twice as large. 0 where under `GRAIN_SHARE` of the picture is
    that clear (a dense film: its gaps hold dots' edges, not the support)."""
    sizes = np.asarray(sizes, dtype=float)
    if not radius > 0:
        return np.zeros(sizes.shape)
    clear = ndimage.distance_transform_edt(~dots) >= GRAIN_CLEAR * radius
    if np.count_nonzero(clear) < max(100, GRAIN_SHARE * clear.size):
        return np.zeros(sizes.shape)
    broad = broad_blur(image, GRAIN_BROAD * radius, mode="reflect")[clear]
    out = np.empty(sizes.shape)
    for k, size in enumerate(sizes.flat):
        values = ndimage.gaussian_filter(image, 0.35 * size * radius, mode="reflect")[clear] - broad
        out.flat[k] = 1.4826 * float(np.median(np.abs(values - np.median(values))))
    return out


def fill_small_holes(mask: np.ndarray, largest: float) -> np.ndarray:
    """``mask`` with its holes of at most ``largest`` pixels filled (bright specks inside a dark dot)."""
    holes, n = ndimage.label(~mask)
    if n == 0:
        return mask
    sizes = np.bincount(holes.ravel(), minlength=n + 1)
    small = sizes <= largest
    small[0] = False
    return mask | small[holes]


def watershed_parts(surface: np.ndarray, markers: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """`skimage.segmentation.watershed` of ``surface`` from ``markers`` within ``mask`` (4-connected), the mask's
    connected pieces flooded in groups side by side in threads (`labrig.threads.run_tasks`; scikit-image floods
    without the GIL): the pieces that begin in each band of `labrig.threads.BAND_ROWS` rows, a group; an image of
    fewer than two bands is flooded whole. A flood never leaves the piece of the mask it starts in, so each piece gets
    the labels one watershed of the whole gives it, but for seeds of one piece at equal heights: scikit-image takes
    those in an order its heap decides, which the other pieces in it sway, so the pixels halfway between two such seeds
    may go to either. The groups do not depend on the number of threads, nor then the labels."""
    from skimage.segmentation import watershed

    if mask.shape[0] < 2 * BAND_ROWS:
        return watershed(surface, markers, mask=mask)
    pieces, n = ndimage.label(mask)
    if n < 2:
        return watershed(surface, markers, mask=mask)
    boxes = label_boxes(pieces, n)  # every label 1 .. n is present
    band = boxes[:, 0] // BAND_ROWS
    last = boxes[:, 1]
    jobs = []
    for b in np.unique(band):
        rows = slice(int(b) * BAND_ROWS, int(last[band == b].max()))
        jobs.append((rows, np.concatenate([[False], band == b])[pieces[rows]]))
    floods = run_tasks([lambda rows=rows, member=member: watershed(surface[rows], np.where(member, markers[rows], 0),
                                                                   mask=member) for rows, member in jobs])
    labels = np.zeros(mask.shape, dtype=floods[0].dtype)
    for (rows, member), flood in zip(jobs, floods):
        labels[rows][member] = flood[member]
    return labels


def split_fused(labels: np.ndarray, distance: np.ndarray, unit_area: float | None = None) -> np.ndarray:
    """Split regions that are two or more fused dots with no neck between them.

    A region whose area exceeds `FUSED_AREA` times the disc of its inscribed radius ``r_m``, and which
    is elongated (`FUSED_ELONGATION`; an irregular single dot is round), holds
    ``k = max(2, round(area / (0.86 pi r_m^2)))`` dots (two discs of radius r whose centres are at least
    r apart, as fused dots are split here), or ``max(2, round(area / unit_area))`` where one dot's area is given;
    its pixels are split among them by k-means (`scipy.cluster.vq.kmeans2`, started from points spread along the
    region's long axis). Returns new labels (1 .. n)."""
    from scipy.cluster.vq import ClusterError, kmeans2

    n = int(labels.max())
    if n == 0:
        return labels
    area = np.bincount(labels.ravel(), minlength=n + 1)[1:]
    inscribed, _ = label_maxima(labels, distance, n)
    ratio = area / np.maximum(math.pi * inscribed**2, 1.0)
    fused = np.flatnonzero(ratio > FUSED_AREA) + 1
    if fused.size == 0:
        return labels
    out = labels.copy()
    following = n + 1
    boxes = label_boxes(labels, n)
    for k in fused:
        box = (slice(boxes[k - 1, 0], boxes[k - 1, 1]), slice(boxes[k - 1, 2], boxes[k - 1, 3]))
        rows, cols = np.nonzero(labels[box] == k)
        points = np.column_stack([rows, cols]).astype(float)
        parts = max(2, round(ratio[k - 1] / 0.86 if unit_area is None else area[k - 1] / unit_area))
        centre = points.mean(axis=0)
        values, vectors = np.linalg.eigh(np.cov((points - centre).T))
        if values[-1] < FUSED_ELONGATION**2 * max(values[0], 1e-12):
            continue  # round: one irregular dot, not fused ones
        along = (points - centre) @ vectors[:, -1]
        starts = centre + np.outer(np.linspace(-0.5, 0.5, parts) * (along.max() - along.min()), vectors[:, -1])
        try:
            _, assigned = kmeans2(points, starts, minit="matrix", iter=20, missing="raise")
        except ClusterError:  # a part came out empty: leave the region whole
            continue
        for part in range(1, parts):
            chosen = assigned == part
            if chosen.any():
                out[box][rows[chosen], cols[chosen]] = following
                following += 1
    return sequential_labels(out)


def sequential_labels(labels: np.ndarray) -> np.ndarray:
    """``labels`` (0 none) renumbered 1 .. m in their order, as `skimage.segmentation.relabel_sequential` does (same
    dtype; ``labels`` itself when they already are)."""
    present = np.bincount(labels.ravel(), minlength=1) > 0
    present[0] = False
    if present[1:].all():
        return labels
    forward = np.zeros(present.size, dtype=labels.dtype)
    forward[present] = np.arange(1, int(present.sum()) + 1)
    return forward[labels]


@jit
def label_boxes(labels, n):
    """Each region 1 .. ``n`` of ``labels``'s bounding box: rows (start, stop) and columns (start, stop) as
    `scipy.ndimage.find_objects` gives them, (n, 4) integers ((0, 0, 0, 0) for a label absent)."""
    h, w = labels.shape
    boxes = np.zeros((n, 4), dtype=np.int64)
    seen = np.zeros(n, dtype=np.bool_)
    for row in range(h):
        for col in range(w):
            k = labels[row, col] - 1
            if k < 0 or k >= n:
                continue
            if not seen[k]:
                seen[k] = True
                boxes[k, 0] = row
                boxes[k, 1] = row + 1
                boxes[k, 2] = col
                boxes[k, 3] = col + 1
            else:
                boxes[k, 1] = row + 1
                boxes[k, 2] = min(boxes[k, 2], col)
                boxes[k, 3] = max(boxes[k, 3], col + 1)
    return boxes


@jit
def label_maxima(labels, values, n):
    """Largest value of each region 1 .. ``n`` of ``labels`` and its flat index (-inf and -1 where empty)."""
    best = np.full(n, -np.inf)
    where = np.full(n, -1, dtype=np.int64)
    flat_labels = labels.ravel()
    flat_values = values.ravel()
    for k in range(flat_labels.size):
        label = flat_labels[k]
        if label > 0 and flat_values[k] > best[label - 1]:
            best[label - 1] = flat_values[k]
            where[label - 1] = k
    return best, where


def disc_maximum(values: np.ndarray, radius: int) -> np.ndarray:
    """The largest of ``values`` within ``radius`` px (a disc, ``dx^2 + dy^2 <= radius^2``) of each pixel, pixels
    past the edge left out: the disc's rows, each a running maximum along x (van Herk's, linear in the pixels), in
    time proportional to ``radius`` times the pixels and memory to the pixels. The same as
    ``scipy.ndimage.maximum_filter`` with that footprint for a radius under the image's shorter side (its
    "reflect" edges then add no value the disc does not hold), whose time grows with the footprint's area and
    memory with its square (a radius of 120 px over 1200 x 1600 px: 116 s and 20 GB). A radius under a quarter of
    `labrig.threads.BAND_ROWS` is computed on bands of rows side by side (`labrig.threads.by_rows`: exact)."""
    if radius < BAND_ROWS // 4:
        return by_rows(lambda part: disc_maximum_whole(part, radius), values, radius)
    return disc_maximum_whole(values, radius)


def disc_maximum_whole(values: np.ndarray, radius: int) -> np.ndarray:
    """`disc_maximum` computed on the whole of ``values`` at once."""
    out = ndimage.maximum_filter1d(values, 2 * radius + 1, axis=1)
    for dy in range(1, min(radius, values.shape[0] - 1) + 1):
        row = ndimage.maximum_filter1d(values, 2 * math.isqrt(radius * radius - dy * dy) + 1, axis=1)
        np.maximum(out[:-dy], row[dy:], out=out[:-dy])
        np.maximum(out[dy:], row[:-dy], out=out[dy:])
    return out


def spaced_maxima(values: np.ndarray, spacing: int, floor: float) -> np.ndarray:
    """Local maxima of ``values`` above ``floor``, at least ``spacing`` px apart: (row, col) of each, highest
    kept first (as `skimage.feature.peak_local_max` with ``min_distance``; a plateau gives one point). A spacing over
    the image's longer side is taken as that side (the footprint is bounded by the image, not by the caller)."""
    spacing = int(min(spacing, max(values.shape)))
    top = (values > floor) & (values == disc_maximum(values, spacing))
    rows, cols = np.nonzero(top)
    if rows.size == 0:
        return np.zeros((0, 2), dtype=np.intp)
    order = np.argsort(-values[rows, cols], kind="stable")
    points = np.column_stack([rows[order], cols[order]])
    first, second = pairs_within(points[:, 1].astype(float), points[:, 0].astype(float), spacing - 1e-9)
    low, high = np.minimum(first, second), np.maximum(first, second)
    keep = np.ones(len(points), dtype=bool)
    for i, j in zip(*(part[np.lexsort((high, low))] for part in (low, high))):  # the higher one (i) first
        if keep[i]:
            keep[j] = False
    return points[keep]


def blob_seeds(image: np.ndarray, mask: np.ndarray, radius: float) -> tuple[np.ndarray, np.ndarray]:
    """One seed per dot of ``image`` (dark dots, unsmoothed), touching ones included: the maxima inside ``mask``, at
    least 0.6 ``radius`` px apart, of its Laplacian of Gaussian at the scale of a disc of radius ``radius`` px
    (``sigma = radius / sqrt 2``, as `skimage.feature.blob_log` finds blobs). Where touching dots leave the
    dot pixels no neck, the distance transform has no maximum per dot; their intensity still has one.
    Returns the seeds' (row, col) and the response (``sigma^2`` times the Laplacian, high at a dark dot's centre)."""
    sigma = max(radius / math.sqrt(2.0), 0.5)
    response = sigma * sigma * ndimage.gaussian_laplace(image, sigma, mode="nearest")
    inside = np.where(mask, response, -np.inf)
    return spaced_maxima(inside, max(2, round(0.6 * radius)), 0.0), response


def region_properties(labels: np.ndarray) -> dict:
    """``label``, ``area``, ``centroid-0`` (row), ``centroid-1`` (column) and ``edge`` (touches the image's
    edge) of regions 1 .. max of ``labels``, by counting (as `skimage.measure.regionprops_table`, faster)."""
    n = int(labels.max())
    sums = label_moments(np.ascontiguousarray(labels, dtype=np.int64), n, 0.0)
    safe = np.maximum(sums[0], 1.0)
    edge = np.zeros(n + 1, dtype=bool)
    edge[np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])] = True
    return {"label": np.arange(1, n + 1), "area": sums[0], "centroid-0": sums[1] / safe, "centroid-1": sums[2] / safe,
            "edge": edge[1:]}


@jit
def label_moments(labels, n, offset):
    """Per region (1 .. n) of ``labels``, rows of: its pixel count and the sums of y, x, y^2, x^2 and xy over its
    pixels (y = row + ``offset``, x = column + ``offset``, px), pixel after pixel in row-major order."""
    sums = np.zeros((6, n))
    h, w = labels.shape
    for row in range(h):
        y = row + offset
        for col in range(w):
            k = labels[row, col] - 1
            if k < 0:
                continue
            x = col + offset
            sums[0, k] += 1.0
            sums[1, k] += y
            sums[2, k] += x
            sums[3, k] += y * y
            sums[4, k] += x * x
            sums[5, k] += y * x
    return sums

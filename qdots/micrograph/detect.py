"""Finding every dot of a micrograph, touching ones included: centres and diameters to a fraction of a pixel.

Five stages, each a maintained library's tool except the profile fit:

1. **Segment.** The image is scaled to [0, 1] by its 0.5 and 99.5 percentiles, smoothed (Gaussian,
   1 px), and split by Otsu's threshold (scikit-image). The illumination is then flattened: the
   background level is estimated away from the dots (at half resolution) by a normalised Gaussian
   convolution four typical radii wide, the image divided by it and thresholded again. Dark or light
   dots: given, or the phase whose objects away from the edge are the larger round ones.
2. **Split touching dots.** The distance transform of the dot pixels (scipy.ndimage), smoothed by
   1 px, has one maximum per dot; its maxima at least 0.6 typical radii apart (`spaced_maxima`) seed
   a watershed of the negative distance (scikit-image), which cuts each aggregate at its necks. A
   region that is clearly two or more fused dots with no neck (large and elongated) is split by
   k-means (`split_fused`). Objects whose inscribed radius is under a third of the typical one
   (text, scale-bar strokes, debris) are not dots.
3. **Centre.** The centroid of each dot's watershed region; for a dot cut by the image edge, the
   point of its region farthest from the visible rim, which stays the disc's centre when part of
   the disc is outside the image.
4. **Diameter from the radial profile.** A threshold puts the edge of a projected sphere (whose
   contrast falls as ``sqrt(1 - rho^2/r^2)``) well inside the true edge (13 % of the diameter at
   half contrast). Instead each dot's azimuthally averaged profile, over its region grown by 0.6
   radii into the background (`skimage.segmentation.expand_labels`), is fitted by
   ``B - C f_p(rho / r)`` blurred by a 2-D Gaussian of width ``s``, with ``f_p(u) = (1 - u^2)^p``
   (``p = 0``: a flat disc; ``p = 1/2``: a projected sphere), ``B`` the local background and ``C``,
   ``r`` per dot (`fit_profiles`: a compiled search over r, refined by a parabola). The blur ``s``
   is chosen once per image by the least residual over up to `SHAPE_SAMPLE` whole dots, the shape
   ``p`` from the curvature of the dots' centres (`central_curvature`), or given.
5. **Noise.** A dot must stand out of the noise (`signal_to_noise`), and an image's dots must have a
   median contrast of several pixel-noise deviations (`MIN_CONTRAST`): noise alone finds no dots.

Coordinates are image pixels: ``x`` the column, ``y`` the row, pixel ``(row, col)`` covering
``[col, col + 1) x [row, row + 1)``, so the image spans ``[0, W] x [0, H]``.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace

import numpy as np
from scipy import ndimage

from labrig.compiled import jit
from labrig.validate import InputError, choice

#: Polarity choices: dots darker than the background (bright-field TEM), lighter, or decided from the image.
POLARITIES = ("auto", "dark", "light")
#: ``polarity="auto"`` takes the dots to be light only when the light phase's round objects are this many
#: times larger than the dark phase's (a dense dark film's vacancies make light objects too).
LIGHT_EVIDENCE = 2.0
#: Dot profiles by name (the exponent p), the shapes tried by ``profile="auto"``, and blur widths s (px).
PROFILES = {"auto": None, "sphere": 0.5, "disc": 0.0}
SHAPES = (0.0, 0.25, 0.5)
#: ``profile="auto"`` measures the shape on at least this many whole dots (else assumes a sphere).
MIN_SHAPE_DOTS = 10
#: ``profile="auto"`` keeps the sphere unless another shape's curvature matches by this much more (`central_curvature`).
CURVATURE_MARGIN = 0.05
BLURS = (0.0, 0.5, 1.0, 1.25, 1.5, 1.75, 2.0, 2.5, 3.0, 4.0)
#: A dot must stand this clearly out of the noise (`signal_to_noise`), and the dots of an image must have a
#: median contrast of at least `MIN_CONTRAST` times the pixel noise (`pixel_noise`; noise alone gives 1.7-2.2,
#: synthetic films at noise 0.3 of the background 2.8-3.4).
MIN_SIGNAL, MIN_CONTRAST = 8.0, 2.5
#: Radius search of the profile fit, in units of the segmented radius, and its step.
FIT_LOW, FIT_HIGH, FIT_STEP = 0.6, 1.5, 0.0025
#: The radius search first tries every COARSE-th step.
COARSE = 6
#: Radial bin width of the profiles, px.
BIN = 0.5
#: The centre of a dot, where its curvature is measured (`central_curvature`), in radii.
CENTRE = 0.5
#: Most dots the shape and blur are chosen from.
SHAPE_SAMPLE = 250
#: Image-wide statistics (percentiles, noise) use every SUBSAMPLE-th pixel.
SUBSAMPLE = 3
#: An object is a dot when its inscribed radius is at least this share of the typical radius.
MIN_INSCRIBED = 1.0 / 3.0
#: A region whose area is more than this many times the disc of its inscribed radius, and whose long axis is
#: this many times its short one (square root of the ratio of its second moments), is fused dots (`split_fused`).
#: Two discs of radius r with centres r apart: area 1.61 pi r^2, elongation 1.41 (1.2 r: 1.72 and 1.56).
FUSED_AREA, FUSED_ELONGATION = 1.6, 1.4
#: Smallest typical dot diameter, px, that can be measured.
MIN_DIAMETER = 4.0


@dataclass(frozen=True)
class Detection:
    """The dots found in one image.

    Attributes
    ----------
    centres : ndarray, shape (N, 2)
        ``(x, y)`` = (column, row) of each centre, image px (see the module docstring).
    diameters : ndarray, shape (N,)
        Fitted diameter of each dot, px.
    cut : ndarray of bool, shape (N,)
        Dots whose disc crosses the edge of the picture (`window`), measured on their visible part.
    contrast : ndarray, shape (N,)
        Fitted contrast ``C`` of each dot, in units of the background level.
    dark : bool
        Whether the dots are darker than the background.
    polarity : str
        How the polarity was decided, in words.
    shape : float
        The profile shape ``p`` chosen (0 flat disc, 0.5 projected sphere).
    profile : str
        How it was chosen, in words.
    blur : float
        The blur width ``s`` chosen, px.
    rejected : int
        Objects of the image that are not dots (text, scale-bar strokes, debris) or that the fit refused.
    image_shape : (int, int)
        ``(H, W)`` of the image, px.
    window : (int, int, int, int)
        ``(x0, y0, x1, y1)``: the part of the image that is picture, px (a constant frame that some
        programs draw around an image is left out, `frame_width`).
    """

    centres: np.ndarray
    diameters: np.ndarray
    cut: np.ndarray
    contrast: np.ndarray
    dark: bool
    polarity: str
    shape: float
    profile: str
    blur: float
    rejected: int
    image_shape: tuple[int, int]
    window: tuple[int, int, int, int]

    @property
    def n_dots(self) -> int:
        return len(self.diameters)

    def coverage(self) -> float:
        """Fraction of the image inside the fitted discs (their union, on the pixel grid)."""
        covered = np.zeros(self.image_shape, dtype=np.bool_)
        paint_discs(covered, np.ascontiguousarray(self.centres, dtype=float), 0.5 * np.asarray(self.diameters, float))
        return float(covered.mean())


@jit
def paint_discs(covered, centres, radii):
    """Set the pixels of ``covered`` whose centres lie inside any disc (``centres`` (x, y), ``radii``, px)."""
    h, w = covered.shape
    for k in range(len(radii)):
        x, y, r = centres[k, 0], centres[k, 1], radii[k]
        for row in range(max(0, int(y - r)), min(h, int(y + r) + 2)):
            for col in range(max(0, int(x - r)), min(w, int(x + r) + 2)):
                if (col + 0.5 - x) ** 2 + (row + 0.5 - y) ** 2 <= r * r:
                    covered[row, col] = True


def scaled(image: np.ndarray, ignore: np.ndarray | None = None) -> np.ndarray:
    """``image`` mapped to [0, 1] by its 0.5 and 99.5 percentiles (outside ``ignore``), clipped."""
    values = image[~ignore] if ignore is not None else image.ravel()
    low, high = np.percentile(values[::SUBSAMPLE], [0.5, 99.5])
    if high <= low:
        low, high = float(values.min()), float(values.max())
    return np.clip((image - low) / (high - low), 0.0, 1.0)


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
    rows = np.minimum(np.arange(image.shape[0]) / step, coarse.shape[0] - 1)
    cols = np.minimum(np.arange(image.shape[1]) / step, coarse.shape[1] - 1)
    return ndimage.map_coordinates(coarse, np.meshgrid(rows, cols, indexing="ij"), order=1, mode="nearest")


def typical_radius(distance: np.ndarray) -> float:
    """The radius of a typical object, from the distance transform of the objects' pixels: the median of
    its maxima (over 5 x 5 px) that reach half the 90th percentile of them (text strokes and noise fall
    below), px."""
    peaks = distance[(distance >= 1.0) & (distance == ndimage.maximum_filter(distance, size=5))]
    if peaks.size == 0:
        return 0.0
    high = np.percentile(peaks, 90)
    return float(np.median(peaks[peaks >= 0.5 * high]))


def inner_components(mask: np.ndarray) -> np.ndarray:
    """Inscribed radius of each connected component of ``mask`` that does not touch the image edge, px."""
    labels, n = ndimage.label(mask)
    if n == 0:
        return np.zeros(0)
    edge = np.unique(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]))
    inscribed, _ = label_maxima(labels, ndimage.distance_transform_edt(mask), n)
    keep = ~np.isin(np.arange(1, n + 1), edge)
    return np.asarray(inscribed)[keep]


def pixel_noise(image: np.ndarray, ignore: np.ndarray) -> float:
    """Standard deviation of the pixel noise of ``image``: the median absolute deviation of
    ``image - gaussian(image, 1 px)`` (where white noise keeps 0.872 of its deviation), robust to edges."""
    residual = (image - ndimage.gaussian_filter(image, 1.0))[~ignore][::SUBSAMPLE]
    return 1.4826 * float(np.median(np.abs(residual - np.median(residual)))) / 0.872


def signal_to_noise(sums, counts, radius, background, noise: float) -> np.ndarray:
    """How clearly each dot stands out of the noise: its background less its mean within 0.7 radii, over the
    noise of that mean (``noise / sqrt(pixels)``). Blobs of noise alone score about 2."""
    rho = (np.arange(sums.shape[1]) + 0.5) * BIN
    inner = rho[None, :] < 0.7 * radius[:, None]
    n = (counts * inner).sum(axis=1)
    mean = (sums * inner).sum(axis=1) / np.maximum(n, 1)
    return (background - mean) * np.sqrt(n) / max(noise, 1e-12)


def fill_small_holes(mask: np.ndarray, largest: float) -> np.ndarray:
    """``mask`` with its holes of at most ``largest`` pixels filled (bright specks inside a dark dot)."""
    holes, n = ndimage.label(~mask)
    if n == 0:
        return mask
    sizes = np.bincount(holes.ravel(), minlength=n + 1)
    small = sizes <= largest
    small[0] = False
    return mask | small[holes]


def split_fused(labels: np.ndarray, distance: np.ndarray) -> np.ndarray:
    """Split regions that are two or more fused dots with no neck between them.

    A region whose area exceeds `FUSED_AREA` times the disc of its inscribed radius ``r_m``, and which
    is elongated (`FUSED_ELONGATION`; an irregular single dot is round), holds
    ``k = max(2, round(area / (0.86 pi r_m^2)))`` dots (two discs of radius r whose centres are at least
    r apart, as fused dots are split here); its pixels are split among them by k-means (`scipy.cluster.vq.kmeans2`,
    started from points spread along the region's long axis). Returns new labels (1 .. n)."""
    from scipy.cluster.vq import ClusterError, kmeans2
    from skimage.segmentation import relabel_sequential

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
    boxes = ndimage.find_objects(labels)
    for k in fused:
        box = boxes[k - 1]
        rows, cols = np.nonzero(labels[box] == k)
        points = np.column_stack([rows, cols]).astype(float)
        parts = max(2, round(ratio[k - 1] / 0.86))
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
    relabelled, _, _ = relabel_sequential(out)
    return relabelled


def frame_width(image: np.ndarray) -> tuple[int, int, int, int]:
    """Rows and columns of a constant frame around ``image`` (a border some programs draw): the number of
    top, bottom, left and right lines, each of one value equal to the corner's, that are not picture."""
    corner = image[0, 0]
    h, w = image.shape

    def run(lines) -> int:
        k = 0
        for line in lines:
            if not np.all(line == corner):
                break
            k += 1
        return k

    top = run(image[i] for i in range(h // 4))
    bottom = run(image[h - 1 - i] for i in range(h // 4))
    left = run(image[:, j] for j in range(w // 4))
    right = run(image[:, w - 1 - j] for j in range(w // 4))
    return top, bottom, left, right


def decide_polarity(smooth: np.ndarray, threshold: float, polarity: str, scale: float = 1.0) -> tuple[bool, str]:
    """Whether the dots are the dark phase, and why: given, or (``"auto"``) dark, as bright-field micrographs
    show them, unless the light phase's components away from the image edge are clearly the larger round
    objects (median inscribed radius over components of >= 2 px, `LIGHT_EVIDENCE` times the dark phase's).
    ``scale``: image px per px of ``smooth`` (2 for a half-resolution image)."""
    if polarity != "auto":
        return polarity == "dark", f"{polarity} dots (given)"
    scores = []
    for dark in (True, False):
        radii = scale * inner_components(smooth < threshold if dark else smooth >= threshold)
        radii = radii[radii >= 2.0]
        scores.append(float(np.median(radii)) if radii.size >= 3 else 0.0)
    dark_score, light_score = scores
    if light_score > LIGHT_EVIDENCE * dark_score:
        return False, (f"light dots (automatic: objects of inscribed radius {light_score:.1f} px away from the edge, "
                       f"against {dark_score:.1f} px in the dark phase)")
    return True, (f"dark dots (automatic: objects of inscribed radius {dark_score:.1f} px away from the edge, "
                  f"against {light_score:.1f} px in the light phase; dark unless the light phase's are "
                  f"{LIGHT_EVIDENCE:g} times larger, as bright field shows dots)")


@functools.cache
def profile_table(shape: float) -> np.ndarray:
    """Tabulated blurred profile ``F[i, j]`` of ``f_p(u) = (1 - u^2)^p`` (radius 1) at ``u = j / 200`` in [0, 2],
    blurred by a 2-D Gaussian of width ``s = i / 100`` in [0, 0.6] radii.

    The Gaussian is separable, so on the line ``y = 0`` the blurred profile is
    ``F(u) = sum_x G(u - x) h(x)`` with ``h(x) = sum_y f(x, y) G(y)``: two matrix products on a grid of
    step 1/200 radius.
    """
    step = 1.0 / 200.0
    grid = np.arange(-520, 521) * step  # x and y in [-2.6, 2.6]
    rho2 = grid[:, None] ** 2 + grid[None, :] ** 2
    f = np.where(rho2 < 1.0, np.maximum(1.0 - rho2, 0.0) ** shape if shape > 0 else 1.0, 0.0)
    u = np.arange(401) * step
    table = np.empty((61, u.size))
    table[0] = np.where(u < 1.0, np.maximum(1.0 - u**2, 0.0) ** shape if shape > 0 else 1.0, 0.0)
    widths = np.arange(1, 61) / 100.0
    g = np.exp(-0.5 * (grid[:, None] / widths[None, :]) ** 2)
    g /= g.sum(axis=0)
    h = f @ g  # h(x) of every width, weighted over y
    for i in range(1, 61):
        table[i] = np.convolve(h[:, i - 1], g[:, i - 1], mode="same")[520:921]  # then blurred along x
    return table


@jit
def _table_value(table, s, u):
    """Bilinear value of `profile_table` at relative blur ``s`` and radius ``u``."""
    si = min(s * 100.0, 59.999)
    ui = u * 200.0
    if ui >= 399.999:
        return 0.0
    i = int(si)
    j = int(ui)
    a = si - i
    b = ui - j
    return ((1 - a) * ((1 - b) * table[i, j] + b * table[i, j + 1])
            + a * ((1 - b) * table[i + 1, j] + b * table[i + 1, j + 1]))


@jit
def _fit_one(sums, counts, i, level, free, table, s, r, bin_width):
    """Least squares of dot ``i``'s profile against ``B - C F(rho / r)`` at relative blur ``s``: (B, C, residual),
    ``B`` fitted when ``free``, else ``level``."""
    sw = 0.0
    sf = 0.0
    sff = 0.0
    sv = 0.0
    sfv = 0.0
    svv = 0.0
    for b in range(sums.shape[1]):
        w = counts[i, b]
        if w == 0:
            continue
        v = sums[i, b] / w
        f = _table_value(table, s, (b + 0.5) * bin_width / r)
        sw += w
        sf += w * f
        sff += w * f * f
        sv += w * v
        sfv += w * f * v
        svv += w * v * v
    if free:
        det = sw * sff - sf * sf
        if det <= 1e-12 * sw * sff or sw == 0.0:
            return np.nan, np.nan, np.inf
        big = (sff * sv - sf * sfv) / det
        c = (sf * sv - sw * sfv) / det
    else:
        big = level
        if sff <= 0.0:
            return np.nan, np.nan, np.inf
        c = (big * sf - sfv) / sff
    if not c > 0.0:
        return big, c, np.inf
    # sum w (v - B + C f)^2
    error = svv + big * big * sw + c * c * sff - 2.0 * big * sv + 2.0 * c * sfv - 2.0 * big * c * sf
    return big, c, max(error, 0.0)


@jit
def fit_profiles(sums, counts, level, free, start, table, blur, low, high, step, bin_width):
    """Fit ``B - C F(rho / r)`` to each dot's radial profile; returns (r, B, C, residual) arrays.

    ``sums[i, b]`` and ``counts[i, b]`` are the summed values and pixel counts of dot ``i``'s bin ``b``
    (radius ``(b + 1/2) bin_width``); ``start[i]`` is its segmented radius; ``level[i]`` its background
    (``B``, unless ``free``: then fitted). r runs over ``start * [low, high]`` in steps of ``COARSE * step``,
    then in steps of ``step`` around the best of those, and is refined by a parabola through the best three.
    """
    n = sums.shape[0]
    k_max = int((high - low) / step) + 1
    radius = np.full(n, np.nan)
    background = np.full(n, np.nan)
    contrast = np.full(n, np.nan)
    residual = np.full(n, np.inf)
    errors = np.empty(k_max)
    for i in range(n):
        errors[:] = np.inf
        coarse = -1
        for k in range(0, k_max, COARSE):  # every COARSE-th radius, then every one around the best of them
            r = start[i] * (low + k * step)
            errors[k] = _fit_one(sums, counts, i, level[i], free, table, blur / r, r, bin_width)[2]
            if errors[k] < np.inf and (coarse < 0 or errors[k] < errors[coarse]):
                coarse = k
        if coarse < 0:
            continue
        best = coarse
        for k in range(max(0, coarse - COARSE), min(k_max, coarse + COARSE + 1)):
            if k % COARSE != 0:
                r = start[i] * (low + k * step)
                errors[k] = _fit_one(sums, counts, i, level[i], free, table, blur / r, r, bin_width)[2]
            if errors[k] < errors[best]:
                best = k
        shift = 0.0
        if 0 < best < k_max - 1 and errors[best - 1] < np.inf and errors[best + 1] < np.inf:
            curve = errors[best - 1] - 2.0 * errors[best] + errors[best + 1]
            if curve > 0:
                shift = 0.5 * (errors[best - 1] - errors[best + 1]) / curve
        r = start[i] * (low + (best + shift) * step)
        big, c, error = _fit_one(sums, counts, i, level[i], free, table, blur / r, r, bin_width)
        radius[i] = r
        background[i] = big
        contrast[i] = c
        residual[i] = error
    return radius, background, contrast, residual


def central_curvature(sums: np.ndarray, counts: np.ndarray, radius: np.ndarray) -> float:
    """Median relative curvature of the dots' centres, ``kappa r^2``: each profile within half its ``radius``
    fitted by ``a + b rho^2`` (least squares, pixels weighted alike; a dark dot brightens away from its
    centre), ``kappa = b / (1 - a)`` with the background at 1. Compare with `predicted_curvature`."""
    rho = (np.arange(sums.shape[1]) + 0.5) * BIN
    inner = (rho[None, :] <= CENTRE * radius[:, None]) & (counts > 0)
    w = np.where(inner, counts, 0.0)
    v = np.divide(sums, counts, out=np.zeros_like(sums), where=counts > 0)
    x = np.broadcast_to(rho**2, v.shape)
    sw, sx, sxx = w.sum(1), (w * x).sum(1), (w * x * x).sum(1)
    sv, sxv = (w * v).sum(1), (w * x * v).sum(1)
    det = sw * sxx - sx * sx
    ok = (det > 0) & (inner.sum(1) >= 3) & np.isfinite(radius)
    if not ok.any():
        return math.nan
    a = (sxx[ok] * sv[ok] - sx[ok] * sxv[ok]) / det[ok]
    b = (sw[ok] * sxv[ok] - sx[ok] * sv[ok]) / det[ok]
    contrast = 1.0 - a
    good = contrast > 0.02
    return float(np.median(b[good] / contrast[good] * radius[ok][good] ** 2)) if good.any() else math.nan


def predicted_curvature(shape: float, relative_blur: float) -> float:
    """``kappa r^2`` (`central_curvature`) of a dot of profile ``shape`` blurred by ``relative_blur`` radii: its
    tabulated profile (`profile_table`) fitted by ``alpha - beta u^2`` within half its radius, weighted by
    the radius as pixels are. About 0 for a flat disc, 0.56 for a projected sphere."""
    table = profile_table(shape)
    row = table[min(round(relative_blur * 100), table.shape[0] - 1)]
    u = np.arange(row.size) / 200.0
    inner = u <= CENTRE
    beta, alpha = np.polyfit(u[inner] ** 2, row[inner], 1, w=np.sqrt(u[inner] + 1e-3))
    return float(-beta / alpha)


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


def spaced_maxima(values: np.ndarray, spacing: int, floor: float) -> np.ndarray:
    """Local maxima of ``values`` above ``floor``, at least ``spacing`` px apart: (row, col) of each, highest
    kept first (as `skimage.feature.peak_local_max` with ``min_distance``; a plateau gives one point)."""
    from scipy.spatial import cKDTree

    y, x = np.ogrid[-spacing:spacing + 1, -spacing:spacing + 1]
    top = (values > floor) & (values == ndimage.maximum_filter(values, footprint=x * x + y * y <= spacing * spacing))
    rows, cols = np.nonzero(top)
    if rows.size == 0:
        return np.zeros((0, 2), dtype=np.intp)
    order = np.argsort(-values[rows, cols], kind="stable")
    points = np.column_stack([rows[order], cols[order]])
    keep = np.ones(len(points), dtype=bool)
    for i, j in sorted(cKDTree(points).query_pairs(spacing - 1e-9)):  # i < j: j is the lower one
        if keep[i]:
            keep[j] = False
    return points[keep]


def region_properties(labels: np.ndarray) -> dict:
    """``label``, ``area``, ``centroid-0`` (row), ``centroid-1`` (column) and ``edge`` (touches the image's
    edge) of regions 1 .. max of ``labels``, by counting (as `skimage.measure.regionprops_table`, faster)."""
    n = int(labels.max())
    flat = labels.ravel()
    rows, cols = np.divmod(np.arange(flat.size), labels.shape[1])
    area = np.bincount(flat, minlength=n + 1)[1:].astype(float)
    safe = np.maximum(area, 1.0)
    edge = np.zeros(n + 1, dtype=bool)
    edge[np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])] = True
    return {"label": np.arange(1, n + 1), "area": area,
            "centroid-0": np.bincount(flat, rows, n + 1)[1:] / safe,
            "centroid-1": np.bincount(flat, cols, n + 1)[1:] / safe, "edge": edge[1:]}


def radial_profiles(image, regions, centres, n_bins: int):
    """Summed values and pixel counts of each region's pixels in radial bins of `BIN` px around its centre."""
    rows, cols = np.nonzero(regions)
    label = regions[rows, cols] - 1
    rho = np.hypot(cols + 0.5 - centres[label, 0], rows + 0.5 - centres[label, 1])
    b = (rho / BIN).astype(np.intp)
    keep = b < n_bins
    index = label[keep] * n_bins + b[keep]
    n = len(centres)
    sums = np.bincount(index, image[rows[keep], cols[keep]], n * n_bins).reshape(n, n_bins)
    counts = np.bincount(index, None, n * n_bins).reshape(n, n_bins)
    return sums, counts


def detect_dots(image, polarity: str = "auto", profile: str = "auto", ignore: np.ndarray | None = None
                ) -> Detection:
    """Every dot of a grey image, with sub-pixel centres and fitted diameters (see the module docstring).

    Parameters
    ----------
    image : ndarray, shape (H, W)
        Grey values (any scale).
    polarity : {"auto", "dark", "light"}
        Whether the dots are darker or lighter than the background; ``"auto"`` decides from the
        image and says how (`Detection.polarity`).
    profile : {"auto", "sphere", "disc"}
        The dots' contrast profile: a projected sphere (``p = 1/2``), a flat disc (``p = 0``), or
        (``"auto"``) the shape of `SHAPES` whose central curvature matches the dots' (`central_curvature`,
        `predicted_curvature`), the sphere unless another matches clearly better (`CURVATURE_MARGIN`);
        `Detection.profile` says which and why.
    ignore : ndarray of bool, shape (H, W), optional
        Pixels to leave out (a scale bar and its label).

    Returns
    -------
    Detection
        With no dots when none is found (``n_dots == 0``).
    """
    polarity = choice("polarity", polarity, POLARITIES)
    profile = choice("profile", profile, tuple(PROFILES))
    image = np.asarray(image, dtype=float)
    if image.ndim != 2 or min(image.shape) < 2:
        raise InputError(f"image must be a 2-D array of at least 2 x 2 px, got shape {image.shape}")
    if not np.all(np.isfinite(image)):
        raise InputError("image has NaN or infinite pixels")
    ignore = np.zeros(image.shape, dtype=bool) if ignore is None else np.asarray(ignore, dtype=bool)
    if ignore.shape != image.shape:
        raise InputError(f"ignore must have the image's shape {image.shape}, got {ignore.shape}")
    h, w = image.shape
    top, bottom, left, right = frame_width(image)
    if h - top - bottom < 2 or w - left - right < 2:
        return _empty((h, w), "constant image", 0)
    inner = (slice(top, h - bottom), slice(left, w - right))
    found = _detect(image[inner], polarity, profile, ignore[inner])
    centres = found.centres + [left, top]
    x0, y0, x1, y1 = left, top, w - right, h - bottom
    r = 0.5 * found.diameters
    cut = found.cut | (centres[:, 0] - r < x0) | (centres[:, 1] - r < y0) | (centres[:, 0] + r > x1) | (
        centres[:, 1] + r > y1)
    return replace(found, centres=centres, cut=cut, image_shape=(h, w), window=(x0, y0, x1, y1))


def _detect(image: np.ndarray, polarity: str, profile: str, ignore: np.ndarray) -> Detection:
    """`detect_dots` on an image without a frame; ``cut`` marks the dots whose watershed region touches its edge."""
    from skimage.filters import threshold_otsu
    from skimage.segmentation import expand_labels, watershed

    unit = scaled(image, ignore)
    smooth = ndimage.gaussian_filter(unit, 1.0)
    if float(smooth[~ignore].max() - smooth[~ignore].min()) < 1e-6:
        return _empty(image.shape, polarity, 0)
    # a first look at half resolution, the broad fall of the light (over a sixth of the image) taken out
    half = (slice(None, None, 2), slice(None, None, 2))
    first = smooth[half] - ndimage.gaussian_filter(smooth[half], max(image.shape) / 12.0, mode="nearest")
    first += float(np.mean(smooth[half]))
    threshold = threshold_otsu(first[~ignore[half]])
    dark, how = decide_polarity(first, threshold, polarity, scale=2.0)
    if not dark:
        smooth, first, threshold = 1.0 - smooth, 1.0 - first, 1.0 - threshold
    # flatten the illumination (its level away from the dots, found at half resolution), then threshold again
    mask = (first < threshold) & ~ignore[half]
    radius = 2.0 * typical_radius(ndimage.distance_transform_edt(mask))
    if radius < 0.5 * MIN_DIAMETER:
        return _empty(image.shape, how, 0)
    away = ~ndimage.binary_dilation(mask, iterations=max(1, int(0.15 * radius))) & ~ignore[half]
    if away.any():
        coarse = background_level(smooth[half], away, 4.0 * radius)
        rows = np.minimum(np.arange(image.shape[0]) / 2.0, coarse.shape[0] - 1)
        cols = np.minimum(np.arange(image.shape[1]) / 2.0, coarse.shape[1] - 1)
        level = ndimage.map_coordinates(coarse, np.meshgrid(rows, cols, indexing="ij"), order=1, mode="nearest")
    else:
        level = np.full(image.shape, float(np.median(smooth)))
    flat = smooth / np.maximum(level, 1e-6)
    threshold = threshold_otsu(flat[~ignore])
    mask = fill_small_holes((flat < threshold) & ~ignore, 0.03 * math.pi * radius**2)
    distance = ndimage.distance_transform_edt(mask)
    radius = typical_radius(distance)
    if radius < 0.5 * MIN_DIAMETER:
        return _empty(image.shape, how, 0)
    # split touching dots: a watershed of the distance transform from its maxima at least 0.6 radii apart
    peaks = spaced_maxima(ndimage.gaussian_filter(distance, 1.0), max(2, round(0.6 * radius)), 0.5)
    deep = distance[tuple(peaks.T)] >= MIN_INSCRIBED * radius
    rejected = int(np.count_nonzero(~deep))
    peaks = peaks[deep]
    n = len(peaks)
    if n == 0:
        return _empty(image.shape, how, rejected)
    markers = np.zeros(image.shape, dtype=np.int32)
    markers[tuple(peaks.T)] = np.arange(1, n + 1)
    labels = watershed(-distance, markers, mask=mask)
    labels = split_fused(labels, distance)
    props = region_properties(labels)
    h, w = image.shape
    centres = np.column_stack([props["centroid-1"] + 0.5, props["centroid-0"] + 0.5])
    deepest, where = label_maxima(labels, distance, len(props["label"]))
    peak = np.column_stack(np.divmod(where, labels.shape[1])).astype(float)
    peak = peak[:, ::-1] + 0.5
    touches = props["edge"]
    centres[touches] = peak[touches]
    start = np.sqrt(props["area"] / math.pi)
    start[touches] = deepest[touches] + 0.5
    # fit each dot's radial profile
    grow = max(2, math.ceil(0.6 * radius))
    regions = expand_labels(labels, distance=grow)
    n_bins = math.ceil(FIT_HIGH * 1.2 * start.max() / BIN) + 1
    sums, counts = radial_profiles(flat, regions, centres, n_bins)
    base = np.ones(len(start))  # flat is the image in units of its background level
    # the blur of each shape from the fit of whole dots; the shape from the curvature of the dots' centres
    whole = np.flatnonzero(~touches)
    sample = whole[np.linspace(0, len(whole) - 1, min(SHAPE_SAMPLE, len(whole))).astype(int)] if len(whole) else whole
    shapes = SHAPES if profile == "auto" else (PROFILES[profile],)
    blurs, radii = {}, {}
    for shape in shapes:
        table = profile_table(shape)
        totals, fits = [], []
        for blur in BLURS:
            fit = fit_profiles(sums[sample], counts[sample], base[sample], True, start[sample], table, blur,
                               FIT_LOW, FIT_HIGH, FIT_STEP, BIN)
            err = fit[3]
            totals.append(float(np.sum(err[np.isfinite(err)])) if np.isfinite(err).any() else math.inf)
            fits.append(fit[0])
        k = int(np.argmin(totals))
        blurs[shape], radii[shape] = BLURS[k], fits[k]
    fitted = min(int(np.isfinite(radii[p]).sum()) for p in shapes)
    if profile == "auto" and fitted < MIN_SHAPE_DOTS:
        shape, how_shape = PROFILES["sphere"], (f"sphere (assumed: {fitted} whole dots, fewer than the "
                                                f"{MIN_SHAPE_DOTS} the shape is measured on)")
    elif profile == "auto":
        measured = {p: central_curvature(sums[sample], counts[sample], radii[p]) for p in shapes}
        predicted = {p: predicted_curvature(p, blurs[p] / float(np.nanmedian(radii[p]))) for p in shapes}
        miss = {p: abs(measured[p] - predicted[p]) if math.isfinite(measured[p]) else math.inf for p in shapes}
        shape = min(shapes, key=miss.get)
        if miss[0.5] - miss[shape] < CURVATURE_MARGIN:
            shape = 0.5
        how_shape = (f"p = {shape:g} from the curvature of {len(sample)} dots' centres ({measured[shape]:.3f} r^2 "
                     f"measured, {predicted[shape]:.3f} for p = {shape:g}; a sphere would give {predicted[0.5]:.3f} "
                     f"against {measured[0.5]:.3f} measured, a flat disc {predicted[0.0]:.3f} against "
                     f"{measured[0.0]:.3f})")
    else:
        shape, how_shape = shapes[0], f"{profile} (given)"
    best = (0.0, shape, blurs[shape])
    _, shape, blur = best
    fitted, background, contrast, _ = fit_profiles(sums, counts, base, True, start, profile_table(shape), blur,
                                                   FIT_LOW, FIT_HIGH, FIT_STEP, BIN)
    noise = pixel_noise(unit, ignore)
    good = np.isfinite(fitted) & (contrast > 0)
    good[good] = signal_to_noise(sums[good], counts[good], fitted[good], background[good], noise) >= MIN_SIGNAL
    if not good.any() or float(np.median(contrast[good])) < MIN_CONTRAST * noise:
        typical = float(np.median(contrast[good])) / noise if good.any() else 0.0
        return _empty(image.shape, f"{how}; what looks like dots has a contrast of {typical:.1f} times the pixel "
                                   f"noise, less than the {MIN_CONTRAST:g} real dots have: noise alone", len(start))
    rejected += int(np.count_nonzero(~good))
    centres, fitted, contrast, touches = centres[good], fitted[good], contrast[good], touches[good]
    return Detection(centres, 2.0 * fitted, touches, contrast, dark, how, float(shape), how_shape, float(blur), rejected,
                     (h, w), (0, 0, w, h))


def _empty(shape, how: str, rejected: int) -> Detection:
    return Detection(np.zeros((0, 2)), np.zeros(0), np.zeros(0, dtype=bool), np.zeros(0), "light" not in how, how,
                     math.nan, "", math.nan, rejected, tuple(shape), (0, 0, shape[1], shape[0]))

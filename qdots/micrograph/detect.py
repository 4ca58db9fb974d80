"""Finding every dot of a micrograph, touching ones included: centres and diameters to a fraction of a pixel.

Five stages, each a maintained library's tool except the profile fits:

1. **Segment.** The image is scaled to [0, 1] by its 0.5 and 99.5 percentiles, smoothed (Gaussian,
   1 px), and split by Otsu's threshold (scikit-image). The illumination is then flattened: the
   background level is estimated away from the dots (at half resolution) by a normalised Gaussian
   convolution four typical radii wide, the image divided by it and thresholded again. Dark or light
   dots: given, or the way the image's strongest edges bend (`edge_curvature`): around the dots, in dense films
   around the vacancies and gaps too, whose edges are the dots' arcs.
2. **Split touching dots.** One seed per dot starts a watershed that cuts each aggregate between its dots. Dots
   of a typical inscribed radius of `BLOB_RADIUS` px or more are seeded at the maxima of the distance transform of
   the dot pixels (scipy.ndimage), smoothed by 1 px, at least 0.6 typical radii apart (`spaced_maxima`), and the
   watershed is of the negative distance (scikit-image), cut at the aggregates' necks. Smaller dots, whose necks
   the blur fills, are seeded at the maxima of their Laplacian of Gaussian at their scale (`blob_seeds`), and the
   watershed is of its negative. A region that is clearly two or more fused dots with no neck (large and
   elongated) is split by k-means (`split_fused`). Objects whose inscribed radius is under a third of the typical one
   (text, scale-bar strokes, debris) are not dots.
3. **Centre.** The centroid of each dot's watershed region (then refined with the fit, stage 4); for
   a dot cut by the image edge, the point of its region farthest from the visible rim, which stays the
   disc's centre when part of the disc is outside the image.
4. **Diameter from the radial profile.** A threshold puts the edge of a projected sphere (whose
   contrast falls as ``sqrt(1 - rho^2/r^2)``) well inside the true edge (13 % of the diameter at
   half contrast). Instead each dot's azimuthally averaged profile is fitted by ``B - C f_p(rho / r)``
   blurred by a 2-D Gaussian of width ``s``, with ``f_p(u) = (1 - u^2)^p`` (``p = 0``: a flat disc;
   ``p = 1/2``: a projected sphere). A first fit of each dot alone (its region grown by 0.6 radii,
   `fit_profiles`) starts the fit with its neighbours taken out (`qdots.micrograph.refine`): every dot
   is modelled and refitted on the image plus its neighbours' model, and its centre moved to where its
   darkness balances. The background ``B`` (a smooth field), the blur and the shape ``p`` are settled
   once per image on a sample of the film (`qdots.micrograph.settle`), or ``p`` is given; faint dots the
   threshold missed are found in the residual of the model of all dots, and the film settled again with
   them (`qdots.micrograph.missed`). Each
   diameter's measurement error comes from measuring the film again with another draw of its own
   noise (`qdots.micrograph.refine.repeat_errors`).
5. **Noise.** A dot must stand out of the noise: its darkness over the noise of its mean (`signal_to_noise`, a
   matched filter that grows with the dot's area) must reach `MIN_SIGNAL`, which noise alone does not (its
   candidates score about 1; measured tail in `MIN_SIGNAL`): noise alone finds no dots.

Coordinates are image pixels: ``x`` the column, ``y`` the row, pixel ``(row, col)`` covering
``[col, col + 1) x [row, row + 1)``, so the image spans ``[0, W] x [0, H]``.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from scipy import ndimage

from labrig.threads import by_rows, run_tasks
from labrig.validate import InputError, choice, real

from ..geometry import nearest_ratio
from .annotations import find_strips
from .choices import POLARITIES, PROFILES
from .detection import Detection
from .discs import discs_cover
from .missed import missed_dots, most_missed
from .polarity import blob_skewness, decide_polarity, edge_curvature, middle_window
from .profiles import (
    BIN,
    FIT_HIGH,
    FIT_LOW,
    FIT_STEP,
    fit_profiles,
    measured_half_widths,
    profile_table,
    radial_profiles,
)
from .refine import per_dot, refine_dots, repeat_errors
from .segment import (
    GRAIN_SIZES,
    MIN_INSCRIBED,
    MIN_SIGNAL,
    background_level,
    blob_seeds,
    broad_blur,
    fill_small_holes,
    grain_noise,
    grow_labels,
    inside_distance,
    label_maxima,
    pixel_noise,
    region_properties,
    scaled,
    signal_to_noise,
    spaced_maxima,
    split_fused,
    stretch,
    typical_radius,
    watershed_parts,
)
from .settle import FIRST_BLUR, samples_hold, settle_profile
from .shapes import OVERLAP_SHARE, overlap_share, region_shapes

#: Smallest typical dot diameter, px, that can be measured.
MIN_DIAMETER = 4.0
#: Dots whose typical inscribed radius (`typical_radius`, which falls 0.5-1.5 px short of the true radius) is under
#: this many px are seeded from their intensity (`blob_seeds`): when touching, the blur (about 1 px) and the 1 px
#: smoothing fill the necks the distance transform needs (touching films of 6, 8 and 10 px dots: recall 0.34, 0.51,
#: 0.93 from the distance transform's maxima, 0.95, 0.94, 0.97 from the intensity's; equal from 12 px on).
BLOB_RADIUS = 5.0
#: Where the dot phase's objects are more than MERGED times as wide (typical inscribed radius) as the dark blobs of the
#: image's Laplacian of Gaussian at its blobs' scale (`blob_skewness`), they are touching small dots merged into one
#: network (the threshold split the film from its vacancies), and the blobs give the radius. Measured ratios (noise
#: 0.05): merged films of 6-7.5 px dots at 10-30 % vacancies 2.1-2.5; every other film of 6-24 px dots (sparse,
#: touching, superlattices with 1-2 px gaps) 1.0-1.4.
MERGED = 1.5
#: The stages `detect_dots` announces (its ``step``), in order.
STAGES = ("settling the blur and background", "fitting dots with their neighbours", "seeking faint dots the threshold "
          "missed", "measuring each diameter again")
#: A first look whose objects grow TEXTURE_GROWTH times or more when the picture is smoothed by COARSE_SMOOTH px, while
#: their pixels grow at most TEXTURE_AREA times, found a support's grain or the particles' inner texture (pores)
#: rather than dots: the picture is smoothed more (`first_look`). Measured: on four real films with grain or pores the
#: objects grow 2.7-12 times and their pixels 0.1-1.1 times; on 13 other real films 0.6-1.25 times; synthetic touching
#: films of 6-10 px dots without vacancies merge when smoothed (objects 1.3-6 times larger, pixels 1.1-1.9 times).
TEXTURE_GROWTH, TEXTURE_AREA, COARSE_SMOOTH = 2.0, 1.15, 3.0
#: The widest smoothing (px) that `detect_dots` takes.
MAX_SMOOTHING = 256.0
#: The blobs' scale and skewness (`blob_skewness`) are read on the middle SKEW_SIDE x SKEW_SIDE px (a quarter of the
#: pixels the edges are read on: they need hundreds of dots, not thousands).
SKEW_SIDE = 512


def detect_dots(image, polarity: str = "auto", profile: str = "auto", ignore: np.ndarray | None = None,
                window: tuple[int, int, int, int] | None = None, step=None, smoothing: float | None = None,
                screen=None) -> Detection:
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
        `predicted_curvature`), the flat disc unless the sphere matches clearly (`qdots.micrograph.settle.SPHERE_MATCH`);
        `Detection.profile` says which and why.
    ignore : ndarray of bool, shape (H, W), optional
        Pixels to leave out (a scale bar and its label).
    window : (int, int, int, int), optional
        ``(x0, y0, x1, y1)``: the part of the image that is picture (default: the image less the frame and data
        strips along its sides, `qdots.micrograph.annotations.find_strips`).
    step : callable, optional
        Called with the name of each stage as it begins (`STAGES`: a progress bar's).
    smoothing : float, optional
        Width (px) of the Gaussian the picture is smoothed by before it is thresholded into dot pixels (the fits are
        made on the picture smoothed by 1 px whatever it is). Default: 1 px, or more where the picture's grain or
        texture is finer than its dots (`TEXTURE_GROWTH`).
    screen : callable, optional
        Called with the dots as first found (`first_found`: their regions' shapes, the diameters of their lone fits)
        and the most dots the picture's edge does not cut that the search can end with (`most_whole`), before the
        profile is settled; where it returns true, the search stops there and returns them as they are (``profile``
        says so): the settling and the fits with the neighbours, most of the time a picture takes, are spared where
        their first look already decides (a retry of `qdots.micrograph.measure` whose objects are not a film of round
        particles).

    Returns
    -------
    Detection
        With no dots when none is found (``n_dots == 0``).
    """
    polarity = choice("polarity", polarity, POLARITIES)
    profile = choice("profile", profile, tuple(PROFILES))
    if smoothing is not None:
        smoothing = real("smoothing", smoothing, 0.5, MAX_SMOOTHING)
    image = np.asarray(image, dtype=float)
    if image.ndim != 2 or min(image.shape) < 2:
        raise InputError(f"image must be a 2-D array of at least 2 x 2 px, got shape {image.shape}")
    if not np.all(np.isfinite(image)):
        raise InputError("image has NaN or infinite pixels")
    ignore = np.zeros(image.shape, dtype=bool) if ignore is None else np.asarray(ignore, dtype=bool)
    if ignore.shape != image.shape:
        raise InputError(f"ignore must have the image's shape {image.shape}, got {ignore.shape}")
    h, w = image.shape
    x0, y0, x1, y1 = find_strips(image)[0] if window is None else (int(v) for v in window)
    if not (0 <= x0 < x1 <= w and 0 <= y0 < y1 <= h):
        raise InputError(f"window must lie inside the {w} x {h} px image, got {(x0, y0, x1, y1)}")
    if x1 - x0 < 2 or y1 - y0 < 2:
        return _empty((h, w), "no picture left inside the frame or strips", 0)
    inner = (slice(y0, y1), slice(x0, x1))

    def placed(found: Detection) -> Detection:  # from the picture inside the window to the image
        centres = found.centres + [x0, y0]
        cut = found.cut | cut_dots(centres, found.diameters, (x0, y0, x1, y1), ignore)
        return replace(found, centres=centres, cut=cut, image_shape=(h, w), window=(x0, y0, x1, y1))

    return placed(_detect(image[inner], polarity, profile, ignore[inner], step or (lambda stage: None), smoothing,
                          None if screen is None else (lambda early, most: bool(screen(placed(early), most)))))


def cut_dots(centres: np.ndarray, diameters: np.ndarray, window: tuple[int, int, int, int],
             ignore: np.ndarray | None) -> np.ndarray:
    """Which dots are cut: their disc crosses the edge of the picture (``window``, ``(x0, y0, x1, y1)`` px) or
    covers pixels left out (``ignore``, a boolean image: a label box, the scale bar), so that only part of them is
    seen."""
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    r = 0.5 * np.asarray(diameters, dtype=float)
    x0, y0, x1, y1 = window
    cut = (centres[:, 0] - r < x0) | (centres[:, 1] - r < y0) | (centres[:, 0] + r > x1) | (centres[:, 1] + r > y1)
    if ignore is not None and ignore.any() and len(r):  # every disc looked at whole: a dot stacked under another too
        discs_cover(np.ascontiguousarray(ignore, dtype=np.bool_), np.ascontiguousarray(centres), r, cut)
    return cut


def first_look(unit: np.ndarray, ignore: np.ndarray, smoothing: float):
    """The dot pixels at a first look at half resolution (dots dark in ``unit``): the picture smoothed by
    ``smoothing`` px, the broad fall of the light (over a sixth of the image) taken out, cut at Otsu's threshold.
    Returns the smoothed picture (full resolution), the half-resolution look, its dot pixels and their typical
    radius, px at full resolution."""
    from skimage.filters import threshold_otsu

    smooth = by_rows(lambda part: ndimage.gaussian_filter(part, smoothing), unit, math.ceil(4.0 * smoothing) + 1)
    half = (slice(None, None, 2), slice(None, None, 2))
    first = smooth[half] - broad_blur(smooth[half], max(unit.shape) / 12.0)
    first += float(np.mean(smooth[half]))
    mask = (first < threshold_otsu(first[~ignore[half]])) & ~ignore[half]
    return smooth, first, mask, 2.0 * typical_radius(ndimage.distance_transform_edt(mask))


def _detect(image: np.ndarray, polarity: str, profile: str, ignore: np.ndarray, step,
            smoothing: float | None = None, screen=None) -> Detection:
    """`detect_dots` on an image without a frame; ``cut`` marks the dots whose watershed region touches its edge."""
    from skimage.filters import threshold_otsu

    given = smoothing is not None
    raw = scaled(image, ignore, clip=False)  # one scaling: the unclipped image for the fits, clipped for the looks
    unit = np.clip(raw, 0.0, 1.0)
    if float(np.ptp(unit[~ignore])) < 1e-6:
        return _empty(image.shape, polarity, 0)
    noise = pixel_noise(unit, ignore)
    look = middle_window(unit.shape) if not ignore[middle_window(unit.shape)].all() else (slice(None),) * 2
    small = middle_window(unit.shape, SKEW_SIDE) if not ignore[middle_window(unit.shape, SKEW_SIDE)].all() else look
    skew, sigma = blob_skewness(unit[small], ignore[small], noise)
    dark, how = decide_polarity(*edge_curvature(unit[look], ignore[look], noise, sigma), skew, sigma, polarity)
    # the dots are measured on the unclipped image (clipping would flatten the darkest cores and the noise), the
    # pixels to ignore left out (NaN); dots are dark in every image below
    target = by_rows(lambda part: ndimage.gaussian_filter(part, 1.0), raw, 5)
    target[ignore] = np.nan
    if not dark:
        unit, target = 1.0 - unit, 1.0 - target
    # a first look at half resolution, smoothed by 1 px; where it finds grain or texture (smoothed by `COARSE_SMOOTH` px,
    # the objects grow `TEXTURE_GROWTH` times or more while their pixels do not: fragments rejoin the particles they
    # belong to, where touching dots would merge and gain area), the picture is smoothed at a third of the coarser
    # look's radius instead
    smoothing = 1.0 if smoothing is None else smoothing
    half = (slice(None, None, 2), slice(None, None, 2))
    # the look and (unless the smoothing is given) the coarser one side by side in threads
    looks = run_tasks([lambda: first_look(unit, ignore, smoothing)]
                      + [lambda: first_look(unit[half], ignore[half], COARSE_SMOOTH / 2.0)] * (not given))
    smooth, first, mask, radius = looks[0]
    if given:
        how += f"; smoothed by {smoothing:.1f} px (given)"
    else:
        coarse = looks[1]  # at a quarter of the resolution: its radius
        if 2.0 * coarse[3] >= TEXTURE_GROWTH * radius and coarse[2].mean() <= TEXTURE_AREA * mask.mean():
            smoothing = float(np.clip(2.0 * coarse[3] / 3.0, COARSE_SMOOTH / 2.0, 2.0 * COARSE_SMOOTH))
            smooth, first, mask, radius = first_look(unit, ignore, smoothing)
            how += f"; smoothed by {smoothing:.1f} px (the picture's grain or texture is finer than its dots)"
    if radius < 0.5 * MIN_DIAMETER:
        return _empty(image.shape, how, 0)
    away = ~ndimage.binary_dilation(mask, iterations=max(1, int(0.15 * radius))) & ~ignore[half]
    if away.any():
        coarse = background_level(smooth[half], away, 4.0 * radius)
        level = stretch(coarse, np.arange(image.shape[0]) / 2.0, np.arange(image.shape[1]) / 2.0)
    else:
        level = np.full(image.shape, float(np.median(smooth)))
    flat = smooth / np.maximum(level, 1e-6)
    threshold = threshold_otsu(flat[~ignore])
    mask = fill_small_holes((flat < threshold) & ~ignore, 0.03 * math.pi * radius**2)
    distance = inside_distance(mask, max(64.0, 4.0 * radius))
    radius = typical_radius(distance)
    if sigma > 0 and smoothing == 1.0:  # touching small dots merged into one network: the blobs give their radius
        curved = by_rows(lambda part: ndimage.gaussian_laplace(part, sigma / 2.0), flat[half],
                         math.ceil(2.0 * sigma) + 1)  # (each band's: exact)
        blobs = 2.0 * typical_radius(inside_distance(mask[half] & (curved > 0), max(64.0, 4.0 * radius)))
        radius = blobs if radius > MERGED * blobs else radius
    if radius < 0.5 * MIN_DIAMETER:
        return _empty(image.shape, how, 0)
    # split touching dots: a watershed from one seed per dot; small dots' seeds from their intensity (`blob_seeds`),
    # larger ones' from the distance transform's maxima (smoothed by 1 px) at least 0.6 radii apart
    if radius < BLOB_RADIUS:
        peaks, response = blob_seeds(unit / np.maximum(level, 1e-6), mask, radius)
    else:
        peaks = spaced_maxima(by_rows(lambda part: ndimage.gaussian_filter(part, 1.0), distance, 5),
                              max(2, round(0.6 * radius)), 0.5)
        response = distance
    deep = distance[tuple(peaks.T)] >= MIN_INSCRIBED * radius
    rejected = int(np.count_nonzero(~deep))
    peaks = peaks[deep]
    n = len(peaks)
    if n == 0:
        return _empty(image.shape, how, rejected)
    markers = np.zeros(image.shape, dtype=np.int32)
    markers[tuple(peaks.T)] = np.arange(1, n + 1)
    labels = split_fused(watershed_parts(-response, markers, mask), distance)
    props = region_properties(labels)
    shapes = region_shapes(labels)
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
    regions = grow_labels(labels, grow)
    n_bins = math.ceil(FIT_HIGH * 1.2 * start.max() / BIN) + 1
    sums, counts, rhos = radial_profiles(target, regions, centres, n_bins)
    whole = np.flatnonzero(~touches)
    first = fit_profiles(sums, counts, rhos, np.ones(len(start)), True, start, profile_table(0.5), FIRST_BLUR,
                         FIT_LOW, FIT_HIGH, FIT_STEP)
    ok = np.isfinite(first[0]) & (first[2] > 0)
    sure = ok & ~touches if (ok & ~touches).any() else ok
    typical = float(np.median(first[0][sure])) if sure.any() else radius
    if screen is not None:
        early = first_found(centres, first, ok, touches, shapes, dark, how, rejected, image.shape)
        if screen(early, most_whole(touches, typical, image.shape)):
            return early
    step("settling the blur and background")
    shape, blur, level, level_map, how_shape, trimmed = settle_profile(target, centres, first[0], first[2], first[1], typical,
                                                              whole, profile)
    step(f"fitting {len(centres)} dots with their neighbours")
    refined = refine_dots(target, centres, first[0], first[2], typical, shape, blur, level, move=True)
    spheres, refit = profile == "auto" and shape == 0.5, ""
    overlapping = overlap_share(nearest_ratio(refined.centres, 2.0 * refined.radius)) if spheres else 0.0
    if overlapping > OVERLAP_SHARE:  # projected spheres wider than their spacing: the particles are flatter
        profile = "disc"
        shape, blur, level, level_map, how_shape, trimmed = settle_profile(target, centres, first[0], first[2], first[1],
                                                                  typical, whole, profile)
        how_shape = refit = (f"p = 0: as projected spheres {100 * overlapping:.0f} % of the dots with a close "
                             "neighbour overlapped it, which particles in one layer cannot do, so they were fitted as "
                             "flat discs")
        refined = refine_dots(target, centres, first[0], first[2], typical, shape, blur, level, move=True)
    step("seeking faint dots the threshold missed")
    # the grain of the support (of the picture alone) beside the search, in a second thread
    extra, grains = run_tasks([
        lambda: missed_dots(target, refined, level_map, typical, shape, blur, noise, trimmed),
        lambda: grain_noise(np.nan_to_num(target[half], nan=float(np.nanmedian(target))), mask[half], 0.5 * typical,
                            GRAIN_SIZES)])
    if len(extra):  # dots the threshold missed: fitted, and the film settled again with them if they are in its samples
        more, n = len(extra), len(centres)
        centres = np.vstack([centres, extra])
        touches = np.concatenate([touches, np.zeros(more, dtype=bool)])
        shapes = np.vstack([shapes, np.full((more, 3), np.nan)])
        whole = np.flatnonzero(~touches)
        first = (np.concatenate([first[0], np.full(more, typical)]), np.concatenate([first[1], np.full(more, np.nan)]),
                 np.concatenate([first[2], np.full(more, float(np.median(first[2][sure])) if sure.any() else 0.0)]))
        if samples_hold(target.shape, centres, whole, typical, np.arange(n, n + more)):
            shape, blur, level, level_map, how_shape, trimmed = settle_profile(target, centres, first[0], first[2], first[1],
                                                                      typical, whole, profile)
            how_shape = refit or how_shape
            refined = refine_dots(target, centres, first[0], first[2], typical, shape, blur, level, move=True)
        else:  # the settling is the same without them: the new dots take the level and blur where they lie, and only
            # they and the dots whose profiles they reach are fitted again
            nearest = np.argmin(np.hypot(*(extra[:, None, :] - centres[None, :n, :]).T), axis=0)
            at = np.clip(extra.astype(int), 0, [target.shape[1] - 1, target.shape[0] - 1])
            level = np.concatenate([level, level_map[at[:, 1], at[:, 0]]])
            blur = blur if np.ndim(blur) == 0 else np.concatenate([blur, np.asarray(blur)[nearest]])
            start = np.vstack([refined.centres, extra])
            reach = 2.0 * float(np.max(refined.reach, initial=0.0)) + 2.0 * typical
            near = np.min(np.hypot(*(start[:, None, :] - extra[None, :, :]).T), axis=0) <= reach
            refined = refine_dots(target, start, np.concatenate([refined.radius, np.full(more, np.nan)]),
                                  np.concatenate([refined.contrast, np.zeros(more)]), typical, shape, blur, level,
                                  move=True, active=near, model=refined.model)
        how_shape += f"; {more} faint dots the threshold missed found in the fit's residual"
    if np.ptp(blur) > 0.05:
        how_shape += f"; the blur {np.min(blur):.2f}-{np.max(blur):.2f} px across the film (uneven focus)"
    centres = np.where(touches[:, None], centres, refined.centres)  # a cut dot keeps the centre of its visible part
    fitted, background = refined.radius, refined.background
    contrast = refined.contrast / np.maximum(background, 1e-12)  # in units of the background, as Detection has it
    good = np.isfinite(fitted) & (contrast > 0)
    assert refined.profiles is not None  # refine_dots keeps the profiles unless told not to
    sums, counts, rhos = refined.profiles
    grain = np.interp(fitted[good] / typical, GRAIN_SIZES, grains)  # the grain at each dot's own size
    score = signal_to_noise(sums[good], counts[good], fitted[good], background[good], noise, grain)
    good[good] = score >= MIN_SIGNAL
    if not good.any():
        best = float(np.max(score)) if score.size else 0.0
        return _empty(image.shape, f"{how}; no dot stands out of the noise: the clearest scores {best:.1f} noise "
                                   f"deviations of its mean, under the {MIN_SIGNAL:g} a dot needs: noise alone",
                      len(start))
    rejected += int(np.count_nonzero(~good))
    step("measuring each diameter again")
    errors = 2.0 * repeat_errors(target, centres, refined, typical, shape, blur, level, level_map)
    widths = measured_half_widths(sums, counts, rhos, fitted, per_dot(blur, len(fitted)))
    centres, fitted, contrast, touches, errors, shapes, widths = (
        part[good] for part in (centres, fitted, contrast, touches, errors, shapes, widths))
    return Detection(centres, 2.0 * fitted, touches, contrast, dark, how, float(shape), how_shape,
                     float(np.median(blur)), rejected, (h, w), (0, 0, w, h), errors, shapes, widths)


def first_found(centres, first, ok, touches, shapes, dark: bool, how: str, rejected: int, shape) -> Detection:
    """The dots as first found, before the profile is settled: those whose lone fit (``first``: radius, background,
    contrast, residual, `qdots.micrograph.profiles.fit_profiles`, at a projected sphere blurred by `FIRST_BLUR`)
    succeeded (``ok``), with those fits' diameters and contrasts, their regions' ``shapes`` and no profile, blur or
    measurement error (NaN)."""
    n = int(np.count_nonzero(ok))
    return Detection(centres[ok], 2.0 * first[0][ok], touches[ok], first[2][ok] / np.maximum(first[1][ok], 1e-12), dark,
                     how, math.nan, "not fitted: the dots as first found, before the profile was settled", math.nan,
                     rejected + len(ok) - n, tuple(shape), (0, 0, shape[1], shape[0]), np.full(n, np.nan), shapes[ok])


def most_whole(touches: np.ndarray, typical: float, shape) -> int:
    """The most dots the picture's edge does not cut that a search can end with, from the regions found (``touches``:
    whether each touches the edge of the picture, of ``shape``; ``typical``: their typical radius, px): the fits can
    leave a dot out, or find that one the edge seemed to cut is whole (a smaller diameter than its lone fit's), but
    add only the faint dots the threshold missed (`qdots.micrograph.missed.most_missed`), and a region that touches
    the edge stays cut."""
    return int(np.count_nonzero(~touches)) + most_missed(len(touches), typical, shape)


def _empty(shape, how: str, rejected: int) -> Detection:
    return Detection(np.zeros((0, 2)), np.zeros(0), np.zeros(0, dtype=bool), np.zeros(0), "light" not in how, how,
                     math.nan, "", math.nan, rejected, tuple(shape), (0, 0, shape[1], shape[0]), np.zeros(0),
                     np.zeros((0, 3)))

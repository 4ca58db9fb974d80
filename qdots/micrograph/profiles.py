"""Dots' radial profiles: the blurred model profiles, the compiled fit of each dot's diameter, the shape choice.

A dot's contrast is modelled as ``B - C f_p(rho / r)`` blurred by a 2-D Gaussian of width ``s``, with
``f_p(u) = (1 - u^2)^p`` (``p = 0``: a flat disc; ``p = 1/2``: a projected sphere). Each dot's azimuthally
averaged profile (`radial_profiles`) is fitted for ``B``, ``C`` and ``r`` (`fit_profiles`); the shape and the
blur are chosen once per image (`choose_profile`).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from labrig.compiled import jit

#: Dot profiles by name (the exponent p), the shapes tried by ``profile="auto"``, and blur widths s (px).
PROFILES = {"auto": None, "sphere": 0.5, "disc": 0.0}
SHAPES = (0.0, 0.25, 0.5)
#: ``profile="auto"`` measures the shape on at least this many whole dots (else assumes a sphere).
MIN_SHAPE_DOTS = 10
#: ``profile="auto"`` keeps the sphere unless another shape's curvature matches by this much more (`central_curvature`).
CURVATURE_MARGIN = 0.05
BLURS = (0.0, 0.5, 1.0, 1.25, 1.5, 1.75, 2.0, 2.5, 3.0, 4.0)
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


def choose_profile(sums: np.ndarray, counts: np.ndarray, start: np.ndarray, whole: np.ndarray, profile: str
                   ) -> tuple[float, float, str]:
    """The profile shape ``p`` and blur (px) of an image's dots, and how the shape was chosen, in words.

    The blur of each candidate shape is the one of `BLURS` whose fits of up to `SHAPE_SAMPLE` whole dots
    (indices ``whole``; ``start`` their segmented radii) leave the least residual; the shape is given
    (``profile`` "sphere" or "disc") or, for ``"auto"``, the one of `SHAPES` whose predicted central
    curvature (`predicted_curvature`) is nearest the measured one (`central_curvature`), the sphere unless
    another matches by `CURVATURE_MARGIN` more, and the sphere with fewer than `MIN_SHAPE_DOTS` whole dots.
    """
    base = np.ones(len(start))  # profiles are in units of the background level
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
    return float(shape), float(blurs[shape]), how_shape

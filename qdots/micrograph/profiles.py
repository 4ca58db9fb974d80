"""Dots' radial profiles: the blurred model profiles and the compiled fit of each dot's diameter.

A dot's contrast is modelled as ``B - C f_p(rho / r)`` blurred by a 2-D Gaussian of width ``s``, with
``f_p(u) = (1 - u^2)^p`` (``p = 0``: a flat disc; ``p = 1/2``: a projected sphere). Each dot's azimuthally
averaged profile (`radial_profiles`) is fitted for ``B``, ``C`` and ``r`` (`fit_profiles`); the shape and the
blur are chosen once per image (`qdots.micrograph.refine.settle_profile`).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from labrig.compiled import jit
from labrig.threads import by_chunks

#: Radius search of the profile fit, in units of the segmented radius, and its step.
FIT_LOW, FIT_HIGH, FIT_STEP = 0.6, 1.5, 0.0025
#: The radius search first tries every COARSE-th step.
COARSE = 6
#: Radial bin width of the profiles, px.
BIN = 0.5
#: The centre of a dot, where its curvature is measured (`central_curvature`), in radii.
CENTRE = 0.5
#: A dot's half-depth width read on its own profile (`measured_half_widths`): its core is the mean of its pixels
#: within CORE radii (at least 1 px), its crest the profile's highest point (three bins pooled) from CREST[0] radii to
#: CREST[1] radii or its
#: radius plus CREST_BLUR blurs, whichever is farther, plus CREST_PAD px (a blurred edge levels off two blurs out),
#: and the crossing of half depth is sought beyond FROM radii.
CORE, CREST, CREST_BLUR, CREST_PAD, FROM = 0.25, (0.7, 1.4), 2.0, 2.0, 0.3


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
def table_value(table, s, u):
    """Bilinear value of `profile_table` at relative blur ``s`` and radius ``u`` (0 beyond the table or at NaN)."""
    si = min(s * 100.0, 59.999) if s > 0.0 else 0.0
    ui = u * 200.0
    if not (0.0 <= ui < 399.999):
        return 0.0
    i = int(si)
    j = int(ui)
    a = si - i
    b = ui - j
    return ((1 - a) * ((1 - b) * table[i, j] + b * table[i, j + 1])
            + a * ((1 - b) * table[i + 1, j] + b * table[i + 1, j + 1]))


@jit
def blur_row(table, s, out):
    """Fill ``out`` with `profile_table`'s profile at relative blur ``s`` (interpolated between its rows as
    `table_value` does): `row_value` then reads it at any radius, for the many pixels of one dot."""
    si = min(s * 100.0, 59.999) if s > 0.0 else 0.0
    i = int(si)
    a = si - i
    for j in range(table.shape[1]):
        out[j] = (1 - a) * table[i, j] + a * table[i + 1, j]


@jit(inline=True)
def row_value(row, u):
    """Linear value of a `blur_row` at radius ``u`` (0 beyond it or at NaN)."""
    ui = u * 200.0
    if not (0.0 <= ui < 399.999):
        return 0.0
    j = int(ui)
    b = ui - j
    return (1 - b) * row[j] + b * row[j + 1]


@jit
def fit_at(sums, counts, rhos, level, free, table, s, r):
    """Least squares of one dot's profile (1-D ``sums``, ``counts``, ``rhos`` per bin) against ``B - C F(rho / r)``
    at relative blur ``s``: (B, C, residual), ``B`` fitted when ``free``, else ``level``; each bin is taken at the
    mean radius of its pixels."""
    sw = 0.0
    sf = 0.0
    sff = 0.0
    sv = 0.0
    sfv = 0.0
    svv = 0.0
    for b in range(sums.shape[0]):
        w = counts[b]
        if w == 0:
            continue
        v = sums[b] / w
        f = table_value(table, s, rhos[b] / w / r)
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
def fit_dot(sums, counts, rhos, level, free, table, blur, start, low, high, step):
    """Fit one dot's profile (`fit_at`) over radii ``start * [low, high]``: every ``COARSE * step``, then every
    ``step`` around the best of those, refined by a parabola through the best three. Returns (r, B, C, residual);
    r is NaN when no radius fits."""
    k_max = int((high - low) / step) + 1
    errors = np.full(k_max, np.inf)
    coarse = -1
    for k in range(0, k_max, COARSE):
        r = start * (low + k * step)
        errors[k] = fit_at(sums, counts, rhos, level, free, table, blur / r, r)[2]
        if errors[k] < np.inf and (coarse < 0 or errors[k] < errors[coarse]):
            coarse = k
    if coarse < 0:
        return np.nan, np.nan, np.nan, np.inf
    best = coarse
    for k in range(max(0, coarse - COARSE), min(k_max, coarse + COARSE + 1)):
        if k % COARSE != 0:
            r = start * (low + k * step)
            errors[k] = fit_at(sums, counts, rhos, level, free, table, blur / r, r)[2]
        if errors[k] < errors[best]:
            best = k
    shift = 0.0
    if 0 < best < k_max - 1 and errors[best - 1] < np.inf and errors[best + 1] < np.inf:
        curve = errors[best - 1] - 2.0 * errors[best] + errors[best + 1]
        if curve > 0:
            shift = 0.5 * (errors[best - 1] - errors[best + 1]) / curve
    r = start * (low + (best + shift) * step)
    big, c, error = fit_at(sums, counts, rhos, level, free, table, blur / r, r)
    return r, big, c, error


@jit
def polish_dot(sums, counts, rhos, level, free, table, blur, start, step, low, high):
    """Fit one dot's profile (`fit_at`) near the radius ``start``: steps of ``step`` (relative) downhill until the
    least residual is bracketed (within ``start * [low, high]``), then a parabola through the three, and once more
    at a quarter of the step. Returns (r, B, C, residual), r NaN when no radius fits."""
    r = start
    for _ in range(2):
        h = step * start
        e0 = fit_at(sums, counts, rhos, level, free, table, blur / r, r)[2]
        em = fit_at(sums, counts, rhos, level, free, table, blur / (r - h), r - h)[2]
        ep = fit_at(sums, counts, rhos, level, free, table, blur / (r + h), r + h)[2]
        moves = 0
        while moves < 8 and (em < e0 or ep < e0):
            if em < ep and r - 2 * h >= low * start:
                r, ep, e0 = r - h, e0, em
                em = fit_at(sums, counts, rhos, level, free, table, blur / (r - h), r - h)[2]
            elif ep <= em and r + 2 * h <= high * start:
                r, em, e0 = r + h, e0, ep
                ep = fit_at(sums, counts, rhos, level, free, table, blur / (r + h), r + h)[2]
            else:
                break
            moves += 1
        if not (e0 < np.inf):
            return np.nan, np.nan, np.nan, np.inf
        curve = em - 2.0 * e0 + ep
        if curve > 0 and em < np.inf and ep < np.inf:
            r += min(max(0.5 * (em - ep) / curve, -1.0), 1.0) * h
        step *= 0.25
    big, c, error = fit_at(sums, counts, rhos, level, free, table, blur / r, r)
    return r, big, c, error


def fit_profiles(sums, counts, rhos, level, free, start, table, blur, low, high, step):
    """Fit ``B - C F(rho / r)`` to each dot's radial profile (`fit_dot`), chunks of dots side by side in threads
    (`labrig.threads.by_chunks`); returns (r, B, C, residual) arrays.

    ``sums[i, b]``, ``counts[i, b]`` and ``rhos[i, b]`` are the summed values, pixel counts and summed radii
    (px) of dot ``i``'s bin ``b`` (`radial_profiles`; the model is taken at each bin's mean radius, not its
    middle, which matters for a centre on the pixel grid's symmetry points); ``start[i]`` is its segmented
    radius; ``level[i]`` its background (``B``, unless ``free``: then fitted). r runs over ``start * [low, high]``.
    """
    level = np.ascontiguousarray(np.broadcast_to(np.asarray(level, dtype=float), (len(sums),)))
    start = np.asarray(start, dtype=float)
    pieces = by_chunks(lambda a, b: fit_profiles_part(sums[a:b], counts[a:b], rhos[a:b], level[a:b], free, start[a:b],
                                                      table, blur, low, high, step), len(sums))
    if not pieces:
        return tuple(np.full(0, value) for value in (np.nan, np.nan, np.nan, np.inf))
    return tuple(np.concatenate(part) for part in zip(*pieces))


@jit
def fit_profiles_part(sums, counts, rhos, level, free, start, table, blur, low, high, step):
    """`fit_profiles` of these dots in this thread."""
    n = sums.shape[0]
    radius = np.full(n, np.nan)
    background = np.full(n, np.nan)
    contrast = np.full(n, np.nan)
    residual = np.full(n, np.inf)
    for i in range(n):
        radius[i], background[i], contrast[i], residual[i] = fit_dot(sums[i], counts[i], rhos[i], level[i], free,
                                                                     table, blur, start[i], low, high, step)
    return radius, background, contrast, residual


@functools.cache
def _half_depth_row(shape: float) -> np.ndarray:
    """`half_depth_radius` at the relative blurs of `profile_table`'s rows (0, 0.01, ... 0.6 radii)."""
    table = profile_table(shape)
    u = np.arange(table.shape[1]) / 200.0
    out = np.empty(table.shape[0])
    for i, row in enumerate(table):
        below = np.flatnonzero(row < 0.5 * row[0])
        j = int(below[0]) if below.size else row.size - 1
        out[i] = u[j - 1] + (0.5 * row[0] - row[j - 1]) / (row[j] - row[j - 1]) * (u[j] - u[j - 1]) if j > 0 else 0.0
    return out


def half_depth_radius(shape: float, relative_blur) -> np.ndarray:
    """Where a dot of profile ``shape`` (radius 1), blurred by ``relative_blur`` radii, has lost half its central
    contrast: the half-depth radius that a line profile or a threshold halfway between the dot and its background
    finds (a flat disc's is about 1, a projected sphere's 0.87 unblurred). Blurs past 0.6 radii are taken as 0.6."""
    row = _half_depth_row(float(shape))
    return np.interp(np.asarray(relative_blur, dtype=float), np.arange(row.size) / 100.0, row)


def central_curvature(sums, counts, rhos, radius, level) -> float:
    """Median relative curvature of the dots' centres, ``kappa r^2``: each profile (`radial_profiles`) within
    `CENTRE` of its ``radius`` fitted by ``a + b rho^2`` (least squares, pixels weighted alike; a dark dot
    brightens away from its centre), ``kappa = b / (level - a)``. Compare with `predicted_curvature`."""
    rho = np.divide(rhos, counts, out=np.zeros_like(rhos), where=counts > 0)
    inner = (rho <= CENTRE * radius[:, None]) & (counts > 0)
    w = np.where(inner, counts, 0.0)
    v = np.divide(sums, counts, out=np.zeros_like(sums), where=counts > 0)
    x = rho**2
    sw, sx, sxx = w.sum(1), (w * x).sum(1), (w * x * x).sum(1)
    sv, sxv = (w * v).sum(1), (w * x * v).sum(1)
    det = sw * sxx - sx * sx
    ok = (det > 0) & (inner.sum(1) >= 3) & np.isfinite(radius)
    if not ok.any():
        return math.nan
    a = (sxx[ok] * sv[ok] - sx[ok] * sxv[ok]) / det[ok]
    b = (sw[ok] * sxv[ok] - sx[ok] * sv[ok]) / det[ok]
    depth = np.asarray(level, dtype=float)[ok] - a
    good = depth > 0.02 * np.asarray(level, dtype=float)[ok]
    return float(np.median(b[good] / depth[good] * radius[ok][good] ** 2)) if good.any() else math.nan


def predicted_curvature(shape: float, relative_blur: float) -> float:
    """``kappa r^2`` (`central_curvature`) of a dot of profile ``shape`` blurred by ``relative_blur`` radii: its
    tabulated profile (`profile_table`) fitted by ``alpha - beta u^2`` within `CENTRE` radii, weighted by the
    radius as pixels are. About 0 for a flat disc, 0.56 for a projected sphere; NaN for a blur that is not finite
    (no dot of the sample kept a radius)."""
    if not math.isfinite(relative_blur):
        return math.nan
    table = profile_table(shape)
    row = table[min(round(relative_blur * 100), table.shape[0] - 1)]
    u = np.arange(row.size) / 200.0
    inner = u <= CENTRE
    beta, alpha = np.polyfit(u[inner] ** 2, row[inner], 1, w=np.sqrt(u[inner] + 1e-3))
    return float(-beta / alpha)


def radial_profiles(image, regions, centres, n_bins: int):
    """Summed values, pixel counts and summed radii (px) of each region's pixels in radial bins of `BIN` px
    around its centre (NaN pixels left out): regions labelled 1 .. N in ``regions`` (0 none), ``centres`` (N, 2)."""
    centres = np.ascontiguousarray(centres, dtype=float).reshape(-1, 2)
    n = len(centres)
    sums, counts, rhos = np.zeros((n, n_bins)), np.zeros((n, n_bins)), np.zeros((n, n_bins))
    region_bins(np.asarray(image, dtype=float), np.asarray(regions), centres, sums, counts, rhos)
    return sums, counts, rhos


@jit
def region_bins(image, regions, centres, sums, counts, rhos):
    """Add each labelled pixel of ``image`` to its region's radial bin (`radial_profiles`), pixel after pixel in
    row-major order."""
    h, w = regions.shape
    n_bins = sums.shape[1]
    for row in range(h):
        for col in range(w):
            k = regions[row, col] - 1
            if k < 0:
                continue
            rho = math.hypot(col + 0.5 - centres[k, 0], row + 0.5 - centres[k, 1])
            b = int(rho / BIN)
            value = image[row, col]
            if b >= n_bins or not np.isfinite(value):  # NaN: a pixel left out
                continue
            sums[k, b] += value
            counts[k, b] += 1.0
            rhos[k, b] += rho


@jit
def measured_half_widths(sums, counts, rhos, radius, blur) -> np.ndarray:
    """Each dot's full width at half depth read on its own profile, px, as a line profile by hand reads it: twice
    the radius where the profile (``sums / counts`` at the mean radius ``rhos / counts`` of each bin, the dot's
    neighbours taken out: `qdots.micrograph.refine.Refined.profiles`) first rises halfway from its core to its crest
    (`CORE`, `CREST`: the crest is the background beside the dot, or a bright fringe around it), linearly
    interpolated between bins. ``radius`` and ``blur`` (px, the fitted ones, one per dot) say where to look. NaN
    where the radius is unknown or the profile never rises halfway."""
    n, n_bins = sums.shape
    out = np.full(n, np.nan)
    for k in range(n):
        r = radius[k]
        if not r > 0.0:
            continue
        core, core_n, crest = 0.0, 0.0, -np.inf
        for b in range(n_bins):
            if counts[k, b] > 0.0:
                rho = rhos[k, b] / counts[k, b]
                if rho < max(CORE * r, 1.0):
                    core += sums[k, b]
                    core_n += counts[k, b]
                elif CREST[0] * r <= rho <= max(CREST[1] * r, r + CREST_BLUR * blur[k]) + CREST_PAD:
                    low, high = max(b - 1, 0), min(b + 2, n_bins)  # three bins pooled: noise lifts a highest bin
                    pooled = counts[k, low:high].sum()
                    crest = max(crest, sums[k, low:high].sum() / pooled)
        if core_n == 0.0 or not crest > core / core_n:
            continue
        half = 0.5 * (core / core_n + crest)
        last_rho, last_value = -1.0, 0.0
        for b in range(n_bins):
            if counts[k, b] == 0.0:
                continue
            rho, value = rhos[k, b] / counts[k, b], sums[k, b] / counts[k, b]
            if rho > FROM * r and value >= half:
                if last_rho >= 0.0 and value > last_value:
                    out[k] = 2.0 * (last_rho + (half - last_value) / (value - last_value) * (rho - last_rho))
                else:
                    out[k] = 2.0 * rho
                break
            last_rho, last_value = rho, value
    return out

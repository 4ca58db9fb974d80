"""Dots measured with their neighbours taken out: each dot's profile fitted on the image plus its
neighbours' fitted model, and each dot's measurement error from two halves of its profile.

On a dense film a dot's azimuthal profile holds its neighbours' blurred edges, and on a superlattice the
narrow ligand gaps never reach the background level: a lone fit's radius and background are pulled by
them. Here every dot is modelled (`paint_model`: ``C_j F_p(|x - x_j| / r_j)`` blurred, summed over the
dots; the image is ``B - model``), and dot ``i``'s profile is taken from ``image + model - own model``
(`dot_profile`): its neighbours' darkening added back, what is left is one dot on the background. Its
``C`` and ``r`` are fitted again (`qdots.micrograph.profiles.fit_dot`) and its model replaced at once, dot
after dot, pass after pass (`refine_pass`, `refine_dots`). The background and the blur come from
`qdots.micrograph.settle`.

The measurement error of each diameter (`repeat_errors`): the film measured again on the fitted model
plus the image's own residual rolled aside, which holds noise and grain of the same kind as the image's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from labrig.compiled import jit
from labrig.threads import available_threads, by_chunks, row_ranges, run_in_threads

from .profiles import BIN, FIT_STEP, blur_row, fit_dot, polish_dot, profile_table, row_value

#: Fitting passes.
PASSES = 3
#: How far the residual is rolled for the repeated measurement of `repeat_errors`, px (rows, columns).
REPEAT_SHIFT = (37, 61)
#: Most dots measured again (`repeat_errors`).
REPEAT_DOTS = 2000
#: Radius search of the first pass, in units of the film's typical radius; of the later ones, of the dot's own,
#: by steps of POLISH_STEP of it (`qdots.micrograph.profiles.polish_dot`).
WIDE, NARROW, POLISH_STEP = (0.45, 1.8), (0.85, 1.18), 0.02
#: A later pass's radius within PINNED (relative) of an end of its `NARROW` search stopped there, short of its minimum
#: (a dot the first pass put far off, fitted among neighbours not yet fitted themselves): after a wide pass it walks on
#: from there, at most WALKS more times, within `WIDE` times the typical radius (`refine_pass`).
PINNED, WALKS = 0.015, 8
#: A dot's profile reaches REACH times its radius (or the typical one, if larger) plus REACH_PAD px.
REACH, REACH_PAD = 1.4, 4.0


@jit(inline=True)
def disc_columns(x, dy, reach, w):
    """The columns (start, stop) of an image ``w`` px wide, on a row ``dy`` px from a centre at ``x``, that may lie
    within ``reach`` px of it (an empty range where none can): a superset, each pixel still tested."""
    if dy * dy >= reach * reach:
        return 0, 0
    half = math.sqrt(reach * reach - dy * dy)
    return max(0, int(x - 0.5 - half)), min(w, int(x - 0.5 + half) + 2)


@jit
def add_disc(model, x, y, r, c, curve, top=0, bottom=-1):
    """Add ``c`` times the profile ``curve`` (a `qdots.micrograph.profiles.blur_row`) at radius ``r`` around (x, y) to
    ``model``, out to twice the radius, row by row over the columns that distance reaches; only rows ``top`` to
    ``bottom`` - 1 (default: all)."""
    h, w = model.shape
    reach = 2.0 * r
    for line in range(max(top, int(y - reach)), min(h if bottom < 0 else bottom, int(y + reach) + 2)):
        dy = line + 0.5 - y
        start, stop = disc_columns(x, dy, reach, w)
        for col in range(start, stop):
            dx = col + 0.5 - x
            rho = math.sqrt(dx * dx + dy * dy)
            if rho < reach:
                model[line, col] += c * row_value(curve, rho / r)


@jit
def paint_model(model, centres, radii, contrast, table, blurs, top, bottom):
    """Add every dot's ``C F(|p - (x, y)| / r)`` (the blurred profile of `profile_table`, out to 2 r) to rows ``top``
    to ``bottom`` - 1 of ``model``, dot after dot (``blurs[k]`` the blur at dot k, px)."""
    curve = np.empty(table.shape[1])
    for k in range(len(radii)):
        r = radii[k]
        y = centres[k, 1]
        if r > 0.0 and contrast[k] != 0.0 and int(y - 2.0 * r) < bottom and int(y + 2.0 * r) + 2 > top:
            blur_row(table, blurs[k] / r, curve)
            add_disc(model, centres[k, 0], y, r, contrast[k], curve, top, bottom)


@jit
def dot_profile(image, model, x, y, r, c, table, blur, far, bin_width, parity, sums, counts, rhos):
    """Fill ``sums``, ``counts`` and ``rhos`` (zeroed here) with the radial bins of ``image + model - own model``
    around (x, y), out to ``far`` px; ``parity`` -1 takes every pixel, 0 or 1 only those in the even or odd 45
    degree sectors around the centre."""
    sums[:] = 0.0
    counts[:] = 0.0
    rhos[:] = 0.0
    h, w = image.shape
    own = r > 0.0 and c > 0.0
    curve = np.empty(table.shape[1])
    if own:
        blur_row(table, blur / r, curve)
    n_bins = sums.shape[0]
    for row in range(max(0, int(y - far)), min(h, int(y + far) + 2)):
        dy = row + 0.5 - y
        start, stop = disc_columns(x, dy, far, w)
        for col in range(start, stop):
            dx = col + 0.5 - x
            rho = math.sqrt(dx * dx + dy * dy)
            b = int(rho / bin_width)
            if rho >= far or b >= n_bins:
                continue
            if parity >= 0 and int((math.atan2(dy, dx) + math.pi) / (0.25 * math.pi)) % 2 != parity:
                continue
            v = image[row, col] + model[row, col]
            if not (v == v):  # a pixel left out (NaN)
                continue
            if own:
                v -= c * row_value(curve, rho / r)
            sums[b] += v
            counts[b] += 1.0
            rhos[b] += rho


def dot_profiles(image, model, centres, radii, contrast, table, blurs, reach, n_bins, bin_width, parity):
    """`dot_profile` of every dot: (sums, counts, rhos) arrays of shape (N, n_bins), as
    `qdots.micrograph.profiles.radial_profiles` gives; chunks of dots side by side in threads
    (`labrig.threads.by_chunks`)."""
    n = len(radii)
    sums, counts, rhos = np.zeros((n, n_bins)), np.zeros((n, n_bins)), np.zeros((n, n_bins))
    by_chunks(lambda start, stop: dot_profiles_part(image, model, centres, radii, contrast, table, blurs, reach,
                                                    bin_width, parity, start, stop, sums, counts, rhos), n)
    return sums, counts, rhos


@jit
def dot_profiles_part(image, model, centres, radii, contrast, table, blurs, reach, bin_width, parity, start, stop,
                      sums, counts, rhos):
    """`dot_profiles` of dots ``start`` .. ``stop`` - 1, into rows of ``sums``, ``counts`` and ``rhos``."""
    for k in range(start, stop):
        dot_profile(image, model, centres[k, 0], centres[k, 1], radii[k], contrast[k], table, blurs[k], reach[k],
                    bin_width, parity, sums[k], counts[k], rhos[k])


@jit
def centre_shift(image, model, x, y, r, level):
    """How far the centre of the dot at (x, y), radius ``r``, is from where its darkness alone (``level - (image +
    model)``, positive part, ``model`` without the dot's own) balances within 0.9 r: (dx, dy), px; (0, 0) when the
    window crosses the image edge or holds no darkness. Repeated, this converges on the dot's centre of symmetry."""
    h, w = image.shape
    window = 0.9 * r
    if not (r > 0.0) or x - window < 0.0 or y - window < 0.0 or x + window > w or y + window > h:
        return 0.0, 0.0
    sx = 0.0
    sy = 0.0
    total = 0.0
    for row in range(max(0, int(y - window)), min(h, int(y + window) + 2)):
        dy = row + 0.5 - y
        start, stop = disc_columns(x, dy, window, w)
        for col in range(start, stop):
            dx = col + 0.5 - x
            if dx * dx + dy * dy >= window * window:
                continue
            dark = level - (image[row, col] + model[row, col])
            if dark > 0.0:  # (False for a pixel left out: NaN)
                sx += dark * dx
                sy += dark * dy
                total += dark
    if total <= 0.0:
        return 0.0, 0.0
    limit = 0.25 * r
    return min(max(sx / total, -limit), limit), min(max(sy / total, -limit), limit)


@jit
def refine_pass(image, model, centres, radius, contrast, background, residual, level, free, table, blurs, reach,
                n_bins, typical, wide, move, active, walk=False):
    """One pass over the ``active`` dots in order: each dot's own model taken out of ``model``, the dot fitted on
    ``image + model`` and its new model put in at once (Gauss-Seidel: the next dot sees it). ``wide``: radii searched
    over `WIDE` times ``typical``; else near the dot's own (`qdots.micrograph.profiles.polish_dot`), and with ``walk``
    on from where that search stopped at its end (`PINNED`). ``move``: each centre first moved to where its darkness
    balances (`centre_shift`). Updates the arrays in place."""
    sums = np.zeros(n_bins)
    counts = np.zeros(n_bins)
    rhos = np.zeros(n_bins)
    curve = np.empty(table.shape[1])
    for k in range(len(radius)):
        if not active[k]:
            continue
        x = centres[k, 0]
        y = centres[k, 1]
        blur = blurs[k]
        old_r = radius[k] if radius[k] > 0.0 else 0.0
        old_c = contrast[k]
        own = old_r > 0.0 and old_c > 0.0
        if own:  # the dot's own model out: the fit and the centre see the image plus its neighbours' models
            blur_row(table, blur / old_r, curve)
            add_disc(model, x, y, old_r, -old_c, curve)
        if move and own:
            dx, dy = centre_shift(image, model, x, y, old_r, level[k])
            x += dx
            y += dy
            centres[k, 0] = x
            centres[k, 1] = y
        dot_profile(image, model, x, y, 0.0, 0.0, table, blur, reach[k], BIN, -1, sums, counts, rhos)
        if wide or not (old_r > 0.0):
            r, big, c, error = fit_dot(sums, counts, rhos, level[k], free, table, blur, typical, WIDE[0], WIDE[1],
                                       FIT_STEP * 2.0)
        else:
            r, big, c, error = polish_dot(sums, counts, rhos, level[k], free, table, blur, old_r, POLISH_STEP,
                                          NARROW[0], NARROW[1])
            start = old_r
            walks = 0
            while walk and walks < WALKS and r > 0.0 and WIDE[0] * typical < r < WIDE[1] * typical \
                    and not (start * (NARROW[0] + PINNED) < r < start * (NARROW[1] - PINNED)):
                start = r
                r, big, c, error = polish_dot(sums, counts, rhos, level[k], free, table, blur, start, POLISH_STEP,
                                              NARROW[0], NARROW[1])
                walks += 1
        new_c = c if (r > 0.0 and c > 0.0) else 0.0
        if new_c > 0.0:
            blur_row(table, blur / r, curve)
            add_disc(model, x, y, r, new_c, curve)
        radius[k] = r
        contrast[k] = new_c
        background[k] = big
        residual[k] = error


def per_dot(value, n: int) -> np.ndarray:
    """``value`` (a number or an array of ``n``) as a float array of ``n``."""
    return np.array(np.broadcast_to(np.asarray(value, dtype=float), (n,)))


def model_image(shape, centres, radii, contrast, table, blur, threads: int | None = None) -> np.ndarray:
    """The darkening of every dot (`paint_model`) as an image of ``shape``; ``blur`` one width or one per dot. Bands of
    rows are painted side by side in ``threads`` threads (default `labrig.threads.available_threads`), each dot by each
    band it reaches: every pixel adds its dots in the same order, so the image is the same to the bit whatever their
    number."""
    model = np.zeros(shape)
    args = (np.ascontiguousarray(centres, dtype=float), np.nan_to_num(np.asarray(radii, float)),
            np.asarray(contrast, float), table, per_dot(blur, len(radii)))
    run_in_threads(lambda rows: paint_model(model, *args, *rows),
                   row_ranges(shape[0], available_threads() if threads is None else threads, least=64))
    return model


@dataclass(frozen=True)
class Refined:
    """Every dot fitted with its neighbours taken out (`refine_dots`).

    Attributes
    ----------
    centres : ndarray (N, 2)
        Each dot's centre, px (moved only when asked).
    radius, background, contrast, residual : ndarray (N,)
        The last pass's fit of each dot: radius (px, NaN where the fit failed), ``B``, ``C`` and the residual
        sum of squares.
    profiles : (ndarray, ndarray, ndarray) or None
        The neighbour-corrected profiles of the fitted dots (sums, counts and summed radii per bin).
    model : ndarray (H, W)
        The darkening of all dots as fitted.
    reach : ndarray (N,)
        How far from its centre each dot's profile reaches, px.
    """

    centres: np.ndarray
    radius: np.ndarray
    background: np.ndarray
    contrast: np.ndarray
    residual: np.ndarray
    profiles: tuple | None
    model: np.ndarray
    reach: np.ndarray


def footprint(reach: np.ndarray, radii: np.ndarray, typical: float) -> float:
    """How far from its centre a dot's fit can read or change the model, px: its profile's reach, or twice the largest
    radius a fit may take (`WIDE` times the typical one, or `NARROW` times its own) plus the quarter radius its centre
    may move, and 2 px."""
    largest = max(WIDE[1] * typical, NARROW[1] * float(np.nanmax(radii, initial=0.0)))
    return max(float(np.max(reach, initial=0.0)), 2.0 * largest + 0.25 * largest) + 2.0


def strip_schedule(centres: np.ndarray, active: np.ndarray, reach: float, threads: int) -> list[list[np.ndarray]]:
    """The active dots of one pass, in two phases of strips: the picture cut into vertical strips at least twice
    ``reach`` wide (`footprint`), the even strips first, then the odd ones. Dots in two strips of one phase are at
    least a strip apart, so their fits never touch the same pixels: each phase's strips are fitted side by side in
    threads (`labrig.threads`), and the result is the same whatever the number of threads. Returns, per phase, one
    mask of dots per thread (at most ``threads``)."""
    width = 2.0 * reach
    strip = np.floor(np.asarray(centres, dtype=float)[:, 0] / width).astype(np.int64) if len(centres) else np.zeros(0,
                                                                                                                   int)
    phases = []
    for parity in (0, 1):
        chosen = active & (strip % 2 == parity)
        if not chosen.any():
            continue
        strips = np.unique(strip[chosen])
        parts = max(1, min(threads, len(strips)))
        phases.append([chosen & np.isin(strip, strips[t::parts]) for t in range(parts)])
    return phases


def profile_reach(radii, typical: float) -> np.ndarray:
    """How far each dot's profile reaches, px: `REACH` times its radius (the typical one where larger or
    unknown) plus `REACH_PAD`."""
    radii = np.nan_to_num(np.asarray(radii, dtype=float))
    return REACH * np.maximum(radii, typical) + REACH_PAD


def refine_dots(image, centres, radii, contrast, typical: float, shape: float, blur: float | np.ndarray, level,
                passes: int = PASSES, reach=None, wide: bool = True, keep_profiles: bool = True,
                move: bool = False, active=None, threads: int | None = None, model=None) -> Refined:
    """Fit every dot again on ``image`` with its neighbours' model added back, ``passes`` times (`refine_pass`:
    the first searches radii widely, the later ones near each dot's own).

    Parameters
    ----------
    image : ndarray (H, W)
        The image, dots darker than the background; NaN where a pixel is to be left out.
    centres : ndarray (N, 2)
        ``(x, y)`` of each dot, px.
    radii, contrast : ndarray (N,)
        Each dot's first fit (NaN or 0 where it failed: such a dot is left out of the first model).
    typical : float
        The film's typical radius, px: the first pass searches [`WIDE`] times it.
    shape : float
        The profile shape ``p`` (`qdots.micrograph.profiles.profile_table`).
    blur : float or ndarray (N,)
        The blur, px: one for the film or one for each dot.
    level : ndarray (N,) or None
        The background under each dot, or None to fit it dot by dot.
    passes : int
        Passes; 0 keeps the radii given (their profiles and model are still computed).
    reach : ndarray (N,), optional
        How far each profile reaches (default `profile_reach` of ``radii``).
    wide : bool
        Whether the first pass searches widely (else every pass starts from the radii given).
    keep_profiles : bool
        Whether to return the last profiles (`Refined.profiles`, else None).
    move : bool
        Whether the passes after a wide one also move each centre (`centre_shift`; not with the background free).
    active : ndarray of bool (N,), optional
        The dots to fit (default all); the others stay as given, in the model.
    threads : int, optional
        Threads the passes run in (default: every CPU this process may use; `strip_schedule`: the result is the same
        whatever their number). 1 where the caller runs fits side by side itself.
    model : ndarray (H, W), optional
        The model of the dots as given (`model_image`, or a `Refined.model` whose dots these are), updated in place;
        default: painted here.
    """
    table = profile_table(shape)
    centres = np.array(centres, dtype=float)
    n = len(centres)
    radius = np.array(radii, dtype=float)
    contrast = np.where(np.isfinite(contrast) & (np.asarray(contrast) > 0), contrast, 0.0).astype(float)
    reach = profile_reach(radius, typical) if reach is None else reach
    n_bins = math.ceil(float(reach.max(initial=1.0)) / BIN) + 1
    base = np.ones(n) if level is None else np.array(level, dtype=float)
    background = base.copy()
    residual = np.full(n, np.inf)
    blurs = per_dot(blur, n)
    model = model_image(image.shape, centres, radius, contrast, table, blurs, threads) if model is None else model
    active = np.ones(n, dtype=bool) if active is None else np.asarray(active, dtype=bool)
    for k in range(passes):
        first = wide and k == 0
        for part in strip_schedule(centres, active, footprint(reach, radius, typical),
                                   available_threads() if threads is None else threads):
            run_in_threads(lambda chosen, first=first: refine_pass(
                image, model, centres, radius, contrast, background, residual, base, level is None, table, blurs,
                reach, n_bins, float(typical), first, move and not first and level is not None, chosen, wide), part)
    profiles = dot_profiles(image, model, centres, np.nan_to_num(radius), contrast, table, blurs, reach, n_bins,
                            BIN, -1) if keep_profiles else None
    return Refined(centres, radius, background, contrast, residual, profiles, model, reach)


def second_image(image, level_map, model, shift: tuple[int, int], threads: int | None = None) -> np.ndarray:
    """`repeat_errors`'s second image of the film: ``clean = level_map - model`` plus the residual ``image - clean``
    rolled by ``shift`` px (rows, columns) as `numpy.roll` rolls, NaN taken as 0 (`numpy.nan_to_num`), NaN wherever
    ``image`` is; in one pass over the pixels (`second_image_rows`), bands of rows side by side in ``threads`` threads
    (default `labrig.threads.available_threads`)."""
    image, level_map, model = (np.ascontiguousarray(a, dtype=float) for a in (image, level_map, model))
    h, w = image.shape
    out = np.empty((h, w))
    run_in_threads(lambda rows: second_image_rows(image, level_map, model, shift[0] % h, shift[1] % w, out, *rows),
                   row_ranges(h, available_threads() if threads is None else threads, least=64))
    return out


@jit
def second_image_rows(image, level_map, model, dy, dx, out, top, bottom):
    """Rows ``top`` to ``bottom`` - 1 of `second_image` into ``out``: ``clean = level_map - model``
    plus the residual ``image - clean`` rolled by (``dy``, ``dx``) px as `numpy.roll` rolls (NaN taken as 0 and
    infinities as the largest finite values, as `numpy.nan_to_num` does), NaN wherever ``image`` is."""
    h, w = image.shape
    largest = np.finfo(np.float64).max
    for i in range(top, bottom):
        si = (i - dy) % h
        for j in range(w):
            if image[i, j] != image[i, j]:
                out[i, j] = np.nan
                continue
            sj = (j - dx) % w
            rest = image[si, sj] - (level_map[si, sj] - model[si, sj])
            if rest != rest:
                rest = 0.0
            elif rest > largest:
                rest = largest
            elif rest < -largest:
                rest = -largest
            out[i, j] = (level_map[i, j] - model[i, j]) + rest


def repeat_errors(image, centres, refined: Refined, typical: float, shape: float, blur, level, level_map,
                  shift: tuple[int, int] = REPEAT_SHIFT) -> np.ndarray:
    """Each radius's measurement error, px, by measuring the film again on a second image of the same film:
    the fitted model plus the first image's residual (``image - (level_map - model)``: its noise, grain and
    misfit) rolled by ``shift`` px, so that each dot sees noise of the same kind but another draw of it. Two
    measurements with independent errors of deviation ``e`` differ by ``sqrt(2) e``: the error of each dot is
    its difference over ``sqrt(2)``, whose root mean square over the dots is ``e``. Up to `REPEAT_DOTS` dots,
    evenly chosen, are measured again (the others' errors are NaN): the error is a statistic of the film."""
    again = second_image(image, level_map, refined.model, shift)
    n = len(refined.radius)
    active = np.zeros(n, dtype=bool)
    active[::max(1, math.ceil(n / REPEAT_DOTS))] = True
    second = refine_dots(again, refined.centres, refined.radius, refined.contrast, typical, shape, blur, level,
                         passes=2, reach=refined.reach, wide=False, keep_profiles=False, move=True, active=active,
                         model=refined.model.copy())
    return np.where(active, np.abs(second.radius - refined.radius) / np.sqrt(2.0), np.nan)

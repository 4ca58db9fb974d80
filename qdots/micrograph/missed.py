"""Dots the segmentation missed, found where the fitted model of all dots leaves a dot's worth of darkness.

On a film without gaps the threshold has almost no background to learn from: faint dots (thin, or at the
low end of a contrast spread) fall on the bright side of it, and their pixels belong to no region. The
model of every other dot fitted (`qdots.micrograph.refine.refine_dots`) leaves each of them as a dark disc
in the residual ``level - model - image``. Missing from the model, such a dot also pulls the background the
film is settled on (`qdots.micrograph.settle`) down: lowering the level is the cheapest way for the least
squares to pay for a dark disc it cannot explain. `missed_dots` finds these discs; the detector fits them
and settles the film again.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from .discs import paint_discs
from .refine import refine_dots
from .segment import broad_blur, spaced_maxima

#: The residual is averaged over a Gaussian of SMOOTH typical radii, less its average over one of BROAD ones.
SMOOTH, BROAD = 0.4, 3.0
#: A missed dot's smoothed residual reaches at least DEPTH times the film's median contrast, and its centre
#: lies at least CLEAR[0] typical radii from every dot found and CLEAR[1] outside its fitted disc (a touching
#: neighbour's centre is about two radii away; a dot that is not quite round, or found off its centre, leaves
#: a crescent along its edge, nearer).
DEPTH, CLEAR = 0.2, (1.5, 0.3)
#: At most this share of the dots found is added (a film the model misfits everywhere is not mended here).
MOST = 0.25
#: A missed dot fits with a radius of at least ROUND typical radii (a crescent or a neck between two particles that are
#: not quite round fits as a small disc); where the background hardly shows (the settling's misfit is trimmed,
#: `qdots.micrograph.settle.TRIM`), ROUND times the median radius of the dots found, fitted with the same model,
#: background and blur: there the typical radius, of the first fits as projected spheres, reads some 15 % over the flat
#: discs' fitted radii, and a faint dot fitted on the level its absence lowered reads small too. On 15 hexagonal films of
#: 16.5 px flat discs 1-2.5 px apart, blurred by 2 px, without vacancies, the dots missed fell from 64 to 21 (28 to 10
#: on the one with 1 px gaps, whose median diameter went from -6.4 % to -3.5 %), none more found falsely; the others'
#: median diameters moved within the settling's jitter (-2.4 to +0.8 %). Measured against the dots found on every film,
#: the real films of the development half gained 1-2 false dots on 4 of them (precision 0.97 -> 0.96, 0.95 -> 0.93),
#: so where the background shows the typical radius is kept. None is sought when the typical radius is over LARGEST of
#: the image's shorter side (a handful of dots at most, and the search's footprint would be the image).
ROUND, LARGEST = 0.8, 0.125
#: Dots of a typical radius of COARSE_RADIUS px or more are sought at half the resolution.
COARSE_RADIUS = 4.0


def most_missed(n_dots: int, typical: float, shape) -> int:
    """The most faint dots `missed_dots` adds to ``n_dots`` dots found of a typical radius ``typical`` px on an image of
    ``shape``: `MOST` of them and one, or none where dots that big leave no room to search (`LARGEST`)."""
    return int(MOST * n_dots) + 1 if 0 < typical <= LARGEST * min(shape) else 0


def missed_dots(image, refined, level_map, typical: float, shape: float, blur, noise: float,
                trimmed: bool = False) -> np.ndarray:
    """Centres (x, y), px, of the dark discs the model leaves unexplained (see the module docstring), each fitted
    on the image with every dot's model added back and kept when it fits as a dot: a radius of at least `ROUND`
    typical radii, or, where the background hardly shows (``trimmed``), `ROUND` times the median radius of the
    dots found.

    Parameters
    ----------
    image : ndarray (H, W)
        The image the dots were fitted on (dots dark; NaN where left out).
    refined : qdots.micrograph.refine.Refined
        The dots found, fitted with their neighbours taken out.
    level_map : ndarray (H, W)
        The background.
    typical : float
        The film's typical radius, px.
    shape : float
        The profile shape ``p``.
    blur : float or ndarray (N,)
        The blur, px: one for the film or one for each dot found.
    noise : float
        The pixel noise's standard deviation, in the image's units.
    trimmed : bool
        Whether the film's settling trimmed its misfit (`qdots.micrograph.settle.settle_profile`): its background
        hardly shows.
    """
    ok = np.isfinite(refined.contrast) & (refined.contrast > 0)
    most = most_missed(len(refined.radius), typical, image.shape)
    if not ok.any() or not most:
        return np.zeros((0, 2))
    residual = np.nan_to_num(level_map - refined.model - image)
    # searched at half the resolution where dots are large enough (`COARSE_RADIUS`): the smoothed residual varies over
    # a dot's size
    k = 2 if typical >= COARSE_RADIUS else 1
    h, w = (side // k * k for side in residual.shape)
    residual = residual[:h, :w].reshape(h // k, k, w // k, k).mean(axis=(1, 3))
    smooth = ndimage.gaussian_filter(residual, SMOOTH * typical / k) - broad_blur(residual, BROAD * typical / k)
    # the smoothed noise: white noise averaged over a Gaussian of width w keeps 1 / (2 sqrt(pi) w) of its deviation
    floor = max(DEPTH * float(np.median(refined.contrast[ok])),
                6.0 * noise / (2.0 * math.sqrt(math.pi) * SMOOTH * typical))
    clear = np.zeros(residual.shape, dtype=np.bool_)
    paint_discs(clear, np.ascontiguousarray(refined.centres / k, dtype=float),
                np.maximum(np.nan_to_num(refined.radius) + CLEAR[1] * typical, CLEAR[0] * typical) / k)
    clear = ~clear
    margin = int(math.ceil(typical / k))  # a dot the edge cuts is left to the segmentation
    clear[:margin], clear[-margin:], clear[:, :margin], clear[:, -margin:] = False, False, False, False
    peaks = spaced_maxima(np.where(clear, smooth, -np.inf), max(2, round(1.5 * typical / k)), floor)
    peaks = peaks[:most]
    if not len(peaks):
        return np.zeros((0, 2))
    extra = (peaks[:, ::-1] + 0.5) * k
    n, more = len(refined.radius), len(extra)
    rows, cols = (np.clip(extra[:, i].astype(int), 0, image.shape[1 - i] - 1) for i in (1, 0))
    blurs = np.broadcast_to(np.asarray(blur, dtype=float), (n,))
    trial = refine_dots(image, np.vstack([refined.centres, extra]), np.concatenate([refined.radius, np.full(more, np.nan)]),
                        np.concatenate([refined.contrast, np.zeros(more)]), typical, shape,
                        np.concatenate([blurs, np.full(more, float(np.median(blurs)))]),
                        np.concatenate([refined.background, level_map[rows, cols]]), passes=2, keep_profiles=False,
                        active=np.arange(n + more) >= n, model=refined.model.copy())  # the new dots start with none
    fitted = refined.radius[ok & np.isfinite(refined.radius)]
    least = ROUND * (float(np.median(fitted)) if trimmed and fitted.size else typical)
    return extra[trial.radius[n:] >= least]

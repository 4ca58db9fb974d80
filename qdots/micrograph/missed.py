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

from .segment import spaced_maxima

#: The residual is averaged over a Gaussian of SMOOTH typical radii, less its average over one of BROAD ones.
SMOOTH, BROAD = 0.4, 3.0
#: A missed dot's smoothed residual reaches at least DEPTH times the film's median contrast, and its centre
#: lies at least CLEAR typical radii from every dot found (a neighbour's centre is two radii away when they
#: touch; a dot found off its centre leaves a crescent, nearer).
DEPTH, CLEAR = 0.2, 1.5
#: At most this share of the dots found is added (a film the model misfits everywhere is not mended here).
MOST = 0.25


def missed_dots(image, level_map, model, centres, contrast, typical: float, noise: float) -> np.ndarray:
    """Centres (x, y), px, of the dark discs the model leaves unexplained (see the module docstring).

    Parameters
    ----------
    image : ndarray (H, W)
        The image the dots were fitted on (dots dark; NaN where left out).
    level_map, model : ndarray (H, W)
        The background and the darkening of all dots fitted (`qdots.micrograph.refine.Refined.model`).
    centres : ndarray (N, 2)
        The dots found, px.
    contrast : ndarray (N,)
        Their fitted contrast ``C`` (in the image's units).
    typical : float
        The film's typical radius, px.
    noise : float
        The pixel noise's standard deviation, in the image's units.
    """
    ok = np.isfinite(contrast) & (contrast > 0)
    if not ok.any() or typical <= 0:
        return np.zeros((0, 2))
    residual = np.nan_to_num(level_map - model - image)
    smooth = ndimage.gaussian_filter(residual, SMOOTH * typical) - ndimage.gaussian_filter(residual,
                                                                                         BROAD * typical)
    # the smoothed noise: white noise averaged over a Gaussian of width w keeps 1 / (2 sqrt(pi) w) of its deviation
    floor = max(DEPTH * float(np.median(contrast[ok])), 6.0 * noise / (2.0 * math.sqrt(math.pi) * SMOOTH * typical))
    h, w = image.shape
    found = np.ones((h, w), dtype=bool)
    where = np.round(centres - 0.5).astype(int)
    inside = (where[:, 0] >= 0) & (where[:, 0] < w) & (where[:, 1] >= 0) & (where[:, 1] < h)
    found[where[inside, 1], where[inside, 0]] = False
    clear = ndimage.distance_transform_edt(found) >= CLEAR * typical
    margin = int(math.ceil(typical))  # a dot the edge cuts is left to the segmentation
    clear[:margin], clear[-margin:], clear[:, :margin], clear[:, -margin:] = False, False, False, False
    peaks = spaced_maxima(np.where(clear, smooth, -np.inf), max(2, round(1.5 * typical)), floor)
    peaks = peaks[: int(MOST * len(centres)) + 1]
    return peaks[:, ::-1] + 0.5 if len(peaks) else np.zeros((0, 2))


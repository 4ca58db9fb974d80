"""Which phase of a grey picture the dots are: the way its strongest edges bend (`edge_curvature`) and, without
edges, the skew of its blobs' Laplacian of Gaussian (`blob_skewness`); `decide_polarity` weighs them and says how.

Read by `qdots.micrograph.detect` on the middle of a picture (`middle_window`).
"""

from __future__ import annotations

import math
from typing import cast

import numpy as np
from scipy import ndimage

from labrig.threads import run_in_threads, run_tasks

#: `edge_curvature` counts edges whose gradient is at least EDGE_NOISE times the noise's (its standard deviation)
#: and decides the polarity only from at least MIN_EDGES of them, read at the smoothing widths EDGE_WIDTHS (px) and
#: the blobs' own. Measured on 20 real micrographs: at 1 px three films of dark particles on a grainy support or with
#: pores inside read light (37-45 % of the edges around the darker side), at 4 px 58-80 %, as every other film there.
EDGE_NOISE, MIN_EDGES, EDGE_WIDTHS = 3.0, 50, (1.0, 2.0, 4.0)
#: The polarity (`edge_curvature`, `blob_skewness`) is read on the middle LOOK_SIDE x LOOK_SIDE px of a larger
#: picture: a million pixels hold thousands of dots' edges, and the filters cost in proportion to the pixels.
LOOK_SIDE = 1024


def blob_skewness(image: np.ndarray, ignore: np.ndarray, noise: float) -> tuple[float, float]:
    """Which way the blobs of ``image`` point, at their own scale: the skewness of its scale-normalised Laplacian
    of Gaussian (``sigma^2`` times the Laplacian, high at a dark blob's centre) at the scale where the response's
    variance, less what the pixel noise (``noise``, white) gives it, is largest. Round objects of one size, dots,
    respond strongly at their centres; the gaps between them (narrow, branched, of no one size) and the vacancies of
    a dense film respond more weakly: dark dots skew the response positive, light ones negative, on sparse, dense
    and superlattice films alike, and exactly opposite on the inverted image.

    Scales ``sigma`` from 1 px, 1.25 apart, to an eighth of the image's shorter side; above 4 px the image is
    block-averaged by ``floor(sigma / 2)`` first. Ignored pixels are set to the median and left out of the moments,
    as is a border of two ``sigma``. Returns the skewness and the scale ``sigma``, px (0 and 0 with no structure
    above the noise)."""
    filled = np.where(ignore, float(np.median(image[~ignore])), image)
    sigmas: list[float] = []
    while (sigmas[-1] * 1.25 if sigmas else 1.0) <= min(image.shape) / 8.0:
        sigmas.append(sigmas[-1] * 1.25 if sigmas else 1.0)

    def moments(sigma: float) -> tuple[float, float, float]:
        """The response's variance less the noise's, its variance and third moment at ``sigma`` (0s: too few px)."""
        block = max(1, int(sigma / 2.0)) if sigma >= 4.0 else 1
        h, w = (side // block * block for side in image.shape)
        shrunk = filled[:h, :w].reshape(h // block, block, w // block, block).mean(axis=(1, 3))
        hidden = cast(np.ndarray, ignore[:h, :w].reshape(h // block, block, w // block, block).any(axis=(1, 3)))
        s = sigma / block
        response = s * s * ndimage.gaussian_laplace(shrunk, s, mode="nearest")
        impulse = np.zeros((2 * math.ceil(4 * s) + 1,) * 2)
        impulse[impulse.shape[0] // 2, impulse.shape[1] // 2] = 1.0
        gain = float(np.sum((s * s * ndimage.gaussian_laplace(impulse, s, mode="constant")) ** 2))
        edge = math.ceil(2.0 * s)
        values = response[edge:-edge, edge:-edge][~hidden[edge:-edge, edge:-edge]]
        if values.size < 16:
            return 0.0, 0.0, 0.0
        centred = values - values.mean()
        variance = float(np.mean(centred**2))
        return variance - gain * (noise / block) ** 2, variance, float(np.mean(centred**3))

    best, chosen = (0.0, 0.0, 0.0), 0.0
    for sigma, found in zip(sigmas, run_tasks([lambda sigma=sigma: moments(sigma) for sigma in sigmas])):
        if found[0] > best[0]:  # the first scale of the largest excess (the scales computed side by side in threads)
            best, chosen = found, sigma
    excess, variance, third = best
    return (third / variance**1.5 if excess > 0 else 0.0), chosen


def middle_window(shape, side: int = LOOK_SIDE) -> tuple[slice, slice]:
    """The middle ``side`` x ``side`` px of an image of ``shape`` (all of a side shorter than ``side``)."""
    return cast(tuple[slice, slice],
                tuple(slice(max(0, (n - side) // 2), max(0, (n - side) // 2) + min(n, side)) for n in shape))


def edge_curvature(image: np.ndarray, ignore: np.ndarray, noise: float, scale: float) -> tuple[float, int]:
    """Which way the edges of ``image`` bend: the share of its strongest edges whose isophote curves around the
    darker side, and how many edges were counted.

    A dot's edge is an arc around it; in a dense film, the vacancies and the gaps between dots are bounded by the
    same arcs, bent the same way, and only the few pixels where two dots meet bend the other. The isophote curvature
    ``div(grad I / |grad I|)`` (Gaussian derivatives at ``s`` px) is positive where the edge curves around a darker
    inside, whatever the dots' profile (flat discs as well as projected spheres). It is read at ``s`` of
    `EDGE_WIDTHS` (and ``scale / 4`` within [1, 3] px, ``scale`` the blobs' scale of `blob_skewness`), and the most
    decided width is kept: at 1 px a support's grain or a particle's inner texture (pores, lattice fringes) can hold
    the steepest edges of a sparse film, at 4 px they are smoothed away and the dots' arcs remain. The edges counted
    are the tenth of the pixels with the steepest gradient, and no less steep than `EDGE_NOISE` times the gradient
    the pixel noise (``noise``) gives, a border of 3 px and the ignored pixels left out. Returns the share (0.5 and 0
    with under `MIN_EDGES` edges)."""
    widths = [s for s in sorted({float(np.clip(scale / 4.0, 1.0, 3.0)), *EDGE_WIDTHS}) if min(image.shape) >= 8 * s]
    best = (0.5, 0)
    for bent, n in run_in_threads(lambda s: _edge_bend(image, ignore, noise, s), widths) if widths else []:
        if n and abs(bent - 0.5) > abs(best[0] - 0.5):
            best = (bent, n)
    return best


def _edge_bend(image: np.ndarray, ignore: np.ndarray, noise: float, s: float) -> tuple[float, int]:
    """`edge_curvature` at one width ``s``, px."""
    # `scipy.ndimage.gaussian_filter`'s derivatives, axis by axis as it filters, the down passes shared
    down = [ndimage.gaussian_filter1d(image, s, axis=0, order=order, mode="nearest") for order in (0, 1, 2)]
    x, y, xx, yy, xy = (ndimage.gaussian_filter1d(down[first], s, axis=1, order=second, mode="nearest")
                        for first, second in ((0, 1), (1, 0), (0, 2), (2, 0), (1, 1)))
    impulse = np.zeros((2 * math.ceil(4 * s) + 1,) * 2)
    impulse[impulse.shape[0] // 2, impulse.shape[1] // 2] = 1.0
    gain = float(np.sum(ndimage.gaussian_filter(impulse, s, order=(0, 1), mode="constant") ** 2))
    steep = x * x + y * y
    keep = ~ignore
    border = max(3, math.ceil(2 * s))
    keep[:border], keep[-border:], keep[:, :border], keep[:, -border:] = False, False, False, False
    if not keep.any():
        return 0.5, 0
    edges = keep & (steep >= max(float(np.quantile(steep[keep], 0.9)), (EDGE_NOISE * noise) ** 2 * gain))
    n = int(np.count_nonzero(edges))
    if n < MIN_EDGES:
        return 0.5, 0
    bend = (xx * y * y - 2.0 * xy * x * y + yy * x * x)[edges]
    return float(np.mean(bend > 0.0)), n


def decide_polarity(bent: float, edges: int, skew: float, sigma: float, polarity: str) -> tuple[bool, str]:
    """Whether the dots are the dark phase, and why: given, or (``"auto"``) the way the image's edges bend
    (`edge_curvature`: ``bent``, the share of ``edges`` edges that curve around the darker side); without edges, the
    sign of ``skew``, the skewness of the image's Laplacian of Gaussian at its blobs' scale ``sigma`` (px,
    `blob_skewness`); dark, as bright field shows dots, when the image has no structure above its noise."""
    if polarity != "auto":
        return polarity == "dark", f"{polarity} dots (given)"
    if edges:
        dark = bent >= 0.5
        return dark, (f"{'dark' if dark else 'light'} dots (automatic: {100 * max(bent, 1 - bent):.0f} % of "
                      f"{edges} edge pixels curve around the {'darker' if dark else 'lighter'} side)")
    dark = skew >= 0.0
    return dark, (f"{'dark' if dark else 'light'} dots (automatic: the Laplacian of Gaussian at the blobs' scale, "
                  f"{sigma:.1f} px, is skewed by {skew:+.2f} toward {'dark' if dark else 'light'} blobs)")

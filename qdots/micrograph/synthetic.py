"""Synthetic micrographs of known boards: the ground truth `detect_dots` is measured against.

`render_micrograph` draws dots as a bright-field TEM shows them: each dot removes a share
``c_i (1 - rho^2 / r_i^2)^p`` of the local illumination (``p = 1/2``: a projected sphere, the
default; ``p = 0``: a flat disc), the contrast ``c_i`` spread dot to dot (and, for uneven contrast,
across the film), the illumination falling across the image, the picture blurred (unevenly, for uneven
focus), the support's grain and noise added. `dense_board`, `superlattice_board` and `sparse_board` give
touching films, square and hexagonal superlattices with ligand gaps, and scattered dots of a chosen size
spread.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage

from labrig.validate import InputError, choice, count, generator, real

from ..geometry import clashing_pairs, pairs_within
from .film import complete_neighbourhood, film_metrics, film_state

#: Largest synthetic image side, px.
MAX_SIDE = 8192
#: Lattices of `superlattice_board`, and its most sites.
LATTICES = ("hexagonal", "square")
MAX_SITES = 4_000_000


def dense_board(width: float, height: float, mean_diameter: float, sigma: float, seed=0, vacancies: float = 0.1
                ) -> tuple[np.ndarray, np.ndarray]:
    """A touching film: a hexagonal lattice of spacing 1.02 mean diameters, ``vacancies`` of its sites empty,
    diameters drawn from N(mean, sigma mean) and cut to [0.5 mean, spacing], each dot shifted at random
    within its site (so no two overlap and many touch). Returns centres (N, 2) and diameters (N,), px."""
    rng = generator("seed", seed)
    spacing = 1.02 * mean_diameter
    rows = int(height / (spacing * math.sqrt(3) / 2)) + 2
    cols = int(width / spacing) + 2
    j, i = np.mgrid[0:rows, 0:cols]
    x = (i + 0.5 * (j % 2)) * spacing
    y = j * spacing * math.sqrt(3) / 2
    centres = np.column_stack([x.ravel(), y.ravel()])
    centres = centres[rng.random(len(centres)) >= vacancies]
    d = np.clip(rng.normal(mean_diameter, sigma * mean_diameter, len(centres)), 0.5 * mean_diameter, spacing)
    room = 0.5 * (spacing - d)
    angle = rng.uniform(0, 2 * math.pi, len(centres))
    shift = room * rng.random(len(centres))
    centres = centres + np.column_stack([np.cos(angle), np.sin(angle)]) * shift[:, None]
    inside = (centres[:, 0] > -0.5 * d) & (centres[:, 0] < width + 0.5 * d) & (centres[:, 1] > -0.5 * d) & (
        centres[:, 1] < height + 0.5 * d)
    return centres[inside], d[inside]


def sparse_board(width: float, height: float, mean_diameter: float, sigma: float, coverage: float = 0.15, seed=0,
                 gap: float = 0.3) -> tuple[np.ndarray, np.ndarray]:
    """Scattered dots: random positions, at least ``gap`` mean diameters apart surface to surface, until
    ``coverage`` of the area is covered (or no more fit). Returns centres (N, 2) and diameters (N,), px.

    Candidates are drawn at once and taken in order, each unless it clashes with one taken before
    (`qdots.geometry.clashing_pairs`)."""
    rng = generator("seed", seed)
    target = coverage * width * height / (math.pi * mean_diameter**2 / 4)
    tries = count("dots", int(20 * target) + 20, 1, 10_000_000)
    x = rng.uniform(0, width, (tries, 2)) * [1.0, height / width]
    d = np.clip(rng.normal(mean_diameter, sigma * mean_diameter, tries), 0.5 * mean_diameter, 1.5 * mean_diameter)
    a, b = clashing_pairs(x, 0.5 * d, gap * mean_diameter)
    earlier: list[list[int]] = [[] for _ in range(tries)]  # the clashing candidates drawn before each one
    for first, second in zip(np.minimum(a, b), np.maximum(a, b)):
        earlier[second].append(first)
    taken = np.zeros(tries, dtype=bool)
    for k in range(tries):
        if taken.sum() >= target:
            break
        taken[k] = not any(taken[m] for m in earlier[k])
    return x[taken], d[taken]


def superlattice_board(width: float, height: float, mean_diameter: float, sigma: float, gap: float,
                       lattice: str = "hexagonal", seed=0, jitter: float = 0.02, vacancies: float = 0.0
                       ) -> tuple[np.ndarray, np.ndarray]:
    """An ordered film: a square or hexagonal lattice of spacing ``mean_diameter + gap`` (px; ``gap`` the ligand
    shell between neighbours, 0 for touching dots), diameters drawn from N(mean, sigma mean) cut at 2.5 SD,
    each site shifted by ``jitter`` spacings at random and ``vacancies`` of them empty; dots closer than
    a tenth of ``gap`` (surface to surface) are pushed apart until none is (so no two overlap: larger dots
    shift their neighbours, as in a real superlattice). Returns centres (N, 2) and diameters (N,), px."""

    lattice = choice("lattice", lattice, LATTICES)
    real("mean_diameter", mean_diameter, 0.0, MAX_SIDE, low_open=True)
    real("gap", gap, 0.0, mean_diameter)
    real("sigma", sigma, 0.0, 0.3)
    real("jitter", jitter, 0.0, 0.5)
    real("vacancies", vacancies, 0.0, 1.0, high_open=True)
    rng = generator("seed", seed)
    spacing = mean_diameter + gap
    row = spacing * math.sqrt(3) / 2 if lattice == "hexagonal" else spacing
    rows = count("rows", int(height / row) + 3, 1, MAX_SIDE)
    cols = count("columns", int(width / spacing) + 3, 1, MAX_SIDE)
    count("lattice sites", rows * cols, 1, MAX_SITES)
    j, i = np.mgrid[-1:rows - 1, -1:cols - 1]
    x = (i + (0.5 * (j % 2) if lattice == "hexagonal" else 0.0)) * spacing
    centres = np.column_stack([x.ravel(), (j * row).ravel()]).astype(float)
    keep = rng.random(len(centres)) >= vacancies
    centres = centres[keep] + jitter * spacing * rng.standard_normal((int(keep.sum()), 2))
    d = mean_diameter * (1.0 + sigma * np.clip(rng.standard_normal(len(centres)), -2.5, 2.5))
    clearance = 0.1 * gap
    for _ in range(500):  # push overlapping pairs apart, half the overlap each, until none is left
        first, second = pairs_within(centres[:, 0], centres[:, 1], float(d.max() + clearance))
        delta = centres[second] - centres[first]
        distance = np.hypot(*delta.T)
        short = 0.5 * (d[first] + d[second]) + clearance - distance
        bad = short > 1e-6
        if not bad.any():
            break
        push = (0.5 * short[bad] + 1e-4)[:, None] * delta[bad] / np.maximum(distance[bad], 1e-9)[:, None]
        np.add.at(centres, first[bad], -push)
        np.add.at(centres, second[bad], push)
    inside = (np.abs(centres[:, 0] - 0.5 * width) < 0.5 * (width + d)) & (
        np.abs(centres[:, 1] - 0.5 * height) < 0.5 * (height + d))
    return centres[inside], d[inside]


def render_micrograph(centres, diameters, shape: tuple[int, int], *, profile: float = 0.5, contrast: float = 0.6,
                      contrast_spread: float = 0.12, blur=1.0, illumination: float = 0.3,
                      noise: float = 0.05, dark: bool = True, contrast_tilt: float = 0.0, texture: float = 0.0,
                      seed=0) -> np.ndarray:
    """A grey micrograph of dots at ``centres`` ((x, y) = (column, row), px) with ``diameters`` (px).

    Parameters
    ----------
    shape : (int, int)
        ``(H, W)``, px (each side in [2, `MAX_SIDE`]).
    profile : float
        ``p`` of the dots' absorption profile ``(1 - rho^2/r^2)^p``: 0.5 a projected sphere, 0 a flat disc.
    contrast : float
        Mean share of the light a dot's centre removes, in (0, 1).
    contrast_spread : float
        Relative standard deviation of the contrast from dot to dot (the issue's 10-15 %).
    blur : float or (float, float)
        Gaussian blur, px; a pair for uneven focus: the blur goes from the first at the left edge to the
        second at the right (the picture blended from the two blurs, column by column).
    illumination : float
        Fall of the illumination from one corner to the opposite one, as a share of its maximum.
    noise : float
        Standard deviation of the additive Gaussian noise, in units of the mean background level.
    dark : bool
        Dark dots on a light background (bright field), else light on dark.
    contrast_tilt : float
        Uneven contrast: the dots' contrast is scaled by ``1 - contrast_tilt`` at the top edge, rising linearly
        to ``1 + contrast_tilt`` at the bottom (thickness or orientation across the film).
    texture : float
        The support's grain (amorphous carbon): noise correlated over about 1.5 px, its standard deviation
        in units of the mean background level.

    Returns
    -------
    ndarray, shape (H, W), float64
    """
    h, w = (count("shape", v, 2, MAX_SIDE) for v in shape)
    real("contrast", contrast, 0.0, 1.0, low_open=True, high_open=True)
    real("noise", noise, 0.0, 10.0)
    real("texture", texture, 0.0, 10.0)
    real("contrast_tilt", contrast_tilt, 0.0, 1.0, high_open=True)
    blurs = tuple(real("blur", b, 0.0, 50.0) for b in np.atleast_1d(blur))
    if len(blurs) not in (1, 2):
        raise InputError(f"blur must be one width or a pair (left, right), got {len(blurs)} values")
    rng = generator("seed", seed)
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    radii = 0.5 * np.asarray(diameters, dtype=float).reshape(-1)
    if len(radii) != len(centres):
        raise InputError(f"centres and diameters differ in length: {len(centres)} and {len(radii)}")
    tilt = 1.0 + contrast_tilt * (2.0 * np.clip(centres[:, 1] / max(h, 1), 0.0, 1.0) - 1.0)
    c = np.clip(contrast * tilt * (1.0 + contrast_spread * rng.standard_normal(len(radii))), 0.05, 0.95)
    absorbed = np.zeros((h, w))
    sub = 4  # 4 x 4 samples per pixel
    offsets = (np.arange(sub) + 0.5) / sub
    for (x, y), r, ci in zip(centres, radii, c):
        r0, r1 = max(0, int(y - r)), min(h, math.ceil(y + r) + 1)
        c0, c1 = max(0, int(x - r)), min(w, math.ceil(x + r) + 1)
        if r0 >= r1 or c0 >= c1:
            continue
        yy = (np.arange(r0, r1)[:, None] + offsets[None, :]).reshape(-1)
        xx = (np.arange(c0, c1)[:, None] + offsets[None, :]).reshape(-1)
        u2 = ((xx[None, :] - x) ** 2 + (yy[:, None] - y) ** 2) / (r * r)
        f = np.where(u2 < 1.0, np.maximum(1.0 - u2, 0.0) ** profile if profile > 0 else 1.0, 0.0)
        f = f.reshape(r1 - r0, sub, c1 - c0, sub).mean(axis=(1, 3))
        absorbed[r0:r1, c0:c1] = np.maximum(absorbed[r0:r1, c0:c1], ci * f)
    yy, xx = np.mgrid[0:h, 0:w]
    light = 1.0 - illumination * (xx / max(w - 1, 1) + yy / max(h - 1, 1)) / 2.0
    image = light * (1.0 - absorbed)
    if not dark:
        image = light * (0.2 + absorbed)
    if len(blurs) == 1:
        image = ndimage.gaussian_filter(image, blurs[0]) if blurs[0] > 0 else image
    else:
        share = np.linspace(0.0, 1.0, w)[None, :]
        image = ((1.0 - share) * ndimage.gaussian_filter(image, blurs[0])
                 + share * ndimage.gaussian_filter(image, blurs[1]))
    if texture > 0:
        grain = ndimage.gaussian_filter(rng.standard_normal((h, w)), 1.5)
        image = image + texture * float(np.mean(light)) * grain / max(float(grain.std()), 1e-12)
    return image + noise * float(np.mean(light)) * rng.standard_normal((h, w))


def score_detection(detection, centres, diameters) -> dict:
    """A detection against the true dots it was rendered from.

    A true dot is found when a detection lies within 0.3 of its diameter; a detection is right when a
    true dot lies within 0.3 of that dot's diameter. Sizes and positions are compared over the true dots
    the image edge does not cut (nor the detector flags as cut); the interior fraction of the detected
    film against the true board's, both with `qdots.micrograph.film.complete_neighbourhood`'s edge rule.

    Returns
    -------
    dict
        ``recall``, ``precision`` (of the uncut detections), ``diameter`` (median ``|d - d_true| / d_true``),
        ``bias`` (median of the signed error), ``position`` (median centre distance, px), ``interior``
        (detected minus true interior fraction) and ``true_interior``.
    """
    from scipy.spatial import cKDTree  # nearest neighbours between two sets (no pair search)

    h, w = detection.image_shape
    inside = ((centres[:, 0] - diameters / 2 >= 0) & (centres[:, 1] - diameters / 2 >= 0)
              & (centres[:, 0] + diameters / 2 <= w) & (centres[:, 1] + diameters / 2 <= h))
    distance, nearest = cKDTree(detection.centres).query(centres)
    found = distance < 0.3 * diameters
    back, truth = cKDTree(centres).query(detection.centres)
    both = found & inside & ~detection.cut[nearest]
    size = np.abs(detection.diameters[nearest[both]] - diameters[both]) / diameters[both]
    true_state = film_state(centres, diameters, (h, w))
    measured_state = film_state(detection.centres, detection.diameters, (h, w))
    window = (0.0, 0.0, float(w), float(h))
    true_cut = ~inside
    true_interior = film_metrics(true_state, ~true_cut, complete_neighbourhood(true_state, window))["interior_fraction"]
    interior = film_metrics(measured_state, ~detection.cut,
                            complete_neighbourhood(measured_state, window))["interior_fraction"]
    return {"recall": float(found[inside].mean()),
            "precision": float(np.mean((back < 0.3 * diameters[truth])[~detection.cut])),
            "diameter": float(np.median(size)), "bias": float(np.median((detection.diameters[nearest[both]]
                                                                         - diameters[both]) / diameters[both])),
            "position": float(np.median(distance[both])), "interior": interior - true_interior,
            "true_interior": true_interior}

"""The shape, blur and background of a film's dots, settled on the fits with the neighbours taken out.

On a dense film the background ``B`` cannot be left free dot by dot: raising every dot's background,
contrast and radius together fits almost as well, and fits dot by dot drift along that direction. So
``B`` is a field: the lone fits' backgrounds smoothed over several dots (`smooth_level`), times a factor
``k``. The factor, the blur and the profile shape are those that leave the least squared difference
between the image and the model of all dots over a sample of the film, its gaps and holes included
(`settle_profile`), where the true film has its minimum. Uneven focus: the blur is then measured dot by
dot (the residual of each dot's fit at a few blurs) and smoothed over the film (`blur_map`).
"""

from __future__ import annotations

import math

import numpy as np

from .profiles import PROFILES, central_curvature, predicted_curvature
from .refine import PASSES, REACH, REACH_PAD, WIDE, profile_reach, refine_dots

#: The background field: the lone fits' backgrounds averaged over LEVEL_WIDTH typical radii (`smooth_level`),
#: times a factor searched in LEVEL_RANGE, first at LEVEL_SCAN (on a dense film the lone fits see the narrow
#: gaps as background, far darker than it).
LEVEL_WIDTH, LEVEL_RANGE = 6.0, (0.8, 2.5)
LEVEL_SCAN = (0.9, 1.0, 1.1, 1.25, 1.45, 1.7, 2.0)
#: Shapes ``p`` tried by ``profile="auto"`` (0 a flat disc, 0.5 a projected sphere); another than the sphere is
#: taken only when its predicted central curvature matches the measured one by CURVATURE_MARGIN more.
SHAPES, CURVATURE_MARGIN = (0.0, 0.5), 0.05
#: Blurs searched, px (the detector smooths every image by 1 px first, so none is under 1 px); the first one
#: tried (also the blur of the lone fits that start everything).
BLURS, FIRST_BLUR = (1.0, 5.0), 1.5
#: The first 3 x 3 pattern of blurs (px) and background factors: its steps.
FOCUS_STEP = (0.3, 0.04)
#: Most dots the shape, blur and background are settled on.
SAMPLE = 100
#: Passes of each fit while settling (from a state fitted at the middle of the pattern).
SAMPLE_PASSES = 2


def choice_sample(centres, whole, typical: float):
    """Up to `SAMPLE` whole dots (indices ``whole``) nearest the middle of the film, the dots near enough to them
    to touch their profiles (``members``, sorted) and the sample's places among the members."""
    if len(whole) == 0:
        whole = np.arange(len(centres))
    middle = np.median(centres[whole], axis=0)
    distance = np.hypot(*(centres - middle).T)
    sample = whole[np.argsort(distance[whole], kind="stable")[:SAMPLE]]
    margin = REACH * WIDE[1] * typical + REACH_PAD + 2.0 * WIDE[1] * typical
    members = np.flatnonzero(distance <= distance[sample].max() + margin)
    return sample, members, np.searchsorted(members, sample)


def total_residual(residual) -> float:
    """Sum of the finite residuals (inf when none is)."""
    finite = np.isfinite(residual)
    return float(np.sum(residual[finite])) if finite.any() else math.inf


def smooth_level(centres, background, typical: float, shape) -> tuple[np.ndarray, np.ndarray]:
    """The dots' backgrounds averaged over their neighbourhood (a Gaussian of `LEVEL_WIDTH` typical radii, on a
    grid of one typical radius): its value at each centre, and the map of it over an image of ``shape``."""
    from scipy import ndimage

    cell = max(typical, 1.0)
    grid = (int(shape[0] / cell) + 1, int(shape[1] / cell) + 1)
    rows = np.clip((centres[:, 1] / cell).astype(int), 0, grid[0] - 1)
    cols = np.clip((centres[:, 0] / cell).astype(int), 0, grid[1] - 1)
    ok = np.isfinite(background)
    total, weight = np.zeros(grid), np.zeros(grid)
    np.add.at(total, (rows[ok], cols[ok]), background[ok])
    np.add.at(weight, (rows[ok], cols[ok]), 1.0)
    total = ndimage.gaussian_filter(total, LEVEL_WIDTH, mode="nearest")
    weight = ndimage.gaussian_filter(weight, LEVEL_WIDTH, mode="nearest")
    fallback = float(np.median(background[ok])) if ok.any() else 1.0
    with np.errstate(invalid="ignore", divide="ignore"):
        level = np.where(weight > 1e-6, total / weight, fallback)
    y = np.clip((np.arange(shape[0]) + 0.5) / cell - 0.5, 0, grid[0] - 1)
    x = np.clip((np.arange(shape[1]) + 0.5) / cell - 0.5, 0, grid[1] - 1)
    full = ndimage.map_coordinates(level, np.meshgrid(y, x, indexing="ij"), order=1, mode="nearest")
    return full[np.clip(centres[:, 1].astype(int), 0, shape[0] - 1), np.clip(centres[:, 0].astype(int), 0,
                                                                             shape[1] - 1)], full


def quadratic_minimum(points: np.ndarray, values: np.ndarray, low, high) -> tuple[np.ndarray, float]:
    """Where the quadratic surface fitted (least squares) to ``values`` at 2-D ``points`` is least, kept within
    the box [low, high], and its value there; the best point when the surface has no minimum."""
    x, y = points.T
    design = np.column_stack([np.ones_like(x), x, y, x * x, y * y, x * y])
    a = np.linalg.lstsq(design, values, rcond=None)[0]
    hessian = np.array([[2 * a[3], a[5]], [a[5], 2 * a[4]]])
    if np.all(np.linalg.eigvalsh(hessian) > 0):
        u, v = np.clip(np.linalg.solve(hessian, -a[1:3]), low, high)
        return np.array([u, v]), float(a @ [1.0, u, v, u * u, v * v, u * v])
    best = int(np.argmin(values))
    return points[best], float(values[best])


def settle_profile(image, centres, radii, contrast, background, typical: float, whole, profile: str
                   ) -> tuple[float, float, np.ndarray, np.ndarray, str]:
    """The dots' shape ``p``, the blur (px) and the background under each dot and everywhere, settled on the sample of
    `choice_sample`: those that leave the least squared difference between the image and the model of all
    dots (`refine_dots`, every dot fitted with the background fixed) over the sample's pixels.

    The background is ``k`` times the lone fits' ``background`` smoothed (`smooth_level`). Each candidate shape
    (`SHAPES` for ``profile="auto"``, else the one given) is fitted at 3 x 3 blurs and ``k`` `FOCUS_STEP` apart
    around `FIRST_BLUR` and the best ``k`` of `LEVEL_SCAN`, from a state fitted at the middle one, and again
    around the minimum of the quadratic surface through the nine residuals (`quadratic_minimum`) at half the
    steps. For ``profile="auto"`` the shape is then the one whose predicted central curvature
    (`qdots.micrograph.profiles.predicted_curvature`, at its blur) is nearest the curvature measured on the
    neighbour-corrected profiles (`qdots.micrograph.profiles.central_curvature`), the projected sphere unless
    another matches by `CURVATURE_MARGIN` more (the residual itself hardly tells a sphere from a disc on real
    particles, which are neither exactly). A last pattern at a quarter of the steps settles the blur and ``k``
    of the shape taken. Returns (p, blur, the level at each dot, the level map, how p was chosen).
    """
    centres = np.asarray(centres, dtype=float)
    field, whole_map = smooth_level(centres, background, typical, image.shape)
    sample, members, inner = choice_sample(centres, whole, typical)
    reach = profile_reach(radii[members], typical)
    margin = float(reach.max()) + 2.0 * WIDE[1] * typical
    (x0, y0), (x1, y1) = np.maximum(centres[members].min(axis=0) - margin, 0).astype(int), np.ceil(
        centres[members].max(axis=0) + margin).astype(int)
    image, field_map = image[y0:y1, x0:x1], whole_map[y0:y1, x0:x1]  # the sample's part of the image
    where, part = centres[members] - [x0, y0], field[members]
    middle = np.median(where[inner], axis=0)
    extent = float(np.max(np.hypot(*(where[inner] - middle).T)))
    rows, cols = np.ogrid[:image.shape[0], :image.shape[1]]
    area = (cols + 0.5 - middle[0]) ** 2 + (rows + 0.5 - middle[1]) ** 2 <= extent**2  # gaps and holes included
    low, high = np.array([BLURS[0], LEVEL_RANGE[0]]), np.array([BLURS[1], LEVEL_RANGE[1]])

    def misfit(state, k) -> float:
        return float(np.nansum((image[area] - k * field_map[area] + state.model[area]) ** 2))

    def pattern(shape, centre, step):
        anchor = refine_dots(image, where, radii[members], contrast[members], typical, shape, centre[0],
                             centre[1] * part, passes=PASSES, reach=reach, keep_profiles=False)
        points = np.clip(centre + step * np.array([(i, j) for i in (-1, 0, 1) for j in (-1, 0, 1)]), low, high)
        values = np.array([misfit(refine_dots(image, where, anchor.radius, anchor.contrast, typical, shape, b, k * part,
                                              passes=SAMPLE_PASSES, reach=reach, wide=False, keep_profiles=False), k)
                           for b, k in points])
        return quadratic_minimum(points, values, low, high)[0], float(values.min())

    shapes = SHAPES if profile == "auto" else (PROFILES[profile],)
    step = np.array(FOCUS_STEP)
    scan = [misfit(refine_dots(image, where, radii[members], contrast[members], typical, shapes[-1], FIRST_BLUR,
                               k * part, passes=PASSES, reach=reach, keep_profiles=False), k) for k in LEVEL_SCAN]
    start = np.array([FIRST_BLUR, LEVEL_SCAN[int(np.argmin(scan))]])
    found = {shape: pattern(shape, start, step)[0] for shape in shapes}
    found = {shape: pattern(shape, found[shape], 0.5 * step)[0] for shape in shapes}
    how = f"{profile} (given)"
    shape = shapes[0]
    if profile == "auto":
        measured, predicted = {}, {}
        for p in shapes:
            state = refine_dots(image, where, radii[members], contrast[members], typical, p, found[p][0],
                                found[p][1] * part, passes=PASSES, reach=reach)
            radius = state.radius[inner]
            measured[p] = central_curvature(*(part_[inner] for part_ in state.profiles), radius,
                                            found[p][1] * part[inner])
            predicted[p] = predicted_curvature(p, found[p][0] / float(np.nanmedian(radius)))
        miss = {p: abs(measured[p] - predicted[p]) if np.isfinite(measured[p]) else np.inf for p in shapes}
        shape = min(shapes, key=miss.get)
        if miss[0.5] - miss[shape] < CURVATURE_MARGIN:
            shape = 0.5
        how = (f"p = {shape:g} from the curvature of {len(sample)} dots' centres ({measured[shape]:.3f} r^2 measured, "
               f"{predicted[shape]:.3f} for p = {shape:g}; a sphere would give {predicted[0.5]:.3f} against "
               f"{measured[0.5]:.3f} measured, a flat disc {predicted[0.0]:.3f} against {measured[0.0]:.3f})")
    blur, k = pattern(shape, found[shape], 0.25 * step)[0]
    return float(shape), float(blur), k * field, k * whole_map, how


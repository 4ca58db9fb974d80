"""The shape, blur and background of a film's dots, settled on the fits with the neighbours taken out.

On a dense film the background ``B`` cannot be left free dot by dot: raising every dot's background,
contrast and radius together fits almost as well, and fits dot by dot drift along that direction. So
``B`` is a field: a quadratic surface through the lone fits' backgrounds (`smooth_level`), times a factor
``k``. The factor, the blur and the profile shape are those that leave the least squared difference
between the image and the model of all dots over a patch of the film, its gaps and holes included (`Sample`,
`settle_profile`), where the true film has its minimum; where the background hardly shows, less the largest few
squares, so that a dot the threshold missed does not set the level (`TRIM`). Uneven focus and contrast: the blur and
``k`` are settled again on each of a few tiles of the film and laid over it (`settle_tiles`).
"""

from __future__ import annotations

import math
from typing import cast

import numpy as np

from labrig.compiled import jit
from labrig.threads import run_tasks

from .choices import PROFILES
from .profiles import central_curvature, predicted_curvature
from .refine import PASSES, REACH, REACH_PAD, WIDE, profile_reach, refine_dots

#: The background field: a quadratic surface through the lone fits' backgrounds (`smooth_level`; their median
#: when fewer than LEVEL_DOTS), times a factor searched in LEVEL_RANGE, first at LEVEL_SCAN (on a dense film
#: the lone fits see the narrow gaps as background, far darker than it).
LEVEL_DOTS, LEVEL_RANGE = 12, (0.8, 2.5)
LEVEL_SCAN = (0.9, 1.0, 1.1, 1.25, 1.45, 1.7, 2.0)
#: Shapes ``p`` tried by ``profile="auto"`` (0 a flat disc, 0.5 a projected sphere). The sphere is taken only when
#: the dots' measured central curvature is within SPHERE_MATCH of its prediction and matches it by CURVATURE_MARGIN
#: more than the disc's: crystals whose thickness tapers at their edge, blurred small dots and real particles with
#: inner contrast read between the two (on the development half of the real micrographs: 20-46 % off the sphere's
#: for faceted and polycrystalline particles, 1-9 % for Z-contrast (ADF) pictures and small blurred particles;
#: synthetic projected spheres within a few %).
SHAPES, CURVATURE_MARGIN, SPHERE_MATCH = (0.0, 0.5), 0.05, 0.25
#: Blurs searched, px (the detector smooths every image by 1 px first, so none is under 1 px); the first one
#: tried (also the blur of the lone fits that start everything); the blurs the first pattern may start from (the
#: best of them at the best ``k``: a film blurred by 4 px is not reached from 1.5 px in steps).
BLURS, FIRST_BLUR, BLUR_SCAN = (1.0, 5.0), 1.5, (1.5, 2.5, 4.0)
#: The first 3 x 3 pattern of blurs (px) and background factors: its steps. The blur and ``k`` the film takes are the
#: minimum of a pattern at half these steps; one more at a quarter of them was taken back: its nine residuals differ
#: by about as much as the fits' own jitter does (on the PbSe square superlattice of the real micrographs' development
#: half, the residual of the middle patch scatters by 0.09 rms about a smooth curve, where the quarter pattern's
#: surface varies by 0.35), so its minimum ran to its border from a change of the picture's last bit, and the mean
#: diameter with it (`python -m benchmarks.micrograph_jitter`: 0.83 % on that film, 0.22 % without it).
FOCUS_STEP = (0.3, 0.04)
#: Most dots the shape, blur and background are settled on; the film is cut in TILES x TILES tiles, each
#: settled again when the film holds TILE_DOTS whole dots a tile (`settle_tiles`).
SAMPLE, TILES, TILE_DOTS = 100, 3, 50
#: Passes of each fit while settling (from a state fitted at the middle of the pattern); TRIMMED_PASSES where the
#: misfit is trimmed (`TRIM`): there the dots' profiles overlap their neighbours' everywhere, and two passes from the
#: pattern's middle leave the fits short of converged (measured below, at `TRIM`).
SAMPLE_PASSES, TRIMMED_PASSES = 2, 4
#: Where the background hardly shows, the misfit leaves out the largest TRIM of its squares (least trimmed squares).
#: A dot the threshold missed (faint, on a film whose gaps never rise to the background) is a dark disc the model
#: cannot explain, and the cheapest way for plain least squares to pay for it is a lower background, a narrower blur
#: and smaller dots everywhere; where the background shows, it pins the level, and plain least squares is kept: the
#: share of the middle patch where the first fits darken the picture by under OPEN_DEPTH of their median contrast
#: (`Sample.open_share`) is at least OPEN_SHARE. Measured open shares: synthetic superlattices without vacancies
#: 0.004-0.041, with 10 % vacancies 0.072, with 6 px gaps 0.109; the first detections of the 15 measured films of the
#: real micrographs' development half 0.071-0.93. But the square PbSe superlattice is measured on its second detection
#: (the dark particles joined by necks, after the light gaps the polarity vote took were refused), whose share is 0.0:
#: of the real micrographs (both halves) it is the one film trimmed. On hexagonal films of 16.5 px flat discs (sigma 7 %,
#: noise 0.03, illumination 0.2, no vacancies, blurred by 2 px), the median diameter read -2.7 -> -0.8 % (gaps of
#: 2.5 px), -6.5 -> -2.4 % (another film), -7.2 -> -3.4 % (1.8 px) and -11.3 -> -6.4 % (1 px), the blur 1.75-2.07 ->
#: 1.97-2.13 px where 2.24 is true (the picture is smoothed by 1 px); the other films (3-10 % vacancies, 6 px
#: gaps, or blurred by 1 px) moved by 0.3 % or less. Trimming 6 % or 10 % gave no more. With TRIMMED_PASSES of 4
#: instead of 2, on twelve more such films (gaps of 1.8, 2 and 2.5 px, four seeds each) the median diameter's error
#: fell from 2.2-3.8 % (mean 3.2 %) to 0.2-3.1 % (mean 1.9 %), none worse; six passes gave 1.9 % again at more cost.
#: What is left is the dots still missed (1 px gaps: -6.4 %, 28 of 780 dots missed).
TRIM, OPEN_DEPTH, OPEN_SHARE = 0.03, 0.05, 0.05
#: Most times the first pattern moves on when its minimum lies on its border (`descend`): moves of up to two
#: steps of `FOCUS_STEP` reach the largest of `BLURS` from `FIRST_BLUR`.
MOVES = 6


def choice_sample(centres, whole, typical: float, point=None):
    """Up to `SAMPLE` whole dots (indices ``whole``) nearest ``point`` (default the middle of the film), the dots
    near enough to them to touch their profiles (``members``, sorted) and the sample's places among the members."""
    if len(whole) == 0:
        whole = np.arange(len(centres))
    point = np.median(centres[whole], axis=0) if point is None else np.asarray(point, dtype=float)
    sample = whole[np.argsort(np.hypot(*(centres[whole] - point).T), kind="stable")[:SAMPLE]]
    middle = np.median(centres[sample], axis=0)
    distance = np.hypot(*(centres - middle).T)
    margin = REACH * WIDE[1] * typical + REACH_PAD + 2.0 * WIDE[1] * typical
    members = np.flatnonzero(distance <= distance[sample].max() + margin)
    return sample, members, np.searchsorted(members, sample)


class Sample:
    """A patch of the film to settle the profile on: the image around up to `SAMPLE` whole dots near ``point``,
    its dots (all those whose profiles touch the sample's), their first fits and background field, and the
    pixels the residual is summed over (a disc over the sample, its gaps and holes included), less the largest
    ``trim`` of the squares (`TRIM`)."""

    def __init__(self, image, centres, radii, contrast, field, field_map, typical: float, whole, point=None,
                 trim: float = 0.0):
        sample, members, self.inner = choice_sample(centres, whole, typical, point)
        self.size = len(sample)
        self.typical = typical
        self.radii, self.contrast, self.part = radii[members], contrast[members], field[members]
        self.reach = profile_reach(self.radii, typical)
        margin = float(self.reach.max()) + 2.0 * WIDE[1] * typical
        (x0, y0) = np.maximum(centres[members].min(axis=0) - margin, 0).astype(int)
        (x1, y1) = np.ceil(centres[members].max(axis=0) + margin).astype(int)
        self.image, self.field_map = image[y0:y1, x0:x1], field_map[y0:y1, x0:x1]
        self.offset = np.array([x0, y0], dtype=float)
        self.where = centres[members] - self.offset
        middle = np.median(self.where[self.inner], axis=0)
        extent = float(np.max(np.hypot(*(self.where[self.inner] - middle).T)))
        rows, cols = np.ogrid[:self.image.shape[0], :self.image.shape[1]]
        self.area = (cols + 0.5 - middle[0]) ** 2 + (rows + 0.5 - middle[1]) ** 2 <= extent**2
        self.trim = trim

    def open_share(self) -> float:
        """The share of the patch's area where the first fits' model (a projected sphere blurred by `FIRST_BLUR`, as
        the lone fits were made) darkens the picture by under `OPEN_DEPTH` of the median contrast: the background
        itself shows."""
        contrast = self.contrast[np.isfinite(self.contrast) & (self.contrast > 0)]
        if not contrast.size or not self.area.any():
            return 1.0
        model = self.fit(0.5, FIRST_BLUR, 1.0, passes=0).model
        return float(np.mean(np.nan_to_num(model[self.area]) < OPEN_DEPTH * float(np.median(contrast))))

    def fit(self, shape, blur, k, start=None, passes: int = PASSES, keep_profiles: bool = False, move: bool = True):
        """`refine_dots` of the patch's dots at (shape, blur, ``k`` times the field), from their first fits or
        ``start`` (a `Refined` state: then every pass starts near its radii, and from its centres unless ``move``,
        which moves them from the first ones)."""
        if start is None:
            return refine_dots(self.image, self.where, self.radii, self.contrast, self.typical, shape, blur,
                               k * self.part, passes=passes, reach=self.reach, wide=True, keep_profiles=keep_profiles,
                               move=move, threads=1)
        return refine_dots(self.image, self.where if move else start.centres, start.radius, start.contrast,
                           self.typical, shape, blur, k * self.part, passes=passes, reach=self.reach, wide=False,
                           keep_profiles=keep_profiles, move=move, threads=1)

    def misfit(self, state, k) -> float:
        """Sum of squares of image minus (background minus model) over the patch's area, the largest ``trim`` of
        them left out (`trimmed_sum`)."""
        area = self.area
        return trimmed_sum((self.image[area] - k * self.field_map[area] + state.model[area]) ** 2, self.trim)

    def best(self, shape, pairs) -> tuple[float, float]:
        """The (blur, ``k``) of ``pairs`` whose fit leaves the least residual, the fits run side by side in threads."""
        misfits = run_tasks([lambda b=b, k=k: self.misfit(self.fit(shape, b, k), k) for b, k in pairs])
        return pairs[int(np.argmin(misfits))]


def trimmed_sum(squares: np.ndarray, share: float) -> float:
    """The sum of the finite ``squares`` less the largest ``share`` of them (with none left out, `numpy.nansum`'s,
    to the last bit: the misfit of a film whose background shows is as it was)."""
    if share <= 0.0:
        return float(np.nansum(squares))
    squares = squares[np.isfinite(squares)]
    keep = int(round((1.0 - share) * squares.size))
    if keep >= squares.size:
        return float(np.sum(squares))
    return float(np.sum(np.partition(squares, keep - 1)[:keep])) if keep > 0 else 0.0


def patterns(jobs) -> list[tuple[np.ndarray, float]]:
    """For each job ``(sample, shape, centre, step, move)``: the 3 x 3 blurs and ``k`` ``step`` apart around
    ``centre``, each fitted from a state fitted at ``centre`` (`Sample.fit`); the minimum of the quadratic surface
    through their residuals (`quadratic_minimum`, within two steps of ``centre``), and the least residual. The states
    at the centres are fitted side by side in threads, then every job's nine fits (`labrig.threads.run_tasks`)."""
    anchors = run_tasks([lambda job=job: job[0].fit(job[1], job[2][0], job[2][1]) for job in jobs])
    grids = []
    for _, _, centre, step, _ in jobs:
        low = np.maximum([BLURS[0], LEVEL_RANGE[0]], centre - 2.0 * step)  # the surface is trusted near its points
        high = np.minimum([BLURS[1], LEVEL_RANGE[1]], centre + 2.0 * step)
        points = np.clip(centre + step * np.array([(i, j) for i in (-1, 0, 1) for j in (-1, 0, 1)]), low, high)
        grids.append((points, low, high))

    def misfit(job, anchor, blur, k) -> float:
        patch, shape, _, _, move = job
        passes = TRIMMED_PASSES if patch.trim else SAMPLE_PASSES
        return patch.misfit(patch.fit(shape, blur, k, anchor, passes, move=move), k)

    values = np.array(run_tasks([lambda job=job, anchor=anchor, b=b, k=k: misfit(job, anchor, b, k)
                                 for job, anchor, (points, _, _) in zip(jobs, anchors, grids) for b, k in points]),
                      dtype=float).reshape(len(jobs), -1)
    return [(quadratic_minimum(points, row, low, high)[0], float(row.min()))
            for (points, low, high), row in zip(grids, values)]


def descend(patch: Sample, shapes, centre, step) -> dict:
    """`patterns` of each of ``shapes`` again around its own minimum while that lies on the pattern's border or beyond
    it (a step or more from its centre) short of the search's bounds (`BLURS`, `LEVEL_RANGE`), at most `MOVES` more
    times, the shapes still moving side by side. A pattern trusts its surface only within two steps of its centre:
    without moving on, the blur of a film blurred by 3 px or more stopped short of it (at 2.55 px from `FIRST_BLUR`,
    the narrower patterns adding 1.5 steps), and the radii paid for it. Returns each shape's last minimum and least
    residual."""
    bounds = np.array([[BLURS[0], LEVEL_RANGE[0]], [BLURS[1], LEVEL_RANGE[1]]])
    centres = {shape: np.asarray(centre, dtype=float) for shape in shapes}
    found = dict(zip(shapes, patterns([(patch, shape, centres[shape], step, True) for shape in shapes])))
    for _ in range(MOVES):
        moving = [shape for shape in shapes if np.any((np.abs(found[shape][0] - centres[shape]) >= step * (1.0 - 1e-9))
                                                      & (found[shape][0] > bounds[0] + 1e-9)
                                                      & (found[shape][0] < bounds[1] - 1e-9))]
        if not moving:
            break
        centres.update({shape: found[shape][0] for shape in moving})
        found.update(zip(moving, patterns([(patch, shape, centres[shape], step, True) for shape in moving])))
    return found


def total_residual(residual) -> float:
    """Sum of the finite residuals (inf when none is)."""
    finite = np.isfinite(residual)
    return float(np.sum(residual[finite])) if finite.any() else math.inf


def surface_terms(x, y, shape) -> np.ndarray:
    """The terms of a quadratic surface over an image of ``shape`` at points (``x``, ``y``), px: 1, x, y, x^2,
    y^2, xy, with x and y scaled to [-1/2, 1/2] over the image."""
    u = np.asarray(x, dtype=float) / shape[1] - 0.5
    v = np.asarray(y, dtype=float) / shape[0] - 0.5
    return np.column_stack([np.ones_like(u), u, v, u * u, v * v, u * v])


def smooth_level(centres, background, shape) -> tuple[np.ndarray, np.ndarray]:
    """The dots' backgrounds as a slowly varying illumination: the quadratic surface (`surface_terms`) fitted to
    them by least squares (their median where fewer than `LEVEL_DOTS` are finite): its value at each centre, and
    its map over an image of ``shape``. A lone fit's background follows its neighbours' darkness and contrast
    (on a film without gaps, most of its profile is its neighbours' edges); averaged over a few dots it still
    wanders by several percent, which the settling would pay for with the radii."""
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    ok = np.isfinite(background)
    if ok.any():  # a failed fit's background far off the others' is left out
        q1, q3 = np.percentile(background[ok], [25, 75])
        ok &= np.abs(background - 0.5 * (q1 + q3)) <= 0.5 * (q3 - q1) + 3.0 * (q3 - q1)
    if ok.sum() < LEVEL_DOTS:
        level = float(np.median(background[ok])) if ok.any() else 1.0
        return np.full(len(centres), level), np.full(shape, level)
    coef = np.linalg.lstsq(surface_terms(centres[ok, 0], centres[ok, 1], shape), background[ok], rcond=None)[0]
    full = np.empty(shape)
    quadratic_map(coef, (np.arange(shape[1]) + 0.5) / shape[1] - 0.5, (np.arange(shape[0]) + 0.5) / shape[0] - 0.5,
                  full)
    return surface_terms(centres[:, 0], centres[:, 1], shape) @ coef, full


@jit
def quadratic_map(coef, u, v, out):
    """The quadratic surface of `surface_terms` with coefficients ``coef`` at every pixel (row ``i`` at ``v[i]``,
    column ``j`` at ``u[j]``), into ``out``: in one pass, the terms summed in their order."""
    for i in range(v.shape[0]):
        for j in range(u.shape[0]):
            out[i, j] = (coef[0] + coef[1] * u[j] + coef[2] * v[i] + coef[3] * u[j] * u[j] + coef[4] * v[i] * v[i]
                         + coef[5] * u[j] * v[i])


@jit
def plane_times(plane, u, v, field, out):
    """``(plane[0] + plane[1] u + plane[2] v)`` times ``field`` at every pixel (row ``i`` at ``v[i]``, column ``j``
    at ``u[j]``), into ``out``, in one pass."""
    for i in range(v.shape[0]):
        for j in range(u.shape[0]):
            out[i, j] = (plane[0] + plane[1] * u[j] + plane[2] * v[i]) * field[i, j]


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
                   ) -> tuple[float, np.ndarray, np.ndarray, np.ndarray, str, bool]:
    """The dots' shape ``p``, the blur and the background at each dot and everywhere, settled on a `Sample` of the
    film: those that leave the least squared difference between the image and the model of all dots
    (`refine_dots`, every dot fitted with the background fixed) over the sample's pixels.

    The background is ``k`` times a quadratic surface through the lone fits' ``background`` (`smooth_level`).
    Each candidate shape (`SHAPES` for ``profile="auto"``, else the one given) is fitted at 3 x 3 blurs and ``k`` `FOCUS_STEP` apart
    around the best ``k`` of `LEVEL_SCAN` (at `FIRST_BLUR`) and the best blur of `BLUR_SCAN` (at that ``k``), from a
    state fitted at the middle one, and again
    around the minimum of the quadratic surface through the nine residuals (`quadratic_minimum`) at half the
    steps; the first pattern moves on while its minimum lies on its border (`descend`). For ``profile="auto"``
    the shape is then the one whose predicted central curvature
    (`qdots.micrograph.profiles.predicted_curvature`, at its blur) matches the curvature measured on the
    neighbour-corrected profiles (`qdots.micrograph.profiles.central_curvature`): the flat disc unless the sphere
    matches within `SPHERE_MATCH` and by `CURVATURE_MARGIN` more (the residual itself hardly tells a sphere from a
    disc on real particles, which are neither exactly). Where both match within `CURVATURE_MARGIN` of each other
    (dots blurred by a third of their radius or more), the lower residual decides, and the message says that the
    shape is hardly seen. The blur and ``k`` of the shape taken are then settled again on each tile of the film
    (`settle_tiles`). Returns (p, the blur at each dot, px, the
    level at each dot, the level map, how p was chosen, whether the misfit was trimmed: the background hardly
    shows).
    """
    centres = np.asarray(centres, dtype=float)
    field, whole_map = smooth_level(centres, background, image.shape)
    patch = Sample(image, centres, radii, contrast, field, whole_map, typical, whole)
    patch.trim = trim = TRIM if patch.open_share() < OPEN_SHARE else 0.0  # for the tiles too
    shapes = SHAPES if profile == "auto" else (cast(float, PROFILES[profile]),)  # only "auto" maps to None
    step = np.array(FOCUS_STEP)
    k = patch.best(shapes[-1], [(FIRST_BLUR, k) for k in LEVEL_SCAN])[1]
    start = np.array(patch.best(shapes[-1], [(b, k) for b in BLUR_SCAN]))
    found = {shape: value[0] for shape, value in descend(patch, shapes, start, step).items()}
    settled = dict(zip(shapes, patterns([(patch, shape, found[shape], 0.5 * step, True) for shape in shapes])))
    found = {shape: settled[shape][0] for shape in shapes}
    how = f"{profile} (given)"
    shape = shapes[0]
    inner = patch.inner
    if profile == "auto":
        measured, predicted = {}, {}
        states = run_tasks([lambda p=p: patch.fit(p, found[p][0], found[p][1], keep_profiles=True) for p in shapes])
        for p, state in zip(shapes, states):
            radius = state.radius[inner]
            sums, counts, rhos = (part_[inner] for part_ in state.profiles)
            measured[p] = central_curvature(sums, counts, rhos, radius, found[p][1] * patch.part[inner])
            kept = radius[np.isfinite(radius)]  # none kept on a picture smoothed far: no curvature to predict
            predicted[p] = predicted_curvature(p, found[p][0] / float(np.median(kept))) if kept.size else math.nan
        miss = {p: abs(measured[p] - predicted[p]) if np.isfinite(measured[p]) else np.inf for p in shapes}
        sphere = miss[0.5] <= SPHERE_MATCH * predicted[0.5] and miss[0.0] - miss[0.5] >= CURVATURE_MARGIN
        # blurred over a third of their radius or more, a sphere and a disc both match their curvature: the
        # residual, the only evidence left, decides
        tied = miss[0.5] <= SPHERE_MATCH * predicted[0.5] and abs(miss[0.0] - miss[0.5]) < CURVATURE_MARGIN
        shape = 0.5 if sphere or (tied and settled[0.5][1] < settled[0.0][1]) else 0.0
        how = (f"p = {shape:g} from the curvature of {patch.size} dots' centres ({measured[shape]:.3f} r^2 measured, "
               f"{predicted[shape]:.3f} for p = {shape:g}; a sphere would give {predicted[0.5]:.3f} against "
               f"{measured[0.5]:.3f} measured, a flat disc {predicted[0.0]:.3f} against {measured[0.0]:.3f})")
        if tied:
            how += (f"; both match, so the lower residual chose (sphere {settled[0.5][1]:.4g}, disc "
                    f"{settled[0.0][1]:.4g}): blurred by {found[shape][0]:.1f} px, the dots' shape is hardly seen, and "
                    "the diameter depends on it (a sphere's is some 10-20 % wider than a disc's); the half-depth width "
                    "does not")
    blur, k = found[shape]
    blurs, levels, level_map = settle_tiles(image, centres, radii, contrast, field, whole_map, typical, whole, shape,
                                            np.array([blur, k]), trim)
    return float(shape), blurs, levels, level_map, how, bool(trim)


def tile_points(shape, centres, whole) -> list[tuple[float, float]]:
    """The middles (x, y), px, of the `TILES` x `TILES` tiles `settle_tiles` settles on an image of ``shape``, or
    none when the film holds fewer than `TILE_DOTS` whole dots a tile."""
    h, w = shape
    n_whole = len(whole) if len(whole) else len(centres)
    if n_whole < TILES * TILES * TILE_DOTS:
        return []
    return [((j + 0.5) * w / TILES, (i + 0.5) * h / TILES) for i in range(TILES) for j in range(TILES)]


def samples_hold(shape, centres, whole, typical: float, dots) -> bool:
    """Whether any of the dots ``dots`` (indices into ``centres``) is among the dots of a patch the film is settled
    on (the middle sample and the tiles' of `settle_profile`): only then can adding them change the settling."""
    for point in [None, *tile_points(shape, centres, whole)]:
        if np.isin(dots, choice_sample(centres, whole, typical, point)[1]).any():
            return True
    return False


def settle_tiles(image, centres, radii, contrast, field, field_map, typical: float, whole, shape: float, settled,
                 trim: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Uneven focus and contrast: the blur and ``k`` settled again (one pattern at a quarter of `FOCUS_STEP`,
    around the film's ``settled`` pair) on a sample near the middle of each of `TILES` x `TILES` tiles of the
    film, when the film holds `TILE_DOTS` whole dots a tile; a plane fitted to the tiles' blurs, and one to their
    ``k``, lay them over the film (a focus or thickness that changes slowly, without each tile's own scatter).
    Returns the blur and the level at each dot, and the level map."""
    h, w = image.shape
    points = tile_points(image.shape, centres, whole)
    if not points:
        blur, k = settled
        return np.full(len(centres), blur), k * field, k * field_map
    patches = [Sample(image, centres, radii, contrast, field, field_map, typical, whole, point, trim) for point in points]
    middles = np.array([np.median(patch.where[patch.inner] + patch.offset, axis=0) for patch in patches])
    values = np.array([found for found, _ in patterns([(patch, shape, np.asarray(settled, dtype=float),
                                                       0.25 * np.array(FOCUS_STEP), False) for patch in patches])])
    design = np.column_stack([np.ones(len(middles)), middles / [w, h]])
    planes = np.linalg.lstsq(design, values, rcond=None)[0]  # blur and k, each a plane over the film

    def lay(x, y):
        return np.column_stack([np.ones(np.size(x)), np.ravel(x) / w, np.ravel(y) / h]) @ planes

    at_dots = lay(centres[:, 0], centres[:, 1])
    level_map = np.empty((h, w))
    plane_times(np.ascontiguousarray(planes[:, 1]), (np.arange(w) + 0.5) / w, (np.arange(h) + 0.5) / h,
                np.asarray(field_map, dtype=float), level_map)
    blurs = np.clip(at_dots[:, 0], *BLURS)
    return blurs, at_dots[:, 1] * field, level_map


"""Packing measurements on a board (thesis section 2.4, Appendix A ``runLinearGraph*``).

Every function takes a `qdots.State`, or anything with ``positions`` (N, 2)
and ``radii`` (N,) attributes in px, and works on whole arrays: pairs come
from one KD-tree query (`qdots.geometry.pairs_with_distances`), counts from
``np.bincount``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from labrig.validate import InputError

from ..geometry import overlapping_pairs, pairs_with_distances, worst_overlap

#: Neighbour rules: "text" is the thesis's prose (section 2.4), "code" its Java (Appendix A).
RULES = ("text", "code")
#: A dot with at least this many neighbours is "interior" (thesis Fig 2-4).
INTERIOR_MIN_NEIGHBOURS = 5
#: Most circles of one `fill_within_radius` call (the Java draws 20, ``qdots analyze`` 30), and most (dot,
#: circle) areas: 24 bytes each in `_disc_in_circle_area`, 82 if all are lenses (4 GB); ``qdots analyze``'s
#: 30 circles over the largest board (`qdots.scene.MAX_DOTS` dots) take 2.4e7.
MAX_CIRCLES, MAX_FILL_TERMS = 10_000, 50_000_000
#: Most pairs ``size_separation_correlation(pairs="all")`` visits: N (N - 1) / 2 for N = 10^5 dots, about a
#: minute at ~1 s per 10^8 pairs (the thesis's boards have 300-500 dots).
MAX_ALL_PAIRS = 5_000_000_000


def state_arrays(state) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 2) and radii (N,) of ``state`` as float arrays, checked."""
    try:
        positions = np.asarray(state.positions, dtype=float)
        radii = np.asarray(state.radii, dtype=float)
    except AttributeError:
        raise InputError(
            f"state must have positions and radii attributes, got {type(state).__name__}"
        ) from None
    if positions.size == 0:
        positions = positions.reshape(0, 2)
    if positions.ndim != 2 or positions.shape[1] != 2:
        raise InputError(f"state.positions must have shape (N, 2), got {positions.shape}")
    if radii.shape != (len(positions),):
        raise InputError(f"state.radii must have shape ({len(positions)},), got {radii.shape}")
    return positions, radii


def overlaps(state) -> tuple[float, tuple[int, int]]:
    """Worst relative overlap between two dots (`qdots.geometry.worst_overlap`).

    The relative overlap of a pair is ``(r_i + r_j - d) / ((r_i + r_j) / 2)``
    with ``d`` the centre distance, i.e. ``(2r - d) / r`` for equal radii: the
    depth of interpenetration in units of the mean radius of the pair.

    Returns
    -------
    worst : float
        Largest relative overlap (dimensionless, > 0), or 0.0 if no two dots
        overlap.
    pair : (int, int)
        Indices ``(i, j)``, ``i < j``, of the worst pair, or ``(-1, -1)``.
    """
    positions, radii = state_arrays(state)
    return worst_overlap(positions, radii)


def escaped(state) -> int:
    """Number of dots whose centre lies outside the box ``[0, width] x [0, height]`` (dots that left
    an open board; 0 on a closed one, where soft contacts let a dot sink into a wall by a fraction of
    its radius at most)."""
    positions, _ = state_arrays(state)
    w, h = (float(v) for v in state.box)
    x, y = positions[:, 0], positions[:, 1]
    return int(np.count_nonzero((x < 0) | (x > w) | (y < 0) | (y > h)))


def neighbour_edges(state, rule: str = "text", mean_radius: float | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every (dot, neighbour) relation of the board, as directed edges.

    Parameters
    ----------
    state : State
        The board (``positions`` and ``radii`` in px).
    rule : {"text", "code"}
        ``"text"`` (default, thesis section 2.4): dots ``i`` and ``j`` are
        neighbours if their surface gap ``d - r_i - r_j`` is less than one
        mean radius. ``"code"`` (thesis Java, ``determinePacking``): ``j``
        counts as a neighbour of ``i`` if ``d <= r_i + 2 r_j``; this is not
        symmetric when the radii differ (a large dot sees a small one less
        readily than the small dot sees it). The Java skips a pair when
        ``d > r_i + 2 r_j``, so equality counts. (The Java's
        ``determinePackingInterior`` uses ``r_i + 1.5 r_j`` instead.)
    mean_radius : float, optional
        The mean radius of the ``"text"`` rule, px (> 0). Default: the mean of
        ``state.radii``. Ignored by ``"code"``.

    Returns
    -------
    src, dst : ndarray of int, shape (E,)
        ``dst[k]`` is a neighbour of ``src[k]``. The ``"text"`` rule lists each
        pair in both directions.
    distance : ndarray, shape (E,)
        Centre distance of each edge, px.
    """
    positions, radii = state_arrays(state)
    if rule not in RULES:
        raise InputError(f"rule must be one of {RULES}, got {rule!r}")
    if len(radii) < 2:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty, np.zeros(0)
    rmax = float(radii.max())
    if rule == "text":
        if mean_radius is None:
            mean_radius = float(radii.mean())
        elif not (isinstance(mean_radius, (int, float)) and math.isfinite(mean_radius) and mean_radius > 0):
            raise InputError(f"mean_radius must be > 0 px, got {mean_radius!r}")
        i, j, d = pairs_with_distances(positions, 2.0 * rmax + mean_radius,
                                       f"mean_radius = {mean_radius:g} px (with the largest radius, {rmax:g} px)")
        near = d - radii[i] - radii[j] < mean_radius
        i_sees_j = j_sees_i = near
    else:
        i, j, d = pairs_with_distances(positions, 3.0 * rmax, f"rule 'code' (3 x the largest radius, {rmax:g} px)")
        i_sees_j = d <= radii[i] + 2.0 * radii[j]
        j_sees_i = d <= radii[j] + 2.0 * radii[i]
    src = np.concatenate([i[i_sees_j], j[j_sees_i]])
    dst = np.concatenate([j[i_sees_j], i[j_sees_i]])
    return src, dst, np.concatenate([d[i_sees_j], d[j_sees_i]])


def neighbour_counts(state, rule: str = "text", mean_radius: float | None = None) -> np.ndarray:
    """Number of neighbours of every dot (see `neighbour_edges` for the rules).

    Returns
    -------
    ndarray of int, shape (N,)
        Neighbour count of each dot.
    """
    src, _, _ = neighbour_edges(state, rule, mean_radius)
    return np.bincount(src, minlength=len(state_arrays(state)[1]))


@dataclass(frozen=True)
class Separation:
    """Spacing of neighbouring dots (the Java's ``determinePacking*`` figures).

    Attributes
    ----------
    rms_excess : float
        Root mean square of the surface gap ``d - r_i - r_j`` over every
        (dot, neighbour) edge, px (the Java's ``rmsPerBall``).
    mean_gap : float
        Mean surface gap over the same edges, px (``averageSpace``; the
        "mean spacing").
    mean_neighbours : float
        Mean neighbour count of the dots measured (``averageNeighbors``).
    n_dots : int
        Dots measured (``totalBalls``).
    """

    rms_excess: float
    mean_gap: float
    mean_neighbours: float
    n_dots: int


def separation(state, rule: str = "text", interior_only: bool = True,
               mean_radius: float | None = None) -> Separation:
    """RMS excess separation, mean spacing and mean neighbours of a board.

    As the Java's ``determinePackingInterior`` (``interior_only=True``, the
    default: only dots with at least 5 neighbours are measured, the figure
    runs' return value) or ``determinePacking`` (``interior_only=False``:
    every dot). The Java's interior variant finds neighbours with
    ``d <= r_i + 1.5 r_j``; here the neighbour ``rule`` is the caller's
    (see `neighbour_edges`). Values are nan when no dot or edge is measured.
    """
    _, radii = state_arrays(state)
    return _separation(radii, neighbour_edges(state, rule, mean_radius), interior_only)


def _separation(radii: np.ndarray, edges, interior_only: bool) -> Separation:
    src, dst, d = edges
    counts = np.bincount(src, minlength=len(radii))
    measured = counts >= INTERIOR_MIN_NEIGHBOURS if interior_only else np.ones(len(radii), dtype=bool)
    keep = measured[src]
    gap = d[keep] - radii[src[keep]] - radii[dst[keep]]
    n = int(measured.sum())
    if not gap.size:
        return Separation(math.nan, math.nan, float(counts[measured].mean()) if n else math.nan, n)
    return Separation(float(np.sqrt(np.mean(gap**2))), float(gap.mean()), float(counts[measured].mean()), n)


def _disc_in_circle_area(a: np.ndarray, d: np.ndarray, big: np.ndarray) -> np.ndarray:
    """Area of disc (radius ``a``, centre at distance ``d``) inside the circle of radius ``big``; broadcasts."""
    a, d, big = np.broadcast_arrays(np.asarray(a, float), np.asarray(d, float), np.asarray(big, float))
    area = np.zeros(a.shape)
    inside = d <= np.abs(big - a)
    area[inside] = np.pi * np.minimum(a, big)[inside] ** 2
    lens = ~inside & (d < a + big)
    a, d, big = a[lens], d[lens], big[lens]
    cos_a = np.clip((d * d + a * a - big * big) / (2 * d * a), -1.0, 1.0)
    cos_b = np.clip((d * d + big * big - a * a) / (2 * d * big), -1.0, 1.0)
    kite = np.sqrt(np.clip((-d + a + big) * (d + a - big) * (d - a + big) * (d + a + big), 0.0, None))
    area[lens] = a * a * np.arccos(cos_a) + big * big * np.arccos(cos_b) - 0.5 * kite
    return area


@dataclass(frozen=True)
class FillCurve:
    """Fraction of a circle covered by dots, for growing circles (``runLinearGraphFillWithinRadius``).

    Attributes
    ----------
    radius : ndarray, shape (M,)
        Circle radii, px.
    fill : ndarray, shape (M,)
        Covered fraction of each circle: the sum of the exact disc-circle
        intersection areas over the circle's area.
    overlap_bound : ndarray, shape (M,)
        Bound on the error of ``fill`` from dots that overlap one another
        (their common area is counted twice): the summed lens areas of the
        overlapping pairs that reach into the circle, over the circle's area.
        The true union fill lies in ``[fill - overlap_bound, fill]``; 0 for a
        board without overlaps.
    centre : (float, float)
        Centre of the circles, px.
    """

    radius: np.ndarray
    fill: np.ndarray
    overlap_bound: np.ndarray
    centre: tuple[float, float]


def fill_within_radius(state, radius, centre=None) -> FillCurve:
    """Covered fraction of circles around a centre, computed exactly (no sampling).

    The Java (``determineFillWithinRadius``) throws 10^6 random points into
    the largest circle and counts those inside a dot (statistical error
    ~5e-4); here each dot's intersection with each circle is the analytic
    lens area, so the result is exact for non-overlapping dots and bounded
    (`FillCurve.overlap_bound`) otherwise.

    Parameters
    ----------
    state : State
        The board.
    radius : float or array_like
        Circle radii, px (> 0). The Java's ``runLinearGraphFillWithinRadius(100, 20)``
        is ``radius = 5 * np.arange(1, 21)``.
    centre : (float, float), optional
        Centre, px. Default: the centre of ``state.box`` (the Java's
        ``boardDimension / 2``), or the dots' centroid if there is no box.
    """
    positions, radii = state_arrays(state)
    big = np.atleast_1d(np.asarray(radius, dtype=float))
    if big.ndim != 1 or not big.size or not np.all(np.isfinite(big) & (big > 0)):
        raise InputError(f"radius must be finite circle radii > 0 px, got {radius!r}")
    if big.size > MAX_CIRCLES:
        raise InputError(f"radius must hold at most {MAX_CIRCLES:,} circles, got {big.size:,}")
    if centre is None:
        box = getattr(state, "box", None)
        centre = (0.5 * float(box[0]), 0.5 * float(box[1])) if box is not None else \
            (tuple(positions.mean(axis=0)) if len(positions) else (0.0, 0.0))
    c = np.asarray(centre, dtype=float)
    if c.shape != (2,) or not np.all(np.isfinite(c)):
        raise InputError(f"centre must be two finite coordinates, px, got {centre!r}")
    d = np.sqrt(((positions - c) ** 2).sum(axis=1))
    reach = d - radii < big.max()
    if int(reach.sum()) * big.size > MAX_FILL_TERMS:
        raise InputError(f"radius: {big.size:,} circles reached by {int(reach.sum()):,} dots make "
                         f"{int(reach.sum()) * big.size:,} areas, more than the {MAX_FILL_TERMS:,} allowed")
    covered = _disc_in_circle_area(radii[reach, None], d[reach, None], big[None, :]).sum(axis=0)
    i, j, dij = overlapping_pairs(positions, radii)
    lens = _disc_in_circle_area(radii[i], dij, radii[j])  # common area of each overlapping pair
    reaches = np.maximum(d[i] - radii[i], d[j] - radii[j])  # the lens lies in both discs
    double = np.array([lens[reaches < b].sum() for b in big])
    area = np.pi * big**2
    return FillCurve(big, covered / area, double / area, (float(c[0]), float(c[1])))


def size_separation_correlation(state, pairs: str = "neighbours", rule: str = "text",
                                mean_radius: float | None = None, edges=None) -> float:
    """Pearson correlation of the surface gap with the size difference of dot pairs.

    For each pair, ``x = d - r_i - r_j`` (gap, px) and ``y = |r_i - r_j|``
    (px); the result is Pearson's r of x and y: positive when unequal dots sit
    farther apart.

    Parameters
    ----------
    pairs : {"neighbours", "all"}
        ``"neighbours"`` (default): the neighbouring pairs of ``rule`` (each
        pair once), a local measure. ``"all"``: every pair of dots, as the
        Java's ``determinePearsonSpatialCorrelation``; it costs O(N^2) time
        (computed in blocks, O(N) memory), about 1 s per 10^8 pairs.
    edges : tuple of arrays, optional
        `neighbour_edges` of the board, if already computed.

    Returns
    -------
    float
        In [-1, 1]; nan with fewer than two pairs or equal sizes (no variance).
    """
    if pairs not in ("neighbours", "all"):
        raise InputError(f"pairs must be 'neighbours' or 'all', got {pairs!r}")
    positions, radii = state_arrays(state)
    sums = np.zeros(6)  # n, sx, sy, sxx, sxy, syy
    def add(x, y):
        sums[:] += (len(x), x.sum(), y.sum(), (x * x).sum(), (x * y).sum(), (y * y).sum())
    if pairs == "neighbours":
        src, dst, d = neighbour_edges(state, rule, mean_radius) if edges is None else edges
        lo, hi = np.minimum(src, dst), np.maximum(src, dst)
        _, first = np.unique(lo * len(radii) + hi, return_index=True)
        i, j, d = lo[first], hi[first], d[first]
        add(d - radii[i] - radii[j], np.abs(radii[i] - radii[j]))
    else:
        n_dots = len(radii)
        if n_dots * (n_dots - 1) // 2 > MAX_ALL_PAIRS:
            raise InputError(f"pairs='all' visits {n_dots * (n_dots - 1) // 2:,} pairs of the {n_dots:,} dots, more than the "
                             f"{MAX_ALL_PAIRS:,} allowed (use pairs='neighbours')")
        block = max(1, 4_000_000 // max(len(radii), 1))
        for start in range(0, len(radii), block):
            rows = slice(start, min(start + block, len(radii)))
            delta = positions[rows, None, :] - positions[None, :, :]
            d = np.sqrt((delta**2).sum(axis=2))
            upper = np.arange(len(radii))[None, :] > np.arange(rows.start, rows.stop)[:, None]
            add((d - radii[rows, None] - radii[None, :])[upper], np.abs(radii[rows, None] - radii[None, :])[upper])
    n, sx, sy, sxx, sxy, syy = sums
    vx, vy = n * sxx - sx * sx, n * syy - sy * sy
    if n < 2 or vx <= 1e-12 * max(n * sxx, 1e-300) or vy <= 1e-12 * max(n * syy, 1e-300):
        return math.nan
    return float((n * sxy - sx * sy) / math.sqrt(vx * vy))


def packing_summary(state, rule: str = "text") -> dict[str, float]:
    """The thesis's packing figures for one board (Fig 2-4, Table 2.1).

    Parameters
    ----------
    state : State
        The board.
    rule : {"text", "code"}
        Neighbour rule, see `neighbour_edges`.

    Returns
    -------
    dict
        ``n_dots`` (int); ``interior_fraction``: fraction of dots with at
        least 5 neighbours (nan with no dots); ``mean_neighbours_interior``:
        mean neighbour count of the interior dots (nan if there are none);
        ``mean_neighbours``: over all dots; ``rms_excess_separation`` and
        ``mean_spacing``: RMS and mean surface gap of the interior dots'
        neighbours, px (see `separation`); ``size_separation_correlation``:
        of neighbouring pairs (see `size_separation_correlation`);
        ``max_overlap``: worst relative overlap (see `overlaps`);
        ``escaped_dots``: dots outside the box (see `escaped`; 0 without a box);
        ``kinetic_energy``: total, mean mass * px^2 / s^2 (nan if ``state``
        has no ``kinetic_energy()`` method).
    """
    edges = neighbour_edges(state, rule)
    radii = state_arrays(state)[1]
    counts = np.bincount(edges[0], minlength=len(radii))
    interior = counts >= INTERIOR_MIN_NEIGHBOURS
    n = len(counts)
    kinetic = getattr(state, "kinetic_energy", None)
    spacing = _separation(radii, edges, interior_only=True)
    return {
        "n_dots": n,
        "interior_fraction": float(interior.mean()) if n else math.nan,
        "mean_neighbours_interior": float(counts[interior].mean()) if interior.any() else math.nan,
        "mean_neighbours": float(counts.mean()) if n else math.nan,
        "rms_excess_separation": spacing.rms_excess,
        "mean_spacing": spacing.mean_gap,
        "size_separation_correlation": size_separation_correlation(state, rule=rule, edges=edges),
        "max_overlap": overlaps(state)[0],
        "escaped_dots": escaped(state) if hasattr(state, "box") else 0,
        "kinetic_energy": float(kinetic()) if callable(kinetic) else math.nan,
    }

"""A measured film as a qdots board, and the thesis's metrics of it with the image's edge taken into account.

The board (`film_state`) holds the detected dots in image pixels with ``y`` pointing up (row 0 at
the top of the picture is ``y = H``), as every qdots board does, so `qdots.render` draws it the
right way up. Velocities are zero (an image has none); masses are proportional to the volume,
``(d / mean d)^3``, a dot's mass being that of its material.

The image's edge cuts the film. `complete_neighbourhood` marks the dots whose every possible
neighbour (the thesis's text rule: surface gap under one mean radius) lies inside the picture: a dot
whose centre is at least ``r_i + r_max + r_mean`` from each edge of the picture. The metrics of a
dot's neighbourhood (interior fraction, mean neighbours, psi6) are averaged over those dots only;
the cut dots themselves take part as neighbours. Sizes are averaged over the dots the edge does
not cut. Clusters are counted as they are seen (one cut by the edge may continue outside).
"""

from __future__ import annotations

import math

import numpy as np

from labrig.threads import run_tasks

from ..analysis.packing import INTERIOR_MIN_NEIGHBOURS, neighbour_counts
from ..analysis.structure import clusters, hexatic_order, radial_distribution
from ..state import State

#: A cluster of at least this many dots is an aggregate (as in the reproduction of thesis Fig 2-2).
AGGREGATE = 5
#: Diameters further than OUTLIER robust deviations from the median are left out of the size statistics (`size_spread`):
#: a normal distribution has one in 150,000 dots there.
OUTLIER = 4.5
#: Two size populations (`size_populations`): the two-normal mixture's information criterion lower by BIMODAL_BIC, its
#: means BIMODAL_GAP of the larger deviation apart, the smaller holding BIMODAL_SHARE of the dots.
BIMODAL_BIC, BIMODAL_GAP, BIMODAL_SHARE = 10.0, 2.5, 0.05
#: g(r)'s first peak (`first_peak`): the first bin that is the highest within PEAK_BINS bins each side of it and
#: reaches PEAK_SHARE of g's largest value.
PEAK_BINS, PEAK_SHARE = 2, 0.5


def film_state(centres: np.ndarray, diameters: np.ndarray, image_shape: tuple[float, float]) -> State:
    """The board of dots at image ``centres`` ((column, row), px) with ``diameters`` (px) on an open board of
    the image's size, ``y`` up, at rest, masses ``(d / mean d)^3``."""
    h, w = image_shape
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    radii = 0.5 * np.asarray(diameters, dtype=float)
    positions = np.column_stack([centres[:, 0], h - centres[:, 1]])
    masses = (radii / radii.mean()) ** 3 if radii.size else np.zeros(0)
    return State(time=0.0, positions=positions, velocities=np.zeros_like(positions), radii=radii, masses=masses,
                 box=(float(w), float(h)), walls=np.zeros((0, 4)), closed=False)


def complete_neighbourhood(state, window: tuple[float, float, float, float] | None = None) -> np.ndarray:
    """Dots all of whose possible neighbours (text rule) lie inside ``window`` ((x0, y0, x1, y1) in the board's
    coordinates; default the whole box): bool array (N,)."""
    positions = np.asarray(state.positions, dtype=float)
    radii = np.asarray(state.radii, dtype=float)
    if radii.size == 0:
        return np.zeros(0, dtype=bool)
    x0, y0, x1, y1 = (0.0, 0.0, *state.box) if window is None else window
    reach = radii + radii.max() + radii.mean()
    x, y = positions[:, 0], positions[:, 1]
    return (x - reach >= x0) & (x + reach <= x1) & (y - reach >= y0) & (y + reach <= y1)


def size_inliers(diameters) -> np.ndarray:
    """Which ``diameters`` the size statistics keep: those within `OUTLIER` robust deviations (the interquartile range
    over 1.349) of the median (all of fewer than 2)."""
    d = np.asarray(diameters, dtype=float)
    if d.size < 2:
        return np.ones(d.size, dtype=bool)
    iqr = float(np.subtract(*np.percentile(d, [75, 25]))) / 1.349
    return np.abs(d - np.median(d)) <= OUTLIER * max(iqr, 1e-9 * float(np.median(d)))


def size_spread(diameters, errors=None) -> dict:
    """The size spread sigma (SD / mean) of ``diameters``, honest about the measurement error and about a few false
    detections.

    A few fused, split or false dots, or letters taken for dots, would set the SD: diameters more than `OUTLIER`
    robust deviations (the interquartile range over 1.349, the SD of a normal distribution) from the median are left
    out of it (``size_outliers`` counts them; a film's own sizes, even two populations of them, lie within). Of the
    others: ``size_spread_measured`` is SD / mean as measured; ``size_spread_error`` the root mean square of their
    measurement ``errors`` over the mean (0 when none are given); ``size_spread`` the true spread,
    ``sqrt(measured^2 - error^2)`` (the measured variance is the true one plus the error's, the errors being
    independent of the sizes). ``size_spread_robust`` is the same from the interquartile range of all of them and the
    errors' median (times 1.4826): far below ``size_spread``, it says the spread is in a tail, not in the bulk.
    ``size_mean`` is the mean of the diameters kept.
    """
    d = np.asarray(diameters, dtype=float)
    if d.size < 2:
        return {"size_spread": math.nan, "size_spread_measured": math.nan, "size_spread_error": math.nan,
                "size_spread_robust": math.nan, "size_outliers": 0, "size_mean": float(d.mean()) if d.size else math.nan}
    e = np.asarray(errors, dtype=float) if errors is not None else np.full(d.size, np.nan)
    iqr = float(np.subtract(*np.percentile(d, [75, 25]))) / 1.349
    inlier = size_inliers(d)
    kept, kept_errors = d[inlier], e[inlier]
    kept_errors = kept_errors[np.isfinite(kept_errors)]
    mean, sd = float(kept.mean()), float(kept.std(ddof=1)) if kept.size > 1 else 0.0
    rms = float(np.sqrt(np.mean(kept_errors**2))) if kept_errors.size else 0.0
    all_errors = e[np.isfinite(e)]
    typical_error = 1.4826 * float(np.median(np.abs(all_errors))) if all_errors.size else 0.0
    return {"size_spread": math.sqrt(max(sd**2 - rms**2, 0.0)) / mean, "size_spread_measured": sd / mean,
            "size_spread_error": rms / mean,
            "size_spread_robust": math.sqrt(max(iqr**2 - typical_error**2, 0.0)) / float(np.median(d)),
            "size_outliers": int(d.size - kept.size), "size_mean": mean}


def size_populations(diameters) -> dict:
    """Whether the diameters fall into two populations (a two-size sample: large particles among small seeds), and
    each population's share, mean and spread (SD / mean).

    A mixture of two normal distributions of ``log d`` (expectation-maximisation from the quartiles, until its
    parameters change by under 1e-10) is preferred to one when its Bayesian information criterion is lower by
    `BIMODAL_BIC`, its two means are at least `BIMODAL_GAP` times the larger of their deviations apart (two modes, not
    a skewed one), and the smaller population holds at least `BIMODAL_SHARE` of the dots and 5 of them. Returns ``size_populations`` (1 or 2) and, for two,
    ``small_share``, ``small_mean_diameter_px``, ``small_spread`` and the same for ``large`` (NaN for one)."""
    out: dict[str, float] = {"size_populations": 1}
    for part in ("small", "large"):
        out.update({f"{part}_share": math.nan, f"{part}_mean_diameter_px": math.nan, f"{part}_spread": math.nan})
    d = np.asarray(diameters, dtype=float)
    d = d[np.isfinite(d) & (d > 0)]
    if d.size < 20:
        return out
    x = np.log(d)
    n = x.size
    one = float(np.sum(_normal_log_density(x, x.mean(), max(x.std(), 1e-6))))
    mean = np.percentile(x, [25, 75]).astype(float)
    sd = np.full(2, max(x.std() / 2, 1e-3))
    weight = np.array([0.5, 0.5])
    for _ in range(200):
        density = weight * np.exp(np.column_stack([_normal_log_density(x, m, s_) for m, s_ in zip(mean, sd)]))
        total = density.sum(axis=1, keepdims=True)
        share = density / np.maximum(total, 1e-300)
        counts = share.sum(axis=0)
        if np.any(counts < 2):
            return out
        before = np.concatenate([weight, mean, sd])
        weight = counts / n
        mean = (share * x[:, None]).sum(axis=0) / counts
        sd = np.sqrt(np.maximum((share * (x[:, None] - mean) ** 2).sum(axis=0) / counts, 1e-8))
        if np.max(np.abs(np.concatenate([weight, mean, sd]) - before)) < 1e-10:  # converged
            break
    two = float(np.sum(np.log(np.maximum(total[:, 0], 1e-300))))
    bic_one, bic_two = -2 * one + 2 * math.log(n), -2 * two + 5 * math.log(n)
    small, large = np.argsort(mean)
    if (bic_two < bic_one - BIMODAL_BIC and mean[large] - mean[small] >= BIMODAL_GAP * sd.max()
            and weight.min() >= BIMODAL_SHARE and counts.min() >= 5):
        out["size_populations"] = 2
        for part, k in (("small", small), ("large", large)):
            members = d[share[:, k] >= 0.5]
            out.update({f"{part}_share": float(weight[k]), f"{part}_mean_diameter_px": float(members.mean()),
                        f"{part}_spread": float(members.std(ddof=1) / members.mean()) if members.size > 1 else 0.0})
    return out


def _normal_log_density(x, mean, sd):
    return -0.5 * ((x - mean) / sd) ** 2 - math.log(sd * math.sqrt(2 * math.pi))


def film_metrics(state, measured: np.ndarray | None = None, complete: np.ndarray | None = None,
                 nm_per_px: float | None = None, errors: np.ndarray | None = None) -> dict:
    """The thesis's packing figures of a film, edge-aware.

    Parameters
    ----------
    state : State
    measured : bool array (N,), optional
        Dots whose size is measured whole (default all): the size statistics use these.
    complete : bool array (N,), optional
        Dots whose neighbourhood is whole (default all): the neighbourhood metrics use these.
    nm_per_px : float, optional
        Scale; sizes are also given in nm when known.
    errors : ndarray (N,), optional
        Each diameter's measurement error, px: the spread is then given with the error taken out (`size_spread`).

    Returns
    -------
    dict
        ``dots``, ``dots_sized``, ``dots_complete``; ``mean_diameter_px``, ``sd_diameter_px`` (and in nm when
        the scale is known; outliers left out); ``size_spread`` (the thesis's sigma, SD / mean, the measurement error
        and outliers taken out), ``size_spread_measured``, ``size_spread_error``, ``size_spread_robust``,
        ``size_outliers`` (`size_spread`);
        ``interior_fraction`` (>= 5 neighbours), ``mean_neighbours``, ``psi6_local``, ``psi6_global``;
        ``aggregates`` (clusters of >= 5 dots), ``largest_share``, ``single_dots``;
        ``gr_peak_diameters`` (the first peak of g(r), `first_peak`, in mean diameters).
    """
    n = len(state.radii)
    measured = np.ones(n, dtype=bool) if measured is None else np.asarray(measured, dtype=bool)
    complete = np.ones(n, dtype=bool) if complete is None else np.asarray(complete, dtype=bool)
    out: dict[str, float] = {"dots": n, "dots_sized": int(measured.sum()), "dots_complete": int(complete.sum())}
    sized = 2.0 * np.asarray(state.radii, dtype=float)[measured]
    spread = size_spread(sized, None if errors is None else np.asarray(errors, dtype=float)[measured])
    mean = spread.pop("size_mean")
    sd = spread["size_spread_measured"] * mean if sized.size > 1 else math.nan
    out.update(mean_diameter_px=mean, sd_diameter_px=sd)
    out.update(spread)
    # the size mixture beside the packing figures, in a second thread (numpy and the compiled pair searches release
    # the GIL)
    populations, packing = run_tasks([lambda: size_populations(sized), lambda: packing_figures(state, complete, mean)])
    out.update(populations)
    if nm_per_px is not None:
        out.update(mean_diameter_nm=mean * nm_per_px, sd_diameter_nm=sd * nm_per_px)
    out.update(packing)
    return out


def packing_figures(state, complete: np.ndarray, mean: float) -> dict:
    """`film_metrics`'s neighbourhood, cluster and g(r) figures: the neighbourhoods of the dots ``complete``, g(r)'s
    first peak in ``mean`` diameters (px)."""
    n = len(state.radii)
    counts = neighbour_counts(state) if n else np.zeros(0, dtype=int)
    hexatic = hexatic_order(state) if n else None
    inner = complete & (counts > 0)
    _, sizes = clusters(state) if n else (None, np.zeros(0, dtype=int))
    peak = math.nan
    if n >= 2:
        rdf = radial_distribution(state, r_max=min(4.0 * mean, *state.box) if math.isfinite(mean) else None, bins=80)
        peak = first_peak(rdf.r, rdf.g) / mean
    return dict(
        interior_fraction=float(np.mean(counts[complete] >= INTERIOR_MIN_NEIGHBOURS)) if complete.any() else math.nan,
        mean_neighbours=float(counts[complete].mean()) if complete.any() else math.nan,
        psi6_local=float(np.abs(hexatic.psi[inner]).mean()) if hexatic is not None and inner.any() else math.nan,
        psi6_global=float(abs(hexatic.psi[inner].mean())) if hexatic is not None and inner.any() else math.nan,
        aggregates=int(np.sum(sizes >= AGGREGATE)), largest_share=float(sizes[0] / n) if n else math.nan,
        single_dots=int(np.sum(sizes == 1)), gr_peak_diameters=peak)


def first_peak(r: np.ndarray, g: np.ndarray) -> float:
    """Where g(r) has its first peak: the first bin of ``g`` that is the highest within `PEAK_BINS` bins each side and
    reaches `PEAK_SHARE` of the largest finite value (NaN bins left out; NaN when no value is positive). Not the
    largest value itself: on an ordered film the shell at sqrt(7) spacings holds 12 neighbours, and where the first
    shell's peak straddles two bins, the later one rises higher (2.78 mean diameters on a hexagonal film whose
    neighbours sit at 1.05)."""
    finite = np.isfinite(g)
    r, g = np.asarray(r, dtype=float)[finite], np.asarray(g, dtype=float)[finite]
    if not g.size or not g.max() > 0:
        return math.nan
    top = float(g.max())
    for k in range(g.size):
        if g[k] >= PEAK_SHARE * top and g[k] >= g[max(0, k - PEAK_BINS):k + PEAK_BINS + 1].max():
            return float(r[k])
    return math.nan  # not reached: the largest value passes both tests

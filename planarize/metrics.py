"""Roughness figures of merit (thesis section 3.2.3) and the per-snapshot record of a run."""

from __future__ import annotations

import math

import numpy as np

from .heightfield import Surface


def _heights(surface) -> np.ndarray:
    z = surface.z if isinstance(surface, Surface) else np.asarray(surface, dtype=float)
    return z.ravel()


def rms(surface) -> float:
    """Root mean square deviation of the heights from their mean, nm (Eq 3.8; every grid point counts once)."""
    z = _heights(surface)
    return float(np.sqrt(np.mean((z - z.mean()) ** 2)))


def z_range(surface) -> float:
    """Highest minus lowest height, nm (Eq 3.7)."""
    z = _heights(surface)
    return float(z.max() - z.min())


def pixel_curvature(surface: Surface) -> float:
    """How sharply a map bends at the scale of its own pixels: the RMS of ``h * laplacian(z)`` over the RMS of
    ``|grad z|``, both by central differences over the interior points, ``h`` the geometric mean of the two
    spacings; dimensionless.

    About 1 where the pixels resolve every feature (the thesis's hill, depression and random films: 1.01-1.07), more
    where features span a pixel or two (centre crops of measured AFM maps: 1.6-3.6; a step 2; white noise and a
    one-pixel pit about 4.5); ``inf`` where the map bends without a slope (a one-pixel checkerboard) or has no
    interior point (fewer than 3 points a side), 0 on a plane."""
    z = surface.z
    if min(z.shape) < 3:
        return math.inf
    dx, dy = surface.spacing
    centre = z[1:-1, 1:-1]
    along_x = (z[2:, 1:-1] - 2 * centre + z[:-2, 1:-1]) / dx ** 2, (z[2:, 1:-1] - z[:-2, 1:-1]) / (2 * dx)
    along_y = (z[1:-1, 2:] - 2 * centre + z[1:-1, :-2]) / dy ** 2, (z[1:-1, 2:] - z[1:-1, :-2]) / (2 * dy)
    bend = math.sqrt(dx * dy) * np.sqrt(np.mean((along_x[0] + along_y[0]) ** 2))
    slope = np.sqrt(np.mean(along_x[1] ** 2 + along_y[1] ** 2))
    if slope == 0:
        return 0.0 if bend == 0 else math.inf
    return float(bend / slope)


#: Columns of a run's history, with units.
HISTORY_COLUMNS = {
    "target_nm": "oxide thickness at which the row was asked for",
    "thickness_nm": "smallest metal-oxide distance when recorded (the thesis's oxide thickness)",
    "distance_mean_nm": "mean metal-oxide distance",
    "distance_std_nm": "standard deviation of the metal-oxide distances (the thesis's error bars)",
    "metal_rms_nm": "RMS of the metal heights (Eq 3.8; the continuum engine: over the surface's area, Eq 3.8's "
                    "limit as the grid refines)",
    "metal_zrange_nm": "z-range of the metal heights (Eq 3.7)",
    "oxide_rms_nm": "RMS of the oxide heights",
    "oxide_zrange_nm": "z-range of the oxide heights",
    "metal_lost_nm3": "metal volume consumed",
    "oxide_gained_nm3": "oxide volume added above the original surface",
    "volume_error": "oxide_gained / ((k_exp - 1) metal_lost) - 1 (0 to round-off with exact accounting; without "
                    "expansion, k_exp = 1, oxide_gained / metal_lost)",
    "iterations": "batches oxidized so far",
    "point_updates": "metal-point oxidations so far",
    "wall_s": "wall time since the start of the run, s",
}
#: The columns whose discretization error a continuum run estimates, each with an ``_error_nm`` column
#: beside it (`planarize.engines.resolution`).
ESTIMATED = ("metal_rms_nm", "metal_zrange_nm", "oxide_rms_nm", "oxide_zrange_nm")
HISTORY_COLUMNS.update({column.replace("_nm", "_error_nm"): f"estimated discretization error of {column} "
                        "(continuum engine: from the run at half its resolution, Richardson's estimate)"
                        for column in ESTIMATED})


def roughness(metal, oxide) -> dict:
    """RMS (Eq 3.8) and z-range (Eq 3.7) of the metal and oxide heights, nm, as history columns."""
    return {"metal_rms_nm": rms(metal), "metal_zrange_nm": z_range(metal),
            "oxide_rms_nm": rms(oxide), "oxide_zrange_nm": z_range(oxide)}


def history_row(engine, target: float, wall: float) -> dict:
    """One history row (`HISTORY_COLUMNS`) for the current state of ``engine``."""
    d = engine.D
    rough = engine.roughness()
    lost = engine.metal_lost()
    gained = engine.oxide_gained()
    expected = (engine.k_exp - 1.0) * lost
    if expected > 0:
        volume_error = gained / expected - 1.0
    elif engine.k_exp == 1.0 and lost > 0:  # no expansion: no oxide should rise above the metal consumed
        volume_error = gained / lost
    else:
        volume_error = 0.0 if gained == 0 else np.inf
    return {
        "target_nm": float(target),
        "thickness_nm": float(d.min()),
        "distance_mean_nm": float(d.mean()),
        "distance_std_nm": float(d.std()),
        **rough,
        "metal_lost_nm3": lost,
        "oxide_gained_nm3": gained,
        "volume_error": float(volume_error),
        "iterations": int(engine.iterations),
        "point_updates": int(engine.point_updates),
        "wall_s": float(wall),
    }


def history_difference(run, reference, thicknesses, columns=("metal_rms_nm", "oxide_rms_nm")) -> float:
    """Largest relative difference of ``columns`` between two runs at the given oxide thicknesses.

    Each run's history is interpolated at ``thicknesses`` (nm) against the
    thickness it actually reached (``thickness_nm``), so runs that record at
    different moments compare at equal oxide thickness.

    Returns
    -------
    float
        ``max |run / reference - 1|`` over the columns and thicknesses.
    """
    targets = np.asarray(thicknesses, dtype=float)
    worst = 0.0
    for column in columns:
        y = np.interp(targets, run.history["thickness_nm"], run.history[column])
        y_ref = np.interp(targets, reference.history["thickness_nm"], reference.history[column])
        worst = max(worst, float(np.max(np.abs(y / y_ref - 1))))
    return worst

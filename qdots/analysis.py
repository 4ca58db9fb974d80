"""Packing measurements on a board (thesis section 2.4, Appendix A ``runLinearGraph*``).

Every function takes a `qdots.State`, or anything with ``positions`` (N, 2)
and ``radii`` (N,) attributes in px, and works on whole arrays: pairs come
from one KD-tree query, counts from ``np.bincount``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

#: Neighbour rules: "text" is the thesis's prose (section 2.4), "code" its Java (Appendix A).
RULES = ("text", "code")
#: A dot with at least this many neighbours is "interior" (thesis Fig 2-4).
INTERIOR_MIN_NEIGHBOURS = 5


def _arrays(state) -> tuple[np.ndarray, np.ndarray]:
    """Positions (N, 2) and radii (N,) of ``state`` as float arrays, checked."""
    try:
        positions = np.asarray(state.positions, dtype=float)
        radii = np.asarray(state.radii, dtype=float)
    except AttributeError:
        raise ValueError(
            f"state must have positions and radii attributes, got {type(state).__name__}"
        ) from None
    if positions.size == 0:
        positions = positions.reshape(0, 2)
    if positions.ndim != 2 or positions.shape[1] != 2:
        raise ValueError(f"state.positions must have shape (N, 2), got {positions.shape}")
    if radii.shape != (len(positions),):
        raise ValueError(f"state.radii must have shape ({len(positions)},), got {radii.shape}")
    return positions, radii


def _pairs(positions: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """All pairs ``i < j`` with centre distance <= ``reach`` px, and their distances."""
    if len(positions) < 2:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty, np.zeros(0)
    pairs = cKDTree(positions).query_pairs(reach, output_type="ndarray")
    i, j = pairs[:, 0], pairs[:, 1]
    delta = positions[i] - positions[j]
    return i, j, np.sqrt(np.einsum("ij,ij->i", delta, delta))


def overlaps(state) -> tuple[float, tuple[int, int]]:
    """Worst relative overlap between two dots.

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
    positions, radii = _arrays(state)
    if len(radii) < 2:
        return 0.0, (-1, -1)
    i, j, d = _pairs(positions, 2.0 * float(radii.max()))
    if not len(d):
        return 0.0, (-1, -1)
    rsum = radii[i] + radii[j]
    relative = (rsum - d) / (0.5 * rsum)
    k = int(np.argmax(relative))
    if relative[k] <= 0:
        return 0.0, (-1, -1)
    return float(relative[k]), (int(i[k]), int(j[k]))


def neighbour_counts(state, rule: str = "text", mean_radius: float | None = None) -> np.ndarray:
    """Number of neighbours of every dot.

    Parameters
    ----------
    state : State
        The board (``positions`` and ``radii`` in px).
    rule : {"text", "code"}
        ``"text"`` (default, thesis section 2.4): dots ``i`` and ``j`` are
        neighbours if their surface gap ``d - r_i - r_j`` is less than one
        mean radius. ``"code"`` (thesis Java, ``runLinearGraph``): ``j``
        counts as a neighbour of ``i`` if ``d <= r_i + 2 r_j``; this is not
        symmetric when the radii differ (a large dot sees a small one less
        readily than the small dot sees it). The Java skips a pair when
        ``d > r_i + 2 r_j``, so equality counts.
    mean_radius : float, optional
        The mean radius of the ``"text"`` rule, px (> 0). Default: the mean of
        ``state.radii``. Ignored by ``"code"``.

    Returns
    -------
    ndarray of int, shape (N,)
        Neighbour count of each dot.
    """
    positions, radii = _arrays(state)
    n = len(radii)
    if rule not in RULES:
        raise ValueError(f"rule must be one of {RULES}, got {rule!r}")
    if n < 2:
        return np.zeros(n, dtype=int)
    rmax = float(radii.max())
    if rule == "text":
        if mean_radius is None:
            mean_radius = float(radii.mean())
        elif not (math.isfinite(mean_radius) and mean_radius > 0):
            raise ValueError(f"mean_radius must be > 0 px, got {mean_radius!r}")
        i, j, d = _pairs(positions, 2.0 * rmax + mean_radius)
        near = d - radii[i] - radii[j] < mean_radius
        i_of, j_of = i[near], j[near]  # symmetric: each pair counts for both dots
    else:
        i, j, d = _pairs(positions, 3.0 * rmax)
        i_sees_j = d <= radii[i] + 2.0 * radii[j]
        j_sees_i = d <= radii[j] + 2.0 * radii[i]
        i_of, j_of = i[i_sees_j], j[j_sees_i]
    return np.bincount(i_of, minlength=n) + np.bincount(j_of, minlength=n)


def packing_summary(state, rule: str = "text") -> dict[str, float]:
    """The thesis's packing figures for one board (Fig 2-4, Table 2.1).

    Parameters
    ----------
    state : State
        The board.
    rule : {"text", "code"}
        Neighbour rule, see `neighbour_counts`.

    Returns
    -------
    dict
        ``n_dots`` (int); ``interior_fraction``: fraction of dots with at
        least 5 neighbours (nan with no dots); ``mean_neighbours_interior``:
        mean neighbour count of the interior dots (nan if there are none);
        ``max_overlap``: worst relative overlap (see `overlaps`);
        ``kinetic_energy``: total, mean mass * px^2 / s^2 (nan if ``state``
        has no ``kinetic_energy()`` method).
    """
    counts = neighbour_counts(state, rule=rule)
    interior = counts >= INTERIOR_MIN_NEIGHBOURS
    n = len(counts)
    kinetic = getattr(state, "kinetic_energy", None)
    return {
        "n_dots": n,
        "interior_fraction": float(interior.mean()) if n else math.nan,
        "mean_neighbours_interior": float(counts[interior].mean()) if interior.any() else math.nan,
        "max_overlap": overlaps(state)[0],
        "kinetic_energy": float(kinetic()) if callable(kinetic) else math.nan,
    }

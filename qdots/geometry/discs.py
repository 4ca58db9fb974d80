"""Discs against discs and against walls: overlaps, clashes, clearances.

Two discs of radii ``r_i``, ``r_j`` whose centres are ``d`` apart (``r_i + r_j``: their contact distance):

* their *relative overlap* is ``(r_i + r_j - d) / ((r_i + r_j) / 2)``, the depth of interpenetration in mean
  radii of the pair (``(2r - d) / r`` for equal radii), > 0 when they overlap (`relative_overlap`,
  `overlapping_pairs`, `worst_overlap`);
* they *clash* within a margin ``m`` when ``d < r_i + r_j + m``: their surfaces are closer than ``m`` px
  (`clashing_pairs` within one set of discs, `DiscTree.clashing_partners` between two);
* one is *nested* in the other when ``d < |r_i - r_j|`` (`nested_pairs`);
* a disc's *nearest ratio* is the distance to its nearest neighbour's centre over the mean of their diameters
  (`nearest_ratio`): under 1, they overlap.

A disc of radius ``r`` whose centre lies ``s`` from a wall segment has the *clearance* ``s - r`` px
(`wall_clearances`; negative: it crosses the wall), the relative overlap ``(r - s) / r``
(`worst_wall_overlap`), and is clear of it by a margin ``m`` when ``s >= r + m`` (`clear_of_walls`).

Each test is written once, in the floating-point form its callers have always used: results do not change
by round-off from one caller to the next.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from labrig.validate import InputError

from .pairs import MAX_PAIRS, pairs_with_distances

#: Most (point, segment) distances of one `segment_distances` call: about 60 bytes each in its
#: temporaries, 1.2 GB (the hard cases take 30,000 dots x 4 walls, a deposition 32 candidates x the lines).
MAX_DISTANCES = 20_000_000
#: Slack of `nested_pairs`, px: two equal discs at one centre count as nested.
NESTING_SLACK = 1e-9
#: Relative widening of the KD-tree reach of `DiscTree.clashing_partners`: the tree's own rounding of the
#: reach never drops a pair that the exact test keeps.
REACH_SLACK = 1e-9


def nearest_ratio(centres: np.ndarray, diameters: np.ndarray) -> np.ndarray:
    """Each disc's nearest-neighbour centre distance over the mean of their two diameters (inf for a lone disc)."""
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    diameters = np.asarray(diameters, dtype=float)
    if len(centres) < 2:
        return np.full(len(centres), np.inf)
    distance, index = cKDTree(centres).query(centres, k=2)
    return distance[:, 1] / (0.5 * (diameters + diameters[index[:, 1]]))


def nearest_centre(points: np.ndarray, centres: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``points``, the distance to the nearest of ``centres`` and its index (inf and 0 when there are
    no centres)."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    if not len(centres):
        return np.full(len(points), np.inf), np.zeros(len(points), dtype=np.intp)
    distance, index = cKDTree(centres).query(points)
    return np.asarray(distance, dtype=float), np.asarray(index, dtype=np.intp)


def relative_overlap(distance, contact):
    """``(contact - distance) / (contact / 2)``: the relative overlap of discs whose centres are ``distance``
    apart and touch at ``contact = r_i + r_j`` (px, > 0); broadcasts. Dimensionless, > 0 when they overlap."""
    return (contact - distance) / (0.5 * contact)


def _overlap_search(radii: np.ndarray) -> str:
    """What sets the reach of an overlap search, for `pairs_with_distances`'s message."""
    return f"the overlap search (2 x the largest radius, {float(radii.max(initial=0.0)):g} px)"


def overlapping_pairs(positions: np.ndarray, radii: np.ndarray, tolerance: float = 0.0, what: str | None = None
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pairs of discs whose relative overlap exceeds ``tolerance``, with their centre distances.

    Parameters
    ----------
    positions : ndarray, shape (N, 2)
        Centres, px.
    radii : ndarray, shape (N,)
        Radii, px (> 0).
    tolerance : float
        Relative overlap allowed, in [0, 1): a pair is listed when ``d < (r_i + r_j) (1 - tolerance / 2)``
        (0: every overlapping pair; touching discs are not listed).
    what : str, optional
        What asked for the search, for the message when it could list too many pairs (default: the overlap
        search and the largest radius).

    Returns
    -------
    i, j : ndarray of int
        The pairs, ``i < j``, in the order of `qdots.geometry.pairs_with_distances`.
    distance : ndarray
        Their centre distances, px.

    Raises
    ------
    labrig.validate.InputError
        When the search (pairs within twice the largest radius) could list more than `MAX_PAIRS` pairs.
    """
    if len(radii) < 2:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty, np.zeros(0)
    i, j, d = pairs_with_distances(positions, 2.0 * float(radii.max()), what or _overlap_search(radii))
    hit = d < (radii[i] + radii[j]) * (1.0 - 0.5 * tolerance)
    return i[hit], j[hit], d[hit]


def worst_overlap(positions: np.ndarray, radii: np.ndarray, tolerance: float = 0.0, what: str | None = None
                  ) -> tuple[float, tuple[int, int]]:
    """The largest relative overlap of two discs, and their pair.

    Among the pairs of `overlapping_pairs` (``positions``, ``radii``, ``tolerance``, ``what``: see there).

    Returns
    -------
    worst : float
        Largest `relative_overlap` (> ``tolerance``), or 0.0 when no pair overlaps by more than
        ``tolerance``.
    pair : (int, int)
        ``(i, j)``, ``i < j``, of that pair (the first in the search's order on a tie), or ``(-1, -1)``.
    """
    i, j, d = overlapping_pairs(positions, radii, tolerance, what)
    if not len(d):
        return 0.0, (-1, -1)
    relative = relative_overlap(d, radii[i] + radii[j])
    k = int(np.argmax(relative))
    return float(relative[k]), (int(i[k]), int(j[k]))


def nested_pairs(positions: np.ndarray, radii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The pairs ``(i, j)``, ``i < j``, of which one disc lies inside the other: centre distance below
    ``|r_i - r_j| + NESTING_SLACK`` px (a dot swallowed by another). Bounded as `overlapping_pairs`."""
    if len(radii) < 2:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty
    i, j, d = pairs_with_distances(positions, 2.0 * float(radii.max()), _overlap_search(radii))
    inside = d < np.abs(radii[i] - radii[j]) + NESTING_SLACK
    return i[inside], j[inside]


def clashing_pairs(centres: np.ndarray, radii: np.ndarray, margin: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """The pairs ``(a, b)``, ``a < b``, of discs whose surfaces are closer than ``margin`` px: centre distance
    ``d < r_a + r_b + margin`` (``margin = 0``: overlapping, touching discs are not listed). Bounded as
    `overlapping_pairs`."""
    if len(radii) < 2:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty
    a, b, d = pairs_with_distances(centres, 2.0 * float(radii.max()) + margin,
                                   f"a clash search (2 x the largest radius, {float(radii.max()):g} px, "
                                   f"+ margin {margin:g} px)")
    bad = d < radii[a] + radii[b] + margin
    return a[bad], b[bad]


class DiscTree:
    """Discs indexed for clash queries (a KD-tree over their centres, built once).

    Parameters
    ----------
    centres : array_like, shape (N, 2)
        Centres, px (N may be 0).
    radii : array_like, shape (N,)
        Radii, px.
    """

    def __init__(self, centres, radii):
        self.centres = np.array(centres, dtype=float).reshape(-1, 2)  # copies: the tree stays true to them
        self.radii = np.array(radii, dtype=float).reshape(-1)
        self._tree = cKDTree(self.centres) if len(self.radii) else None

    def __len__(self) -> int:
        return len(self.radii)

    def clashing_partners(self, centres, radii, margin: float = 0.0) -> np.ndarray:
        """For each disc given, the lowest index of a disc of the tree whose surface it comes closer than
        ``margin`` px to (centre distance ``d < r + R + margin``), or -1 when it is clear of them all.

        The queries go in chunks of at most `qdots.geometry.MAX_PAIRS` / N discs, so that no more pairs
        than that are listed at once.

        Returns
        -------
        ndarray of int, shape (P,)
        """
        centres = np.asarray(centres, dtype=float).reshape(-1, 2)
        radii = np.asarray(radii, dtype=float).reshape(-1)
        partners = np.full(len(radii), -1, dtype=np.intp)
        if self._tree is None or not len(radii):
            return partners
        step = max(1, MAX_PAIRS // len(self.radii))
        for start in range(0, len(radii), step):
            part = slice(start, start + step)
            pos, r = centres[part], radii[part]
            reach = float(r.max() + self.radii.max() + margin) * (1.0 + REACH_SLACK)
            pairs = cKDTree(pos).sparse_distance_matrix(self._tree, reach, output_type="ndarray")
            if not len(pairs):
                continue
            i, j = pairs["i"], pairs["j"]
            dx = pos[i, 0] - self.centres[j, 0]
            dy = pos[i, 1] - self.centres[j, 1]
            bad = np.sqrt(dx * dx + dy * dy) < r[i] + self.radii[j] + margin
            found = np.full(len(r), len(self.radii), dtype=np.intp)
            np.minimum.at(found, i[bad], j[bad])
            partners[part] = np.where(found < len(self.radii), found, -1)
        return partners


def segment_distances(points: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Distance from each point to each segment, px; shape (P, M).

    Parameters
    ----------
    points : ndarray, shape (P, 2)
    segments : ndarray, shape (M, 4)
        ``(x0, y0, x1, y1)`` with nonzero length. ``P * M`` is at most `MAX_DISTANCES`.
    """
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    segments = np.asarray(segments, dtype=float).reshape(-1, 4)
    if len(points) * len(segments) > MAX_DISTANCES:
        raise InputError(f"{len(points):,} points x {len(segments):,} segments make {len(points) * len(segments):,} "
                         f"distances, more than the {MAX_DISTANCES:,} allowed")
    start, along = segments[None, :, :2], segments[None, :, 2:] - segments[None, :, :2]
    offset = points[:, None, :] - start
    t = np.clip(np.einsum("pmk,pmk->pm", offset, along) / np.einsum("pmk,pmk->pm", along, along), 0.0, 1.0)
    return np.linalg.norm(offset - t[:, :, None] * along, axis=2)


def wall_clearances(centres: np.ndarray, radii: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Clearance of each disc from each segment, ``s - r`` px (negative: the disc crosses it); shape (P, M).
    ``P * M`` is at most `MAX_DISTANCES`."""
    return segment_distances(centres, segments) - np.asarray(radii, dtype=float).reshape(-1)[:, None]


def worst_wall_overlap(centres: np.ndarray, radii: np.ndarray, segments: np.ndarray
                       ) -> tuple[float, tuple[int, int]]:
    """The largest relative overlap of a disc with a wall segment, ``(r - s) / r``, and where it is.

    Returns
    -------
    worst : float
        Largest ``(r - s) / r`` (> 0), or 0.0 when every disc is clear of every segment (touching counts as
        clear).
    where : (int, int)
        ``(disc, segment)`` of that overlap (the first on a tie), or ``(-1, -1)``.
    """
    radii = np.asarray(radii, dtype=float).reshape(-1)
    if not len(radii) or not len(segments):
        return 0.0, (-1, -1)
    relative = -wall_clearances(centres, radii, segments) / radii[:, None]
    k, m = np.unravel_index(int(np.argmax(relative)), relative.shape)
    if not relative[k, m] > 0:
        return 0.0, (-1, -1)
    return float(relative[k, m]), (int(k), int(m))


def clear_of_walls(centres: np.ndarray, radii: np.ndarray, segments: np.ndarray, margin: float = 0.0) -> np.ndarray:
    """Which discs keep ``margin`` px clear of every segment: ``s >= r + margin`` for each segment (all True
    without segments); bool, shape (P,). ``P * M`` is at most `MAX_DISTANCES`."""
    radii = np.asarray(radii, dtype=float).reshape(-1)
    if not len(segments):
        return np.ones(len(radii), dtype=bool)
    return np.all(segment_distances(centres, segments) >= radii[:, None] + margin, axis=1)

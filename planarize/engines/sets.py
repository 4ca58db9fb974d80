"""The oxide sets of every metal point as one object, `OxideSets`, and the compiled steps that read and write it.

A metal point's oxide set is the oxide points that grow when it is oxidized (`planarize.engines.features`).
The fast engine keeps all of them as rows ``(metal point, oxide point)`` and, per sweep, picks the batch
of points to oxidize (`OxideSets.batch`), finds the points whose distance may have grown
(`OxideSets.stale`), replaces the sets of recomputed points (`OxideSets.replace`) and bounds distances by
the nearest set point (`OxideSets.bound`). Every step is one compiled pass that runs without the GIL.
"""

from __future__ import annotations

import math

import numpy as np

from labrig.compiled import jit

from .features import FeatureTables
from .kernels import nearest_image

_INF = math.inf


@jit
def _batch(distance, tolerance, tie, wait, neighbours, pair_o, start, sharers, d, first):
    n = len(distance)
    limit = distance.min() + tolerance
    candidates = np.empty(n, dtype=np.intp)
    count = 0
    for p in range(n):  # every point written, the candidates counted: no branch to mispredict
        candidates[count] = p
        count += distance[p] <= limit
    candidates = candidates[:count]
    for p in candidates:  # d: inf except at the candidates (restored before returning)
        d[p] = distance[p] if wait else 0.0  # (together: no candidate is closer than another)
    for p in candidates:  # first: per oxide point, the smallest candidate distance holding it
        for r in range(start[p], start[p + 1]):
            first[pair_o[r]] = min(first[pair_o[r]], d[p])
    out = np.zeros(n, dtype=np.bool_)
    n_rows = 0
    for p in candidates:
        rival = _INF
        for b in range(neighbours.shape[1]):
            u = neighbours[p, b]
            if u >= 0:
                rival = min(rival, d[u])
        for r in range(start[p], start[p + 1]):
            rival = min(rival, first[pair_o[r]])
        taken = not rival < d[p] - tie
        out[p] = taken
        n_rows += taken * (start[p + 1] - start[p])
    rows = np.empty(n_rows, dtype=np.intp)
    row_size = np.empty(n_rows)
    row_sharers = np.empty(n_rows)
    c = 0
    for p in candidates:
        if out[p]:
            for r in range(start[p], start[p + 1]):
                rows[c] = r
                row_size[c] = start[p + 1] - start[p]
                row_sharers[c] = sharers[pair_o[r]]
                c += 1
    for p in candidates:
        for r in range(start[p], start[p + 1]):
            first[pair_o[r]] = _INF
        d[p] = _INF
    return out, rows, row_size, row_sharers


@jit
def _stale(in_batch, raised, neighbours, pair_m, pair_o):
    n = len(in_batch)
    stale = in_batch.copy()
    for p in range(n):
        if in_batch[p]:
            for b in range(neighbours.shape[1]):
                u = neighbours[p, b]
                if u >= 0:
                    stale[u] = True
    is_raised = np.zeros(n, dtype=np.bool_)
    for a in range(len(raised)):
        is_raised[raised[a]] = True
    for r in range(len(pair_m)):  # rows are sorted by metal point: the writes stream, a branch would mispredict
        stale[pair_m[r]] |= is_raised[pair_o[r]]
    return stale


@jit
def _replace_rows(pair_m, pair_o, start, sharers, points, owner, oxide):
    n = len(start) - 1
    size = len(pair_m)
    for p in points:
        size -= start[p + 1] - start[p]
    size += len(owner)
    new_m = np.empty(size, dtype=np.intp)
    new_o = np.empty(size, dtype=np.intp)
    new_start = np.empty(n + 1, dtype=np.intp)
    c = 0
    a = 0  # next of points
    j = 0  # next row of owner, oxide
    for p in range(n):  # a merge: rows stay sorted by metal point
        new_start[p] = c
        if a < len(points) and points[a] == p:
            a += 1
            for r in range(start[p], start[p + 1]):
                sharers[pair_o[r]] -= 1
            while j < len(owner) and owner[j] == p:
                new_m[c], new_o[c] = p, oxide[j]
                sharers[oxide[j]] += 1
                c += 1
                j += 1
        else:
            for r in range(start[p], start[p + 1]):
                new_m[c], new_o[c] = p, pair_o[r]
                c += 1
    new_start[n] = c
    return new_m, new_o, new_start


@jit
def _vertex_gap(metal, oxide, zm, zo, t):
    gap = np.empty(len(metal))
    for a in range(len(metal)):
        m, o = metal[a], oxide[a]
        mi, oi = m // t.ny, o // t.ny
        di, dj = nearest_image(oi - mi, (o - oi * t.ny) - (m - mi * t.ny), t.nx, t.ny, t.periodic)
        ex, ey, ez = di * t.dx, dj * t.dy, zo[o] - zm[m]
        gap[a] = math.sqrt(ex * ex + ey * ey + ez * ez)
    return gap


@jit
def _remember_nearest(owner, oxide, near, zm, zo, t):
    gap = _vertex_gap(owner, oxide, zm, zo, t)
    start = 0
    while start < len(owner):
        best = start
        stop = start + 1
        while stop < len(owner) and owner[stop] == owner[start]:
            if gap[stop] <= gap[best]:  # of equally near ones, the last
                best = stop
            stop += 1
        near[owner[start]] = oxide[best]
        start = stop




class OxideSets:
    """The oxide set of every metal point of an ``n``-point grid, as rows ``(metal point, oxide point)``.

    Invariants, kept by `replace` (the only method that writes rows):

    * rows are sorted by metal point: those of point ``p`` are rows ``start[p]:start[p + 1]`` of
      `metal` and `oxide`, and within them the oxide points are distinct and ascending;
    * ``sharers[o]`` is the number of rows holding oxide point ``o``: the metal points whose set holds
      it, Eq 3.9's second factor;
    * ``nearest[p]`` is the oxide point of ``p``'s rows nearest to ``p`` when the rows were written
      (`note_nearest`), so that its distance now is an upper bound of ``p``'s distance (`bound`):
      the point-to-point distance is one of the feature pairs a distance is the smallest of.

    Attributes
    ----------
    metal, oxide : ndarray of int, shape (rows,)
    start : ndarray of int, shape (n + 1,)
    sharers, nearest : ndarray of int, shape (n,)
    """

    def __init__(self, n: int):
        self.metal = np.zeros(0, dtype=np.intp)
        self.oxide = np.zeros(0, dtype=np.intp)
        self.start = np.zeros(n + 1, dtype=np.intp)
        self.sharers = np.zeros(n, dtype=np.intp)
        self.nearest = np.full(n, -1, dtype=np.intp)
        self._scratch = (np.full(n, np.inf), np.full(n, np.inf))  # for `batch`: inf between calls

    def sizes(self) -> np.ndarray:
        """Number of oxide points in each metal point's set."""
        return np.diff(self.start)

    def replace(self, points, owner, oxide) -> None:
        """Replace the sets of ``points`` (ascending) by the rows ``owner, oxide`` (every owner among
        ``points``, ascending; oxide points ascending within an owner)."""
        self.metal, self.oxide, self.start = _replace_rows(
            self.metal, self.oxide, self.start, self.sharers, np.asarray(points, dtype=np.intp),
            np.asarray(owner, dtype=np.intp), np.asarray(oxide, dtype=np.intp))

    def note_nearest(self, tables: FeatureTables, zm, zo, owner, oxide) -> None:
        """For each metal point of the rows ``owner, oxide`` (grouped by owner), remember its nearest oxide point."""
        _remember_nearest(np.asarray(owner, dtype=np.intp), np.asarray(oxide, dtype=np.intp), self.nearest, zm, zo,
                          tables)

    def bound(self, tables: FeatureTables, zm, zo, points) -> np.ndarray:
        """Upper bound of each of ``points``' distance now: its distance to the `nearest` point of its set, nm.

        (It is looser than the old closest pair by at most a feature's size, which at 100 nm of oxide
        widens the candidate search by hundredths of a nm.)
        """
        points = np.asarray(points, dtype=np.intp)
        return _vertex_gap(points, self.nearest[points], zm, zo, tables)

    def batch(self, distance, tolerance: float, tie: float, wait: bool, neighbours):
        """The points to oxidize now: within ``tolerance`` of the smallest ``distance``, and (if ``wait``) each
        the closest among the candidates it interacts with (a neighbour in ``neighbours``, or a sharer of an
        oxide point), exact ties (within ``tie``) together.

        Returns the points (boolean mask), their set rows (ascending), and for each row its set's size and its
        oxide point's number of sharers (Eq 3.9's shares).
        """
        return _batch(distance, float(tolerance), float(tie), bool(wait), neighbours, self.oxide, self.start,
                      self.sharers, *self._scratch)

    def stale(self, in_batch, raised, neighbours) -> np.ndarray:
        """The points whose distance may have grown (boolean mask): those of ``in_batch``, their
        ``neighbours`` (their features moved) and the points whose set holds a ``raised`` oxide point."""
        return _stale(in_batch, np.asarray(raised, dtype=np.intp), neighbours, self.metal, self.oxide)

"""Pair searches: which dots are near which, on the compiled cell grid and on a KD-tree.

* `pairs_within` (the engine's): every pair ``(i, j)``, ``i < j``, closer than a cutoff, strictly, in the
  order of a cell grid (compiled). `VerletPairs` keeps such a list with a skin and rebuilds it only when
  some dot has moved more than ``skin / 2`` since the last build, so it never misses a pair within the
  cutoff (two dots closing in on each other can reduce their distance by at most ``skin`` before a
  rebuild). ``skin = 0`` rebuilds every step. The grid search is 1.5-2.3x faster than scipy's KD-tree
  from 300 to 30,000 dots (measured on a 2-core machine). `pairs_closer` keeps the sub-list of pairs
  whose surfaces are closer than a gap; `pair_separation` is the offset of one pair (compiled callers).
* `pairs_with_distances` (the analysis's): every pair ``(i, j, d)`` at most a reach apart, with its
  centre distance, in the order of scipy's KD-tree, refused beforehand (`pair_bound`) when they could be
  more than `MAX_PAIRS`.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import cKDTree

from labrig.compiled import jit
from labrig.validate import InputError, real

from ..limits import MAX_SKIN

#: Most pairs of dots one pair search lists (the engine's Verlet lists; `pairs_with_distances`, by `pair_bound`,
#: for the analysis and the scene checks): about 40 bytes a pair in indices, distances and offsets, 4 GB. The
#: largest boards measured have far fewer: 4e6 pairs for g(r) to 5 mean diameters on 10^5 dots, about 1e7 within
#: 2 diameters on 10^6.
MAX_PAIRS = 100_000_000
#: Most cells of the grid of one pair search (8 bytes each: 512 MiB). A board gets about 2 cells a dot,
#: 2e6 for the largest (`qdots.scene.MAX_DOTS`); only dots strung along a line with a cutoff far below their
#: spacing asked for more, and now get wider cells (the same pairs).
MAX_GRID_CELLS = 2**26


@jit(inline=True)
def pair_separation(x, y, radii, a, b):
    """``(dx, dy, d2, contact)`` of dots ``a`` and ``b``: the offset from ``a`` to ``b`` (px), its squared
    length (px^2) and the distance at which they touch, ``r_a + r_b`` (px)."""
    dx = x[b] - x[a]
    dy = y[b] - y[a]
    return dx, dy, dx * dx + dy * dy, radii[a] + radii[b]


@jit
def moved_beyond(x, y, anchor_x, anchor_y, reach):
    """True when some point moved farther than ``reach`` from its anchor (one pass, no temporaries)."""
    reach2 = reach * reach
    for k in range(x.size):
        dx = x[k] - anchor_x[k]
        dy = y[k] - anchor_y[k]
        if not dx * dx + dy * dy <= reach2:  # also true for nan
            return True
    return False


@jit
def extent(x, y):
    """``(x0, y0, x1, y1, finite)``: the bounding box of the points, px, and whether every coordinate is
    finite, in one pass (four numpy reductions and two finiteness checks cost ~10 us at 300 dots)."""
    x0 = y0 = math.inf
    x1 = y1 = -math.inf
    finite = True
    for k in range(x.size):
        if not (abs(x[k]) < math.inf and abs(y[k]) < math.inf):
            finite = False
        x0 = min(x0, x[k])
        x1 = max(x1, x[k])
        y0 = min(y0, y[k])
        y1 = max(y1, y[k])
    return x0, y0, x1, y1, finite


@jit
def _cell_pairs(x, y, cutoff, cell, nx, ny, x0, y0, out_i, out_j):
    """Pairs ``i < j`` closer than ``cutoff`` found through a grid of ``nx`` x ``ny`` cells of side ``cell``
    from ``(x0, y0)``; written to ``out_i``, ``out_j`` when they are long enough. Returns how many there are."""
    n = x.size
    ids = np.empty(n, np.int64)
    for a in range(n):
        ids[a] = min(int((x[a] - x0) / cell), nx - 1) * ny + min(int((y[a] - y0) / cell), ny - 1)
    order = np.argsort(ids)
    start = np.zeros(nx * ny + 1, np.int64)
    for a in range(n):
        start[ids[a] + 1] += 1
    for c in range(nx * ny):
        start[c + 1] += start[c]
    cutoff2 = cutoff * cutoff
    reach = int(math.ceil(cutoff / cell))
    room = out_i.size
    m = 0
    for s in range(n):
        a = order[s]
        own = ids[a]
        cx = own // ny
        cy = own % ny
        for ex in range(max(cx - reach, 0), min(cx + reach, nx - 1) + 1):
            for ey in range(max(cy - reach, 0), min(cy + reach, ny - 1) + 1):
                c = ex * ny + ey
                if c < own:
                    continue  # each pair of cells once
                for t in range(start[c], start[c + 1]):
                    b = order[t]
                    if c == own and b <= a:
                        continue
                    dx = x[b] - x[a]
                    dy = y[b] - y[a]
                    if dx * dx + dy * dy < cutoff2:
                        if m < room:
                            out_i[m] = min(a, b)
                            out_j[m] = max(a, b)
                        m += 1
    return m


def pairs_within(x: np.ndarray, y: np.ndarray, cutoff: float, expected: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """Every pair ``(i, j)``, ``i < j``, of points closer than ``cutoff`` (two int arrays).

    Cells are at least ``cutoff / 2`` wide and at most ~2 per point (a sparse board does not
    allocate an empty grid), `MAX_GRID_CELLS` in all. With ``expected`` near the number of pairs (a
    Verlet list's last count) one pass over the grid suffices; otherwise a second pass fills arrays of
    the size counted.

    Raises
    ------
    ValueError
        On non-finite coordinates; `labrig.validate.InputError` when there are more than `MAX_PAIRS`
        pairs (counted before anything of their size is allocated).
    """
    if len(x) < 2:
        return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp)
    x0, y0, x1, y1, finite = extent(x, y)
    if not finite:
        raise ValueError("pair search: the positions are not all finite")
    width, height = x1 - x0, y1 - y0
    cell = max(cutoff / 2.0, math.sqrt(max(width * height, 1.0) / (2.0 * len(x))))
    if (width / cell + 1.0) * (height / cell + 1.0) > MAX_GRID_CELLS:  # dots along a line, a tiny cutoff
        cell = (width + height) / (math.sqrt(MAX_GRID_CELLS) - 1.0)
    nx, ny = int(width / cell) + 1, int(height / cell) + 1
    room = int(1.25 * min(expected, MAX_PAIRS, len(x) * (len(x) - 1) // 2)) + 16  # a hint: never more than can be
    i, j = np.empty(room, dtype=np.intp), np.empty(room, dtype=np.intp)
    m = _cell_pairs(x, y, cutoff, cell, nx, ny, x0, y0, i, j)
    if m > MAX_PAIRS:
        raise InputError(f"pair search: {m:,} pairs of dots closer than {cutoff:g} px, more than the "
                         f"{MAX_PAIRS:,} allowed (the largest dot and the forces' range set this distance)")
    if m > room:
        i, j = np.empty(m, dtype=np.intp), np.empty(m, dtype=np.intp)
        _cell_pairs(x, y, cutoff, cell, nx, ny, x0, y0, i, j)
    return i[:m].copy(), j[:m].copy()


def pair_bound(x: np.ndarray, y: np.ndarray, reach: float) -> int:
    """An upper bound on the number of pairs of points at most ``reach`` apart (px), without listing them.

    The points are binned in square cells at least ``reach / 2`` wide (and about 3 per point at most): two
    points within ``reach`` lie in cells at most 2 apart along x and along y, so the bound counts, for each
    point, the points in the 5 x 5 cells around its own (a summed-area table). O(N) time and memory; about
    twice the true count on a uniform board (25 cells of side ``reach / 2`` against a disc of radius
    ``reach``), ``N (N - 1) / 2`` when every point is within ``reach`` of every other.

    Parameters
    ----------
    x, y : ndarray, shape (N,)
        Coordinates, px; non-finite ones give the largest bound, ``N (N - 1) / 2``.
    reach : float
        Distance, px (>= 0).
    """
    x, y = np.asarray(x, dtype=float).ravel(), np.asarray(y, dtype=float).ravel()
    n = x.size
    every = n * (n - 1) // 2
    if n < 2:
        return 0
    if not (math.isfinite(reach) and np.isfinite(x).all() and np.isfinite(y).all()):
        return every
    x0, y0 = float(x.min()), float(y.min())
    width, height = float(x.max()) - x0, float(y.max()) - y0
    # 1e-6: a pair within reach is less than 2 cells apart even after the round-off of (x - x0) / cell
    cell = max(0.5 * max(reach, 0.0) * (1.0 + 1e-6), math.sqrt(width * height / n), max(width, height) / n)
    if not cell > 0:  # every point at one place
        return every
    k = math.ceil(max(reach, 0.0) / cell + 1e-6)  # how many cells apart two points within reach may be
    ix = np.floor((x - x0) / cell).astype(np.int64)
    iy = np.floor((y - y0) / cell).astype(np.int64)
    nx, ny = int(ix.max()) + 1, int(iy.max()) + 1
    counts = np.bincount(ix * ny + iy, minlength=nx * ny).reshape(nx, ny)
    table = np.zeros((nx + 1, ny + 1), dtype=np.int64)
    table[1:, 1:] = counts.cumsum(axis=0).cumsum(axis=1)
    lo_x, hi_x = np.clip(np.arange(nx) - k, 0, nx), np.clip(np.arange(nx) + k + 1, 0, nx)
    lo_y, hi_y = np.clip(np.arange(ny) - k, 0, ny), np.clip(np.arange(ny) + k + 1, 0, ny)
    around = (table[hi_x][:, hi_y] - table[lo_x][:, hi_y] - table[hi_x][:, lo_y] + table[lo_x][:, lo_y])
    return min(every, (int((counts * around).sum()) - n) // 2)


@jit
def pairs_closer(x, y, radii, i, j, extra):
    """The pairs ``(i[k], j[k])`` whose surfaces are closer than ``extra`` px (centre distance below
    ``r_i + r_j + extra``), in their order: two new int arrays (a sub-list of a longer pair list)."""
    keep = np.empty(i.size, np.bool_)
    m = 0
    for k in range(i.size):
        dx, dy, d2, contact = pair_separation(x, y, radii, i[k], j[k])
        reach = contact + extra
        keep[k] = d2 < reach * reach
        m += keep[k]
    out_i = np.empty(m, i.dtype)
    out_j = np.empty(m, j.dtype)
    m = 0
    for k in range(i.size):
        if keep[k]:
            out_i[m] = i[k]
            out_j[m] = j[k]
            m += 1
    return out_i, out_j


class VerletPairs:
    """Pairs of dots within a cutoff distance, with a Verlet skin.

    Parameters
    ----------
    skin : float
        Extra distance kept in the list, px (>= 0). The speed/accuracy knob
        is exact either way; a larger skin means fewer rebuilds but longer
        lists.
    """

    def __init__(self, skin: float = 3.0):
        self.skin = real("skin", skin, 0.0, MAX_SKIN, unit="px")
        self.rebuilds = 0
        self._anchor_x = np.zeros(0)
        self._anchor_y = np.zeros(0)
        self._cutoff = -1.0
        self.i = np.zeros(0, dtype=np.intp)
        self.j = np.zeros(0, dtype=np.intp)

    def invalidate(self) -> None:
        """Force a rebuild at the next query (the set of dots changed)."""
        self._cutoff = -1.0

    def update(self, x: np.ndarray, y: np.ndarray, cutoff: float) -> bool:
        """Make `i`, `j` hold every pair with centre distance < ``cutoff``.

        Returns True when the list was rebuilt.
        """
        if cutoff == self._cutoff and len(x) == len(self._anchor_x):
            if not moved_beyond(x, y, self._anchor_x, self._anchor_y, 0.5 * self.skin):
                return False
        self._rebuild(x, y, cutoff)
        return True

    def _rebuild(self, x: np.ndarray, y: np.ndarray, cutoff: float) -> None:
        self._anchor_x = x.copy()
        self._anchor_y = y.copy()
        self._cutoff = cutoff
        self.rebuilds += 1
        self.i, self.j = pairs_within(x, y, cutoff + self.skin, expected=self.i.size)


def pairs_with_distances(positions: np.ndarray, reach: float, what: str | None = None
                         ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every pair ``i < j`` of points with centre distance <= ``reach`` px, and that distance.

    Parameters
    ----------
    positions : ndarray, shape (N, 2)
        Centres, px.
    reach : float
        Largest centre distance, px (>= 0); a pair at exactly ``reach`` is listed.
    what : str, optional
        What asked for ``reach``, for the message when the pairs could be too many.

    Returns
    -------
    i, j : ndarray of int, shape (P,)
        The pairs, ``i < j``, in the order of scipy's KD-tree (``cKDTree.query_pairs``).
    distance : ndarray, shape (P,)
        Centre distance of each pair, px.

    Raises
    ------
    labrig.validate.InputError
        Naming ``what`` when the pairs could be more than `MAX_PAIRS` (`pair_bound`, checked before the
        search when ``N (N - 1) / 2`` exceeds it).
    """
    n = len(positions)
    if n < 2:
        empty = np.zeros(0, dtype=np.intp)
        return empty, empty, np.zeros(0)
    if n * (n - 1) // 2 > MAX_PAIRS:
        bound = pair_bound(positions[:, 0], positions[:, 1], reach)
        if bound > MAX_PAIRS:
            raise InputError(f"{what or f'a reach of {reach:g} px'} takes up to {bound:.3g} pairs of the {n:,} dots "
                             f"(within {reach:g} px), more than the {MAX_PAIRS:,} allowed")
    pairs = cKDTree(positions).query_pairs(reach, output_type="ndarray")
    i, j = pairs[:, 0], pairs[:, 1]
    delta = positions[i] - positions[j]
    return i, j, np.sqrt(np.einsum("ij,ij->i", delta, delta))

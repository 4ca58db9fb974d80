"""The fast engine's per-sweep bookkeeping, compiled with numba: batch selection, stale points, set rows,
search bounds and radii (`planarize.engines.fast.FastEngine` uses these when numba is installed).

Each function is the compiled twin of a numpy method of `FastEngine` (named in its docstring) and
gives the same results bit for bit (tests/test_planarize_compiled.py); the compiled ones also run
without the GIL, so the engine's threads can share the work.
"""

from __future__ import annotations

import math

import numpy as np

from .kernels import _INF, _jit, _nearest_image, _star


@_jit
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


def batch(distance, tolerance: float, tie: float, wait: bool, neighbours, pair_o, start, sharers, d, first):
    """`FastEngine._batch`, compiled: the points within ``tolerance`` of the smallest ``distance`` that
    (if ``wait``) no interacting candidate (a neighbour in ``neighbours``, or a sharer of an oxide point) is
    more than ``tie`` closer than (boolean mask); their set rows (ascending), and for each row its set's size and
    its oxide point's number of sharers. The set rows of point ``p`` are ``start[p]:start[p + 1]`` of
    ``pair_o``; ``sharers`` counts the rows of each oxide point; ``d`` and ``first`` are scratch arrays
    of inf (length of ``distance``), left as they were."""
    return _batch(distance, float(tolerance), float(tie), bool(wait), neighbours, pair_o, start, sharers, d, first)


@_jit
def _within(which, gap, r_ox, r_me):
    oxide = np.empty(len(which), dtype=np.bool_)
    metal = np.empty(len(which), dtype=np.bool_)
    for a in range(len(which)):
        oxide[a] = gap[a] <= r_ox[which[a]]
        metal[a] = gap[a] <= r_me[which[a]]
    return oxide, metal


def within(which, gap, r_ox, r_me):
    """For search results (query ``which``, distance ``gap``): within the query's oxide radius ``r_ox``,
    and within its metal radius ``r_me`` (two boolean arrays)."""
    return _within(which, gap, r_ox, r_me)


@_jit
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


def stale(in_batch, raised, neighbours, pair_m, pair_o) -> np.ndarray:
    """`FastEngine._stale`, compiled: the oxidized points, their ``neighbours`` and the points whose set
    (rows ``pair_m``, ``pair_o``) holds a ``raised`` oxide point (boolean mask)."""
    return _stale(in_batch, np.asarray(raised, dtype=np.intp), neighbours, pair_m, pair_o)


@_jit
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


def replace_rows(pair_m, pair_o, start, sharers, points, owner, oxide):
    """`FastEngine._replace_rows`, compiled: the set rows (sorted by metal point, those of point ``p`` at
    ``start[p]:start[p + 1]``) with those of ``points`` (ascending) replaced by the rows ``owner, oxide``
    (every owner among ``points``, ascending); returns the new rows and starts, updates ``sharers`` (the
    number of rows of each oxide point) in place."""
    return _replace_rows(pair_m, pair_o, start, sharers, np.asarray(points, dtype=np.intp),
                         np.asarray(owner, dtype=np.intp), np.asarray(oxide, dtype=np.intp))


@_jit
def _vertex_gap(metal, oxide, zm, zo, nx, ny, dx, dy, periodic):
    gap = np.empty(len(metal))
    for a in range(len(metal)):
        m, o = metal[a], oxide[a]
        mi, oi = m // ny, o // ny
        di, dj = _nearest_image(oi - mi, (o - oi * ny) - (m - mi * ny), nx, ny, periodic)
        ex, ey, ez = di * dx, dj * dy, zo[o] - zm[m]
        gap[a] = math.sqrt(ex * ex + ey * ey + ez * ez)
    return gap


def vertex_gap(grid, zm, zo, metal, oxide) -> np.ndarray:
    """Distance from each metal point ``metal[a]`` to the oxide point ``oxide[a]`` (nearest periodic image), nm:
    `FastEngine._vertex_gap`, compiled."""
    return _vertex_gap(np.asarray(metal, dtype=np.intp), np.asarray(oxide, dtype=np.intp), zm, zo, grid.nx, grid.ny,
                       grid.dx, grid.dy, grid.periodic)


@_jit
def _radii(zm, points, bound, oxide_reach, tie, exact, edge_nb, edge2, quad_cell, cell_corners, half2):
    inflate = 1 + 1e-12
    r_ox = np.empty(len(points))
    r_me = np.empty(len(points))
    for a in range(len(points)):
        star = _star(zm, points[a], exact, edge_nb, edge2, quad_cell, cell_corners, half2)
        r_ox[a] = math.sqrt(bound[a] * bound[a] + oxide_reach * oxide_reach) * inflate + tie
        r_me[a] = math.sqrt(bound[a] * bound[a] + star * star) * inflate + tie
    return r_ox, r_me


def radii(kernel, zm, points, bound, oxide_reach: float, tie: float):
    """`FastEngine._radii`, compiled: the oxide and metal search radii of metal points ``points``."""
    g = kernel.grid
    return _radii(zm, np.asarray(points, dtype=np.intp), np.asarray(bound, dtype=float), float(oxide_reach),
                  float(tie), kernel.distance == "exact", g.edge_neighbours, kernel._edge_x ** 2 + kernel._edge_y ** 2,
                  g.quadrant_cell, g.cell_corners, kernel._half_x ** 2 + kernel._half_y ** 2)


@_jit
def _remember_nearest(owner, oxide, near, zm, zo, nx, ny, dx, dy, periodic):
    gap = _vertex_gap(owner, oxide, zm, zo, nx, ny, dx, dy, periodic)
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


def remember_nearest(grid, zm, zo, owner, oxide, near) -> None:
    """`FastEngine._remember_nearest`, compiled: for each metal point of the set rows ``owner, oxide``
    (grouped by owner), ``near[point]`` = its rows' oxide point nearest to it."""
    _remember_nearest(np.asarray(owner, dtype=np.intp), np.asarray(oxide, dtype=np.intp), near, zm, zo, grid.nx,
                      grid.ny, grid.dx, grid.dy, grid.periodic)

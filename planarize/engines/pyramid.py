"""Ball queries on a height grid through a pyramid of height bounds (compiled with numba).

The fast engine asks, for thousands of metal points per sweep, which oxide
grid points lie within a radius in 3-D. A KD-tree must be rebuilt after every
sweep because the oxide rises; a grid already sorts its points in x and y, so
all it needs is height bounds per block. `HeightPyramid` keeps, for blocks of
4^L x 4^L points (L = 1, 2, ... until a level has at most 4 x 4 blocks), the
lowest and highest height in the block; a query descends only into blocks
whose bounding box comes within the radius. Rebuilding the bounds costs one
pass over the grid, far less than a KD-tree.

Periodic grids use the nearest periodic image in x and y, as the engine's
offsets do.
"""

from __future__ import annotations

import math

import numpy as np

from labrig.compiled import jit

_FACTOR = 2


class HeightPyramid:
    """Block height bounds of a surface ``z`` (flat, C order) on a grid (`planarize.grid.Grid`)."""

    def __init__(self, grid, z: np.ndarray):
        self.grid = grid
        shapes, offsets = [], [0]
        bx, by, size = grid.nx, grid.ny, 1
        while bx > _FACTOR or by > _FACTOR:
            bx, by, size = -(-bx // _FACTOR), -(-by // _FACTOR), size * _FACTOR
            shapes.append((bx, by, size))
            offsets.append(offsets[-1] + bx * by)
        if not shapes:  # a grid of at most 4 x 4 points: one level of 1 x 1 blocks
            shapes.append((1, 1, _FACTOR))
            offsets.append(1)
        self.shapes = np.array(shapes, dtype=np.intp)  # (levels, 3): blocks in x, in y, points per block side
        self.offsets = np.array(offsets, dtype=np.intp)
        self.low = np.empty(offsets[-1])
        self.high = np.empty(offsets[-1])
        self.rebuild(z)

    def rebuild(self, z: np.ndarray) -> None:
        """Bounds from the heights ``z`` everywhere."""
        _build(np.asarray(z, dtype=float), self.grid.nx, self.grid.ny, self.shapes, self.offsets, self.low, self.high)

    def ball(self, z: np.ndarray, points: np.ndarray, zq: np.ndarray, radius: np.ndarray, cache=None):
        """Grid points within ``radius[q]`` (3-D, nm) of query ``q``, above grid point ``points[q]`` at
        height ``zq[q]``.

        Returns (query index, point index, distance) arrays, grouped by query
        in query order (within a query, in no particular order). With a
        `BallCache`, a query point asked before with a radius at least as
        large is answered from the points found then; the caller guarantees
        that between calls query points only sink and grid points only rise
        (see `BallCache`).
        """
        g = self.grid
        if cache is None:
            cache = _NO_CACHE
        return _ball(z, np.asarray(points, dtype=np.intp), np.asarray(zq, dtype=float),
                     np.asarray(radius, dtype=float), g.nx, g.ny, g.dx, g.dy, g.periodic, self.shapes, self.offsets,
                     self.low, self.high, cache is not _NO_CACHE, cache.offsets, cache.count, cache.radius,
                     cache.margin)


class BallCache:
    """What each query point's last pyramid search found, searched a ``margin`` (nm) wider than asked.

    A search is kept only for a query point below every grid point: if from
    then on query points only sink and grid points only rise (the fast
    engine's metal and oxide), its distance to every grid point only grows, so
    a point outside the wider radius then is still outside it, and a later
    query with a radius up to the wider one needs only the points found.
    Each query point keeps at most ``capacity`` points, as grid offsets of
    at most 127 rows and columns (2 bytes each: the table is read at random,
    so its size is its cost).
    """

    def __init__(self, n: int, margin: float, capacity: int = 40):
        self.margin = float(margin)
        self.offsets = np.zeros((n, capacity, 2), dtype=np.int8)
        self.count = np.full(n, -1, dtype=np.int32)  # -1: nothing kept
        self.radius = np.zeros(n)


_NO_CACHE = BallCache(0, 0.0, 0)


@jit
def _build(z, nx, ny, shapes, offsets, low, high):
    low[:] = np.inf
    high[:] = -np.inf
    size = shapes[0, 2]
    by, base = shapes[0, 1], offsets[0]
    for i in range(nx):
        for j in range(ny):
            b = base + (i // size) * by + j // size
            h = z[i * ny + j]
            low[b] = min(low[b], h)
            high[b] = max(high[b], h)
    for level in range(1, len(shapes)):
        below_by, below = shapes[level - 1, 1], offsets[level - 1]
        by, base = shapes[level, 1], offsets[level]
        for bi in range(shapes[level - 1, 0]):
            for bj in range(below_by):
                child = below + bi * below_by + bj
                b = base + (bi // _FACTOR) * by + bj // _FACTOR
                low[b] = min(low[b], low[child])
                high[b] = max(high[b], high[child])


@jit
def _runs(start, stop, n, size, out):
    """Split the unwrapped index range ``start .. stop`` into pieces that each lie in one block of
    ``size`` (indices wrap modulo ``n``); ``out[k] = (block, unwrapped first index of the block)``."""
    count = 0
    u = start
    while u <= stop:
        w = u % n
        block = w // size
        first = u - (w - block * size)
        out[count, 0], out[count, 1] = block, first
        count += 1
        u = first + min(size, n - block * size)
    return count


@jit(inline=True)
def _near(level, bi, bj, u0, v0, iq, jq, h, r2, ua, ub, va, vb, nx, ny, dx, dy, shapes, offsets, low, high):
    """Whether block ``(bi, bj)`` of ``level`` (first row/column ``u0, v0`` unwrapped) can hold a point within
    the query's window and ball."""
    size = shapes[level, 2]
    u1 = u0 + min(size, nx - bi * size) - 1
    v1 = v0 + min(size, ny - bj * size) - 1
    if u1 < ua or u0 > ub or v1 < va or v0 > vb:
        return False
    b = offsets[level] + bi * shapes[level, 1] + bj
    hx = max(0, u0 - iq, iq - u1) * dx
    hy = max(0, v0 - jq, jq - v1) * dy
    hz = max(0.0, low[b] - h, h - high[b])
    return hx * hx + hy * hy + hz * hz <= r2


@jit(inline=True)
def _grow(which, found, gap, need):
    """The result arrays with room for at least ``need`` entries (doubled as often as it takes).

    (Each candidate is then written at the end and counted only if it is inside the ball: no branch
    per candidate, which mispredicts often.)"""
    while need > len(which):
        n = len(which)
        which = np.concatenate((which, np.empty(n, dtype=np.intp)))
        found = np.concatenate((found, np.empty(n, dtype=np.intp)))
        gap = np.concatenate((gap, np.empty(n)))
    return which, found, gap


@jit
def _ball(z, points, zq, radius, nx, ny, dx, dy, periodic, shapes, offsets, low, high, use_cache, kept, kept_count,
          kept_radius, margin):
    top = len(shapes) - 1
    capacity = 16 * len(points) + 64
    which = np.empty(capacity, dtype=np.intp)
    found = np.empty(capacity, dtype=np.intp)
    gap = np.empty(capacity)
    count = 0
    # entries: level, block i, block j, unwrapped first row, unwrapped first column (blocks already tested)
    stack = np.empty((64 + 16 * len(shapes), 5), dtype=np.intp)
    floor = np.inf  # the lowest grid point: searches from below it can be kept
    for b in range(offsets[top], offsets[top + 1]):
        floor = min(floor, low[b])
    runs_i = np.empty((8, 2), dtype=np.intp)
    runs_j = np.empty((8, 2), dtype=np.intp)
    for q in range(len(points)):
        p = points[q]
        iq, jq, h, r2 = p // ny, p % ny, zq[q], radius[q] * radius[q]
        if use_cache and kept_count[p] >= 0 and radius[q] <= kept_radius[p]:
            which, found, gap = _grow(which, found, gap, count + kept_count[p])
            for c in range(kept_count[p]):
                di, dj = np.intp(kept[p, c, 0]), np.intp(kept[p, c, 1])
                u, v = iq + di, jq + dj
                if periodic:
                    u += nx if u < 0 else (-nx if u >= nx else 0)
                    v += ny if v < 0 else (-ny if v >= ny else 0)
                k = u * ny + v
                ex, ey, ez = di * dx, dj * dy, z[k] - h
                d2 = ex * ex + ey * ey + ez * ez
                which[count], found[count], gap[count] = q, k, math.sqrt(d2)
                count += d2 <= r2
            continue
        keep = use_cache and h < floor
        search = radius[q] + margin if keep else radius[q]
        wide2 = search * search  # the blocks and points searched; those within r2 are answered
        stored = 0
        wi, wj = int(search / dx), int(search / dy)
        if periodic:  # each point once, at its nearest image
            ua, ub = iq - min(wi, (nx - 1) // 2), iq + min(wi, nx // 2)
            va, vb = jq - min(wj, (ny - 1) // 2), jq + min(wj, ny // 2)
        else:
            ua, ub = max(iq - wi, 0), min(iq + wi, nx - 1)
            va, vb = max(jq - wj, 0), min(jq + wj, ny - 1)
        start = 0  # the finest level whose blocks are as wide as the window: at most 3 x 3 of them
        while start < top and shapes[start, 2] < max(ub - ua, vb - va) + 1:
            start += 1
        depth = 0
        for a in range(_runs(ua, ub, nx, shapes[start, 2], runs_i)):
            for b in range(_runs(va, vb, ny, shapes[start, 2], runs_j)):
                if _near(start, runs_i[a, 0], runs_j[b, 0], runs_i[a, 1], runs_j[b, 1], iq, jq, h, wide2, ua, ub,
                         va, vb, nx, ny, dx, dy, shapes, offsets, low, high):
                    stack[depth, 0], stack[depth, 1], stack[depth, 2] = start, runs_i[a, 0], runs_j[b, 0]
                    stack[depth, 3], stack[depth, 4] = runs_i[a, 1], runs_j[b, 1]
                    depth += 1
        while depth:
            depth -= 1
            level, bi, bj, u0, v0 = stack[depth, 0], stack[depth, 1], stack[depth, 2], stack[depth, 3], stack[depth, 4]
            size = shapes[level, 2]
            if level > 0:
                child = shapes[level - 1, 2]
                for ci in range(bi * _FACTOR, min(bi * _FACTOR + _FACTOR, shapes[level - 1, 0])):
                    for cj in range(bj * _FACTOR, min(bj * _FACTOR + _FACTOR, shapes[level - 1, 1])):
                        cu0 = u0 + ci * child - bi * size
                        cv0 = v0 + cj * child - bj * size
                        if _near(level - 1, ci, cj, cu0, cv0, iq, jq, h, wide2, ua, ub, va, vb, nx, ny, dx, dy, shapes,
                                 offsets, low, high):
                            stack[depth, 0], stack[depth, 1], stack[depth, 2] = level - 1, ci, cj
                            stack[depth, 3], stack[depth, 4] = cu0, cv0
                            depth += 1
                continue
            u1 = u0 + min(size, nx - bi * size) - 1
            v1 = v0 + min(size, ny - bj * size) - 1
            which, found, gap = _grow(which, found, gap, count + size * size)
            for u in range(max(u0, ua), min(u1, ub) + 1):
                ex = (u - iq) * dx
                row = (bi * size + u - u0) * ny
                for v in range(max(v0, va), min(v1, vb) + 1):
                    ey = (v - jq) * dy
                    k = row + bj * size + v - v0
                    ez = z[k] - h
                    d2 = ex * ex + ey * ey + ez * ez
                    if keep and d2 <= wide2:
                        if stored < kept.shape[1] and abs(u - iq) <= 127 and abs(v - jq) <= 127:
                            kept[p, stored, 0], kept[p, stored, 1] = u - iq, v - jq
                        else:
                            stored = kept.shape[1]  # too many or too far: not kept
                        stored += 1
                    which[count], found[count], gap[count] = q, k, math.sqrt(d2)
                    count += d2 <= r2
        if keep:
            kept_count[p] = stored if stored <= kept.shape[1] else -1
            kept_radius[p] = search
    return which[:count], found[:count], gap[:count]

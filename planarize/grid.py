"""Topology of a height grid: flat point indices, neighbours, cells, periodic images.

Points are numbered ``k = i * ny + j`` (C order of ``z[i, j]``). Directions
are given as grid offsets ``(di, dj)``; on an open grid a neighbour past the
edge is ``-1``, on a periodic grid indices wrap while lateral offsets do not
(the neighbour of the last point in +x lies one ``dx`` further, in the next
period), so geometry is always computed from offsets, never from wrapped
coordinates.
"""

from __future__ import annotations

import numpy as np

from labrig.validate import InputError, count, flag, real, reals

from .heightfield import MAX_POINTS

#: The four grid directions of the thesis's line segments: +x, -x, +y, -y.
EDGE_DIRECTIONS = ((1, 0), (-1, 0), (0, 1), (0, -1))
#: The four cells around a point, by the signs of their far corner: (sx, sy).
QUADRANTS = ((1, 1), (-1, 1), (-1, -1), (1, -1))


class Grid:
    """Index arithmetic of an ``nx`` x ``ny`` grid.

    Parameters
    ----------
    shape : (int, int)
    spacing : (float, float)
        ``dx``, ``dy``, nm.
    periodic : bool
    """

    def __init__(self, shape: tuple[int, int], spacing: tuple[float, float], periodic: bool):
        if isinstance(shape, (str, bytes)) or not hasattr(shape, "__len__") or len(shape) != 2:
            raise InputError(f"grid shape must be two counts (nx, ny), got {shape!r}")
        self.nx, self.ny = (count(f"grid shape {name}", n, 1, MAX_POINTS) for name, n in zip(("nx", "ny"), shape))
        if self.nx * self.ny > MAX_POINTS:  # the tables below take ~200 bytes per point
            raise InputError(f"grid shape is {self.nx} x {self.ny} points, more than the {MAX_POINTS:,} a surface "
                             "may have")
        self.dx, self.dy = (real(f"grid spacing {name}", d, 0.0, low_open=True, unit="nm")
                            for name, d in zip(("dx", "dy"), reals("grid spacing", spacing, 2)))
        self.periodic = flag("periodic", periodic)
        self.n = self.nx * self.ny
        k = np.arange(self.n)
        self.i, self.j = k // self.ny, k % self.ny
        #: neighbour index along each of EDGE_DIRECTIONS, shape (n, 4), -1 past an open edge
        self.edge_neighbours = np.stack([self.shift(k, di, dj) for di, dj in EDGE_DIRECTIONS], axis=1)
        #: the 3 other corners of each QUADRANTS cell, shape (n, 4, 3): (sx, 0), (sx, sy), (0, sy); -1 if no cell
        corners = np.stack([np.stack([self.shift(k, sx, 0), self.shift(k, sx, sy), self.shift(k, 0, sy)], axis=1)
                            for sx, sy in QUADRANTS], axis=1)
        missing = np.any(corners < 0, axis=2, keepdims=True)
        self.quadrant_corners = np.where(missing, -1, corners)
        #: the cell of each QUADRANTS quadrant, named by its lower-left corner, shape (n, 4); -1 if none
        lower_left = np.stack([self.shift(k, min(sx, 0), min(sy, 0)) for sx, sy in QUADRANTS], axis=1)
        self.quadrant_cell = np.where(missing[:, :, 0], -1, lower_left)
        #: corners of the cell named by each point, in a fixed order: (0, 0), (1, 0), (1, 1), (0, 1); -1 if none
        cell = np.stack([k, self.shift(k, 1, 0), self.shift(k, 1, 1), self.shift(k, 0, 1)], axis=1)
        self.cell_corners = np.where((cell < 0).any(axis=1, keepdims=True), -1, cell)

    def shift(self, k, di: int | np.ndarray, dj: int | np.ndarray) -> np.ndarray:
        """Index of the point ``(di, dj)`` away from each ``k``; -1 past an open edge."""
        i = self.i[k] + di
        j = self.j[k] + dj
        if self.periodic:
            return (i % self.nx) * self.ny + (j % self.ny)
        ok = (i >= 0) & (i < self.nx) & (j >= 0) & (j < self.ny)
        return np.where(ok, i * self.ny + j, -1)

    def offsets(self, frm, to) -> tuple[np.ndarray, np.ndarray]:
        """Grid offsets ``(di, dj)`` from points ``frm`` to points ``to`` (nearest periodic image)."""
        di = self.i[to] - self.i[frm]
        dj = self.j[to] - self.j[frm]
        if self.periodic:
            di = di - self.nx * np.floor_divide(di + self.nx // 2, self.nx)
            dj = dj - self.ny * np.floor_divide(dj + self.ny // 2, self.ny)
        return di, dj

    def window(self, centre: int, wx: int, wy: int) -> np.ndarray:
        """Indices of the points within ``wx`` rows and ``wy`` columns of ``centre`` (each once)."""
        i0, j0 = self.i[centre], self.j[centre]
        if self.periodic:
            # a window wider than the grid would visit points twice
            ii = np.arange(i0 - min(wx, (self.nx - 1) // 2), i0 + min(wx, self.nx // 2) + 1) % self.nx
            jj = np.arange(j0 - min(wy, (self.ny - 1) // 2), j0 + min(wy, self.ny // 2) + 1) % self.ny
        else:
            ii = np.arange(max(i0 - wx, 0), min(i0 + wx, self.nx - 1) + 1)
            jj = np.arange(max(j0 - wy, 0), min(j0 + wy, self.ny - 1) + 1)
        return (ii[:, None] * self.ny + jj[None, :]).ravel()

    def block(self, k) -> np.ndarray:
        """The points ``k`` and their 8 neighbours (those that exist), unique, sorted."""
        k = np.asarray(k).ravel()
        mark = np.zeros(self.n, dtype=bool)
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                near = self.shift(k, di, dj)
                mark[near[near >= 0]] = True
        return np.flatnonzero(mark)

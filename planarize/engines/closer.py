"""Where raised oxide can have come closer: the fast engine's take-closer region, and KD-tree ball searches.

Raising an oxide point can bring it closer to metal points other than those whose set holds it.
Each sweep the fast engine asks `below_raised` which metal points a raised feature may reach, then
searches the raised points near them (`TreeSearch`) and lets each take a raised point that is now as
close or closer than its set. Once the whole metal lies below the whole oxide, nothing can come
closer and the step costs one comparison.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import maximum_filter, minimum_filter
from scipy.spatial import cKDTree

from ..grid import Grid

#: Side of the tiles (points) in which `below_raised` first looks for metal points a raised feature may reach.
TILE = 8


class TreeSearch:
    """Ball searches of 3-D grid points (all, or ``points``) at heights ``z``, in a KD-tree.

    Parameters
    ----------
    grid : Grid
    z : ndarray, shape (n,)
        Heights of the grid points, nm.
    points : ndarray of int, optional
        Grid points to search among (default all).
    span : (float, float)
        Lowest and highest height any query or point can have, nm: queries are shifted above the
        lowest, and on a periodic grid the z period is made far longer than ``span`` plus ``reach``.
    reach : float
        Largest radius asked for, nm.
    k : int
        Neighbours asked of the tree per query before falling back to ball queries.
    """

    def __init__(self, grid: Grid, z: np.ndarray, points=None, *, span: tuple[float, float], reach: float,
                 k: int = 16):
        idx = slice(None) if points is None else points
        self.shift = -float(span[0])
        data = np.column_stack([grid.i[idx] * grid.dx, grid.j[idx] * grid.dy, z[idx] + self.shift])
        box = None
        if grid.periodic:  # z must not wrap: make its period far longer than any query reaches
            box = (grid.nx * grid.dx, grid.ny * grid.dy, 4.0 * (span[1] + self.shift + reach) + 1.0)
        self.tree = cKDTree(data, balanced_tree=False, compact_nodes=False, boxsize=box)
        self.grid, self.k = grid, k

    def __call__(self, points: np.ndarray, z: np.ndarray, radius: np.ndarray):
        """Tree points within ``radius[i]`` of ``(points[i], z[i])``: (query index, point index, distance).

        A k-nearest query runs at C speed; the few queries whose k-th neighbour is still inside
        their radius are redone as ball queries. Results are grouped by query.
        """
        g, tree = self.grid, self.tree
        queries = np.column_stack([g.i[points] * g.dx, g.j[points] * g.dy, z + self.shift])
        if not len(queries):
            return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp), np.zeros(0)
        k = min(self.k, tree.n)
        dist, idx = tree.query(queries, k=k, distance_upper_bound=float(radius.max()))
        dist, idx = dist.reshape(len(queries), k), idx.reshape(len(queries), k)
        inside = dist <= radius[:, None]
        more = np.flatnonzero(inside[:, -1]) if k < tree.n else np.zeros(0, dtype=np.intp)
        inside[more] = False
        q = np.broadcast_to(np.arange(len(queries))[:, None], inside.shape)[inside]
        p, d = idx[inside], dist[inside]
        if len(more):
            found = tree.query_ball_point(queries[more], radius[more], return_sorted=False)
            extra_q = np.repeat(more, [len(f) for f in found])
            extra_p = np.concatenate([np.asarray(f, dtype=np.intp) for f in found])
            gap = tree.data[extra_p] - queries[extra_q]
            if tree.boxsize is not None:  # nearest periodic image
                gap -= tree.boxsize * np.round(gap / tree.boxsize)
            order = np.argsort(np.concatenate([q, extra_q]), kind="stable")
            q = np.concatenate([q, extra_q])[order]
            p = np.concatenate([p, extra_p])[order]
            d = np.concatenate([d, np.sqrt((gap * gap).sum(axis=1))])[order]
        return q, p, d


def below_raised(grid: Grid, zm: np.ndarray, zo: np.ndarray, anchors: np.ndarray, rise: float, tie: float,
                 reach: float) -> np.ndarray:
    """Metal points that a raised feature may have come closer to (boolean, shape (n,)).

    Raising points of a feature moves every point of it up; a point of the metal's own features
    that lies below all of the old feature gets only farther from it. So a metal point can gain
    only if the highest point of its features (its 3 x 3 block) is above the lowest point of a
    raised feature (the anchor's 3 x 3 block, before the rise) within ``reach`` (nm, laterally).

    The test is made first for tiles of `TILE` x `TILE` points (the lowest oxide point of any tile
    holding an anchor, or its rim, within reach of the tile, against the tile's highest metal point
    and its rim); where few tiles pass, then point by point in them (a superset of the points that
    can gain), else with whole-grid filters (exactly).

    Parameters
    ----------
    grid : Grid
    zm, zo : ndarray, shape (n,)
        Metal and oxide heights after the sweep, nm.
    anchors : ndarray of int
        Grid points whose features were raised.
    rise : float
        Largest rise of an oxide point in the sweep, nm.
    tie : float
        Round-off allowance, nm.
    reach : float
        How far laterally a raised feature can reach a metal point that could take it, nm.
    """
    out = np.zeros(grid.n, dtype=bool)
    if float(zm.max()) + tie < float(zo.min()) - rise:
        return out  # the whole metal lies below the whole oxide (thick oxide)
    tiles = (-(-grid.nx // TILE), -(-grid.ny // TILE))
    mode = "wrap" if grid.periodic else "constant"
    # tiles within reach of a point: its own and ceil(cells / TILE) on each side (+1: a partial last tile)
    size = [min(2 * (math.ceil(math.ceil(reach / d) / TILE) + 1) + 1, 2 * t + 1)
            for d, t in ((grid.dx, tiles[0]), (grid.dy, tiles[1]))]
    has_anchor = np.zeros(tiles, dtype=bool)
    has_anchor[grid.i[anchors] // TILE, grid.j[anchors] // TILE] = True
    low = np.where(has_anchor, _tile_extreme(zo, grid, tiles, np.min, mode) - rise, np.inf)
    near_low = minimum_filter(low, size=size, mode=mode, cval=np.inf)
    maybe = (_tile_extreme(zm, grid, tiles, np.max, mode) + tie >= near_low).ravel()
    if not maybe.any():
        return out
    shape = (grid.nx, grid.ny)
    if maybe.mean() > 1 / 8:  # many tiles: whole-grid filters cost less than blocks point by point
        edge = "wrap" if grid.periodic else "nearest"
        low = np.full(shape, np.inf)
        low.flat[anchors] = minimum_filter(zo.reshape(shape), size=3, mode=edge).flat[anchors] - rise
        size = [min(2 * math.ceil(reach / d) + 1, 2 * n + 1) for d, n in ((grid.dx, grid.nx), (grid.dy, grid.ny))]
        near = minimum_filter(low, size=size, mode=mode, cval=np.inf)
        return (maximum_filter(zm.reshape(shape), size=3, mode=edge) + tie >= near).ravel()
    tile = (grid.i // TILE) * tiles[1] + grid.j // TILE
    points = np.flatnonzero(maybe[tile])
    out[points] = _block_max(grid, zm, points) + tie >= near_low.ravel()[tile[points]]
    return out


def _block_max(grid: Grid, z: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Highest ``z`` over the 3 x 3 block around each of ``points``."""
    step = np.array([-1, 0, 1])
    k = grid.shift(points[:, None], np.repeat(step, 3)[None, :], np.tile(step, 3)[None, :])
    return np.max(np.where(k >= 0, z[k], z[points][:, None]), axis=1)  # (past an open edge: the point itself)


def _tile_extreme(z: np.ndarray, grid: Grid, tiles: tuple[int, int], extreme, mode: str) -> np.ndarray:
    """``extreme`` (np.min or np.max) of the heights ``z`` over each tile of `TILE` x `TILE` points and
    the points around it (shape ``tiles``)."""
    fill = np.inf if extreme is np.min else -np.inf
    padded = np.full((tiles[0] * TILE, tiles[1] * TILE), fill)
    padded[: grid.nx, : grid.ny] = z.reshape(grid.nx, grid.ny)
    per_tile = extreme(padded.reshape(tiles[0], TILE, tiles[1], TILE), axis=(1, 3))
    rim = minimum_filter if extreme is np.min else maximum_filter
    return rim(per_tile, size=3, mode=mode, cval=fill)

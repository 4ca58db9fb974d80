"""Raised oxide offered to the metal points near it (the fast engine's take-closer step), and the
KD-tree searches it uses (also the fast engine's candidate search without numba).

Raising an oxide point can bring it closer to metal points other than those whose set holds it;
each sweep, `TakeCloser._take_closer` finds the metal points a raised feature may reach
(`TakeCloser._below_raised`) and lets each take a raised point that is now as close or closer
than its set. Once the whole metal lies below the whole oxide, nothing can come closer and the
step costs one comparison.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.ndimage import maximum_filter, minimum_filter
from scipy.spatial import cKDTree

#: Side of the tiles (points) in which `TakeCloser._below_raised` first looks for metal points a raised feature may reach.
TILE = 8


class TakeCloser:
    """The take-closer step and KD-tree searches of `planarize.engines.fast.FastEngine` (a mixin: it uses the
    engine's grid, heights, distances, sets and candidate search)."""

    def _tree(self, z: np.ndarray, points=None) -> tuple[cKDTree, float]:
        """3-D tree of grid points at heights ``z``; returns it and the z shift applied to queries."""
        g = self.grid
        idx = slice(None) if points is None else points
        shift = -float(min(self.zm.min(), self.zo.min()))
        data = np.column_stack([self._x[idx], self._y[idx], z[idx] + shift])
        if not g.periodic:
            return cKDTree(data, balanced_tree=False, compact_nodes=False), shift
        span = float(max(self.zm.max(), self.zo.max())) + shift
        # z must not wrap: make its period far longer than any query reaches
        box = (g.nx * g.dx, g.ny * g.dy, 4.0 * (span + self._reach_limit()) + 1.0)
        return cKDTree(data, balanced_tree=False, compact_nodes=False, boxsize=box), shift


    def _reach_limit(self) -> float:
        return float(np.max(self.D[np.isfinite(self.D)], initial=0.0)) + float(np.max(self.zo - self.zm)) \
            + 2.0 * max(self._metal_longest, self._oxide_longest)

    @staticmethod
    def _ball(tree: cKDTree, queries: np.ndarray, radius: np.ndarray, k: int = 16):
        """Tree points within ``radius[i]`` of each query, grouped by query.

        Returns (query index, point index, distance) arrays. A k-nearest query
        runs at C speed; the few queries whose k-th neighbour is still inside
        their radius are redone as ball queries.
        """
        if not len(queries):
            return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp), np.zeros(0)
        k = min(k, tree.n)
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

    def _tree_search(self, points=None, k: int = 16):
        """`_candidates`'s search in a KD-tree of the oxide points (all, or ``points``)."""
        tree, shift = self._tree(self.zo, points)

        def search(points, z, radius):
            return self._ball(tree, np.column_stack([self._x[points], self._y[points], z + shift]), radius, k)
        return search

    def _below_raised(self, anchors: np.ndarray, rise: float) -> np.ndarray:
        """Metal points that a raised feature may have come closer to (boolean, shape (n,)).

        Raising points of a feature moves every point of it up; a point of the
        metal's own features that lies below all of the old feature gets only
        farther from it. So a metal point can gain only if the highest point of
        its features (its 3 x 3 block) is above the lowest point of a raised
        feature (the anchor's 3 x 3 block, before the rise) within reach.

        The test is made first for tiles of `TILE` x `TILE` points (the lowest
        oxide point of any tile holding an anchor, or its rim, within reach of
        the tile, against the tile's highest metal point and its rim); where
        few tiles pass, then point by point in them (a superset of the points
        that can gain), else with whole-grid filters (exactly).
        """
        g = self.grid
        out = np.zeros(g.n, dtype=bool)
        if float(self.zm.max()) + self.tie < float(self.zo.min()) - rise:
            return out  # the whole metal lies below the whole oxide (thick oxide)
        tiles = (-(-g.nx // TILE), -(-g.ny // TILE))
        mode = "wrap" if g.periodic else "constant"
        reach = math.sqrt(float(self.D.max()) ** 2 + max(self._oxide_reach, self._metal_longest) ** 2)
        # tiles within reach of a point: its own and ceil(cells / TILE) on each side (+1: a partial last tile)
        size = [min(2 * (math.ceil(math.ceil(reach / d) / TILE) + 1) + 1, 2 * t + 1)
                for d, t in ((g.dx, tiles[0]), (g.dy, tiles[1]))]
        has_anchor = np.zeros(tiles, dtype=bool)
        has_anchor[g.i[anchors] // TILE, g.j[anchors] // TILE] = True
        low = np.where(has_anchor, _tile_extreme(self.zo, g, tiles, np.min, mode) - rise, np.inf)
        near_low = minimum_filter(low, size=size, mode=mode, cval=np.inf)
        maybe = (_tile_extreme(self.zm, g, tiles, np.max, mode) + self.tie >= near_low).ravel()
        if not maybe.any():
            return out
        shape = (g.nx, g.ny)
        if maybe.mean() > 1 / 8:  # many tiles: whole-grid filters cost less than blocks point by point
            edge = "wrap" if g.periodic else "nearest"
            low = np.full(shape, np.inf)
            low.flat[anchors] = minimum_filter(self.zo.reshape(shape), size=3, mode=edge).flat[anchors] - rise
            size = [min(2 * math.ceil(reach / d) + 1, 2 * n + 1) for d, n in ((g.dx, g.nx), (g.dy, g.ny))]
            near = minimum_filter(low, size=size, mode=mode, cval=np.inf)
            return (maximum_filter(self.zm.reshape(shape), size=3, mode=edge) + self.tie >= near).ravel()
        tile = (g.i // TILE) * tiles[1] + g.j // TILE
        points = np.flatnonzero(maybe[tile])
        out[points] = self._block_extreme(self.zm, points, np.max) + self.tie >= near_low.ravel()[tile[points]]
        return out

    def _block_extreme(self, z: np.ndarray, points: np.ndarray, extreme) -> np.ndarray:
        """``extreme`` (np.min or np.max) of ``z`` over the 3 x 3 block around each of ``points``."""
        step = np.array([-1, 0, 1])
        k = self.grid.shift(points[:, None], np.repeat(step, 3)[None, :], np.tile(step, 3)[None, :])
        return extreme(np.where(k >= 0, z[k], z[points][:, None]), axis=1)  # (past an open edge: the point itself)

    def _take_closer(self, raised: np.ndarray, skip: np.ndarray, rise: float) -> None:
        """Metal points near the raised oxide points take them if now as close or closer than their set."""
        if not len(raised):
            return
        anchors = self.grid.block(raised) if self.distance == "exact" else raised  # exact: cell centres moved
        # ask the other metal points that a raised feature can come closer to for the anchors within reach
        metal = np.flatnonzero(~skip & self._below_raised(anchors, rise))
        if not len(metal):
            return
        # (few raised points are near any one metal point: a short k-nearest query, ball queries for the rest)
        which, anchor, oxide_slots, metal_slots = self._candidates(self._tree_search(anchors, k=4), metal,
                                                                   *self._radii(metal, self.D[metal] + self.tie))
        if not len(which):
            return
        found, distance, owner, oxide = self._closest(self.kernel, self.zm, self.zo, metal[which], anchors[anchor],
                                                     self.tie, oxide_slots, metal_slots)
        closer = distance < self.D[found] - self.tie
        tied = ~closer & (distance <= self.D[found] + self.tie)
        if not (closer.any() or tied.any()):
            return
        # a closer point's set is replaced, a tied point's grows
        new = (closer | tied)[owner]
        pm, po = found[owner[new]], oxide[new]
        if tied.any():
            old = np.isin(self.pair_m, found[tied])
            key = np.unique(np.concatenate([pm, self.pair_m[old]]) * self.grid.n + np.concatenate([po, self.pair_o[old]]))
            pm, po = key // self.grid.n, key % self.grid.n
        self._replace_rows(found[closer | tied], pm, po)
        # the nearest set point: among the new rows, and for a tie also the old nearest
        kept = found[tied]
        metal = np.concatenate([found[owner[new]], kept])
        order = np.argsort(metal, kind="stable")
        self._remember_nearest(metal[order], np.concatenate([oxide[new], self._near[kept]])[order])
        self.D[found] = np.minimum(self.D[found], np.where(closer | tied, distance, np.inf))



def _tile_extreme(z: np.ndarray, grid, tiles: tuple[int, int], extreme, mode: str) -> np.ndarray:
    """``extreme`` (np.min or np.max) of the heights ``z`` over each tile of `TILE` x `TILE` points and
    the points around it (shape ``tiles``)."""
    fill = np.inf if extreme is np.min else -np.inf
    padded = np.full((tiles[0] * TILE, tiles[1] * TILE), fill)
    padded[: grid.nx, : grid.ny] = z.reshape(grid.nx, grid.ny)
    per_tile = extreme(padded.reshape(tiles[0], TILE, tiles[1], TILE), axis=(1, 3))
    rim = minimum_filter if extreme is np.min else maximum_filter
    return rim(per_tile, size=3, mode=mode, cval=fill)

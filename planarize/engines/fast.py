"""The fast engine: batched oxidation, bulk candidate searches, incremental distance updates.

Each `advance` oxidizes every metal point whose distance is within
``tolerance`` of the smallest (one Eq 3.9 step each, fractions computed for
the whole batch at once, so volume balance stays exact), then brings
distances up to date for the metal points that can have changed, and only
those:

* the oxidized points and their 8 neighbours (their own features moved),
* the points whose oxide set holds a raised oxide point (they may be farther),
* the points within reach of a raised oxide point (they may be closer):
  found with a 3-D KD-tree of the metal points.

Each of those is recomputed exactly: the nearest oxide point of its previous
set gives an upper bound ``B`` of its new distance, and a feature closer
than ``B`` must have a grid point within ``sqrt(B^2 + L^2)`` (``L`` the
longest feature edge), so a ball query of the oxide points lists every
candidate: a height pyramid (`planarize.engines.pyramid`) and the compiled kernel
(`planarize.engines.kernels`) when numba is installed, split over ``threads``
threads, else a KD-tree and the numpy kernel. A metal point below the whole
oxide only moves away from every oxide point from then on, so its search,
made a little wider, is kept and answers its later searches up to that
radius (`planarize.engines.pyramid.BallCache`). The results are the same bit
for bit either way and for any thread count. Periodic grids take the
nearest periodic image in x and y.

``tolerance = 0`` oxidizes exact ties only and reproduces the reference
engine to round-off; larger tolerances take larger batches (fewer sweeps)
at the cost of oxidizing some points slightly early.
"""

from __future__ import annotations

import functools
import math
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from labrig.validate import InputError

from . import bookkeeping, features, kernels
from .base import INTERACTING, Engine
from .closer import TakeCloser
from .pyramid import BallCache, HeightPyramid

#: Candidate pairs evaluated per kernel call (bounds memory: 33 distances each in exact mode).
CHUNK_PAIRS = 400_000
#: Fewest points per thread worth a thread of their own (below, the hand-over costs more than it saves).
POINTS_PER_THREAD = 512
#: How much wider (in steps) a metal point's candidate search is made when its result is kept for later sweeps.
CACHE_MARGIN = 0.5
#: Sweeps between exact measurements of the longest feature edges (in between, upper bounds that only grow).
REACH_REFRESH = 64


class FastEngine(TakeCloser, Engine):
    """Batched, vectorized engine. See `planarize.engines.base.Engine` for the common parameters.

    Parameters
    ----------
    tolerance : float, optional
        Batch tolerance, nm (>= 0): points within this distance of the
        smallest are oxidized together. Default ``0.1 * step``: within 2 % of the
        sequential reference's roughness on the thesis hill (1.5 %; half a step: 3.3 %, and 7.5 % on
        average over copies with their exact ties broken), for 40 % more time there and 14 % on the Ta
        film (`docs/performance.md`). Where agreement with the sequential algorithm matters less than
        time, half a step costs least in accuracy: on a 257 x 257 periodic random surface to 200 nm it is
        1.3x faster and changes the roughness by 0.2 % (1.4x per nm on 1025 x 1025 at 60 nm); for more
        speed, ``interacting="together"`` at one step is 2.6x faster there for 0.4 %.
    interacting : {"wait", "together"}
        What candidates that interact (share an oxide point or a grid segment) do. ``"wait"`` (default):
        a candidate with a strictly closer interacting one waits for a later sweep, as in the sequential
        algorithm. ``"together"``: every candidate is oxidized in the sweep, with Eq 3.9's shares counted
        over the whole batch (volume balance stays exact); far fewer distance recomputations per update,
        so large rough surfaces run several times faster at a tolerance of a step or more, for a
        roughness change measured in `docs/performance.md`. At tolerance 0 both give the same results.
    jit : bool, optional
        Use the numba-compiled kernel and height-pyramid search
        (`planarize.engines.kernels`, `planarize.engines.pyramid`) instead of numpy and a
        KD-tree; the results are identical. Default: when numba is installed.
    threads : int, optional
        Threads for the compiled distance updates (the compiled code runs
        without the GIL); the results do not depend on it. Default: the CPUs
        this process may use. Ignored without ``jit``.

    Attributes
    ----------
    recomputed : int
        Exact distance recomputations (candidate search and set) so far: the engine's main cost, several per
        point update because an update moves features that other points' distances were measured to.
    """

    name = "fast"

    def __init__(self, metal, oxide=None, *, tolerance: float | None = None, interacting: str = "wait",
                 jit: bool | None = None, threads: int | None = None, **kwargs):
        super().__init__(metal, oxide, **kwargs)
        tolerance = 0.1 * self.step if tolerance is None else tolerance
        try:
            tolerance = float(tolerance)
        except (TypeError, ValueError):
            raise InputError(f"tolerance must be a number of nm, got {tolerance!r}") from None
        if not (math.isfinite(tolerance) and tolerance >= 0):
            raise InputError(f"tolerance must be >= 0 nm, got {tolerance!r}")
        self.tolerance = max(tolerance, self.tie)
        if interacting not in INTERACTING:
            raise InputError(f"interacting must be one of {INTERACTING}, got {interacting!r}")
        self.interacting = interacting
        if jit and not kernels.AVAILABLE:
            raise ImportError("jit=True needs numba: pip install 'nanodisorder[fast]' (or numba)")
        self.jit = kernels.AVAILABLE if jit is None else bool(jit)
        if threads is None:
            threads = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
        if isinstance(threads, bool) or not isinstance(threads, (int, np.integer)) or threads < 1:
            raise InputError(f"threads must be a whole number >= 1, got {threads!r}")
        self.threads = int(threads) if self.jit else 1
        self._closest = kernels.closest_sets if self.jit else features.closest_sets
        self._pyramid = HeightPyramid(self.grid, self.zo) if self.jit else None
        # candidate searches of metal points below the whole oxide, kept (their distances can only grow)
        self._cache = BallCache(self.grid.n, CACHE_MARGIN * self.step) if self.jit else None
        g = self.grid
        self._x = g.i * g.dx
        self._y = g.j * g.dy
        # the oxide sets as (metal point, oxide point) rows sorted by metal point: those of point p are rows
        # _start[p]:_start[p + 1]; _sharers counts the rows of each oxide point
        self.pair_m = np.zeros(0, dtype=np.intp)
        self.pair_o = np.zeros(0, dtype=np.intp)
        self._start = np.zeros(g.n + 1, dtype=np.intp)
        self._sharers = np.zeros(g.n, dtype=np.intp)
        self._scratch = (np.full(g.n, np.inf), np.full(g.n, np.inf)) if self.jit else None  # for `_batch`
        self.D[:] = np.inf
        # points interact when they share a feature: grid segments (4 neighbours), and with exact
        # distances also cell centres (8 neighbours)
        reach = ((1, 0), (-1, 0), (0, 1), (0, -1)) if self.distance == "thesis" else \
            tuple((di, dj) for di in (-1, 0, 1) for dj in (-1, 0, 1) if di or dj)
        self._neighbours = [g.shift(np.arange(g.n), di, dj) for di, dj in reach]
        self._neighbour_table = np.stack(self._neighbours, axis=1)
        self._near = np.full(g.n, -1, dtype=np.intp)  # per metal point, the nearest oxide point of its set
        self.recomputed = 0
        self._update_reaches()
        everything = np.arange(g.n)
        self._recompute(everything, self.zo - self.zm)  # the oxide straight above bounds every distance

    def _star(self, z: np.ndarray, points: np.ndarray) -> np.ndarray:
        """`FeatureKernel.star_reach` of ``z`` at ``points`` (compiled when jit)."""
        return kernels.star_reach(self.kernel, z, points) if self.jit else self.kernel.star_reach(z, points)

    def _update_reaches(self, metal_moved: np.ndarray | None = None, oxide_moved: np.ndarray | None = None) -> None:
        """Upper bounds of the longest metal and oxide feature edges, nm.

        Measured exactly every `REACH_REFRESH` sweeps (and when no moves are
        given); in between, raised to the longest edge at the points that
        moved: every edge that changed touches one of them (with exact
        distances, the half-diagonals of the cells around them too).
        """
        if metal_moved is None or self.iterations - self._reach_checked >= REACH_REFRESH:
            everything = np.arange(self.grid.n)
            self._metal_longest = float(self._star(self.zm, everything).max())
            self._oxide_longest = float(self._star(self.zo, everything).max())
            self._reach_checked = self.iterations
        else:
            def longest(job):
                moved, z = job
                near = self.grid.block(moved) if self.distance == "exact" else moved
                return float(self._star(z, near).max(initial=0.0))
            jobs = [(metal_moved, self.zm), (oxide_moved, self.zo)]
            side_by_side = self.threads > 1 and min(len(metal_moved), len(oxide_moved)) >= POINTS_PER_THREAD
            metal, oxide = self._map(longest, jobs) if side_by_side else map(longest, jobs)
            self._metal_longest = max(self._metal_longest, metal)
            self._oxide_longest = max(self._oxide_longest, oxide)
        self._oxide_reach = self.kernel.oxide_reach(self._oxide_longest)

    # -- distances -------------------------------------------------------------------------

    def _radii(self, points: np.ndarray, bound: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Search radii (oxide features, metal features) around metal points ``points`` for the
        features that can be closer than ``bound[i]`` to them.

        An oxide feature closer than ``B`` to metal point ``m`` has a grid point
        within ``sqrt(B^2 + R^2)`` of ``m``, ``R`` = `FeatureKernel.oxide_reach`;
        a metal feature at ``m`` closer than ``B`` to an oxide point lies within
        ``sqrt(B^2 + S^2)`` of it, ``S`` = the star reach of ``m``. (When the
        closest point ``q`` is a perpendicular foot, ``|m - a|^2 = d^2 + |q - a|^2``
        for every grid point ``a`` of the feature.)
        """
        if self.jit:
            return bookkeeping.radii(self.kernel, self.zm, points, bound, self._oxide_reach, self.tie)
        inflate = 1 + 1e-12
        r_ox = np.sqrt(bound**2 + self._oxide_reach**2) * inflate + self.tie
        r_me = np.sqrt(bound**2 + self._star(self.zm, points) ** 2) * inflate + self.tie
        return r_ox, r_me

    def _candidates(self, search, points: np.ndarray, r_ox: np.ndarray, r_me: np.ndarray):
        """(query index, anchor, oxide slots?, metal slots?) of the pairs within the radii `_radii` of
        metal points ``points``; ``search(points, z, radius)`` lists the grid points within
        ``radius[i]`` of ``(points[i], z[i])`` as (query index, point, distance)."""
        which, anchors, gap = search(points, self.zm[points], np.maximum(r_ox, r_me))
        if self.jit:  # (in a thread: compiled code runs without the GIL, numpy's small steps hold it)
            return (which, anchors) + bookkeeping.within(which, gap, r_ox, r_me)
        return which, anchors, gap <= r_ox[which], gap <= r_me[which]

    def _recompute(self, points: np.ndarray, bound: np.ndarray | None = None) -> None:
        """Exact distance and set of ``points``, given an upper bound of each new distance (default `_bound`)."""
        if not len(points):
            return
        self.recomputed += len(points)
        if self._pyramid is None:
            search = self._tree_search()
        else:
            self._pyramid.rebuild(self.zo)
            search = functools.partial(self._pyramid.ball, self.zo, cache=self._cache)
        parts = self._map(lambda part: self._closest_within(search, points[part], None if bound is None else bound[part]),
                          self._split(len(points)))
        found, distance, owner, oxide = (np.concatenate(column) for column in zip(*parts))
        self.D[found] = distance
        self._replace_rows(points, owner, oxide)

    def _replace_rows(self, points: np.ndarray, owner: np.ndarray, oxide: np.ndarray) -> None:
        """Replace the sets of ``points`` (ascending) by the rows ``owner, oxide`` (owners among ``points``,
        ascending)."""
        if self.jit:
            self.pair_m, self.pair_o, self._start = bookkeeping.replace_rows(
                self.pair_m, self.pair_o, self._start, self._sharers, points, owner, oxide)
            return
        n = self.grid.n
        keep = np.ones(n, dtype=bool)
        keep[points] = False
        keep = keep[self.pair_m]
        pm, po = np.concatenate([self.pair_m[keep], owner]), np.concatenate([self.pair_o[keep], oxide])
        order = np.argsort(pm, kind="stable")
        self.pair_m, self.pair_o = pm[order], po[order]
        self._start = np.concatenate([[0], np.cumsum(np.bincount(self.pair_m, minlength=n))])
        self._sharers = np.bincount(self.pair_o, minlength=n)

    def _closest_within(self, search, points: np.ndarray, bound: np.ndarray | None):
        """`_recompute`'s work for ``points`` (in a thread; each step compiled when jit): their distances
        and sets, as (points, distances, set rows' metal points, their oxide points); notes each one's
        nearest set point."""
        r_ox, r_me = self._radii(points, self._bound(points) if bound is None else bound)
        which, anchors, oxide_slots, metal_slots = self._candidates(search, points, r_ox, r_me)
        metal = points[which]
        if len(which) <= CHUNK_PAIRS:
            found, distance, owner, oxide = self._closest(self.kernel, self.zm, self.zo, metal, anchors, self.tie,
                                                          oxide_slots, metal_slots)
            self._remember_nearest(found[owner], oxide)
            return found, distance, found[owner], oxide
        lengths = np.bincount(which, minlength=len(points))
        starts = np.concatenate([[0], np.cumsum(lengths)])
        found, distance, owner, oxide = [], [], [], []
        for lo, hi in _chunks(lengths, CHUNK_PAIRS):
            sel = slice(int(starts[lo]), int(starts[hi]))
            f, d, ow, ox = self._closest(self.kernel, self.zm, self.zo, metal[sel], anchors[sel], self.tie,
                                        oxide_slots[sel], metal_slots[sel])
            found.append(f)
            distance.append(d)
            owner.append(f[ow])
            oxide.append(ox)
        found, distance, owner, oxide = (np.concatenate(column) for column in (found, distance, owner, oxide))
        self._remember_nearest(owner, oxide)
        return found, distance, owner, oxide

    def _vertex_gap(self, metal: np.ndarray, oxide: np.ndarray) -> np.ndarray:
        """Distance between metal and oxide grid points (nearest periodic image), nm."""
        if self.jit:
            return bookkeeping.vertex_gap(self.grid, self.zm, self.zo, metal, oxide)
        di, dj = self.grid.offsets(metal, oxide)
        return np.sqrt((di * self.grid.dx) ** 2 + (dj * self.grid.dy) ** 2 + (self.zo[oxide] - self.zm[metal]) ** 2)

    def _remember_nearest(self, owner: np.ndarray, oxide: np.ndarray) -> None:
        """Note each metal point's nearest oxide point among its new set rows ``owner, oxide`` (grouped by owner)."""
        if self.jit:
            bookkeeping.remember_nearest(self.grid, self.zm, self.zo, owner, oxide, self._near)
            return
        if not len(owner):
            return
        gap = self._vertex_gap(owner, oxide)
        start = np.flatnonzero(np.concatenate([[True], owner[1:] != owner[:-1]]))
        nearest = np.flatnonzero(gap == np.repeat(np.minimum.reduceat(gap, start), np.diff(np.append(start, len(owner)))))
        last = np.append(owner[nearest][1:] != owner[nearest][:-1], True)  # of equally near ones, the last
        self._near[owner[nearest[last]]] = oxide[nearest[last]]

    def _bound(self, points: np.ndarray) -> np.ndarray:
        """Upper bound of each point's distance now: its distance to the oxide point of its set that was
        nearest when the set was found.

        (The point-to-point distance is one of the feature pairs the distance is
        the smallest of, so this bounds it from above; it is looser than the
        old closest pair by at most a feature's size, which at 100 nm of oxide
        widens the candidate search by hundredths of a nm.)
        """
        return self._vertex_gap(points, self._near[points])

    def _split(self, n: int) -> list[slice]:
        """``range(n)`` in consecutive parts, one per thread (at least `POINTS_PER_THREAD` items each)."""
        parts = max(1, min(self.threads, n // POINTS_PER_THREAD))
        return [slice(n * p // parts, n * (p + 1) // parts) for p in range(parts)]

    def _map(self, function, parts: list) -> list:
        """``function`` over ``parts``, in threads when there are several (the compiled code releases the GIL)."""
        rest = [_pool(len(parts) - 1).submit(function, part) for part in parts[1:]]
        return [function(parts[0])] + [future.result() for future in rest]  # this thread takes the first part

    # -- one sweep -------------------------------------------------------------------------

    def advance(self) -> None:
        in_batch, rows, set_size, sharers = self._batch()
        raised, lowered, rise = self.oxidize(self.pair_m[rows], self.pair_o[rows], set_size, sharers, self.step)
        self._update_reaches(lowered, raised)
        # points whose own features or whose oxide points moved: from scratch
        stale = self._stale(in_batch, raised)
        points = np.flatnonzero(stale)
        self._recompute(points)
        # the others near a raised oxide point: take it if it is now as close or closer
        self._take_closer(raised, stale, rise)

    def _stale(self, in_batch: np.ndarray, raised: np.ndarray) -> np.ndarray:
        """The points whose distance may have grown (boolean mask): the oxidized ones, the points sharing
        a feature with one, and the points whose set holds a ``raised`` oxide point."""
        if self.jit:
            return bookkeeping.stale(in_batch, raised, self._neighbour_table, self.pair_m, self.pair_o)
        is_raised = np.zeros(self.grid.n, dtype=bool)
        is_raised[raised] = True
        stale = in_batch.copy()
        batch = np.flatnonzero(in_batch)
        for k in self._neighbours:
            stale[k[batch][k[batch] >= 0]] = True
        stale[self.pair_m[is_raised[self.pair_o]]] = True
        return stale

    def _batch(self):
        """The points to oxidize now: within ``tolerance`` of the smallest distance, and (with
        ``interacting="wait"``) each the closest among the candidates it interacts with (shares an
        oxide point or a feature with).

        Waiting, interacting points are oxidized one after the other, as in the sequential
        algorithm; points that do not interact commute, so oxidizing them together changes nothing.
        Oxidized together, interacting points split their oxide points' growth (Eq 3.9) within the
        sweep, which changes the result by what the tolerance lets in (none at tolerance 0).

        Returns the points (boolean mask), their set rows (ascending), and for each row the size
        of its set and the number of sets holding its oxide point (Eq 3.9's shares).
        """
        if self.jit:
            return bookkeeping.batch(self.D, self.tolerance, self.tie, self.interacting == "wait", self._neighbour_table,
                                     self.pair_o, self._start, self._sharers, *self._scratch)
        g = self.grid
        d = np.where(self.D <= self.D.min() + self.tolerance, self.D, np.inf)
        if self.interacting == "together":
            d[np.isfinite(d)] = 0.0  # no candidate is closer than another
        rival = np.full(g.n, np.inf)  # smallest distance of an interacting candidate
        for k in self._neighbours:
            rival = np.minimum(rival, np.where(k >= 0, d[k], np.inf))
        rows = np.isfinite(d[self.pair_m])
        first = np.full(g.n, np.inf)  # per oxide point, the smallest candidate distance holding it
        np.minimum.at(first, self.pair_o[rows], d[self.pair_m[rows]])
        np.minimum.at(rival, self.pair_m[rows], first[self.pair_o[rows]])
        # exact ties go together (as in the reference); a strictly closer rival makes a point wait
        in_batch = np.isfinite(d) & ~(rival < d - self.tie)
        rows = np.flatnonzero(in_batch[self.pair_m])
        set_size = np.diff(self._start)[self.pair_m[rows]].astype(float)
        return in_batch, rows, set_size, self._sharers[self.pair_o[rows]].astype(float)

@functools.lru_cache(maxsize=None)
def _pool(threads: int) -> ThreadPoolExecutor:
    """One pool per thread count, kept for the life of the process (a pool per sweep costs more than a sweep)."""
    return ThreadPoolExecutor(threads, thread_name_prefix="planarize")


if hasattr(os, "register_at_fork"):  # a forked child (e.g. a sweep worker) has none of the pools' threads
    os.register_at_fork(after_in_child=_pool.cache_clear)


def _chunks(lengths: np.ndarray, limit: int):
    """Split consecutive groups of ``lengths`` into runs of about ``limit`` items: (start, stop) group indices."""
    ends = np.cumsum(lengths)
    start = 0
    while start < len(lengths):
        base = ends[start - 1] if start else 0
        stop = int(np.searchsorted(ends, base + limit, side="right"))
        stop = max(stop, start + 1)
        yield start, stop
        start = stop

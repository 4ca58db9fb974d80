"""The fast engine: batched oxidation, bulk candidate searches, incremental distance updates, compiled.

Each `FastEngine.advance` (a *sweep*) oxidizes every metal point whose distance is within
``tolerance`` of the smallest (one Eq 3.9 step each, shares computed for the whole batch at once,
so volume balance stays exact), then brings distances up to date for the metal points that can have
changed, and only those:

* the oxidized points and their neighbours, and the points whose oxide set holds a raised oxide
  point (they may be farther): recomputed from scratch;
* the other points within reach of a raised oxide point (they may be closer): offered the raised
  points (`planarize.engines.closer`).

A recomputation is exact: the nearest oxide point of the previous set bounds the new distance
(`OxideSets.bound`), and every feature closer than that bound has a grid point within
`planarize.engines.kernels.search_radii` of the metal point, so a ball search of the oxide points
lists every candidate (`planarize.engines.pyramid.HeightPyramid`), and the compiled kernel
(`planarize.engines.kernels.closest_sets`) evaluates them, split over ``threads`` threads. A metal
point below the whole oxide only moves away from every oxide point from then on, so its search,
made a little wider, is kept and answers its later searches (`planarize.engines.pyramid.BallCache`).
Results are the same bit for bit for any thread count. Periodic grids take the nearest periodic image.

``tolerance = 0`` oxidizes exact ties only and reproduces the reference engine to round-off; larger
tolerances take larger batches (fewer sweeps) at the cost of oxidizing some points slightly early.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from labrig.params import Param
from labrig.threads import available_threads, run_in_threads
from labrig.validate import InputError, count

from . import PARAMS
from .base import Engine, run_sweeps
from .closer import TreeSearch, below_raised
from .features import oxide_reach
from .kernels import closest_sets, search_radii, star_reach, within
from .pyramid import BallCache, HeightPyramid
from .sets import OxideSets

#: Candidate pairs evaluated per kernel call (bounds memory: 33 distances each in exact mode).
CHUNK_PAIRS = 400_000
#: Fewest points per thread worth a thread of their own (below, the hand-over costs more than it saves).
POINTS_PER_THREAD = 512
#: How much wider (in steps) a metal point's candidate search is made when its result is kept for later sweeps.
CACHE_MARGIN = 0.5
#: Sweeps between exact measurements of the longest feature edges (in between, upper bounds that only grow).
REACH_REFRESH = 64
#: Most threads.
MAX_THREADS = 256


@dataclass(frozen=True)
class Fast:
    """The fast engine and its speed/accuracy settings (`FastEngine`): ``anodize(..., engine=Fast(...))``.

    Parameters
    ----------
    tolerance : float, optional
        Batch tolerance, nm (>= 0): points within this distance of the smallest are oxidized
        together. Default ``0.1 * step``: within 2 % of the sequential reference's roughness on the
        thesis hill (1.5 %; half a step: 3.3 %, and 7.5 % on average over copies with their exact ties
        broken), for 40 % more time there and 14 % on the Ta film (`docs/performance.md`). Where
        agreement with the sequential algorithm matters less than time, half a step costs least in
        accuracy: on a 257 x 257 periodic random surface to 200 nm it is 1.3x faster and changes the
        roughness by 0.2 %; for more speed, ``interacting="together"`` at one step is 2.6x faster
        there for 0.4 %.
    interacting : {"wait", "together"}
        What candidates that interact (share an oxide point or a grid segment) do. ``"wait"``
        (default): a candidate with a strictly closer interacting one waits for a later sweep, as in
        the sequential algorithm. ``"together"``: every candidate is oxidized in the sweep, with Eq
        3.9's shares counted over the whole batch (volume balance stays exact); far fewer distance
        recomputations per update, so large rough surfaces run several times faster at a tolerance of
        a step or more. At tolerance 0 both give the same results.
    threads : int, optional
        Threads for the compiled distance updates, in [1, `MAX_THREADS`]; the results do not depend
        on it. Default: the CPUs this process may use.
    """

    tolerance: float | None = None
    interacting: str = "wait"
    threads: int | None = None

    name = "fast"
    #: The declarations of the settings a scene file's ``[engine]`` table takes (`labrig.params.Param`).
    PARAMS: ClassVar[dict[str, Param]] = PARAMS["fast"]

    def __post_init__(self) -> None:
        for key, param in self.PARAMS.items():
            object.__setattr__(self, key, param.check(key, getattr(self, key)))
        if self.threads is not None:
            object.__setattr__(self, "threads", count("threads", self.threads, 1, MAX_THREADS))

    def build(self, metal, oxide, model) -> FastEngine:
        """The engine for ``metal`` (and ``oxide``) under ``model``."""
        return FastEngine(metal, oxide, model, settings=self)

    def options(self) -> dict:
        """The settings as plain data (the fields that differ from the defaults)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)
                if getattr(self, f.name) != f.default}

    def run(self, metal, oxide, thickness, model, rows_at, shots_at, *, progress=False, observer=None,
            max_seconds=None):
        """A run on ``metal``'s grid, sweep by sweep (`planarize.engines.base.run_sweeps`); the arguments are
        `planarize.anodize`'s, checked."""
        return run_sweeps(self, metal, oxide, thickness, model, rows_at, shots_at, progress=progress,
                          observer=observer, max_seconds=max_seconds)


class FastEngine(Engine):
    """Batched, compiled engine. See `planarize.engines.base.Engine` for ``metal``, ``oxide``, ``model``
    and `Fast` for ``settings``.

    Attributes
    ----------
    sets : OxideSets
        Every metal point's oxide set.
    recomputed : int
        Exact distance recomputations (candidate search and set) so far: the engine's main cost,
        several per point update because an update moves features that other points' distances were
        measured to.
    """

    name = "fast"
    #: the sweep at which the reaches were last measured exactly (set by the first `_update_reaches`)
    _reach_checked: int

    def __init__(self, metal, oxide=None, model=None, settings: Fast | None = None):
        super().__init__(metal, oxide, model)
        self.settings = Fast() if settings is None else settings
        if not isinstance(self.settings, Fast):
            raise InputError(f"settings must be planarize.engines.Fast, got {type(self.settings).__name__}")
        tolerance = 0.1 * self.step if self.settings.tolerance is None else self.settings.tolerance
        self.tolerance = max(tolerance, self.tie)
        self.interacting = self.settings.interacting
        threads = self.settings.threads
        self.threads = available_threads() if threads is None else int(threads)
        g = self.grid
        self.sets = OxideSets(g.n)
        self._pyramid = HeightPyramid(g, self.zo)
        # candidate searches of metal points below the whole oxide, kept (their distances can only grow)
        self._cache = BallCache(g.n, CACHE_MARGIN * self.step)
        # points interact when they share a feature: grid segments (4 neighbours), and with exact
        # distances also cell centres (8 neighbours)
        offsets = ((1, 0), (-1, 0), (0, 1), (0, -1)) if self.distance == "thesis" else \
            tuple((di, dj) for di in (-1, 0, 1) for dj in (-1, 0, 1) if di or dj)
        self.neighbours = np.stack([g.shift(np.arange(g.n), di, dj) for di, dj in offsets], axis=1)
        self.D[:] = np.inf
        self.recomputed = 0
        self._update_reaches()
        everything = np.arange(g.n)
        self._recompute(everything, self.zo - self.zm)  # the oxide straight above bounds every distance

    # -- bounds of how far features reach ---------------------------------------------------

    def _update_reaches(self, metal_moved: np.ndarray | None = None, oxide_moved: np.ndarray | None = None) -> None:
        """Upper bounds of the longest metal and oxide feature edges, nm.

        Measured exactly every `REACH_REFRESH` sweeps (and when no moves are
        given); in between, raised to the longest edge at the points that
        moved: every edge that changed touches one of them (with exact
        distances, the half-diagonals of the cells around them too).
        """
        if metal_moved is None or self.iterations - self._reach_checked >= REACH_REFRESH:
            self._metal_longest = float(star_reach(self.tables, self.zm).max())
            self._oxide_longest = float(star_reach(self.tables, self.zo).max())
            self._reach_checked = self.iterations
        else:
            assert oxide_moved is not None  # the two moves are given together
            def longest(job):
                moved, z = job
                near = self.grid.block(moved) if self.distance == "exact" else moved
                return float(star_reach(self.tables, z, near).max(initial=0.0))
            jobs = [(metal_moved, self.zm), (oxide_moved, self.zo)]
            side_by_side = self.threads > 1 and min(len(metal_moved), len(oxide_moved)) >= POINTS_PER_THREAD
            metal, oxide = self._map(longest, jobs) if side_by_side else map(longest, jobs)
            self._metal_longest = max(self._metal_longest, metal)
            self._oxide_longest = max(self._oxide_longest, oxide)
        self._oxide_reach = oxide_reach(self._oxide_longest, self.distance)

    # -- distances --------------------------------------------------------------------------

    def _recompute(self, points: np.ndarray, bound: np.ndarray | None = None) -> None:
        """Exact distance and set of ``points``, given an upper bound of each new distance (default
        `OxideSets.bound`)."""
        if not len(points):
            return
        self.recomputed += len(points)
        self._pyramid.rebuild(self.zo)
        search = functools.partial(self._pyramid.ball, self.zo, cache=self._cache)

        def part(section):
            return self._closest_within(search, points[section], None if bound is None else bound[section])

        found, distance, owner, oxide = (np.concatenate(column) for column in zip(*self._map(part, self._split(len(points)))))
        self.D[found] = distance
        self.sets.replace(points, owner, oxide)

    def _closest_within(self, search, points: np.ndarray, bound: np.ndarray | None):
        """`_recompute`'s work for ``points`` (in a thread; every step compiled): their distances and sets,
        as (points, distances, set rows' metal points, their oxide points); notes each one's nearest set point."""
        if bound is None:
            bound = self.sets.bound(self.tables, self.zm, self.zo, points)
        r_ox, r_me = search_radii(self.tables, self.zm, points, bound, self._oxide_reach, self.tie)
        which, anchors, gap = search(points, self.zm[points], np.maximum(r_ox, r_me))
        oxide_slots, metal_slots = within(which, gap, r_ox, r_me)
        metal = points[which]
        parts = []
        lengths = np.bincount(which, minlength=len(points))
        starts = np.concatenate([[0], np.cumsum(lengths)])
        for lo, hi in _chunks(lengths, CHUNK_PAIRS):
            sel = slice(int(starts[lo]), int(starts[hi]))
            f, d, ow, ox = closest_sets(self.tables, self.zm, self.zo, metal[sel], anchors[sel], self.tie,
                                        oxide_slots[sel], metal_slots[sel])
            parts.append((f, d, f[ow], ox))
        if not parts:  # no points
            return (np.zeros(0, dtype=np.intp), np.zeros(0)) + 2 * (np.zeros(0, dtype=np.intp),)
        found, distance, owner, oxide = (np.concatenate(column) for column in zip(*parts)) if len(parts) > 1 \
            else parts[0]
        self.sets.note_nearest(self.tables, self.zm, self.zo, owner, oxide)
        return found, distance, owner, oxide

    def _split(self, n: int) -> list[slice]:
        """``range(n)`` in consecutive parts, one per thread (at least `POINTS_PER_THREAD` items each)."""
        parts = max(1, min(self.threads, n // POINTS_PER_THREAD))
        return [slice(n * p // parts, n * (p + 1) // parts) for p in range(parts)]

    def _map(self, function, parts: list) -> list:
        """``function`` over ``parts``, in threads when there are several (the compiled code releases the GIL)."""
        return run_in_threads(function, parts)

    # -- one sweep --------------------------------------------------------------------------

    def advance(self, until: float = math.inf) -> None:
        in_batch, rows, set_size, sharers = self.sets.batch(self.D, self.tolerance, self.tie,
                                                            self.interacting == "wait", self.neighbours)
        raised, lowered, rise = self.oxidize(self.sets.metal[rows], self.sets.oxide[rows], set_size, sharers,
                                             self.step)
        self._update_reaches(lowered, raised)
        # points whose own features or whose oxide points moved: from scratch
        stale = self.sets.stale(in_batch, raised, self.neighbours)
        self._recompute(np.flatnonzero(stale))
        # the others near a raised oxide point: take it if it is now as close or closer
        self._take_closer(raised, stale, rise)

    def _take_closer(self, raised: np.ndarray, skip: np.ndarray, rise: float) -> None:
        """Metal points near the raised oxide points (but not in ``skip``) take them if now as close or closer
        than their set: a closer point's set is replaced, a tied point's set grows."""
        if not len(raised):
            return
        anchors = self.grid.block(raised) if self.distance == "exact" else raised  # exact: cell centres moved
        reach = math.sqrt(float(self.D.max()) ** 2 + max(self._oxide_reach, self._metal_longest) ** 2)
        metal = np.flatnonzero(~skip & below_raised(self.grid, self.zm, self.zo, anchors, rise, self.tie, reach))
        if not len(metal):
            return
        # (few raised points are near any one metal point: a short k-nearest query, ball queries for the rest)
        limit = float(np.max(self.D[np.isfinite(self.D)], initial=0.0)) + float(np.max(self.zo - self.zm)) \
            + 2.0 * max(self._metal_longest, self._oxide_longest)
        span = (float(min(self.zm.min(), self.zo.min())), float(max(self.zm.max(), self.zo.max())))
        search = TreeSearch(self.grid, self.zo, anchors, span=span, reach=limit, k=4)
        r_ox, r_me = search_radii(self.tables, self.zm, metal, self.D[metal] + self.tie, self._oxide_reach, self.tie)
        which, anchor, gap = search(metal, self.zm[metal], np.maximum(r_ox, r_me))
        if not len(which):
            return
        oxide_slots, metal_slots = within(which, gap, r_ox, r_me)
        found, distance, owner, oxide = closest_sets(self.tables, self.zm, self.zo, metal[which], anchors[anchor],
                                                     self.tie, oxide_slots, metal_slots)
        closer = distance < self.D[found] - self.tie
        tied = ~closer & (distance <= self.D[found] + self.tie)
        if not (closer.any() or tied.any()):
            return
        new = (closer | tied)[owner]
        pm, po = found[owner[new]], oxide[new]
        sets = self.sets
        if tied.any():
            old = np.isin(sets.metal, found[tied])
            key = np.unique(np.concatenate([pm, sets.metal[old]]) * self.grid.n + np.concatenate([po, sets.oxide[old]]))
            pm, po = key // self.grid.n, key % self.grid.n
        sets.replace(found[closer | tied], pm, po)
        # the nearest set point: among the new rows, and for a tie also the old nearest
        kept = found[tied]
        points = np.concatenate([found[owner[new]], kept])
        order = np.argsort(points, kind="stable")
        sets.note_nearest(self.tables, self.zm, self.zo, points[order], np.concatenate([oxide[new], sets.nearest[kept]])[order])
        self.D[found] = np.minimum(self.D[found], np.where(closer | tied, distance, np.inf))


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

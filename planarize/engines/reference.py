"""The reference engine: the thesis's algorithm (section 3.3, Matlab Listings B.1-B.3), one batch of ties at a time.

Data structures as in the Matlab: ``D`` (``distance2ox``), ``ox[m]``
(``oxpoints``: the oxide points closest to metal point ``m``) and ``met[o]``
(``metpoints``: the metal points whose set holds ``o``), as Python sets.
Each `advance`:

1. takes the metal points at the smallest distance (exact ties together),
2. raises their oxide points and lowers them by Eq 3.9 (`Engine.oxidize`),
3. recomputes from scratch the distance of every metal point whose distance
   may have grown: the oxidized points, their 8 neighbours (their segments and
   cells moved), and ``met[o]`` of every raised oxide point (``updatemetalpoint3``),
4. lets every metal point near a raised oxide point take it if it is now
   closer (``updateoxidepoint``).

Searches use the thesis's triangle-inequality windows: a point whose
distance is at most ``B`` can only be closer to features whose grid points
lie within ``sqrt(B^2 + L^2)`` in x and y (``L`` the longest feature edge),
so only those are examined. The differences from the Matlab, each a fix:
the window adds the feature-length term (the Matlab's could miss a segment
whose ends lie just outside it), the neighbours of an oxidized point are
updated (the Matlab left their segment distances stale), and exact ties are
oxidized together (see `planarize.engines.base`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from labrig.params import Param

from .base import Engine, run_sweeps
from .kernels import closest_sets


class ReferenceEngine(Engine):
    """The thesis algorithm, sequential and windowed. See `planarize.engines.base.Engine` for parameters."""

    name = "reference"

    def __init__(self, metal, oxide=None, model=None) -> None:
        super().__init__(metal, oxide, model)
        n = self.grid.n
        self.ox: list[set[int]] = [set() for _ in range(n)]
        self.met: list[set[int]] = [set() for _ in range(n)]
        self.D[:] = np.inf
        self._length = self.max_feature_length()
        self._length_checked = 0
        # the oxide point straight above is a first bound on every distance
        self._recompute(np.arange(n), self.zo - self.zm)

    # -- bookkeeping -----------------------------------------------------------------------

    def _assign(self, m: int, distance: float, oxide: set[int]) -> None:
        for o in self.ox[m]:
            self.met[o].discard(m)
        self.ox[m] = oxide
        for o in oxide:
            self.met[o].add(m)
        self.D[m] = distance

    def _feature_reach(self) -> float:
        """An upper bound of the longest feature edge, nm (exact every 1000 iterations, grown in between)."""
        if self.iterations - self._length_checked >= 1000:
            self._length = self.max_feature_length()
            self._length_checked = self.iterations
        return self._length

    def _update(self, m, v, rule: str, metal_only=None) -> None:
        """Closest sets over the (metal, anchor) pairs ``m``, ``v``; ``rule`` "replace" or "take closer".

        ``metal_only`` (bool per pair, optional): pairs that compare only the metal features at ``m``
        with the anchor point (no oxide features of the anchor).
        """
        oxide = None if metal_only is None else ~metal_only
        found, distance, owner, oxide = closest_sets(self.tables, self.zm, self.zo, m, v, self.tie, oxide=oxide)
        sets = np.split(oxide, np.flatnonzero(np.diff(owner)) + 1)
        for p, d, s in zip(found.tolist(), distance.tolist(), sets):
            if rule == "replace" or d < self.D[p] - self.tie:
                self._assign(p, d, set(s.tolist()))
            elif d <= self.D[p] + self.tie:
                self._assign(p, min(d, self.D[p]), self.ox[p] | set(s.tolist()))

    def _window(self, centre: int, reach: float) -> np.ndarray:
        return self.grid.window(centre, int(reach // self.grid.dx), int(reach // self.grid.dy))

    def _recompute(self, points: np.ndarray, bound: np.ndarray) -> None:
        """Distance and set of ``points`` from scratch; ``bound`` is an upper bound of each new distance."""
        reach = np.sqrt(bound**2 + self._feature_reach() ** 2)
        windows = [self._window(p, r) for p, r in zip(points.tolist(), reach.tolist())]
        m = np.repeat(points, [len(w) for w in windows])
        self._update(m, np.concatenate(windows), "replace")

    def _take_closer(self, raised: np.ndarray) -> None:
        """Metal points near the raised oxide points take them if now as close or closer."""
        g = self.grid
        exact = self.distance == "exact"
        # a feature touching a raised point can be within D.max() only of metal points this close
        reach = math.sqrt(float(self.D.max()) ** 2 + self._feature_reach() ** 2)
        ms, vs = [], []
        for o in raised.tolist():
            anchors = g.block(o) if exact else np.array([o])  # exact: cell centres move with their corners
            window = self._window(o, reach + (max(g.dx, g.dy) if exact else 0.0))
            ms.append(np.repeat(window, len(anchors)))
            vs.append(np.tile(anchors, len(window)))
        if ms:
            self._update(np.concatenate(ms), np.concatenate(vs), "take closer")

    # -- one iteration ---------------------------------------------------------------------

    def advance(self, until: float = math.inf) -> None:
        batch = np.flatnonzero(self.D <= self.D.min() + self.tie)
        owner = np.array([m for m in batch for _ in self.ox[m]], dtype=np.intp)
        oxide = np.array([o for m in batch for o in sorted(self.ox[m])], dtype=np.intp)
        set_size = np.array([len(self.ox[m]) for m in owner], dtype=float)
        sharers = np.array([len(self.met[o]) for o in oxide], dtype=float)
        stale = set(self.grid.block(batch).tolist())
        for o in set(oxide.tolist()):
            stale |= self.met[o]
        raised, _, moved = self.oxidize(owner, oxide, set_size, sharers, self.step)
        self._length += 2.0 * moved
        points = np.array(sorted(stale), dtype=np.intp)
        self._recompute(points, self.D[points] + moved)
        self._take_closer(raised)


class MatlabEngine(ReferenceEngine):
    """The Matlab listings' shortcuts, kept to measure what they cost (`ReferenceEngine` fixes them).

    * one metal point per iteration, the first of the smallest in storage order
      (Matlab's ``min``), ties included;
    * search windows of ``floor((distance + 1.5 k_exp step) / dx)`` points with no
      feature-length term (``maxruffness``); a segment is searched over the union of the
      windows around its two ends (``union(allpoints2dist(index, ...), allpoints2dist(point2ind,
      ...))``): the metal segments of a recomputed point against the oxide points in the windows
      of both ends, a raised oxide point's segments against the metal points in both windows
      (a grid segment's ends are neighbours, so the union is the window grown by one point in x
      or in y; the four grown segments of a point are all compared with each point of that rim,
      where the listing compares only the one whose end it belongs to);
    * the neighbours of an oxidized point keep their old distances;
    * raised oxide points are offered only to metal points within
      ``smallestdist + maxruffness`` (``updateoxidepoint``).
    """

    name = "matlab"

    def _slack(self) -> float:
        return 1.5 * self.k_exp * self.step  # the Matlab's maxruffness

    def _windows(self, centre: int, reach: float) -> tuple[np.ndarray, np.ndarray]:
        """The listing's window around ``centre``, and its rim: the points the windows around
        ``centre``'s four grid neighbours add (``union(window(index), window(point2ind))``)."""
        g = self.grid
        wx, wy = int(reach // g.dx), int(reach // g.dy)
        window = g.window(centre, wx, wy)
        grown = np.union1d(g.window(centre, wx + 1, wy), g.window(centre, wx, wy + 1))
        return window, np.setdiff1d(grown, window, assume_unique=True)

    def _recompute(self, points: np.ndarray, bound: np.ndarray) -> None:
        reach = np.maximum(bound, 0.0) + self._slack()
        ms, vs, rims = [], [], []
        for p, r in zip(points.tolist(), reach.tolist()):
            window, rim = self._windows(p, r)
            ms.append(np.full(len(window) + len(rim), p))
            vs += [window, rim]
            rims += [np.zeros(len(window), bool), np.ones(len(rim), bool)]  # rim: metal segments only
        self._update(np.concatenate(ms), np.concatenate(vs), "replace", metal_only=np.concatenate(rims))

    def _take_closer(self, raised: np.ndarray) -> None:
        reach = float(self.D.min()) + self._slack()
        ms, vs = [], []
        for o in raised.tolist():
            window = np.concatenate(self._windows(o, reach))
            ms.append(window)
            vs.append(np.full(len(window), o))
        if ms:
            self._update(np.concatenate(ms), np.concatenate(vs), "take closer")

    def advance(self, until: float = math.inf) -> None:
        m = int(np.argmin(self.D))
        oxide = np.array(sorted(self.ox[m]), dtype=np.intp)
        owner = np.full(len(oxide), m, dtype=np.intp)
        set_size = np.full(len(oxide), float(len(oxide)))
        sharers = np.array([len(self.met[o]) for o in oxide], dtype=float)
        stale = {m}
        for o in oxide.tolist():
            stale |= self.met[o]
        previous = self.D.copy()
        raised, _, _ = self.oxidize(owner, oxide, set_size, sharers, self.step)
        points = np.array(sorted(stale), dtype=np.intp)
        self._recompute(points, previous[points])
        self._take_closer(raised)


@dataclass(frozen=True)
class Reference:
    """The thesis's sequential algorithm (`ReferenceEngine`): ``anodize(..., engine=Reference())``. No settings."""

    name = "reference"
    #: The engine class `build` makes.
    engine = ReferenceEngine
    #: The settings a scene file's ``[engine]`` table takes: none.
    PARAMS: ClassVar[dict[str, Param]] = {}

    def build(self, metal, oxide, model) -> ReferenceEngine:
        """The engine for ``metal`` (and ``oxide``) under ``model``."""
        return self.engine(metal, oxide, model)

    def options(self) -> dict:
        return {}

    def run(self, metal, oxide, thickness, model, rows_at, shots_at, *, progress=False, observer=None,
            max_seconds=None):
        """A run on ``metal``'s grid, sweep by sweep (`planarize.engines.base.run_sweeps`); the arguments are
        `planarize.anodize`'s, checked."""
        return run_sweeps(self, metal, oxide, thickness, model, rows_at, shots_at, progress=progress,
                          observer=observer, max_seconds=max_seconds)


@dataclass(frozen=True)
class Matlab(Reference):
    """The reference with the Matlab listings' shortcuts (`MatlabEngine`), to measure what they cost. No settings."""

    name = "matlab"
    engine = MatlabEngine

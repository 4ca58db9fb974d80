"""`PairScheme`: how the engine evaluates pair forces in time, the one owner of the multiple-time-step scheme.

A pair force (`qdots.VanDerWaals`) states its law only (`PairLaw`): the pull of the pairs within a surface gap
over some seconds. The scheme says which pairs are pulled when. A Verlet pair list holds every pair within the
law's range plus a skin; with ``far_interval`` unset every pair is pulled every step, as the thesis pulled every
pair once per frame. With ``far_interval`` set, the pairs closer than ``near_gap / 2`` (the contacts and the pairs
about to touch) are pulled every step, and the far pairs, whose pull is small and slow to change, get the pull
of a whole ``far_interval`` at once, at the start of the step that follows each interval's middle, evaluated
where the dots were at that middle (multiple time stepping, in the impulse form of r-RESPA: position Verlet
for the far field, second order in the interval). Between ``near_gap / 2`` and ``near_gap`` a pair's pull
passes smoothly from the one to the other (`NEAR_FADE`), so pairs crossing over are neither pulled twice nor
missed. The far passes follow the clock (`qdots.forces.base.instants_in_step`), so a resumed run keeps them.

The engines' settings hold its parameters (`qdots.engine.Chipmunk.pairs`, `qdots.engine.Event.pairs`) and hand
the scheme to the forces in each step's context (`qdots.forces.StepContext.pairs`). Its error and cost as
measured: docs/engines.md and docs/performance.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, ClassVar, Protocol

from labrig.params import Param, check_fields

from ..limits import MAX_SKIN

if TYPE_CHECKING:
    import numpy as np

    from ..forces.base import StepContext

#: Largest `PairScheme.near_gap`, px (twice the largest van der Waals range).
MAX_NEAR_GAP = 2000.0
#: Longest interval between passes over the far pairs, s.
MAX_FAR_INTERVAL = 1e4
#: Where the every-step pull starts to fade, as a fraction of `PairScheme.near_gap`: a pair's pull moves
#: smoothly (smoothstep in the gap) from the every-step pass at ``NEAR_FADE * near_gap`` to the far pass at
#: ``near_gap`` (a hard cut put a pair's path several times farther from the dt -> 0 path; docs/engines.md).
NEAR_FADE = 0.5


class PairLaw(Protocol):
    """What a pair force gives the scheme: its range and its pull (physics only)."""

    #: No force beyond this surface gap, px.
    max_gap: float

    def pair_constants(self, ctx: StepContext) -> Any:
        """What the law derives from the dots and the collision rule once per run (kept in the force's cache)."""

    def add_pair_kicks(self, constants: Any, x: np.ndarray, y: np.ndarray, i: np.ndarray, j: np.ndarray,
                       radii: np.ndarray, gap_to: float, fade_from: float, fade_to: float, far: bool, seconds: float,
                       dv: np.ndarray) -> None:
        """Add to ``dv`` the pull over ``seconds`` of the pairs ``(i, j)`` closer than the surface gap ``gap_to``:
        the part pulled every step, weighted 1 up to ``fade_from`` and fading to 0 at ``fade_to``, or (``far``)
        the rest; at the positions ``x, y`` (px)."""


@dataclass(frozen=True)
class PairScheme:
    """Which pairs a pair force pulls in each step: a Verlet pair list and, optionally, multiple time stepping.

    Parameters
    ----------
    pair_skin : float
        Verlet skin of the pair list, px, in [0, `qdots.limits.MAX_SKIN`] (`qdots.geometry.VerletPairs`): the
        list is rebuilt when a dot has moved half of it. Exact either way; a larger skin means fewer rebuilds
        and longer lists.
    near_gap : float
        Surface gap, px, in (0, `MAX_NEAR_GAP`], below which pairs are pulled every step (wholly below
        ``near_gap / 2``, fading out above) when ``far_interval`` is set.
    far_interval : float, optional
        Seconds between the passes over the far pairs, in (0, `MAX_FAR_INTERVAL`]. None (default): every pair
        every step.
    """

    pair_skin: float = 6.0
    near_gap: float = 4.0
    far_interval: float | None = None

    #: Declarations of the fields (`labrig.params`); the engines' settings declare theirs with these.
    PARAMS: ClassVar[dict[str, Param]] = {
        "pair_skin": Param("float", 0.0, MAX_SKIN, unit="px", doc="Verlet skin of the van der Waals pair list"),
        "near_gap": Param("float", 0.0, MAX_NEAR_GAP, low_open=True, unit="px",
                          doc="van der Waals pairs closer than this are pulled every step"),
        "far_interval": Param("float", 0.0, MAX_FAR_INTERVAL, low_open=True, unit="s", optional=True,
                              doc="time between passes over the farther van der Waals pairs",
                              unset="every pair every step"),
    }

    def __post_init__(self) -> None:
        check_fields(self, self.PARAMS)

    def splits(self, max_gap: float) -> bool:
        """True when a law of range ``max_gap`` (px) has its far pairs pulled every ``far_interval``."""
        return self.far_interval is not None and self.near_gap < max_gap

    def pull(self, law: PairLaw, ctx: StepContext) -> None:
        """Add the pull of ``law`` in the step ``ctx`` to ``ctx.dv``: every pair, or the near pairs and, when an
        interval's middle has passed, the far pass. What it derives from the dots it keeps in ``ctx.cache``."""
        from ..forces.base import instants_in_step
        from ..geometry import VerletPairs, pairs_closer

        cache = ctx.cache
        if not cache:  # first step with these dots
            import numpy as np

            cache.update(law=law.pair_constants(ctx), radii=np.ascontiguousarray(ctx.radii, dtype=float),
                         cutoff=law.max_gap + 2.0 * float(ctx.radii.max(initial=0.0)),
                         pairs=VerletPairs(self.pair_skin), split=self.splits(law.max_gap))
            cache["near"] = cache["pairs"].i, cache["pairs"].j
        pairs = cache["pairs"]
        rebuilt = pairs.update(ctx.x, ctx.y, cache["cutoff"])
        if not cache["split"]:
            self._pull(law, ctx, pairs.i, pairs.j, law.max_gap, False, ctx.dt)
            return
        if rebuilt:  # every pair that can come within near_gap before the next rebuild
            cache["near"] = pairs_closer(ctx.x, ctx.y, cache["radii"], pairs.i, pairs.j, self.near_gap + pairs.skin)
        near_i, near_j = cache["near"]
        self._pull(law, ctx, near_i, near_j, self.near_gap, False, ctx.dt)
        # the far pass: at the start of the step that follows each interval's middle (the middles in
        # (time - dt, time]), its pull over the interval, where the dots were at the (last) middle
        interval = self.far_interval
        assert interval is not None  # a split scheme has one (`splits`)
        intervals = instants_in_step(ctx.time - ctx.dt + 0.5 * interval, ctx.dt, interval)
        if intervals:
            lag = ctx.time - (math.floor((ctx.time + 0.5 * interval) / interval + 1e-9) - 0.5) * interval
            x = ctx.x - ctx.velocity[:, 0] * lag
            y = ctx.y - ctx.velocity[:, 1] * lag
            self._pull(law, ctx, pairs.i, pairs.j, law.max_gap, True, intervals * interval, x, y)

    def _pull(self, law: PairLaw, ctx: StepContext, i, j, gap_to: float, far: bool, seconds: float, x=None,
              y=None) -> None:
        """The law's pull over ``seconds`` of the pairs ``i, j`` closer than ``gap_to``: the part pulled every step
        (``far`` False) or the far pass's part; at the dots' positions ``x, y`` (default: ``ctx``'s)."""
        cache = ctx.cache
        split = cache["split"]
        fade_to = self.near_gap if split else law.max_gap
        fade_from = NEAR_FADE * fade_to if split else fade_to
        law.add_pair_kicks(cache["law"], ctx.x if x is None else x, ctx.y if y is None else y, i, j, cache["radii"],
                           gap_to, fade_from, fade_to, far, seconds, ctx.dv)

"""`Event`: the settings of the event engine, the thesis's own algorithm (exact hard discs, event by event).

The engine itself is `qdots.engine.event_backend.EventBackend`, which `Event.build` makes. What the cap on a
frame's collisions does to a film, as measured: docs/engines.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from labrig.params import Param

from .pair_scheme import PairScheme
from .settings import DT, THESIS_FRAME, TUNE_ALLOCATOR, Settings

#: Most collisions the event engine may be allowed in one frame.
MAX_EVENTS = 1_000_000_000
#: The default cap on a frame's collisions (`Event.max_events`).
FRAME_EVENTS = 1_000_000
#: The Java's cap (``maxIterations = 2500``): ``max_events = THESIS_EVENTS`` runs the thesis's loop as it was.
THESIS_EVENTS = 2500
#: Largest gap the event engine keeps between discs at contact, mean radii.
MAX_BUFFER = 1e-2


@dataclass(frozen=True)
class Event(Settings):
    """The event engine and its numerical knobs: frames of ``dt`` at whose start the forces act, then every
    collision within the frame found and resolved exactly, in time order (`qdots.engine.event_loop`).

    Parameters
    ----------
    dt : float
        The frame, s, in `qdots.engine.settings.DT_RANGE` (default: the thesis's 20 ms).
    max_events : int
        Most collisions resolved in one frame, in [1, `MAX_EVENTS`]; a frame that reaches it leaves the rest of
        the frame unmoved, as the thesis's loop did, and the engine counts it (``diagnostics()["capped_frames"]``).
        Default `FRAME_EVENTS`, against the Java's `THESIS_EVENTS`: a capped frame keeps the velocities the
        unresolved collisions would have damped, which heats a film whose clusters collapse inelastically
        (docs/engines.md).
    buffer : float
        Gap kept between discs at contact, in mean radii, in (0, `MAX_BUFFER`] (the thesis: a millionth of the
        mean radius added to every radius).
    pair_skin : float
        Verlet skin of the van der Waals pair list, px (`pairs`): every pair in range is pulled every frame, as
        in the thesis.
    tune_allocator : bool
        Raise glibc's allocator thresholds when the simulation is built (`qdots.engine.allocator`): speed only.
    """

    dt: float = THESIS_FRAME
    max_events: int = FRAME_EVENTS
    buffer: float = 1e-6
    pair_skin: float = 6.0
    tune_allocator: bool = True

    kind: ClassVar[str] = "event"
    PARAMS: ClassVar[dict[str, Param]] = {
        "dt": DT,
        "max_events": Param("int", 1, MAX_EVENTS, doc="most collisions the event engine resolves in a frame"),
        "buffer": Param("float", 0.0, MAX_BUFFER, low_open=True, unit="mean radii",
                        doc="gap the event engine keeps between discs at contact"),
        "pair_skin": PairScheme.PARAMS["pair_skin"],
        "tune_allocator": TUNE_ALLOCATOR,
    }
    SAVED: ClassVar[tuple[str, ...]] = ("dt", "max_events", "buffer", "pair_skin")

    @property
    def pairs(self) -> PairScheme:
        """The pair forces' scheme: every pair in range pulled every frame, from a list of skin ``pair_skin``."""
        return PairScheme(pair_skin=self.pair_skin)

    def build(self, walls, restitution, key, positions, velocities, radii, masses):
        from .event_backend import EventBackend

        return EventBackend(self, walls, restitution, key, positions, velocities, radii, masses)

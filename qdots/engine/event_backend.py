"""`EventBackend`: the event engine of one simulation (`qdots.engine.Backend`), built by `qdots.engine.Event`.

The thesis's own algorithm, beside `qdots.engine.chipmunk_backend.ChipmunkBackend`. Each frame of ``dt`` s (the
thesis's 20 ms) does what section 2.2 lists: the forces change the velocities at the frame's start (thermal kicks
when their interval has come, the van der Waals pull of every pair in range, `qdots.forces`), then every
collision within the frame is found and resolved exactly, in time order (`qdots.engine.event_loop`): hard discs
kept a ``buffer`` apart, Eq 2.5 per impact with the restitution drawn per impact as the Java draws it, elastic
walls. The same scene, forces, collision rule, random streams, checkpoints and writers as the Chipmunk engine;
only how the dots move between the frames' velocity changes differs, so the two engines can be set side by side
on one experiment.
"""

from __future__ import annotations

from time import perf_counter

import numpy as np

from ..forces.base import StepContext
from ..geometry import pairs_within
from ..restitution import Restitution
from .contacts import start_run
from .event import Event
from .event_loop import CAPPED, REBUILD, advance_events, fastest, neighbour_table

#: The candidates of a frame are the pairs that can touch at up to this many times the fastest speed at the
#: frame's start (an impact can speed a light dot up to twice its partner's speed); a faster dot makes the
#: frame build them again (`qdots.engine.event_loop`).
SPEED_MARGIN = 2.0
#: Slowest speed the candidates are built for, px/s (a still board still lets the kicks move it).
SLOWEST = 1.0


class EventBackend:
    """The event-driven side of one simulation: the dots' arrays, the collision record, each force's cache.

    Parameters
    ----------
    settings : qdots.engine.Event
        The numerical knobs.
    walls, restitution, key, positions, velocities, radii, masses
        As `qdots.engine.settings.Settings.build` takes them.
    """

    def __init__(self, settings: Event, walls: np.ndarray, restitution: Restitution, key: int,
                 positions: np.ndarray, velocities: np.ndarray, radii: np.ndarray, masses: np.ndarray):
        self.settings = settings
        self._pairs = settings.pairs
        self.walls, self.collisions = start_run(walls, settings, key)
        #: ``collisions``: counts of impacts and the position in the elasticity draws
        #: (`qdots.engine.contacts.CollisionRecord`).
        self.collisions.set_rule(restitution)
        #: Wall-clock seconds spent in the forces and in the events, accumulated over all frames.
        self.timings = {"forces": 0.0, "events": 0.0}
        #: Collisions resolved (dot-dot and dot-wall) and frames that reached ``max_events``, over all frames.
        self.events = 0
        self.capped_frames = 0
        self._candidates = 0
        self._restitution = restitution
        self.rebuild(positions, velocities, radii, masses)

    def rebuild(self, positions, velocities, radii, masses) -> None:
        """(Re)start from these dots (px, px/s, px, mean dot masses); the forces' caches are emptied."""
        self.x = np.zeros(0)
        self.y = np.zeros(0)
        self.vx = np.zeros(0)
        self.vy = np.zeros(0)
        self.radii = np.zeros(0)
        self.masses = np.zeros(0)
        self.add_dots(positions, velocities, radii, masses)

    def add_dots(self, positions, velocities, radii, masses) -> None:
        """Add dots (validated by the caller); the forces' caches are emptied."""
        positions = np.asarray(positions, dtype=float).reshape(-1, 2)
        velocities = np.asarray(velocities, dtype=float).reshape(-1, 2)
        self.x = np.concatenate([self.x, positions[:, 0]])
        self.y = np.concatenate([self.y, positions[:, 1]])
        self.vx = np.concatenate([self.vx, velocities[:, 0]])
        self.vy = np.concatenate([self.vy, velocities[:, 1]])
        self.radii = np.concatenate([self.radii, radii])
        self.masses = np.concatenate([self.masses, masses])
        self.radii.setflags(write=False)
        self.masses.setflags(write=False)
        self._inv_mass = 1.0 / self.masses
        self._caches: dict[int, dict] = {}

    @property
    def n_dots(self) -> int:
        return self.x.size

    # -- what acts, between runs --------------------------------------------------------------------

    def set_restitution(self, rule: Restitution) -> None:
        """Apply ``rule`` to the collisions from now on."""
        self._restitution = rule
        self.collisions.set_rule(rule)

    def retune(self, settings: Event) -> None:
        """Take new knobs between runs; a different pair list skin empties the forces' caches."""
        old, self.settings = self.settings, settings
        self._pairs = settings.pairs
        if self._pairs != old.pairs:
            self.forget_forces()

    def forget_forces(self) -> None:
        """Empty every force's cache (the forces, or the scheme their pairs are pulled with, changed)."""
        self._caches = {}

    def force_cache(self, k: int) -> dict:
        """The cache of the ``k``-th force (what it derived from the dots)."""
        return self._caches.get(k, {})

    # -- running ------------------------------------------------------------------------------------

    def step(self, forces, time: float, rng: np.random.Generator) -> int:
        """One frame of ``settings.dt`` from ``time`` s: the forces' velocity changes, then every collision."""
        start = perf_counter()
        settings = self.settings
        n = self.n_dots
        if n and forces:
            dv = np.zeros((n, 2))
            ctx = StepContext(time=time, dt=settings.dt, x=self.x, y=self.y,
                              velocity=np.column_stack([self.vx, self.vy]), radii=self.radii, masses=self.masses,
                              rng=rng, dv=dv, pairs=self._pairs, restitution=self._restitution)
            for index, force in enumerate(forces):
                ctx.cache = self._caches.setdefault(index, {})
                force.kick(ctx)
            self.vx += dv[:, 0]
            self.vy += dv[:, 1]
        middle = perf_counter()
        if n:
            self._events(settings)
        self.timings["forces"] += middle - start
        self.timings["events"] += perf_counter() - middle
        return 1

    def _events(self, settings: Event) -> None:
        """Resolve the frame's collisions, building the candidate pairs again whenever a dot outruns them."""
        n, dt = self.n_dots, settings.dt
        buffer = settings.buffer * float(self.radii.mean())
        largest = float(self.radii.max())
        stamp = np.zeros(n)
        now, done = 0.0, 0
        while True:
            bound = SPEED_MARGIN * max(fastest(self.vx, self.vy), SLOWEST)
            reach = 2.0 * (largest + buffer) + 2.0 * bound * (dt - now)
            i, j = pairs_within(self.x, self.y, reach, expected=self._candidates)
            self._candidates = i.size  # one pass over the grid next time (two when the count is not known)
            start, partners = neighbour_table(n, i, j)
            status, now, done = advance_events(self.x, self.y, self.vx, self.vy, stamp, now, dt, self.radii,
                                               self._inv_mass, buffer, start, partners, self.walls,
                                               self.collisions.array, bound, settings.max_events, done)
            if status != REBUILD:
                break
        self.events += done
        if status == CAPPED:
            self.capped_frames += 1

    def substep(self) -> float:
        """The frame, s: a frame is one step (the runaway check's step)."""
        return self.settings.dt

    def take_unplanned_travel(self) -> float:
        """0: exact collisions never let a dot travel into another."""
        return 0.0

    def diagnostics(self) -> dict[str, float]:
        """``events``: the collisions resolved (dot-dot and dot-wall); ``capped_frames``: the frames that reached
        ``max_events`` (their rest unmoved, as the thesis's loop), over all frames."""
        return {"events": self.events, "capped_frames": self.capped_frames}

    def read(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities of the dots, two new (N, 2) arrays (px, px/s)."""
        return np.column_stack([self.x, self.y]), np.column_stack([self.vx, self.vy])

    def write_velocities(self, velocities: np.ndarray) -> None:
        """Set every dot's velocity from an (N, 2) array, px/s."""
        self.vx = np.ascontiguousarray(velocities[:, 0], dtype=float)
        self.vy = np.ascontiguousarray(velocities[:, 1], dtype=float)


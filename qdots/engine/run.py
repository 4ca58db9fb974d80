"""`ChipmunkEngine`: everything a simulation's run needs while it runs, on Chipmunk.

A `qdots.Simulation` says what acts (forces, the collision rule), keeps the clock and the writers, and
drives an engine. The engine owns the run's machinery: the `pymunk.Space` with the walls and one body
per dot, the bulk body I/O, the collision callbacks and their record (counts and the elasticity draw
stream), the sub-step plan, and each force's per-run cache. Building the space in one place means a new
simulation and one re-seated from a checkpoint have the same Chipmunk history (body order, shape ids,
spatial index) and step identically.
"""

from __future__ import annotations

import numpy as np

from ..restitution import Restitution
from .bodies import BodyArrays
from .chipmunk import add_discs, new_space, tune_space
from .contacts import install_handlers, start_run
from .settings import EngineSettings
from .stepping import Stepper


class ChipmunkEngine:
    """The Chipmunk side of one simulation: its space, bodies, collision record, sub-step plan and force caches.

    Parameters
    ----------
    walls : ndarray, shape (M, 4)
        Static segments ``(x0, y0, x1, y1)``, px (the box edges included when the board is closed).
    restitution : qdots.Restitution
        The collision rule.
    settings : EngineSettings
        The numerical knobs.
    key : int
        Key of the collision rule's draw stream (`qdots.engine.contacts.stream_key`).
    positions, velocities : ndarray, shape (N, 2)
        The dots' centres (px) and velocities (px/s), validated by the caller (a `qdots.Scene`).
    radii, masses : ndarray, shape (N,)
        Their radii (px) and masses (mean dot masses).
    """

    def __init__(self, walls: np.ndarray, restitution: Restitution, settings: EngineSettings, key: int,
                 positions: np.ndarray, velocities: np.ndarray, radii: np.ndarray, masses: np.ndarray):
        self.walls, self.collisions = start_run(walls, settings, key)
        #: ``collisions``: counts of impacts and the position in the elasticity draws
        #: (`qdots.engine.contacts.CollisionRecord`).
        #: Wall-clock seconds spent in the force phase (bulk read, sub-step plan, kicks, force write) and in
        #: Chipmunk's steps (which include the collision callbacks), accumulated over all steps.
        self.timings = {"forces": 0.0, "pymunk": 0.0}
        self._restitution = restitution
        self._at_contact = settings.impacts == "contact"
        self._stepper: Stepper | None = None
        self.build(settings, positions, velocities, radii, masses)

    def build(self, settings: EngineSettings, positions, velocities, radii, masses) -> None:
        """(Re)create the space holding the walls and these dots (px, px/s, px, mean dot masses).

        The forces' caches are emptied and Chipmunk's contact cache and spatial index start afresh; the
        collision record and the timings carry over.
        """
        self.space = new_space(self.walls, settings)
        self._at_contact = settings.impacts == "contact"
        self._bodies = []
        self.radii = np.zeros(0)
        self.masses = np.zeros(0)
        self._stepper = None
        self.add_dots(positions, velocities, radii, masses)
        install_handlers(self.space, self._restitution, self.collisions, self._at_contact)

    def add_dots(self, positions, velocities, radii, masses) -> None:
        """Add dots to the space (validated by the caller); the forces' caches are emptied."""
        self._bodies += add_discs(self.space, positions, velocities, radii, masses)
        self.radii = np.concatenate([self.radii, radii])
        self.masses = np.concatenate([self.masses, masses])
        self.radii.setflags(write=False)
        self.masses.setflags(write=False)
        old = self._stepper
        self._stepper = Stepper(self.space, self._bodies, self.radii, self.masses, self.walls, self.collisions)
        if old is not None and old.space is self.space:  # same space: Chipmunk's contact impulses carry over
            self._stepper.previous = old.previous
        self.io: BodyArrays = self._stepper.io

    @property
    def n_dots(self) -> int:
        return len(self._bodies)

    # -- what acts, between runs --------------------------------------------------------------------

    def set_restitution(self, rule: Restitution) -> None:
        """Apply ``rule`` to the contacts that begin from now on."""
        self._restitution = rule
        install_handlers(self.space, rule, self.collisions, self._at_contact)

    def tune(self, settings: EngineSettings) -> None:
        """Apply the knobs that change on a live space (iterations, slop, bias, where impacts are resolved)."""
        tune_space(self.space, settings)
        if (settings.impacts == "contact") != self._at_contact:
            self._at_contact = settings.impacts == "contact"
            install_handlers(self.space, self._restitution, self.collisions, self._at_contact)

    def forget_forces(self) -> None:
        """Empty every force's cache (the forces, or the settings their numerics read, changed)."""
        self._stepper.forget_forces()

    def force_cache(self, k: int) -> dict:
        """The cache of the ``k``-th force (what it derived from the dots: pair lists, per-dot constants)."""
        return self._stepper.caches.get(k, {})

    # -- running ------------------------------------------------------------------------------------

    def step(self, forces, settings: EngineSettings, time: float, rng: np.random.Generator) -> int:
        """Advance one time step of ``settings.dt`` from ``time`` s; returns the Chipmunk sub-steps taken."""
        return self._stepper.step(forces, settings, self._restitution, time, rng, self.timings)

    @property
    def last_substeps(self) -> int:
        """Sub-steps of the last step (0 before the first)."""
        return self._stepper.previous

    def take_capped_travel(self) -> float:
        """The largest travel into a contact per sub-step (radii) in a step whose sub-steps hit their cap, since
        the last call (then reset to 0)."""
        return self._stepper.take_capped_travel()

    def read(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities of the dots, two new (N, 2) arrays (px, px/s)."""
        return self.io.read()

    def write_velocities(self, velocities: np.ndarray) -> None:
        """Set every dot's velocity from an (N, 2) array, px/s."""
        self.io.write_velocities(velocities)

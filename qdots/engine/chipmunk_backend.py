"""`ChipmunkBackend`: the Chipmunk engine of one simulation (`qdots.engine.Backend`), built by `qdots.engine.Chipmunk`.

It owns the run's machinery: the `pymunk.Space` with the walls and one body per dot, the bulk body I/O, the
collision callbacks and their record (counts and the elasticity draw stream), the sub-step plan, and each
force's per-run cache. Building the space in one place means a new simulation and one re-seated from a
checkpoint have the same Chipmunk history (body order, shape ids, spatial index) and step identically.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..restitution import Restitution
from .bodies import BodyArrays
from .chipmunk import Chipmunk
from .chipmunk_step import Stepper
from .contacts import install_handlers, start_run
from .pymunk_adapter import add_discs, new_space, tune_space

if TYPE_CHECKING:
    import pymunk


class ChipmunkBackend:
    """The Chipmunk side of one simulation: its space, bodies, collision record, sub-step plan and force caches.

    Parameters
    ----------
    settings : qdots.engine.Chipmunk
        The numerical knobs.
    walls, restitution, key, positions, velocities, radii, masses
        As `qdots.engine.settings.Settings.build` takes them.
    """

    def __init__(self, settings: Chipmunk, walls: np.ndarray, restitution: Restitution, key: int,
                 positions: np.ndarray, velocities: np.ndarray, radii: np.ndarray, masses: np.ndarray):
        self.settings = settings
        self.walls, self.collisions = start_run(walls, settings, key)
        #: Wall-clock seconds spent in the force phase (bulk read, sub-step plan, kicks, force write) and in
        #: Chipmunk's steps (which include the collision callbacks), accumulated over all steps.
        self.timings = {"forces": 0.0, "pymunk": 0.0}
        self._restitution = restitution
        self._stepper: Stepper | None = None
        self.rebuild(positions, velocities, radii, masses)

    def rebuild(self, positions, velocities, radii, masses) -> None:
        """(Re)create the space holding the walls and these dots (px, px/s, px, mean dot masses).

        The forces' caches are emptied and Chipmunk's contact cache and spatial index start afresh; the
        collision record and the timings carry over.
        """
        self.space = new_space(self.walls, self.settings)
        self._bodies: list[pymunk.Body] = []
        self.radii = np.zeros(0)
        self.masses = np.zeros(0)
        self._stepper = None
        self.add_dots(positions, velocities, radii, masses)
        install_handlers(self.space, self._restitution, self.collisions, self.settings.impacts == "contact")

    def add_dots(self, positions, velocities, radii, masses) -> None:
        """Add dots to the space (validated by the caller); the forces' caches are emptied."""
        self._bodies += add_discs(self.space, positions, velocities, radii, masses)
        self.radii = np.concatenate([self.radii, radii])
        self.masses = np.concatenate([self.masses, masses])
        self.radii.setflags(write=False)
        self.masses.setflags(write=False)
        old = self._stepper
        self._stepper = Stepper(self.space, self._bodies, self.radii, self.masses, self.walls, self.settings,
                                self.collisions)
        if old is not None and old.space is self.space:  # same space: Chipmunk's contact impulses carry over
            self._stepper.previous = old.previous
        self.io: BodyArrays = self._stepper.io

    @property
    def n_dots(self) -> int:
        return len(self._bodies)

    @property
    def _live_stepper(self) -> Stepper:
        """The stepper of the current space (None only while `rebuild` replaces it)."""
        assert self._stepper is not None
        return self._stepper

    # -- what acts, between runs --------------------------------------------------------------------

    def set_restitution(self, rule: Restitution) -> None:
        """Apply ``rule`` to the contacts that begin from now on."""
        self._restitution = rule
        install_handlers(self.space, rule, self.collisions, self.settings.impacts == "contact")

    def retune(self, settings: Chipmunk) -> None:
        """Take new knobs between runs: a different spatial index or thread count rebuilds the space from the
        board (as a checkpoint would), the solver's knobs change on the live space, a different pair scheme
        empties the forces' caches."""
        old, self.settings = self.settings, settings
        if (old.spatial_hash, old.threads) != (settings.spatial_hash, settings.threads):
            positions, velocities = self.read()
            self.rebuild(positions, velocities, self.radii, self.masses)
            return
        self._live_stepper.settings = settings
        tune_space(self.space, settings)
        if settings.impacts != old.impacts:
            install_handlers(self.space, self._restitution, self.collisions, settings.impacts == "contact")
        if settings.pairs != old.pairs:
            self.forget_forces()

    def forget_forces(self) -> None:
        """Empty every force's cache (the forces, or the scheme their pairs are pulled with, changed)."""
        self._live_stepper.forget_forces()

    def force_cache(self, k: int) -> dict:
        """The cache of the ``k``-th force (what it derived from the dots: pair lists, per-dot constants)."""
        return self._live_stepper.caches.get(k, {})

    # -- running ------------------------------------------------------------------------------------

    def step(self, forces, time: float, rng: np.random.Generator) -> int:
        """Advance one time step of ``settings.dt`` from ``time`` s; returns the Chipmunk sub-steps taken."""
        return self._live_stepper.step(forces, self._restitution, time, rng, self.timings)

    def substep(self) -> float:
        """The last step's sub-step, s (``dt / substeps`` before the first step)."""
        return self.settings.dt / max(self._live_stepper.previous, self.settings.substeps)

    def take_unplanned_travel(self) -> float | None:
        """The largest travel into a contact per sub-step (radii) in a step whose sub-steps hit ``max_substeps``,
        since the last call (then reset to 0); None when the sub-steps are not planned (``overlap_tolerance``
        None)."""
        travel = self._live_stepper.take_capped_travel()
        return None if self.settings.overlap_tolerance is None else travel

    def diagnostics(self) -> dict[str, float]:
        """``last_substeps``: the sub-steps of the last step (0 before the first)."""
        return {"last_substeps": self._live_stepper.previous}

    def read(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions and velocities of the dots, two new (N, 2) arrays (px, px/s)."""
        return self.io.read()

    def write_velocities(self, velocities: np.ndarray) -> None:
        """Set every dot's velocity from an (N, 2) array, px/s."""
        self.io.write_velocities(velocities)

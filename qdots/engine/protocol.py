"""`Backend`: the engine protocol, what a `qdots.Simulation` asks of the engine that moves its dots.

An engine's settings (`qdots.engine.Chipmunk`, `qdots.engine.Event`) build one backend per simulation and hand
it their settings once, when it is built (`Backend.retune` hands new ones between runs). The simulation keeps
the clock, the forces, the collision rule and the writers; the backend owns what a run needs while it runs:
the dots' arrays (or Chipmunk's space), the collision record, each force's per-run cache and its timings.
Whatever else an engine counts it reports in `Backend.diagnostics`, so that no caller probes its attributes.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    import numpy as np

    from ..forces.base import Force
    from ..restitution import Restitution
    from .contacts import CollisionRecord
    from .settings import Settings


class Backend(Protocol):
    """The engine of one simulation.

    Attributes
    ----------
    settings : qdots.engine.settings.Settings
        The settings it was built with (or last retuned to).
    collisions : qdots.engine.contacts.CollisionRecord
        Counts of impacts and the position in the elasticity draws (what a checkpoint saves).
    timings : dict
        Wall-clock seconds spent in each part of its steps (its own keys), accumulated over all steps.
    radii, masses : ndarray, shape (N,)
        The dots' radii (px) and masses (mean dot masses), read-only.
    """

    settings: Settings
    collisions: CollisionRecord
    timings: dict[str, float]
    radii: np.ndarray
    masses: np.ndarray

    @property
    def n_dots(self) -> int:
        """Dots on the board."""

    def step(self, forces: Sequence[Force], time: float, rng: np.random.Generator) -> int:
        """Advance one time step of ``settings.dt`` from ``time`` s; returns the sub-steps it took (1 without)."""

    def read(self) -> tuple[np.ndarray, np.ndarray]:
        """Positions (px) and velocities (px/s) of the dots, two new (N, 2) arrays."""

    def write_velocities(self, velocities: np.ndarray) -> None:
        """Set every dot's velocity from an (N, 2) array, px/s."""

    def add_dots(self, positions: np.ndarray, velocities: np.ndarray, radii: np.ndarray,
                 masses: np.ndarray) -> None:
        """Add dots (validated by the caller); the forces' caches are emptied."""

    def rebuild(self, positions: np.ndarray, velocities: np.ndarray, radii: np.ndarray,
                masses: np.ndarray) -> None:
        """Start again from these dots, as a backend built from them would (the collision record and the
        timings carry over); the forces' caches are emptied."""

    def retune(self, settings: Settings) -> None:
        """Take new settings of the same engine between runs (what needs it is rebuilt from the current board)."""

    def set_restitution(self, rule: Restitution) -> None:
        """Apply the collision rule ``rule`` from now on."""

    def forget_forces(self) -> None:
        """Empty every force's cache (the forces changed)."""

    def force_cache(self, k: int) -> dict:
        """The cache of the ``k``-th force: what it derived from the dots (pair lists, per-dot constants)."""

    def substep(self) -> float:
        """Length of the last step's sub-steps, s (the step itself for an engine without sub-steps)."""

    def take_unplanned_travel(self) -> float | None:
        """How far a dot travelled into a contact within one sub-step (radii) in steps that could not keep it
        within the engine's plan, since the last call (then reset); None when the engine plans no travel (the
        simulation then bounds it by the dots' speeds)."""

    def diagnostics(self) -> dict[str, float]:
        """What the engine counts beyond the collision record (sub-steps, events, capped frames, ...), by name."""

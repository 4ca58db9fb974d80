"""The kinetic-energy budget of each time step (the thesis's 20 ms frame), by mass class, on either engine.

Both engines do one frame the same way (`qdots.engine`): at its start every force adds its velocity change
to the dots (the van der Waals pull, then the thermal kicks, in the order of the simulation's forces), then
the engine moves the dots and resolves their collisions until the frame ends. So the kinetic energy of a
class of dots changes twice in a frame::

    start  --(each force's velocity change)-->  after the forces  --(collisions, contacts)-->  end

and ``injected = after - start`` (split by force), ``removed = after - end`` (what the collisions took;
negative when they added energy), ``injected - removed = end - start``.

`EnergyBudget` measures it from outside the engines, through the forces' own hook: it puts a probe (a
`qdots.forces.Force` that adds no velocity change) before the first force and after each one. The first
probe reads the velocities the frame starts with (`StepContext.velocity`, which is where the last frame
ended); each later probe the velocities plus the changes the forces have added so far (`StepContext.dv`),
which is exactly what the engine adds to the dots. A frame's end is the next frame's start (the dots a
deposition adds between frames start at rest, so they add no energy), and the last frame's end is read
from the simulation by `EnergyBudget.finish`. The probes draw nothing and change nothing: a run with the
budget attached before its first step is bit-identical to one without (the forces' caches are emptied when
it is attached, as any change of forces does, which before the first step changes nothing).

Energies are in mean-dot mass px^2/s^2 (a dot of the mean mass moving at 1 px/s has 0.5).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..forces.base import Force, StepContext

if TYPE_CHECKING:
    from ..simulation import Simulation


class _Probe(Force):
    """A force that adds nothing and tells the budget what the velocities are, with the changes added so far."""

    def __init__(self, budget: EnergyBudget, stage: int):
        self._budget = budget
        self._stage = stage

    def kick(self, ctx: StepContext) -> None:
        self._budget._observe(self._stage, ctx)

    def params(self) -> dict:
        return {"stage": self._stage}


@dataclass
class FrameBudget:
    """The per-frame record of an `EnergyBudget` (F frames, C mass classes, K forces).

    Attributes
    ----------
    time : ndarray, shape (F,)
        Time at each frame's start, s.
    dots : ndarray of int, shape (F, C)
        Dots of each class on the board during the frame.
    start, end : ndarray, shape (F, C)
        Kinetic energy of each class at the frame's start and end.
    after : ndarray, shape (F, K, C)
        Kinetic energy of each class after the first k + 1 forces' velocity changes (``after[:, -1]``: after all).
    speed : ndarray, shape (F, C)
        Summed speed of each class's dots at the frame's start, px/s (divide by ``dots`` for the mean).
    impacts : ndarray of int, shape (F,)
        Dot-dot impacts the engine counted in the frame (`qdots.engine.contacts.CollisionRecord.dot_dot`).
    forces : tuple of str
        The forces' class names, in the order they act.
    classes : tuple of str
        The mass classes' names.
    """

    time: np.ndarray
    dots: np.ndarray
    start: np.ndarray
    end: np.ndarray
    after: np.ndarray
    speed: np.ndarray
    impacts: np.ndarray
    forces: tuple
    classes: tuple

    @property
    def injected(self) -> np.ndarray:
        """Kinetic energy the forces' velocity changes add in each frame, by class, shape (F, C)."""
        return self.after[:, -1] - self.start

    def injected_by(self, k: int) -> np.ndarray:
        """Kinetic energy the ``k``-th force's velocity change adds (after the forces before it), shape (F, C)."""
        before = self.start if k == 0 else self.after[:, k - 1]
        return self.after[:, k] - before

    @property
    def removed(self) -> np.ndarray:
        """Kinetic energy the collisions and contacts take in each frame, by class, shape (F, C)."""
        return self.after[:, -1] - self.end


class EnergyBudget:
    """Records the kinetic energy at each frame's start, after each force, and at its end, by mass class.

    Parameters
    ----------
    mass_edges : sequence of float
        Class boundaries in mean-dot masses, increasing: class ``c`` holds the dots with
        ``mass_edges[c - 1] <= m < mass_edges[c]`` (so ``len(mass_edges) + 1`` classes; none: one class).
    names : sequence of str, optional
        The classes' names (default "class 0", "class 1", ...).

    Use: ``budget = EnergyBudget((0.88, 1.13)); budget.attach(sim)`` before the simulation's first step, run it
    (``sim.run``, a deposition, `qdots.experiment.populate`), then ``budget.finish(sim)`` and ``budget.frames()``.
    """

    def __init__(self, mass_edges=(), names=None) -> None:
        self.edges = np.asarray(mass_edges, dtype=float).reshape(-1)
        if np.any(np.diff(self.edges) <= 0):
            raise ValueError("mass_edges must increase")
        n = self.edges.size + 1
        self.names = tuple(names) if names is not None else tuple(f"class {c}" for c in range(n))
        if len(self.names) != n:
            raise ValueError(f"{n} classes need {n} names, got {len(self.names)}")
        self._forces: tuple[str, ...] = ()
        self._sim: Simulation | None = None
        self._class_of = np.zeros(0, dtype=np.int64)
        self._rows: list[tuple] = []
        self._pending: list | None = None  # the frame whose end is not known yet

    @property
    def n_classes(self) -> int:
        return self.edges.size + 1

    def classes_of(self, masses) -> np.ndarray:
        """The class of each dot of these masses."""
        return np.searchsorted(self.edges, np.asarray(masses, dtype=float), side="right")

    # -- attaching ----------------------------------------------------------------------------------

    def instrument(self, forces) -> tuple[Force, ...]:
        """``forces`` with the probes around them: a probe first, then each force followed by a probe."""
        forces = tuple(forces)
        self._forces = tuple(type(force).__name__ for force in forces)
        wrapped: list[Force] = [_Probe(self, 0)]
        for k, force in enumerate(forces):
            wrapped += [force, _Probe(self, k + 1)]
        return tuple(wrapped)

    def attach(self, sim) -> EnergyBudget:
        """Put the probes among ``sim``'s forces (before its first step, for a bit-identical run); returns self."""
        if any(isinstance(force, _Probe) for force in sim.forces):
            raise ValueError("this simulation already carries an energy budget")
        self._sim = sim
        sim.forces = self.instrument(sim.forces)
        return self

    def detach(self, sim) -> None:
        """Take the probes out of ``sim``'s forces."""
        sim.forces = [force for force in sim.forces if not isinstance(force, _Probe)]

    # -- recording ----------------------------------------------------------------------------------

    def _energy(self, masses, vx, vy) -> np.ndarray:
        return np.bincount(self._class_of, weights=0.5 * masses * (vx * vx + vy * vy), minlength=self.n_classes)

    def _observe(self, stage: int, ctx: StepContext) -> None:
        masses = ctx.masses
        if masses.size != self._class_of.size:
            self._class_of = self.classes_of(masses)
        v = ctx.velocity
        if stage == 0:
            energy = self._energy(masses, v[:, 0], v[:, 1])
            self._close(energy)
            speed = np.bincount(self._class_of, weights=np.hypot(v[:, 0], v[:, 1]), minlength=self.n_classes)
            impacts = self._sim.collisions.dot_dot if self._sim is not None else 0
            dots = np.bincount(self._class_of, minlength=self.n_classes)
            self._pending = [ctx.time, dots, energy, [], speed, impacts]
        else:
            assert self._pending is not None  # stage 0 of this step opened the frame
            dv = ctx.dv
            self._pending[3].append(self._energy(masses, v[:, 0] + dv[:, 0], v[:, 1] + dv[:, 1]))

    def _close(self, end: np.ndarray, impacts: int | None = None) -> None:
        """The pending frame ended with the energies ``end`` (by class; new dots, at rest, add nothing)."""
        if self._pending is None:
            return
        time, dots, start, after, speed, counted = self._pending
        if impacts is None:
            impacts = self._sim.collisions.dot_dot if self._sim is not None else counted
        self._rows.append((time, dots, start, np.array(after), end, speed, impacts - counted))
        self._pending = None

    def finish(self, sim) -> None:
        """Close the last frame from ``sim``'s velocities now (call it after the last step)."""
        if self._pending is None:
            return
        state = sim.state()
        n = self._pending[1].sum()
        v = state.velocities[:n]  # dots added since the frame began are at rest
        self._class_of = self.classes_of(state.masses)
        end = np.bincount(self._class_of[:n], weights=0.5 * state.masses[:n] * (v ** 2).sum(axis=1),
                          minlength=self.n_classes)
        self._close(end, sim.collisions.dot_dot)

    def frames(self) -> FrameBudget:
        """The frames recorded so far whose end is known."""
        rows = self._rows
        k, c = len(self._forces), self.n_classes
        if not rows:
            empty = np.zeros((0, c))
            return FrameBudget(np.zeros(0), np.zeros((0, c), int), empty, empty, np.zeros((0, k, c)), empty,
                               np.zeros(0, int), self._forces, self.names)
        return FrameBudget(time=np.array([r[0] for r in rows]), dots=np.array([r[1] for r in rows]),
                           start=np.array([r[2] for r in rows]), end=np.array([r[4] for r in rows]),
                           after=np.array([r[3] for r in rows]).reshape(len(rows), k, c),
                           speed=np.array([r[5] for r in rows]), impacts=np.array([r[6] for r in rows]),
                           forces=self._forces, classes=self.names)

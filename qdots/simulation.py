"""`Simulation`: a scene moving under what acts on it, driven by an engine, with writers attached.

A `Scene` says what exists; a `Simulation` holds what acts on it and what records it, and keeps the clock:

* ``sim.forces`` -- the forces (`qdots.forces`), replaceable between runs (``sim.forces = [...]``);
* ``sim.restitution`` -- the collision rule (`qdots.Restitution`), replaceable between runs;
* ``sim.engine`` -- the engine and its numerical knobs (`qdots.Chipmunk` or `qdots.Event`), replaceable
  between runs;
* writers -- anything with a ``write(state)`` method, attached once with a trigger
  (``sim.attach(movie, every=200)`` or ``seconds=0.5``) and given the state on that schedule in
  every later run.

Everything a run needs while it runs (Chipmunk's space and bodies or the event engine's arrays, the collision
record, each force's per-run cache) belongs to the backend the engine's settings build, ``sim.backend``
(`qdots.engine.Backend`, the engine protocol): forces and the collision rule hold physics only, so one force
object can serve any number of simulations.
"""

from __future__ import annotations

import warnings
from collections.abc import Iterable, Sequence

import numpy as np

from labrig.progress import progress_bar
from labrig.validate import InputError, generator, real

from .engine import Backend, Settings, engine_from_dict
from .engine.contacts import CollisionRecord, stream_key
from .forces.base import Force
from .motion import SAFE_TRAVEL, RunawayError, check_motion, describe_forces, warn_travel  # noqa: F401
from .restitution import Restitution
from .scene import Scene, check_clear
from .state import State
from .writers import WriterSchedule

#: Relative overlap above which a finished run warns (and says so in its summary). Soft contacts
#: overlap by < 1 % of a radius at the default settings; 10 % means the time step is too large.
OVERLAP_WARNING = 0.1

#: Most time steps one `Simulation.run` takes (about 14 hours at 300 dots on one core).
MAX_STEPS = 1_000_000_000
#: Fewest steps between two checks of the dots' motion in `Simulation.run` (a check reads the whole board).
CHECK_EVERY = 50


class Simulation:
    """Dots of a `Scene` moving under forces and a collision rule, on an engine.

    Each time step, every force adds its velocity change where the dots are at the step's start (the thesis's
    frame: "acceleration ... is added only at the beginning of each time step as a change in velocity"); the
    engine then moves the dots to the step's end and resolves their collisions with the partial-elasticity rule:
    Chipmunk's impulse solver in planned sub-steps (`qdots.Chipmunk`, the default) or the thesis's exact events
    (`qdots.Event`).

    Parameters
    ----------
    scene : Scene
        What exists: board, walls, dots.
    forces : iterable of Force
        Forces acting on the dots (e.g. ``VanDerWaals()``, ``ThermalKicks()``).
    restitution : qdots.Restitution, optional
        The collision rule (thesis Eq 2.5); default ``Restitution()``, the thesis's.
    seed : int or numpy.random.SeedSequence, optional
        Seed of the simulation's generator. Every random draw (collision
        elasticities, thermal noise) comes from it, so equal seeds give
        bit-identical runs.
    engine : qdots.Chipmunk or qdots.Event, optional
        The engine and its numerical knobs; default ``qdots.Chipmunk()``.
    **settings
        Shorthand for the engine's settings (e.g. ``dt=2e-3``, or ``kind="event"``; `qdots.engine.engine_from_dict`).
    """

    def __init__(self, scene: Scene, forces: Iterable[Force] = (), *, restitution: Restitution | None = None,
                 seed: int | np.random.SeedSequence | None = None, engine: Settings | None = None,
                 **settings):
        if not isinstance(scene, Scene):
            raise InputError(f"scene must be a qdots.Scene, got {type(scene).__name__}")
        if engine is not None and settings:
            raise InputError(f"give engine=qdots.Chipmunk(...) (or Event) or the settings {sorted(settings)}, not both")
        if engine is None:
            engine = engine_from_dict(settings)
        _check_engine("engine", engine)
        restitution = Restitution() if restitution is None else restitution
        if not isinstance(restitution, Restitution):
            raise InputError(f"restitution must be a qdots.Restitution, got {type(restitution).__name__}")
        self._settings = engine
        self._restitution = restitution
        self.scene = scene
        self.rng = generator("seed", seed)
        self.steps_taken = 0
        #: Simulation time at step 0, s (nonzero for a run resumed from a checkpoint).
        self.start_time = 0.0
        #: Sub-steps the engine took, summed over all steps (one a step on an engine without sub-steps).
        self.substeps_taken = 0
        self._schedule = WriterSchedule()
        self._warned_travel = False
        self._forces: tuple[Force, ...] = ()
        #: The engine of this simulation, built by its settings: everything a run needs while it runs
        #: (`qdots.engine.Backend`).
        self.backend: Backend = engine.build(scene.wall_segments(), restitution, stream_key(self.rng), scene.positions,
                                             scene.velocities, scene.radii, scene.masses)
        self.forces = forces

    # -- what acts on the dots ----------------------------------------------------------------

    @property
    def forces(self) -> tuple[Force, ...]:
        """The forces, in the order they act; assign a new sequence to change them between runs."""
        return self._forces

    @forces.setter
    def forces(self, forces: Iterable[Force]) -> None:
        if isinstance(forces, Force) or not hasattr(forces, "__iter__"):
            raise InputError(f"forces must be a sequence of qdots Force objects, got {forces!r}")
        forces = tuple(forces)
        for force in forces:
            if not isinstance(force, Force):
                raise InputError(f"forces must be qdots.forces.Force instances, got {type(force).__name__}")
        for force in forces:
            force.check_run(self.dt)
            force.check_rule(self._restitution)
        self._forces = forces
        self.backend.forget_forces()

    @property
    def engine(self) -> Settings:
        """The engine and its knobs (`qdots.Chipmunk` or `qdots.Event`); assign new settings between runs.

        Settings of the same engine go to its backend (`qdots.engine.Backend.retune`), which applies them and
        rebuilds from the board what needs it; another engine's settings build that engine on the current board,
        with the same collision record. The time so far is kept either way.
        """
        return self._settings

    @engine.setter
    def engine(self, settings: Settings) -> None:
        _check_engine("engine", settings)
        for force in self._forces:
            force.check_run(settings.dt)
        time_now = self.time
        old, self._settings = self._settings, settings
        if settings.dt != old.dt:  # the time so far is kept; steps count from here with the new step
            self._schedule.restart(self.steps_taken, settings.dt)
            self.start_time, self.steps_taken = time_now, 0
        if type(settings) is type(old):
            self.backend.retune(settings)
            return
        board, record = self.current_scene(), self.backend.collisions  # another engine goes on from this board
        self.backend = settings.build(board.wall_segments(), self._restitution, record.key, board.positions,
                                      board.velocities, board.radii, board.masses)
        self.backend.collisions.copy_from(record)

    @property
    def settings(self) -> Settings:
        """Deprecated alias of `engine` (0.3; removed in 0.4)."""
        _deprecated("Simulation.settings", "Simulation.engine")
        return self.engine

    @settings.setter
    def settings(self, settings: Settings) -> None:
        _deprecated("Simulation.settings", "Simulation.engine")
        self.engine = settings

    @property
    def restitution(self) -> Restitution:
        """The collision rule; assign a new `qdots.Restitution` to change it between runs."""
        return self._restitution

    @restitution.setter
    def restitution(self, rule: Restitution) -> None:
        if not isinstance(rule, Restitution):
            raise InputError(f"restitution must be a qdots.Restitution, got {type(rule).__name__}")
        for force in self._forces:
            force.check_rule(rule)
        self._restitution = rule
        self.backend.set_restitution(rule)
        self.backend.forget_forces()  # the sticking speed enters the thesis's van der Waals proxy

    @property
    def collisions(self) -> CollisionRecord:
        """Counts of impacts and the position in the elasticity draws (`qdots.engine.contacts.CollisionRecord`)."""
        return self.backend.collisions

    @property
    def timings(self) -> dict:
        """Wall-clock seconds spent in each part of the engine's steps (the forces, the engine's own work), over
        all steps."""
        return self.backend.timings

    @property
    def radii(self) -> np.ndarray:
        """Dot radii, px (read-only)."""
        return self.backend.radii

    @property
    def masses(self) -> np.ndarray:
        """Dot masses, mean dot masses (read-only)."""
        return self.backend.masses

    def force_cache(self, force: Force) -> dict:
        """What ``force`` (one of `forces`) derived from the dots in this simulation: its pair lists, per-dot
        constants (the engine owns it; a benchmark reads a pair list's ``rebuilds`` there)."""
        for k, candidate in enumerate(self._forces):
            if candidate is force:
                return self.backend.force_cache(k)
        raise InputError(f"{force!r} is not one of this simulation's forces")

    # -- writers --------------------------------------------------------------------------------

    def attach(self, writer, every: int | None = None, *, seconds: float | None = None):
        """Give ``writer`` the state every ``every`` steps (or every ``seconds`` of simulated time) in later runs.

        Steps are counted from the simulation's step 0, so the schedule is one even comb over
        successive runs (a deposition makes hundreds) and no step is written twice. Without
        ``every`` and ``seconds``, the writer's own ``every`` attribute (steps) is used.

        Returns
        -------
        writer
        """
        self._schedule.attach(writer, self.dt, every, seconds)
        return writer

    def detach(self, writer) -> None:
        """Stop giving ``writer`` states (it is not closed)."""
        self._schedule.detach(writer)

    @property
    def writers(self) -> tuple:
        """The attached writers, in the order they write."""
        return self._schedule.writers

    # -- the board ------------------------------------------------------------------------------

    def add_dots(self, positions, radii, masses=None, velocities=None) -> None:
        """Add dots to the running board (the thesis's sequential deposition).

        Parameters
        ----------
        positions : array_like, shape (K, 2)
            Centres, px. Each new dot must lie inside the box and overlap
            neither a wall segment nor any dot already on the board.
        radii : array_like, shape (K,)
            Radii, px (> 0).
        masses : array_like, shape (K,), optional
            Masses (mean dot mass = 1); default 1.
        velocities : array_like, shape (K, 2), optional
            Velocities, px/s; default 0.

        Raises
        ------
        labrig.validate.InputError
            As `Scene` does for bad values, and when a new dot overlaps a wall
            segment or a dot already on the board.
        """
        fresh = Scene(box=self.scene.box, positions=positions, radii=radii, masses=masses,
                      velocities=velocities)
        if fresh.n_dots:
            # (a Scene replaces its default None fields by arrays)
            assert self.scene.segments is not None and fresh.velocities is not None and fresh.masses is not None
            check_clear(fresh, self.state(), self.scene.segments)
            self.backend.add_dots(fresh.positions, fresh.velocities, fresh.radii, fresh.masses)

    def current_scene(self) -> Scene:
        """The board as it is now, as a `Scene` (``from_engine=True``: soft-contact overlaps and dots
        that left an open board are kept as they are)."""
        state = self.state()
        return self.scene.replace(positions=state.positions, velocities=state.velocities,
                                  radii=state.radii, masses=state.masses, from_engine=True)

    def reseat(self) -> None:
        """Rebuild the engine from the current board (`qdots.engine.Backend.rebuild`).

        Positions, velocities, time, the generator, the forces and the writers carry over;
        Chipmunk's contact cache and spatial index start afresh, exactly as in
        a simulation loaded from a checkpoint of this moment (see
        `qdots.io.checkpoint`). A run that re-seats and a run resumed from the
        checkpoint therefore continue bit for bit alike.
        """
        board = self.current_scene()
        assert board.velocities is not None and board.masses is not None  # (a Scene fills its defaults)
        self.backend.rebuild(board.positions, board.velocities, board.radii, board.masses)

    @property
    def n_dots(self) -> int:
        return self.backend.n_dots

    @property
    def dt(self) -> float:
        """Time step, s."""
        return self._settings.dt

    @property
    def time(self) -> float:
        """Simulation time, s: start time + steps taken * dt (no round-off drift)."""
        return self.start_time + self.steps_taken * self._settings.dt

    # -- running --------------------------------------------------------------------------------

    def step(self, n: int = 1) -> None:
        """Advance ``n`` time steps (no writers, no checks: `run` is the checked way)."""
        for _ in range(int(n)):
            try:
                k = self.backend.step(self._forces, self.time, self.rng)
            except (ValueError, OverflowError, MemoryError, FloatingPointError, RuntimeError):
                self._check_motion()  # a blown-up board makes the pair searches fail: say what happened
                raise
            self.substeps_taken += k
            self.steps_taken += 1

    def run(self, seconds: float, *, progress: bool = False) -> State:
        """Advance by ``seconds`` of simulated time (rounded to whole steps), writing on the attached writers' schedules.

        Parameters
        ----------
        seconds : float
            Simulated time to advance, s (>= 0; checked by `check_run` before the first step).
        progress : bool
            Show a progress bar in steps with an ETA (`labrig.progress.progress_bar`: it says when numba compiles
            and leaves that time out of its ETA).

        Returns
        -------
        State
            The state at the end.

        Raises
        ------
        RunawayError
            When the dots leave the model's range (speeds that cross the board in one sub-step, or
            non-finite values; checked between chunks of steps: every `CHECK_EVERY` steps, at most
            200 times per run).

        Warns
        -----
        RuntimeWarning
            Once per simulation, when a dot moves more than `SAFE_TRAVEL`
            radii in one sub-step (contacts can then be missed).
        """
        n_steps = self.check_run(seconds)
        chunk = max(CHECK_EVERY, n_steps // 200)
        end = self.steps_taken + n_steps
        with progress_bar(n_steps, unit="step", desc="qdots run", show=progress, leave=False) as bar:
            while True:
                self._schedule.write_due(self.steps_taken, self.state)
                if self.steps_taken >= end:
                    break
                stop = self._schedule.next_due(self.steps_taken, min(end, self.steps_taken + chunk))
                done = stop - self.steps_taken
                self.step(done)
                self._check_motion()
                bar.update(done)
                bar.set_postfix_str(f"t = {self.time:.2f} s", refresh=False)
        return self.state()

    def check_run(self, seconds: float) -> int:
        """The steps a run of ``seconds`` s takes; `InputError` if it would take more than `MAX_STEPS`, make a force
        act more often than it may (`qdots.forces.Force.check_run`), or give a writer more states than it takes.

        `run` calls it before it starts; call it yourself to check a series of runs (a deposition) as one.
        """
        seconds = real("seconds", seconds, 0.0)
        steps = seconds / self.dt
        if steps > MAX_STEPS + 0.5:
            said = f"{round(steps):,}" if steps < 1e15 else f"{steps:.3g}"
            raise InputError(f"a run of {seconds:g} s at dt = {self.dt:g} s is {said} steps, more than the "
                             f"{MAX_STEPS:,} one run may take")
        n_steps = round(steps)
        for force in self._forces:
            force.check_run(self.dt, n_steps)
        self._schedule.check_run(self.steps_taken, n_steps)
        return n_steps

    def _check_motion(self) -> None:
        """Stop when the dots leave the model's range; warn (once) when contacts can be missed at this speed."""
        if not self.n_dots:
            return
        position, velocity = self.backend.read()

        def describe() -> tuple[str, str]:
            forces = describe_forces(self._forces)
            return f"at t = {self.time:g} s (step {self.steps_taken})", f"the forces ({forces}) or the time step"

        travel = check_motion(position, velocity, self.radii, self.backend.substep(), self.scene.box, describe)
        unplanned = self.backend.take_unplanned_travel()
        if unplanned is not None:  # the engine plans for its contacts: warn only when it could not
            travel = unplanned
        if travel > SAFE_TRAVEL and not self._warned_travel:
            self._warned_travel = True
            warn_travel(travel, f"at t = {self.time:g} s")

    def state(self) -> State:
        """A snapshot of the board (copies of every array)."""
        position, velocity = self.backend.read()
        return State(
            time=self.time,
            positions=position,
            velocities=velocity,
            radii=self.radii.copy(),
            masses=self.masses.copy(),
            box=self.scene.box,
            walls=self.scene.wall_segments().copy(),
            closed=self.scene.closed,
        )

    def set_velocities(self, velocities: Sequence[Sequence[float]] | np.ndarray) -> None:
        """Overwrite every dot's velocity (px/s) from an (N, 2) array."""
        v = np.asarray(velocities, dtype=float)
        if v.shape != (self.n_dots, 2) or not np.isfinite(v).all():
            raise InputError(f"velocities must be a finite ({self.n_dots}, 2) array, got shape {v.shape}")
        self.backend.write_velocities(v)

    def __repr__(self) -> str:
        return (f"Simulation(n_dots={self.n_dots}, t={self.time:g} s, engine={self._settings!r}, "
                f"forces={list(self._forces)})")


def _check_engine(name: str, engine) -> None:
    """`InputError` unless ``engine`` is the settings of an engine (`qdots.Chipmunk`, `qdots.Event`)."""
    if not isinstance(engine, Settings) or type(engine) is Settings:
        raise InputError(f"{name} must be the settings of an engine, qdots.Chipmunk(...) or qdots.Event(...), "
                         f"got {type(engine).__name__}")


def _deprecated(old: str, new: str) -> None:
    warnings.warn(f"{old} is deprecated since 0.3 and goes in 0.4: use {new}", DeprecationWarning, stacklevel=3)

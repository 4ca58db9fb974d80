"""`Simulation`: a scene moving under pymunk, with the forces and writers attached to it.

A `Scene` says what exists; a `Simulation` owns what acts on it and what records it:

* ``sim.forces`` -- the forces (`qdots.forces`), replaceable between runs (``sim.forces = [...]``);
* ``sim.settings`` -- the engine's knobs (`EngineSettings`), replaceable between runs;
* ``sim.restitution`` -- the collision rule (`qdots.Restitution`), replaceable between runs;
* writers -- anything with a ``write(state)`` method, attached once with a trigger
  (``sim.attach(movie, every=200)`` or ``seconds=0.5``) and given the state on that schedule in
  every later run.
"""

from __future__ import annotations

from typing import Iterable, Sequence

import numpy as np

from labrig.progress import progress_bar
from labrig.validate import InputError, real
from labrig.validate import seed as valid_seed

from .collisions import CollisionRecord, Restitution, install_handlers, stream_key
from .forces.base import Force
from .motion import SAFE_TRAVEL, RunawayError, check_motion, warn_travel  # noqa: F401 (public here too)
from .scene import Scene, check_clear
from .settings import OVERLAP_CORRECTION, EngineSettings  # noqa: F401 (public here too)
from .space import add_discs, new_space, tune_space
from .state import State
from .stepping import Stepper
from .writers import WriterSchedule

#: Relative overlap above which a finished run warns (and says so in its summary). Soft contacts
#: overlap by < 1 % of a radius at the default settings; 10 % means the time step is too large.
OVERLAP_WARNING = 0.1

#: Most time steps one `Simulation.run` takes (about 14 hours at 300 dots on one core).
MAX_STEPS = 1_000_000_000
#: Fewest steps between two checks of the dots' motion in `Simulation.run` (a check reads the whole board).
CHECK_EVERY = 50


class Simulation:
    """Dots of a `Scene` moving in a `pymunk.Space`.

    Each step (`qdots.stepping`): read all positions and velocities in bulk, choose the Chipmunk
    sub-steps so that no dot travels more than ``overlap_tolerance`` radii into a contact within
    one, let every force add its velocity change (evaluated where the dots are at the end of the
    first sub-step), hand that change to Chipmunk as a body force, and advance Chipmunk, which moves
    the dots, adds the forces' velocity change, and resolves contacts with the partial-elasticity
    rule (`qdots.collisions`). With no forces and ``overlap_tolerance=None`` the bulk read is skipped.

    Parameters
    ----------
    scene : Scene
        What exists: board, walls, dots, collision rule.
    forces : iterable of Force
        Forces acting on the dots (e.g. ``VanDerWaals()``, ``ThermalKicks()``).
    seed : int or numpy.random.SeedSequence, optional
        Seed of the simulation's generator. Every random draw (collision
        elasticities, thermal noise) comes from it, so equal seeds give
        bit-identical runs.
    engine : EngineSettings, optional
        The engine's knobs; default ``EngineSettings()``.
    **settings
        Shorthand for ``engine=EngineSettings(**settings)`` (e.g. ``dt=2e-3``). The knobs:

        The knobs and their meaning: `EngineSettings`.
    """

    def __init__(self, scene: Scene, forces: Iterable[Force] = (), *,
                 seed: int | np.random.SeedSequence | None = None, engine: EngineSettings | None = None,
                 **settings):
        if not isinstance(scene, Scene):
            raise InputError(f"scene must be a qdots.Scene, got {type(scene).__name__}")
        if engine is not None and settings:
            raise InputError(f"give engine=EngineSettings(...) or the settings {sorted(settings)}, not both")
        if engine is None:
            engine = EngineSettings.from_dict(settings)
        if not isinstance(engine, EngineSettings):
            raise InputError(f"engine must be a qdots.EngineSettings, got {type(engine).__name__}")
        self._settings = engine
        self.scene = scene
        self.rng = _generator(seed)
        self.steps_taken = 0
        #: Simulation time at step 0, s (nonzero for a run resumed from a checkpoint).
        self.start_time = 0.0
        #: Wall-clock seconds spent in the force phase (bulk read, sub-step plan, kicks, force
        #: write) and in Chipmunk's ``space.step`` calls (which include the collision
        #: callbacks), accumulated over all steps.
        self.timings = {"forces": 0.0, "pymunk": 0.0}
        #: Counts of impacts and the position in the elasticity draws (`qdots.collisions.CollisionRecord`).
        self.collisions = CollisionRecord(stream_key(self.rng))
        #: Chipmunk sub-steps taken, summed over all steps.
        self.substeps_taken = 0
        self._schedule = WriterSchedule()
        self._warned_travel = False
        self._forces: tuple[Force, ...] = ()
        self._stepper: Stepper | None = None
        self.radii = np.zeros(0)
        self.masses = np.zeros(0)
        self.forces = forces
        self._build(scene)

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
        for force in forces:
            force.bind(self.radii, self.masses)
        self._forces = forces

    @property
    def settings(self) -> EngineSettings:
        """The engine's knobs; assign new `EngineSettings` to change them between runs.

        The time step, iterations, slop and bias apply at once; a different spatial index or
        thread count rebuilds Chipmunk's space from the board (as `reseat` does).
        """
        return self._settings

    @settings.setter
    def settings(self, settings: EngineSettings) -> None:
        if not isinstance(settings, EngineSettings):
            raise InputError(f"settings must be a qdots.EngineSettings, got {type(settings).__name__}")
        for force in self._forces:
            force.check_run(settings.dt)
        time_now = self.time
        old, self._settings = self._settings, settings
        if settings.dt != old.dt:  # the time so far is kept; steps count from here with the new step
            self._schedule.restart(self.steps_taken, settings.dt)
            self.start_time, self.steps_taken = time_now, 0
        if (old.spatial_hash, old.threads) != (settings.spatial_hash, settings.threads):
            self.reseat()
        else:
            tune_space(self.space, settings)

    @property
    def restitution(self) -> Restitution:
        """The collision rule; assign a new `qdots.Restitution` to change it between runs."""
        return self.scene.restitution

    @restitution.setter
    def restitution(self, rule: Restitution) -> None:
        if not isinstance(rule, Restitution):
            raise InputError(f"restitution must be a qdots.Restitution, got {type(rule).__name__}")
        self.scene = self.scene.replace(restitution=rule)
        install_handlers(self.space, rule, self.collisions)

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

    # -- the space ------------------------------------------------------------------------------

    def _build(self, scene: Scene) -> None:
        """(Re)create the pymunk space holding ``scene``'s walls and dots.

        Construction and checkpoint re-seating both come through here, so two
        simulations built from the same board have the same Chipmunk history
        (body order, shape ids, spatial index) and step identically.
        """
        self.space = new_space(scene, self._settings)
        self._bodies = []
        self.radii = np.zeros(0)
        self.masses = np.zeros(0)
        self._add_bodies(scene.positions, scene.velocities, scene.radii, scene.masses)
        install_handlers(self.space, scene.restitution, self.collisions)

    def _add_bodies(self, positions, velocities, radii, masses) -> None:
        self._bodies += add_discs(self.space, positions, velocities, radii, masses)
        self.radii = np.concatenate([self.radii, radii])
        self.masses = np.concatenate([self.masses, masses])
        self.radii.setflags(write=False)
        self.masses.setflags(write=False)
        old = self._stepper
        self._stepper = Stepper(self.space, self._bodies, self.radii, self.masses, self.scene.wall_segments())
        if old is not None and old.space is self.space:  # same space: Chipmunk's contact impulses carry over
            self._stepper.previous = old.previous
        self._io = self._stepper.io
        for force in self._forces:
            force.bind(self.radii, self.masses)

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
            check_clear(fresh, self.state(), self.scene.segments)
            self._add_bodies(fresh.positions, fresh.velocities, fresh.radii, fresh.masses)

    def current_scene(self) -> Scene:
        """The board as it is now, as a `Scene` (``from_engine=True``: soft-contact overlaps and dots
        that left an open board are kept as they are)."""
        state = self.state()
        return self.scene.replace(positions=state.positions, velocities=state.velocities,
                                  radii=state.radii, masses=state.masses, from_engine=True)

    def reseat(self) -> None:
        """Rebuild Chipmunk's space from the current board.

        Positions, velocities, time, the generator, the forces and the writers carry over;
        Chipmunk's contact cache and spatial index start afresh, exactly as in
        a simulation loaded from a checkpoint of this moment (see
        `qdots.io.checkpoint`). A run that re-seats and a run resumed from the
        checkpoint therefore continue bit for bit alike.
        """
        self._build(self.current_scene())

    @property
    def n_dots(self) -> int:
        return len(self._bodies)

    @property
    def dt(self) -> float:
        """Time step, s."""
        return self._settings.dt

    @property
    def substeps(self) -> int:
        """Chipmunk steps per time step."""
        return self._settings.substeps

    @property
    def time(self) -> float:
        """Simulation time, s: start time + steps taken * dt (no round-off drift)."""
        return self.start_time + self.steps_taken * self._settings.dt

    # -- running --------------------------------------------------------------------------------

    def step(self, n: int = 1) -> None:
        """Advance ``n`` time steps (no writers, no checks: `run` is the checked way)."""
        for _ in range(int(n)):
            try:
                k = self._stepper.step(self._forces, self._settings, self.time, self.rng, self.timings)
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
        n_steps = round(seconds / self.dt)
        if n_steps > MAX_STEPS:
            raise InputError(f"a run of {seconds:g} s at dt = {self.dt:g} s is {n_steps:,} steps, more than the "
                             f"{MAX_STEPS:,} one run may take")
        for force in self._forces:
            force.check_run(self.dt, n_steps)
        self._schedule.check_run(self.steps_taken, n_steps)
        return n_steps

    def _check_motion(self) -> None:
        """Stop when the dots leave the model's range; warn (once) when contacts can be missed at this speed."""
        if not self.n_dots:
            return
        position, velocity = self._io.read()

        def describe() -> tuple[str, str]:
            forces = ", ".join(map(_describe, self._forces)) or "none"
            return f"at t = {self.time:g} s (step {self.steps_taken})", f"the forces ({forces}) or the time step"

        sub_dt = self.dt / max(self._stepper.previous, self.substeps)  # the last step's sub-step
        travel = check_motion(position, velocity, self.radii, sub_dt, self.scene.box, describe)
        if self._settings.overlap_tolerance is not None:  # contacts are planned for: warn only when capped
            travel = self._stepper.take_capped_travel()
        if travel > SAFE_TRAVEL and not self._warned_travel:
            self._warned_travel = True
            warn_travel(travel, f"at t = {self.time:g} s")

    def state(self) -> State:
        """A snapshot of the board (copies of every array)."""
        position, velocity = self._io.read()
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
        self._io.write_velocities(v)

    def __repr__(self) -> str:
        return (f"Simulation(n_dots={self.n_dots}, t={self.time:g} s, dt={self.dt:g} s, "
                f"substeps={self.substeps}, forces={list(self._forces)})")


def _describe(force: Force) -> str:
    """A force with its parameters, for messages (its class name if it cannot say them)."""
    try:
        return repr(force)
    except (AttributeError, TypeError, ValueError):
        return type(force).__name__


def _generator(seed) -> np.random.Generator:
    """The simulation's generator from a seed (an integer >= 0, a SeedSequence or None)."""
    if seed is None or isinstance(seed, np.random.SeedSequence):
        return np.random.default_rng(seed)
    return np.random.default_rng(valid_seed("seed", seed))

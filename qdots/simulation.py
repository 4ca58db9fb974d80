"""`Simulation`: a scene moving under what acts on it, driven by an engine, with writers attached.

A `Scene` says what exists; a `Simulation` holds what acts on it and what records it, and keeps the clock:

* ``sim.forces`` -- the forces (`qdots.forces`), replaceable between runs (``sim.forces = [...]``);
* ``sim.restitution`` -- the collision rule (`qdots.Restitution`), replaceable between runs;
* ``sim.settings`` -- the engine's numerical knobs (`qdots.EngineSettings`), replaceable between runs;
* writers -- anything with a ``write(state)`` method, attached once with a trigger
  (``sim.attach(movie, every=200)`` or ``seconds=0.5``) and given the state on that schedule in
  every later run.

Everything a run needs while it runs (the Chipmunk space and bodies, the collision callbacks and their
record, the sub-step plan, each force's per-run cache) belongs to its engine, ``sim.engine``
(`qdots.engine.ChipmunkEngine`): forces and the collision rule hold physics only, so one force object can
serve any number of simulations.
"""

from __future__ import annotations

from typing import Iterable, Sequence

import numpy as np

from labrig.progress import progress_bar
from labrig.validate import InputError, generator, real

from .engine import ENGINE_CLASSES
from .engine.contacts import CollisionRecord, stream_key
from .engine.settings import OVERLAP_CORRECTION, EngineSettings  # noqa: F401 (public here too)
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
#: Settings the forces' numerical methods read: changing one empties the forces' caches.
FORCE_NUMERICS = ("pair_skin", "near_gap", "far_interval")


class Simulation:
    """Dots of a `Scene` moving under forces and a collision rule, on the Chipmunk engine.

    Each step (`qdots.engine.stepping`): read all positions and velocities in bulk, choose the Chipmunk
    sub-steps so that no dot travels more than ``overlap_tolerance`` radii into a contact within
    one, let every force add its velocity change (evaluated where the dots are at the end of the
    first sub-step), hand that change to Chipmunk as a body force, and advance Chipmunk, which moves
    the dots, adds the forces' velocity change, and resolves contacts with the partial-elasticity
    rule (`qdots.engine.contacts`). With no forces and ``overlap_tolerance=None`` the bulk read is skipped.

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
    engine : EngineSettings, optional
        The engine's numerical knobs; default ``EngineSettings()``.
    **settings
        Shorthand for ``engine=EngineSettings(**settings)`` (e.g. ``dt=2e-3``).
    """

    def __init__(self, scene: Scene, forces: Iterable[Force] = (), *, restitution: Restitution | None = None,
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
        #: Chipmunk sub-steps taken, summed over all steps.
        self.substeps_taken = 0
        self._schedule = WriterSchedule()
        self._warned_travel = False
        self._forces: tuple[Force, ...] = ()
        #: The engine: everything a run needs while it runs (`qdots.engine.ChipmunkEngine` or `EventEngine`).
        self.engine = ENGINE_CLASSES[engine.kind](scene.wall_segments(), restitution, engine, stream_key(self.rng),
                                                  scene.positions, scene.velocities, scene.radii, scene.masses)
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
        self.engine.forget_forces()

    @property
    def settings(self) -> EngineSettings:
        """The engine's knobs; assign new `EngineSettings` to change them between runs.

        The time step, iterations, slop and bias apply at once; a different spatial index or
        thread count rebuilds Chipmunk's space from the board (as `reseat` does); a different pair
        skin, near gap or far interval empties the forces' caches.
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
        if settings.kind != old.kind:  # another engine goes on from this board, with the same record
            board, record = self.current_scene(), self.engine.collisions
            self.engine = ENGINE_CLASSES[settings.kind](board.wall_segments(), self._restitution, settings, record.key,
                                                        board.positions, board.velocities, board.radii, board.masses)
            self.engine.collisions.copy_from(record)
        elif (old.spatial_hash, old.threads) != (settings.spatial_hash, settings.threads):
            self.reseat()
        else:
            self.engine.tune(settings)
        if any(getattr(old, name) != getattr(settings, name) for name in FORCE_NUMERICS):
            self.engine.forget_forces()

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
        self.engine.set_restitution(rule)
        self.engine.forget_forces()  # the sticking speed enters the thesis's van der Waals proxy

    @property
    def collisions(self) -> CollisionRecord:
        """Counts of impacts and the position in the elasticity draws (`qdots.engine.contacts.CollisionRecord`)."""
        return self.engine.collisions

    @property
    def timings(self) -> dict:
        """Wall-clock seconds spent in the force phase and in Chipmunk's steps, over all steps."""
        return self.engine.timings

    @property
    def radii(self) -> np.ndarray:
        """Dot radii, px (read-only)."""
        return self.engine.radii

    @property
    def masses(self) -> np.ndarray:
        """Dot masses, mean dot masses (read-only)."""
        return self.engine.masses

    def force_cache(self, force: Force) -> dict:
        """What ``force`` (one of `forces`) derived from the dots in this simulation: its pair lists, per-dot
        constants (the engine owns it; a benchmark reads a pair list's ``rebuilds`` there)."""
        for k, candidate in enumerate(self._forces):
            if candidate is force:
                return self.engine.force_cache(k)
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
            check_clear(fresh, self.state(), self.scene.segments)
            self.engine.add_dots(fresh.positions, fresh.velocities, fresh.radii, fresh.masses)

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
        board = self.current_scene()
        self.engine.build(self._settings, board.positions, board.velocities, board.radii, board.masses)

    @property
    def n_dots(self) -> int:
        return self.engine.n_dots

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
                k = self.engine.step(self._forces, self._settings, self.time, self.rng)
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
        position, velocity = self.engine.read()

        def describe() -> tuple[str, str]:
            forces = describe_forces(self._forces)
            return f"at t = {self.time:g} s (step {self.steps_taken})", f"the forces ({forces}) or the time step"

        sub_dt = self.dt / max(self.engine.last_substeps, self._settings.substeps)  # the last step's sub-step
        travel = check_motion(position, velocity, self.radii, sub_dt, self.scene.box, describe)
        if self._settings.overlap_tolerance is not None:  # contacts are planned for: warn only when capped
            travel = self.engine.take_capped_travel()
        if travel > SAFE_TRAVEL and not self._warned_travel:
            self._warned_travel = True
            warn_travel(travel, f"at t = {self.time:g} s")

    def state(self) -> State:
        """A snapshot of the board (copies of every array)."""
        position, velocity = self.engine.read()
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
        self.engine.write_velocities(v)

    def __repr__(self) -> str:
        return (f"Simulation(n_dots={self.n_dots}, t={self.time:g} s, dt={self.dt:g} s, "
                f"substeps={self._settings.substeps}, forces={list(self._forces)})")

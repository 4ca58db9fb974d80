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

import dataclasses
import math
import time
import warnings
from dataclasses import dataclass
from typing import Iterable, Protocol, Sequence

import numpy as np
import pymunk
from scipy.spatial import cKDTree

from labrig.deprecation import warn as warn_renamed
from labrig.validate import InputError, count, real
from labrig.validate import seed as valid_seed

from .bulk import BodyArrays
from .collisions import DOT, WALL, CollisionCounter, Restitution, install_handlers
from .forces.base import Force, StepContext
from .scene import Scene, segment_distances
from .settings import OVERLAP_CORRECTION, EngineSettings  # noqa: F401 (public here too)
from .state import State

#: Relative overlap above which a finished run warns (and says so in its summary). Soft contacts
#: overlap by < 1 % of a radius at the default settings; 10 % means the time step is too large.
OVERLAP_WARNING = 0.1

#: Largest travel per sub-step, in radii, that a run accepts without a warning. Chipmunk sees a
#: contact only once two discs overlap, so a dot can overlap by what it travels in a sub-step; at
#: ~0.75 r it passes through walls, while up to ~0.35 r the hard cases stay within their overlap
#: tolerances (measured: `benchmarks.qdots_hard_cases`).
SAFE_TRAVEL = 0.5

#: Most time steps one `Simulation.run` takes (about 14 hours at 300 dots on one core).
MAX_STEPS = 1_000_000_000


class RunawayError(InputError, FloatingPointError):
    """The dots left the model's range: speeds that cross the board in one sub-step, or non-finite values.

    The parameters (forces, time step) are outside what the model can integrate; the message says
    what was measured and lists them.
    """


class Writer(Protocol):
    """Anything that records states during a run (movie, trajectory, table)."""

    def write(self, state: State) -> None: ...


@dataclass
class Attached:
    """A writer attached to a simulation: it gets the state every ``period`` steps (counted from step 0)."""

    writer: object
    period: int
    seconds: float | None = None  # given in seconds: the period follows the time step
    last: int = -1  # the step last written


class Simulation:
    """Dots of a `Scene` moving in a `pymunk.Space`.

    Each step: read all positions and velocities in bulk, let every force
    add its velocity change (evaluated on the same start-of-step state),
    write the velocities back in bulk, then advance Chipmunk by ``dt`` in
    ``substeps`` equal sub-steps, which moves the dots and resolves contacts
    with the partial-elasticity rule (`qdots.collisions`). With no forces
    the bulk read/write is skipped entirely.

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

        ``dt`` (s): time step; forces are applied once per step.
        ``substeps``: Chipmunk steps per time step. More sub-steps resolve contacts
        more finely at proportional cost.
        ``iterations``: Chipmunk solver iterations per sub-step (pymunk default 10).
        Two-body impacts are exact with any count; simultaneous impacts of
        three or more dots converge with more (an elastic gas loses ~1e-5
        of its energy per such event at 10, none at 30).
        ``collision_slop`` (px): overlap Chipmunk tolerates without correcting
        (pymunk's default 0.1 px is 1.3 % of a mean radius, ours is 0.01 px).
        ``collision_bias``: fraction of an overlap left uncorrected after one second
        (pymunk's meaning, in [0, 1)). Default: correct 30 % of the overlap per
        sub-step (`OVERLAP_CORRECTION`). The correction moves positions only
        (pseudo-velocities), not the velocities that carry energy.
        ``spatial_hash`` ``(cell_size_px, count)``: Chipmunk's spatial hash instead of
        its default bounding-box tree.
        ``threads`` (1 or 2): Chipmunk solver threads; it helps dense piles a little.
    """

    def __init__(self, scene: Scene, forces: Iterable[Force] = (), *,
                 seed: int | np.random.SeedSequence | None = None, engine: EngineSettings | None = None,
                 **settings):
        if not isinstance(scene, Scene):
            raise InputError(f"scene must be a qdots.Scene, got {type(scene).__name__}")
        if engine is not None and settings:
            raise InputError(f"give engine=EngineSettings(...) or the settings {sorted(settings)}, not both")
        if engine is None:
            try:
                engine = EngineSettings(**settings)
            except TypeError:
                names = [f.name for f in dataclasses.fields(EngineSettings)]
                unknown = sorted(set(settings) - set(names))
                raise InputError(f"unknown engine setting {unknown[0]!r} (known: {', '.join(names)})") from None
        if not isinstance(engine, EngineSettings):
            raise InputError(f"engine must be a qdots.EngineSettings, got {type(engine).__name__}")
        self._settings = engine
        self.scene = scene
        self.rng = _generator(seed)
        self.steps_taken = 0
        #: Simulation time at step 0, s (nonzero for a run resumed from a checkpoint).
        self.start_time = 0.0
        #: Wall-clock seconds spent in the force phase (bulk read, kicks, bulk
        #: write) and in Chipmunk's ``space.step`` (which includes the collision
        #: callbacks), accumulated over all steps.
        self.timings = {"forces": 0.0, "pymunk": 0.0}
        self.collisions = CollisionCounter()
        self._writers: list[Attached] = []
        self._warned_travel = False
        self._forces: tuple[Force, ...] = ()
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
        time_now = self.time
        old, self._settings = self._settings, settings
        if settings.dt != old.dt:  # the time so far is kept; steps count from here with the new step
            now, self.start_time, self.steps_taken = self.steps_taken, time_now, 0
            for attached in self._writers:
                attached.last = 0 if attached.last == now else -1
        if (old.spatial_hash, old.threads) != (settings.spatial_hash, settings.threads):
            self.reseat()
        else:
            self._tune_space()
        if settings.dt != old.dt:
            for attached in self._writers:  # a writer given in seconds keeps its interval in seconds
                if attached.seconds is not None:
                    attached.period = _period(attached.seconds, settings.dt)

    @property
    def restitution(self) -> Restitution:
        """The collision rule; assign a new `qdots.Restitution` to change it between runs."""
        return self.scene.restitution

    @restitution.setter
    def restitution(self, rule: Restitution) -> None:
        if not isinstance(rule, Restitution):
            raise InputError(f"restitution must be a qdots.Restitution, got {type(rule).__name__}")
        self.scene = self.scene.replace(restitution=rule)
        install_handlers(self.space, rule, self.rng, self.collisions)

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
        if not callable(getattr(writer, "write", None)):
            raise InputError(f"a writer needs a write(state) method, got {type(writer).__name__}")
        if every is not None and seconds is not None:
            raise InputError("give every (steps) or seconds, not both")
        if any(a.writer is writer for a in self._writers):
            raise InputError(f"{writer!r} is attached already")
        if seconds is not None:
            period = _period(seconds, self.dt)
        else:
            period = count("every", getattr(writer, "every", None) if every is None else every, 1)
        self._writers.append(Attached(writer, period, None if seconds is None else float(seconds)))
        return writer

    def detach(self, writer) -> None:
        """Stop giving ``writer`` states (it is not closed)."""
        kept = [a for a in self._writers if a.writer is not writer]
        if len(kept) == len(self._writers):
            raise InputError(f"{writer!r} is not attached")
        self._writers = kept

    @property
    def writers(self) -> tuple:
        """The attached writers, in the order they write."""
        return tuple(a.writer for a in self._writers)

    # -- the space ------------------------------------------------------------------------------

    def _tune_space(self) -> None:
        settings, space = self._settings, self.space
        space.iterations = int(settings.iterations)
        space.collision_slop = float(settings.collision_slop)
        space.collision_bias = settings.bias

    def _build(self, scene: Scene) -> None:
        """(Re)create the pymunk space holding ``scene``'s walls and dots.

        Construction and checkpoint re-seating both come through here, so two
        simulations built from the same board have the same Chipmunk history
        (body order, shape ids, spatial index) and step identically.
        """
        settings = self._settings
        self.space = space = pymunk.Space(threaded=settings.threads > 1)
        if settings.threads > 1:
            space.threads = settings.threads
        self._tune_space()
        if settings.spatial_hash is not None:
            cell, cells = settings.spatial_hash
            space.use_spatial_hash(float(cell), int(cells))
        for x0, y0, x1, y1 in scene.wall_segments():
            wall = pymunk.Segment(space.static_body, (x0, y0), (x1, y1), 0.0)
            wall.friction = 0.0
            wall.elasticity = 1.0
            wall.collision_type = WALL
            space.add(wall)
        self._bodies: list[pymunk.Body] = []
        self.radii = np.zeros(0)
        self.masses = np.zeros(0)
        self._add_bodies(scene.positions, scene.velocities, scene.radii, scene.masses)
        install_handlers(space, scene.restitution, self.rng, self.collisions)

    def _add_bodies(self, positions, velocities, radii, masses) -> None:
        for (x, y), (vx, vy), r, m in zip(positions, velocities, radii, masses):
            body = pymunk.Body(float(m), math.inf)  # frictionless discs never spin
            body.position = (float(x), float(y))
            body.velocity = (float(vx), float(vy))
            circle = pymunk.Circle(body, float(r))
            circle.friction = 0.0
            circle.elasticity = 0.0  # lasting contacts are inelastic; impacts are set in `begin`
            circle.collision_type = DOT
            self.space.add(body, circle)
            self._bodies.append(body)
        self._io = BodyArrays(self.space, self._bodies)
        self.radii = np.concatenate([self.radii, radii])
        self.masses = np.concatenate([self.masses, masses])
        self.radii.setflags(write=False)
        self.masses.setflags(write=False)
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
        now = self.state()
        fresh = Scene(box=self.scene.box, positions=positions, radii=radii, masses=masses,
                      velocities=velocities)
        if fresh.n_dots == 0:
            return
        if len(self.scene.segments):
            gap = segment_distances(fresh.positions, self.scene.segments) - fresh.radii[:, None]
            k, m = np.unravel_index(np.argmin(gap), gap.shape)
            if gap[k, m] < 0:
                raise InputError(f"new dot {k} crosses wall segments[{m}]")
        if now.n_dots:
            tree = cKDTree(now.positions)
            reach = fresh.radii + float(now.radii.max())
            for k, (point, r) in enumerate(zip(fresh.positions, fresh.radii)):
                for j in tree.query_ball_point(point, reach[k]):
                    if np.linalg.norm(point - now.positions[j]) < r + now.radii[j]:
                        raise InputError(f"new dot {k} overlaps dot {j} already on the board")
        self._add_bodies(fresh.positions, fresh.velocities, fresh.radii, fresh.masses)

    def current_scene(self) -> Scene:
        """The board as it is now, as a `Scene` (``from_engine=True``: soft-contact overlaps and dots
        that left an open board are kept as they are)."""
        state = self.state()
        return self.scene.replace(positions=state.positions, velocities=state.velocities,
                                  radii=state.radii, masses=state.masses, from_engine=True)

    def board(self) -> Scene:
        """Deprecated name of `current_scene`."""
        warn_renamed("Simulation.board()", "Simulation.current_scene()")
        return self.current_scene()

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
        substep = self.dt / self.substeps
        clock = time.perf_counter
        timings = self.timings
        for _ in range(int(n)):
            t0 = clock()
            if self._forces:
                self._apply_forces()
            t1 = clock()
            for _ in range(self.substeps):
                self.space.step(substep)
            timings["forces"] += t1 - t0
            timings["pymunk"] += clock() - t1
            self.steps_taken += 1

    def _apply_forces(self) -> None:
        position, velocity = self._io.read()
        ctx = StepContext(
            time=self.time,
            dt=self.dt,
            x=np.ascontiguousarray(position[:, 0]),
            y=np.ascontiguousarray(position[:, 1]),
            velocity=velocity,
            radii=self.radii,
            masses=self.masses,
            rng=self.rng,
            dv=np.zeros_like(velocity),
        )
        try:
            for force in self._forces:
                force.kick(ctx)
        except (ValueError, OverflowError, MemoryError, FloatingPointError, RuntimeError):
            self._check_motion()  # a blown-up board makes the pair search fail: say what happened
            raise
        self._io.write_velocities(velocity + ctx.dv)

    def _write_due(self) -> None:
        """Give each attached writer the state if the current step is on its schedule and not yet written."""
        for attached in self._writers:
            if self.steps_taken % attached.period == 0 and attached.last != self.steps_taken:
                attached.writer.write(self.state())
                attached.last = self.steps_taken

    def run(self, seconds: float, *, progress: bool = False, writers: Sequence[Writer] = ()) -> State:
        """Advance by ``seconds`` of simulated time (rounded to whole steps), writing on the attached writers' schedules.

        Parameters
        ----------
        seconds : float
            Simulated time to advance, s (>= 0; at most `MAX_STEPS` steps).
        progress : bool
            Show a progress bar in simulated seconds with an ETA (needs ``tqdm``).
        writers : sequence of Writer
            Deprecated: attach writers with `attach`. Writers given here are attached (with their
            own ``every``) if they are not already.

        Returns
        -------
        State
            The state at the end.

        Raises
        ------
        RunawayError
            When the dots leave the model's range (speeds that cross the board in one sub-step, or
            non-finite values; checked between chunks of steps, at most 200 times per run).

        Warns
        -----
        RuntimeWarning
            Once per simulation, when a dot moves more than `SAFE_TRAVEL`
            radii in one sub-step (contacts can then be missed).
        """
        seconds = real("seconds", seconds, 0.0)
        n_steps = round(seconds / self.dt)
        if n_steps > MAX_STEPS:
            raise InputError(f"a run of {seconds:g} s at dt = {self.dt:g} s is {n_steps:,} steps, more than the "
                             f"{MAX_STEPS:,} one run may take")
        for writer in writers:
            if writer not in self.writers:
                warn_renamed("Simulation.run(writers=...)", "Simulation.attach(writer)")
                self.attach(writer)
        bar = None
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=n_steps, unit="step", desc="qdots run", leave=False)
        chunk = max(1, n_steps // 200)
        end = self.steps_taken + n_steps
        try:
            while True:
                self._write_due()
                if self.steps_taken >= end:
                    break
                due = [self.steps_taken + a.period - self.steps_taken % a.period for a in self._writers]
                stop = min([end, self.steps_taken + chunk, *due])
                done = stop - self.steps_taken
                self.step(done)
                self._check_motion()
                if bar is not None:
                    bar.update(done)
                    bar.set_postfix_str(f"t = {self.time:.2f} s", refresh=False)
        finally:
            if bar is not None:
                bar.close()
        return self.state()

    def _check_motion(self) -> None:
        """Stop when the dots leave the model's range; warn (once) when contacts can be missed at this speed."""
        if not self.n_dots:
            return
        position, velocity = self._io.read()
        speed = np.hypot(velocity[:, 0], velocity[:, 1])
        fastest = float(speed.max()) if np.isfinite(speed).all() else math.inf
        sub_dt = self.dt / self.substeps
        span = math.hypot(*self.scene.box)
        if not (np.isfinite(position).all() and fastest * sub_dt < span):
            raise RunawayError(
                f"the dots left the model's range at t = {self.time:g} s (step {self.steps_taken}): speeds of "
                f"{fastest:.3g} px/s cross the {self.scene.box[0]:g} x {self.scene.box[1]:g} px board in one "
                f"sub-step of {sub_dt:g} s; the forces ({', '.join(map(_describe, self._forces)) or 'none'}) or the "
                "time step are outside what the model integrates")
        travel = float((speed / self.radii).max()) * sub_dt
        if travel > SAFE_TRAVEL and not self._warned_travel:
            self._warned_travel = True
            warnings.warn(f"at t = {self.time:g} s a dot moves {travel:.2f} radii per sub-step (> {SAFE_TRAVEL}): "
                          "contacts are found only once discs overlap, so overlaps of that size and dots passing "
                          "through walls become possible; use a smaller dt or more substeps", RuntimeWarning,
                          stacklevel=3)

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


def _period(seconds: float, dt: float) -> int:
    """Whole steps of ``dt`` closest to ``seconds`` (at least one)."""
    return max(1, round(real("seconds", seconds, 0.0, low_open=True) / dt))


def _generator(seed) -> np.random.Generator:
    """The simulation's generator from a seed (an integer >= 0, a SeedSequence or None)."""
    if seed is None or isinstance(seed, np.random.SeedSequence):
        return np.random.default_rng(seed)
    return np.random.default_rng(valid_seed("seed", seed))

"""`Simulation`: a scene moving under pymunk with pluggable forces."""

from __future__ import annotations

import math
import time
import warnings
import weakref
from typing import Callable, Iterable, Protocol, Sequence

import numpy as np
import pymunk
from scipy.spatial import cKDTree

from labrig.validate import InputError

from .bulk import BodyArrays
from .collisions import DOT, WALL, CollisionCounter, install_handlers
from .forces.base import Force, StepContext
from .scene import Scene, segment_distances
from .settings import OVERLAP_CORRECTION, EngineSettings  # noqa: F401 (public here too)
from .state import State

#: Relative overlap accepted when a board is read back from a running simulation:
#: soft contacts overlap by < 1 % of a radius at the defaults; 10 % guards against nonsense.
ENGINE_OVERLAP_TOLERANCE = 0.1

#: Largest travel per sub-step, in radii, that a run accepts without a warning. Chipmunk sees a
#: contact only once two discs overlap, so a dot can overlap by what it travels in a sub-step; at
#: ~0.75 r it passes through walls, while up to ~0.35 r the hard cases stay within their overlap
#: tolerances (measured: `benchmarks.qdots_hard_cases`).
SAFE_TRAVEL = 0.5


def _weak(obj: object) -> Callable[[], object]:
    try:
        return weakref.ref(obj)
    except TypeError:  # not weak-referenceable: hold it (ids then never collide)
        return lambda: obj


class Writer(Protocol):
    """Anything that records states during a run (movie, trajectory, table)."""

    every: int

    def write(self, state: State) -> None: ...


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
    dt : float
        Time step, s (> 0). Forces are applied once per step.
    substeps : int
        Chipmunk steps per time step (>= 1). More sub-steps resolve contacts
        more finely at proportional cost.
    iterations : int
        Chipmunk solver iterations per sub-step (>= 1, pymunk default 10).
        Two-body impacts are exact with any count; simultaneous impacts of
        three or more dots converge with more (an elastic gas loses ~1e-5
        of its energy per such event at 10, none at 30).
    collision_slop : float
        Overlap Chipmunk tolerates without correcting, px (>= 0; pymunk's
        default 0.1 px is 1.3 % of a mean radius, ours is 0.01 px).
    collision_bias : float, optional
        Fraction of an overlap left uncorrected after one second (pymunk's
        meaning, in [0, 1)). Default: correct 30 % of the overlap per
        sub-step (`OVERLAP_CORRECTION`; pymunk's default corrects 10 % per
        step at its design rate of 60 Hz, under 1 % per step at 1 ms). The
        correction moves positions only (pseudo-velocities), not the
        velocities that carry energy.
    spatial_hash : (float, int), optional
        ``(cell_size_px, count)`` to use Chipmunk's spatial hash instead of
        its default bounding-box tree.
    threads : int
        Chipmunk solver threads (1 or 2). Only the solver is threaded; it
        helps dense piles a little and dilute gases not at all.
    """

    def __init__(
        self,
        scene: Scene,
        forces: Iterable[Force] = (),
        *,
        seed: int | np.random.SeedSequence | None = None,
        dt: float = 1e-3,
        substeps: int = 1,
        iterations: int = 10,
        collision_slop: float = 0.01,
        collision_bias: float | None = None,
        spatial_hash: tuple[float, int] | None = None,
        threads: int = 1,
    ):
        if not isinstance(scene, Scene):
            raise TypeError(f"scene must be a qdots.Scene, got {type(scene).__name__}")
        self.settings = EngineSettings(dt=dt, substeps=substeps, iterations=iterations,
                                       collision_slop=collision_slop, collision_bias=collision_bias,
                                       spatial_hash=None if spatial_hash is None else tuple(spatial_hash),
                                       threads=threads)
        self.forces: tuple[Force, ...] = tuple(forces)
        for force in self.forces:
            if not isinstance(force, Force):
                raise TypeError(f"forces must be qdots.forces.Force instances, got {type(force).__name__}")
        self.scene = scene
        self.rng = np.random.default_rng(seed)
        self.steps_taken = 0
        #: Simulation time at step 0, s (nonzero for a run resumed from a checkpoint).
        self.start_time = 0.0
        #: Wall-clock seconds spent in the force phase (bulk read, kicks, bulk
        #: write) and in Chipmunk's ``space.step`` (which includes the collision
        #: callbacks), accumulated over all steps.
        self.timings = {"forces": 0.0, "pymunk": 0.0}
        self.collisions = CollisionCounter()
        self._last_written: dict[int, tuple[Callable[[], object], int]] = {}
        self._warned_travel = False
        self._build(scene)

    def _build(self, scene: Scene) -> None:
        """(Re)create the pymunk space holding ``scene``'s walls and dots.

        Construction and checkpoint re-seating both come through here, so two
        simulations built from the same board have the same Chipmunk history
        (body order, shape ids, spatial index) and step identically.
        """
        settings = self.settings
        self.space = space = pymunk.Space(threaded=settings.threads > 1)
        if settings.threads > 1:
            space.threads = settings.threads
        space.iterations = int(settings.iterations)
        space.collision_slop = float(settings.collision_slop)
        space.collision_bias = settings.bias
        if settings.spatial_hash is not None:
            cell, count = settings.spatial_hash
            space.use_spatial_hash(float(cell), int(count))
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
        for force in self.forces:
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
        ValueError
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

    def board(self) -> Scene:
        """The board as it is now, as a `Scene` (soft-contact overlap accepted)."""
        state = self.state()
        return self.scene.replace(positions=state.positions, velocities=state.velocities,
                                  radii=state.radii, masses=state.masses,
                                  overlap_tolerance=ENGINE_OVERLAP_TOLERANCE)

    def reseat(self) -> None:
        """Rebuild Chipmunk's space from the current board.

        Positions, velocities, time, the generator and the forces carry over;
        Chipmunk's contact cache and spatial index start afresh, exactly as in
        a simulation loaded from a checkpoint of this moment (see
        `qdots.io.checkpoint`). A run that re-seats and a run resumed from the
        checkpoint therefore continue bit for bit alike.
        """
        self._build(self.board())

    @property
    def n_dots(self) -> int:
        return len(self._bodies)

    @property
    def dt(self) -> float:
        """Time step, s (fixed for the life of the simulation)."""
        return self.settings.dt

    @property
    def substeps(self) -> int:
        """Chipmunk steps per time step."""
        return self.settings.substeps

    @property
    def time(self) -> float:
        """Simulation time, s: start time + steps taken * dt (no round-off drift)."""
        return self.start_time + self.steps_taken * self.settings.dt

    def step(self, n: int = 1) -> None:
        """Advance ``n`` time steps."""
        substep = self.dt / self.substeps
        clock = time.perf_counter
        timings = self.timings
        for _ in range(int(n)):
            t0 = clock()
            if self.forces:
                self._apply_forces()
            t1 = clock()
            for _ in range(self.substeps):
                self.space.step(substep)
            timings["forces"] += t1 - t0
            timings["pymunk"] += clock() - t1
            self.steps_taken += 1

    def _write_due(self, writers: Sequence[Writer]) -> None:
        """Give each writer the state if the current step is on its schedule and not yet written."""
        for writer in writers:
            if self.steps_taken % writer.every:
                continue
            mark = self._last_written.get(id(writer))
            if mark is not None and mark[0]() is writer and mark[1] == self.steps_taken:
                continue
            writer.write(self.state())
            # a weak reference tells a reused id() from the same writer without keeping it alive
            self._last_written[id(writer)] = (_weak(writer), self.steps_taken)

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
        for force in self.forces:
            force.kick(ctx)
        self._io.write_velocities(velocity + ctx.dv)

    def run(self, seconds: float, *, progress: bool = False, writers: Sequence[Writer] = ()) -> State:
        """Advance by ``seconds`` of simulated time (rounded to whole steps).

        Parameters
        ----------
        seconds : float
            Simulated time to advance, s (>= 0).
        progress : bool
            Show a progress bar in simulated seconds with an ETA (needs ``tqdm``).
        writers : sequence of Writer
            Objects with an ``every`` attribute (steps) and a
            ``write(state)`` method, e.g. `qdots.render.MovieWriter`. A writer
            gets the state at every step count that is a multiple of
            ``every`` (counted from the simulation's step 0, so a writer passed
            to successive runs, as in a deposition, keeps one even schedule and
            never sees the same step twice). The run does not close them.

        Returns
        -------
        State
            The state at the end.

        Raises
        ------
        FloatingPointError
            When a position or velocity has become NaN or infinite (checked
            between chunks of steps, at most 200 times per run).

        Warns
        -----
        RuntimeWarning
            Once per simulation, when a dot moves more than `SAFE_TRAVEL`
            radii in one sub-step (contacts can then be missed).
        """
        if not (math.isfinite(seconds) and seconds >= 0):
            raise InputError(f"seconds must be >= 0, got {seconds!r}")
        n_steps = int(round(seconds / self.dt))
        for writer in writers:
            if not (isinstance(writer.every, (int, np.integer)) and writer.every >= 1):
                raise InputError(f"writer.every must be an integer >= 1 step, got {writer.every!r}")
        bar = None
        if progress:
            from tqdm.auto import tqdm

            bar = tqdm(total=n_steps, unit="step", desc="qdots run", leave=False)
        chunk = max(1, n_steps // 200)
        end = self.steps_taken + n_steps
        try:
            while True:
                self._write_due(writers)
                if self.steps_taken >= end:
                    break
                due = [self.steps_taken + w.every - self.steps_taken % w.every for w in writers]
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
        """Stop on a non-finite state; warn (once) when contacts can be missed at this speed."""
        if not self.n_dots:
            return
        position, velocity = self._io.read()
        if not (np.isfinite(position).all() and np.isfinite(velocity).all()):
            raise FloatingPointError(f"non-finite dot positions or velocities at t = {self.time:g} s "
                                     f"(step {self.steps_taken}): a force or the time step is unstable")
        travel = float((np.hypot(velocity[:, 0], velocity[:, 1]) / self.radii).max()) * self.dt / self.substeps
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
        )

    def set_velocities(self, velocities: Sequence[Sequence[float]] | np.ndarray) -> None:
        """Overwrite every dot's velocity (px/s) from an (N, 2) array."""
        v = np.asarray(velocities, dtype=float)
        if v.shape != (self.n_dots, 2) or not np.isfinite(v).all():
            raise InputError(f"velocities must be a finite ({self.n_dots}, 2) array, got shape {v.shape}")
        self._io.write_velocities(v)

    def __repr__(self) -> str:
        return (f"Simulation(n_dots={self.n_dots}, t={self.time:g} s, dt={self.dt:g} s, "
                f"substeps={self.substeps}, forces={list(self.forces)})")

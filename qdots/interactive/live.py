"""A board whose parameters change while it runs: the model behind `qdots.interactive`.

`LiveRun` holds a `Simulation` and the knobs a person turns while watching it
(`Knobs`: time step, elasticity, van der Waals, thermal kicks, drag, gravity).
Everything goes through the public `Scene` / `Simulation` / forces API:

* Turning a knob sets the running simulation's forces (``sim.forces``), engine (``sim.engine``: which
  engine, its time step) or collision rule (``sim.restitution``); the board goes on
  as it is, exactly as a script that sets the same values at the same step.
* Walls and gratings are added by rebuilding the simulation from the current board
  (`Simulation.current_scene`) with the new segments, after checking that no dot sits across
  them, carrying over the time, the random stream and the forces, as `qdots.io.checkpoint.load`
  does. Velocities and positions are kept exactly.
* Dots are dropped by the thesis's deposition protocol
  (`qdots.deposition.deposit`) one at a time, ``interval`` seconds of board
  time apart, between frames: the same film as one ``deposit`` call with the
  same generator, while the board stays on screen.

It needs no widget library and runs in scripts and tests as well.
"""

from __future__ import annotations

import collections
import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from labrig.validate import InputError, choice, count, real

from ..analysis.packing import packing_summary
from ..analysis.structure import hexatic_order
from ..deposition import deposit
from ..engine import ENGINES, Chipmunk, Settings
from ..engine.settings import DT_RANGE
from ..forces import CentreGravity, Drag, Gravity, ThermalKicks, VanDerWaals
from ..forces.base import Force
from ..forces.fields import MAX_ACCELERATION, MAX_DRAG, THESIS_GRAVITY
from ..forces.thermal import MAX_SCALE
from ..forces.vdw import MAX_RANGE
from ..geometry import worst_wall_overlap
from ..io import checkpoint
from ..restitution import Restitution
from ..scene import MAX_DOTS, Scene, grating_segments
from ..simulation import Simulation
from ..state import State

#: Gravity modes: off, uniform toward y = 0 (`Gravity`), toward the board centre (`CentreGravity`).
GRAVITY_MODES = ("none", "uniform", "centre")
#: The board of a `LiveRun` given no scene: empty, closed, px.
DEFAULT_BOX = (400.0, 400.0)
#: Most time steps per frame.
MAX_FRAME_STEPS = 100_000


@dataclass(frozen=True)
class Knobs:
    """The parameters a person turns while a board runs.

    Parameters
    ----------
    dt : float
        Time step, s, in `qdots.engine.settings.DT_RANGE` (default: the engines' default, the thesis's frame).
    elasticity : float
        Mean dot-dot restitution, in [0, 1] (`qdots.Restitution.mean`; thesis 0.8).
    vdw_r0 : float
        Strength of the van der Waals proxy, px: ``R0`` of `qdots.VanDerWaals`
        (the thesis's ``setVanDerWaalCoeff``; 15). 0 switches it off.
    thermal : float
        Thermal kick magnitude as a multiple of the thesis's (`qdots.ThermalKicks`
        ``scale``, >= 0). 0 switches the kicks off.
    drag : float
        Substrate friction ``f``, 1/s (>= 0): `qdots.Drag` ``(f, f / 30)``, the
        thesis's ``setFriction(f, f)`` at 30 px per length unit. 0 = none.
    gravity : {"none", "uniform", "centre"}
        No gravity, `qdots.Gravity` toward y = 0, or `qdots.CentreGravity`
        toward the centre of the board.
    gravity_magnitude : float
        Acceleration, px/s^2 (>= 0; thesis 750).
    engine : {"chipmunk", "event"}
        The engine that moves the dots (`qdots.engine.ENGINES`): Chipmunk's soft contacts or the
        thesis's event-driven exact hard discs. It can be switched while the board runs.
    """

    dt: float = Chipmunk.dt
    elasticity: float = 0.8
    vdw_r0: float = 15.0
    thermal: float = 1.0
    drag: float = 0.0
    gravity: str = "none"
    gravity_magnitude: float = THESIS_GRAVITY
    engine: str = Chipmunk.kind

    def __post_init__(self) -> None:
        for name, high, unit in (("dt", DT_RANGE[1], "s"), ("elasticity", 1.0, ""), ("vdw_r0", MAX_RANGE, "px"),
                                 ("thermal", MAX_SCALE, ""), ("drag", MAX_DRAG, "1/s"),
                                 ("gravity_magnitude", MAX_ACCELERATION, "px/s^2")):
            low = DT_RANGE[0] if name == "dt" else 0.0
            object.__setattr__(self, name, real(name, getattr(self, name), low, high, unit=unit))
        choice("gravity", self.gravity, GRAVITY_MODES)
        choice("engine", self.engine, tuple(ENGINES))

    def forces(self, box: tuple[float, float]) -> list:
        """Fresh force objects for a board of size ``box`` (px); a knob at 0 adds no force."""
        forces: list[Force] = []
        if self.vdw_r0 > 0:
            forces.append(VanDerWaals(r0=self.vdw_r0))
        if self.thermal > 0:
            forces.append(ThermalKicks(scale=self.thermal))
        if self.drag > 0:
            forces.append(Drag(self.drag, self.drag / 30.0))
        if self.gravity == "uniform" and self.gravity_magnitude > 0:
            forces.append(Gravity((0.0, -self.gravity_magnitude)))
        elif self.gravity == "centre" and self.gravity_magnitude > 0:
            forces.append(CentreGravity((box[0] / 2.0, box[1] / 2.0), self.gravity_magnitude))
        return forces


@dataclass
class _Drop:
    """Dots still to deposit with one set of protocol parameters."""

    count: int
    mean_diameter: float
    sigma: float
    interval: float
    mass_model: str


class LiveRun:
    """A running board with knobs, walls, deposition, readouts, checkpoints and a movie.

    Parameters
    ----------
    scene : Scene, optional
        The starting board; default an empty closed `DEFAULT_BOX`. To go on
        from a saved run: ``LiveRun(qdots.load(path).current_scene())``.
    knobs : Knobs, optional
        Starting parameters, the collision rule's mean elasticity among them; default `Knobs()`.
    seed : int or SeedSequence, optional
        Root seed: one child seeds the simulation, one the deposition.
    frame_steps : int
        Time steps per `advance`, in [1, `MAX_FRAME_STEPS`].
    engine : qdots.Chipmunk or qdots.Event, optional
        The engine's other settings (``substeps``, ``iterations``, ...); the time step and which engine are
        the ``dt`` and ``engine`` knobs (switching engines keeps the settings the two share).
    """

    def __init__(self, scene: Scene | None = None, knobs: Knobs | None = None, *, seed=None,
                 frame_steps: int = 50, engine: Settings | None = None):
        if scene is None:
            scene = Scene(box=DEFAULT_BOX, positions=np.zeros((0, 2)), radii=np.zeros(0))
        if not isinstance(scene, Scene):
            raise InputError(f"scene must be a qdots.Scene, got {type(scene).__name__}")
        self.knobs = Knobs() if knobs is None else knobs
        if not isinstance(self.knobs, Knobs):
            raise InputError(f"knobs must be a qdots.interactive.Knobs, got {type(self.knobs).__name__}")
        engine = Chipmunk() if engine is None else engine
        if not isinstance(engine, Settings):
            raise InputError(f"engine must be a qdots.Chipmunk or qdots.Event, got {type(engine).__name__}")
        self.frame_steps = count("frame_steps", frame_steps, 1, MAX_FRAME_STEPS)
        sim_seed, drop_seed = np.random.SeedSequence(seed).spawn(2)
        #: The settings of each engine the board has run on, by kind: a toggle back finds its own again.
        self._engines = {engine.kind: engine}
        self.sim = Simulation(scene, self.knobs.forces(scene.box), restitution=Restitution(mean=self.knobs.elasticity),
                              seed=sim_seed, engine=self._engine_for(self.knobs))
        self._drop_rng = np.random.default_rng(drop_seed)
        self._drops: collections.deque[_Drop] = collections.deque()
        self._next_drop = -np.inf
        self._movie = None
        #: Simulated seconds per wall-clock second over the last `advance` (0 before the first).
        self.speed = 0.0

    # -- knobs: set on the running simulation; walls: rebuild it from the current board ---------

    def set(self, **changes) -> None:
        """Turn knobs (names of `Knobs` fields) on the running simulation.

        Raises
        ------
        labrig.validate.InputError
            On an unknown knob or a bad value (nothing is changed then).
        """
        names = [f.name for f in dataclasses.fields(Knobs)]
        unknown = sorted(set(changes) - set(names))
        if unknown:
            raise InputError(f"unknown knob {unknown[0]!r} (knobs: {', '.join(names)})")
        knobs = dataclasses.replace(self.knobs, **changes)
        sim, old = self.sim, self.knobs
        if (knobs.dt, knobs.engine) != (old.dt, old.engine):
            self._engines[sim.engine.kind] = sim.engine
            sim.engine = self._engine_for(knobs)
        if knobs.elasticity != old.elasticity:
            sim.restitution = dataclasses.replace(sim.restitution, mean=knobs.elasticity)
        forces = knobs.forces(sim.scene.box)
        if [f.to_dict() for f in forces] != [f.to_dict() for f in old.forces(sim.scene.box)]:
            sim.forces = forces
        self.knobs = knobs

    def _engine_for(self, knobs: Knobs) -> Settings:
        """The settings of the engine ``knobs.engine`` at time step ``knobs.dt``: those it had on this board (or
        was given), else the current engine's switched to it (`qdots.engine.Settings.replace`)."""
        known = self._engines.get(knobs.engine)
        if known is None:
            known = next(iter(self._engines.values())).replace(kind=knobs.engine)
        return known.replace(dt=knobs.dt)

    def _rebuild(self, board: Scene) -> None:
        """A new simulation of ``board`` that goes on with the old one's time, random stream, forces and writers."""
        old = self.sim
        sim = Simulation(board, self.knobs.forces(board.box), restitution=old.restitution, seed=0, engine=old.engine)
        sim.rng.bit_generator.state = old.rng.bit_generator.state
        sim.collisions.copy_from(old.collisions)
        sim.start_time = old.time
        for writer in old.writers:
            sim.attach(writer)
        self.sim = sim

    def add_segments(self, segments) -> None:
        """Add static walls ``(x0, y0, x1, y1)`` (px), shape (M, 4).

        Raises
        ------
        ValueError
            On a bad segment (as `Scene`) or one that crosses a dot on the board.
        """
        board = self.sim.current_scene()
        assert board.segments is not None  # Scene.__post_init__ replaces the default None by an array
        new = board.replace(segments=np.vstack([board.segments, np.asarray(segments, dtype=float).reshape(-1, 4)]))
        assert new.segments is not None
        added = new.segments[len(board.segments):]
        _, (k, m) = worst_wall_overlap(board.positions, board.radii, added)
        if k >= 0:
            x0, y0, x1, y1 = added[m]
            raise InputError(f"wall ({x0:g}, {y0:g}) - ({x1:g}, {y1:g}) px crosses dot {k} at "
                             f"({board.positions[k, 0]:.1f}, {board.positions[k, 1]:.1f}) px")
        self._rebuild(new)

    def add_wall(self, x0: float, y0: float, x1: float, y1: float) -> None:
        """Add one straight wall from ``(x0, y0)`` to ``(x1, y1)``, px."""
        self.add_segments([[x0, y0, x1, y1]])

    def add_grating(self, pitch: float, offset: float = 0.0) -> None:
        """Add horizontal grating lines ``pitch`` px apart (`qdots.grating_segments`)."""
        lines = grating_segments(self.sim.scene.box, pitch, offset)
        if not len(lines):
            raise InputError(f"no grating line fits: pitch {pitch:g} px + offset {offset:g} px >= board height "
                             f"{self.sim.scene.box[1]:g} px")
        self.add_segments(lines)

    def clear_walls(self) -> None:
        """Remove every wall and grating line (the box edges stay)."""
        self._rebuild(self.sim.current_scene().replace(segments=None))

    # -- running ---------------------------------------------------------------------------------

    def drop(self, n_dots: int, mean_diameter: float = 15.0, sigma: float = 0.0, interval: float = 1.0,
             mass_model: str = "equal") -> None:
        """Queue ``n_dots`` dots for deposition by `qdots.deposition.deposit`, ``interval`` s apart.

        They are placed during the next `advance` calls, as the board time
        reaches each one's turn (the first at once). Arguments as `deposit`; the board, with the
        dots on it and those queued, holds at most `qdots.scene.MAX_DOTS`.
        """
        n_dots = count("n_dots", n_dots, 0, MAX_DOTS)
        total = self.sim.n_dots + self.pending + n_dots
        if total > MAX_DOTS:
            raise InputError(f"n_dots = {n_dots:,} would bring the board to {total:,} dots ({self.sim.n_dots:,} on it, "
                             f"{self.pending:,} queued), more than the {MAX_DOTS:,} allowed")
        # validate now, not at the first frame: a dry run places nothing
        deposit(self.sim, 0, mean_diameter, sigma, interval=interval, mass_model=mass_model, rng=self._drop_rng)
        if n_dots:
            self._drops.append(_Drop(n_dots, float(mean_diameter), float(sigma), float(interval), mass_model))

    @property
    def pending(self) -> int:
        """Dots queued by `drop` and not yet placed."""
        return sum(d.count for d in self._drops)

    def _place_due(self) -> None:
        """Place queued dots whose turn has come (several at once if their interval is 0)."""
        while self._drops and self.sim.time >= self._next_drop - 0.5 * self.sim.dt:
            batch = self._drops[0]
            try:
                deposit(self.sim, 1, batch.mean_diameter, batch.sigma, mass_model=batch.mass_model,
                        interval=0.0, rng=self._drop_rng)
            except ValueError:
                self._drops.clear()  # the board is full: drop the rest of the queue
                raise
            batch.count -= 1
            self._next_drop = self.sim.time + batch.interval
            if not batch.count:
                self._drops.popleft()

    def advance(self, steps: int | None = None) -> State:
        """Run ``steps`` time steps (default `frame_steps`), placing queued dots on their turn.

        The movie being recorded (see `record`) gets its frames on its schedule.

        Returns
        -------
        State
            The board at the end.
        """
        remaining = self.frame_steps if steps is None else count("steps", steps, 0, MAX_FRAME_STEPS)
        start_wall, start_time = time.perf_counter(), self.sim.time
        self._place_due()
        while remaining:
            n = remaining
            if self._drops:
                n = min(n, max(1, round((self._next_drop - self.sim.time) / self.sim.dt)))
            self.sim.run(n * self.sim.dt)
            remaining -= n
            self._place_due()
        wall = time.perf_counter() - start_wall
        self.speed = (self.sim.time - start_time) / wall if wall > 0 else 0.0
        return self.sim.state()

    # -- readouts and files ----------------------------------------------------------------------

    def readout(self) -> dict:
        """What the board looks like now.

        Returns
        -------
        dict
            ``time_s``, ``n_dots``, ``interior_fraction`` and ``mean_neighbours``
            (`qdots.analysis.packing_summary`), ``psi6_global`` and
            ``psi6_local`` (`qdots.analysis.structure.hexatic_order`), ``max_overlap``,
            ``pending`` (queued dots) and ``speed`` (x real time). Measures
            of an empty board are nan.
        """
        state = self.sim.state()
        summary = packing_summary(state)
        hexatic = hexatic_order(state)
        return {"time_s": state.time, "n_dots": state.n_dots, "interior_fraction": summary["interior_fraction"],
                "mean_neighbours": summary["mean_neighbours"], "psi6_global": hexatic.global_order,
                "psi6_local": hexatic.local_order, "max_overlap": summary["max_overlap"],
                "pending": self.pending, "speed": self.speed}

    def save(self, path) -> Path:
        """Write a checkpoint (`qdots.save`); ``qdots.load(path)`` resumes it."""
        return checkpoint.save(self.sim, path)

    @property
    def recording(self) -> bool:
        """True while a movie is being recorded."""
        return self._movie is not None

    def record(self, path, every: int | None = None, fps: float = 25, size_px: int = 600) -> None:
        """Start recording an MP4 movie (`qdots.render.MovieWriter`), a frame every ``every`` steps.

        Default ``every``: `frame_steps`. Stop with `stop_recording`.
        """
        if self._movie is not None:
            raise InputError(f"already recording to {self._movie.path}; stop that first")
        from ..render import MovieWriter

        movie = MovieWriter(path, every=self.frame_steps if every is None else every, fps=fps, size_px=size_px)
        self._movie = self.sim.attach(movie)

    def stop_recording(self) -> Path | None:
        """Finish the movie; returns its path (None if nothing was recording)."""
        movie, self._movie = self._movie, None
        if movie is None:
            return None
        self.sim.detach(movie)
        return movie.close()

    def __repr__(self) -> str:
        return f"LiveRun({self.sim!r}, knobs={self.knobs}, pending={self.pending})"

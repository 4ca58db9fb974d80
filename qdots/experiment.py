"""`Experiment`: one whole thesis-style run (board, deposition, forces, engine) as plain data.

>>> from qdots.experiment import Experiment, run_experiment
>>> exp = Experiment(name="demo").quick(0.05)
>>> sim = run_experiment(exp)            # doctest: +SKIP

An experiment is frozen, validated on construction (messages name the key,
e.g. ``deposition.sigma``, and the allowed range), saved and loaded as TOML by
`qdots.io.experiment_file`, and reproducible: the same experiment gives a
bit-identical board.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, ClassVar

import numpy as np

from labrig.params import Param, check_fields
from labrig.validate import MAX_SEED, InputError, real

from .deposition import GAP, MASS_MODELS, MAX_INTERVAL, MAX_MASS_EXPONENT, deposit, deposit_around_centre, ring_radius
from .engine import Chipmunk, Settings
from .forces import Force, ThermalKicks, VanDerWaals, force_from_dict
from .limits import SIGMA
from .placement import MAX_TRIES
from .restitution import Restitution
from .scene import MAX_DOTS, MAX_LENGTH, MAX_MASS, MIN_DIAMETER, Scene
from .simulation import MAX_STEPS, Simulation

#: Deposition protocols: dots at random in the board (or grating channel), or on a ring around a centre.
PROTOCOLS = ("random", "centre")
#: Longest settling time, s (the thesis settles for 100 s).
MAX_SETTLE = 1e5


def _set(obj, name: str, value) -> None:
    object.__setattr__(obj, name, value)


@dataclass(frozen=True)
class Board:
    """The rectangle the dots live in.

    Parameters
    ----------
    width, height : float
        Size, px (> 0; thesis 600 x 600). The board spans ``[0, width] x [0, height]``.
    closed : bool
        The four edges are hard (elastic) walls (thesis: yes).
    """

    width: float = 600.0
    height: float = 600.0
    closed: bool = True

    #: Declarations of the fields: checks and file comments (`labrig.params`).
    PARAMS: ClassVar[dict[str, Param]] = {
        "width": Param("float", 0.0, MAX_LENGTH, low_open=True, unit="px", doc="board width"),
        "height": Param("float", 0.0, MAX_LENGTH, low_open=True, unit="px", doc="board height"),
        "closed": Param("bool", doc="the four edges are hard walls"),
    }

    def __post_init__(self) -> None:
        check_fields(self, self.PARAMS, "board.")


@dataclass(frozen=True)
class Deposition:
    """How the dots arrive (`qdots.deposition`).

    Parameters
    ----------
    protocol : {"random", "centre"}
        ``"random"``: `deposit` uniformly over the board, or over the grating
        channel when there is one (``runRandomAttraction*``). ``"centre"``:
        `deposit_around_centre` on a growing ring around the centre of the
        first `qdots.CentreGravity` force, else the board centre (``runRandomCenter``).
    n_dots : int
        Dots deposited (>= 0).
    mean_diameter : float
        Mean diameter, px (> 0; thesis 15).
    sigma : float
        Standard deviation of the diameter as a fraction of the mean, [0, 1).
    mass_model : {"equal", "area", "volume", "bimodal", "power"}
        See `qdots.deposition.dot_masses`; "equal" is the thesis's figure default.
    heavy_mass : float
        Mass of the heavy dots of the bimodal model (> 0; thesis 2).
    mass_exponent : float, optional
        ``p`` of the "power" model, masses ``(d / mean)^p``, in [0, 6] (needed by it, unused by the others).
    interval : float
        Simulated time between two dots, s (>= 0; thesis 1, centre runs 0.5).
    settle : float
        Simulated time after the last dot, s (>= 0; thesis 100, centre runs 15).
    max_tries : int
        Consecutive rejected candidates for one dot before the board counts as full (>= 1).
    """

    protocol: str = "random"
    n_dots: int = 300
    mean_diameter: float = 15.0
    sigma: float = 0.0
    mass_model: str = "equal"
    heavy_mass: float = 2.0
    mass_exponent: float | None = None
    interval: float = 1.0
    settle: float = 100.0
    max_tries: int = 10_000

    #: Declarations of the fields: checks and file comments (`labrig.params`).
    PARAMS: ClassVar[dict[str, Param]] = {
        "protocol": Param("str", choices=PROTOCOLS, doc='where the dots arrive ("random": uniformly in the board or '
                                                        'grating channel, "centre": on a ring around the centre)'),
        "n_dots": Param("int", 0, MAX_DOTS, doc="dots deposited"),
        "mean_diameter": Param("float", MIN_DIAMETER, MAX_LENGTH, unit="px", doc="mean dot diameter"),
        "sigma": SIGMA,
        "mass_model": Param("str", choices=MASS_MODELS, doc='dot masses ("equal", ~ d^2 "area", ~ d^3 "volume", '
                                                            'half the dots heavy_mass "bimodal", ~ d^p "power")'),
        "heavy_mass": Param("float", 0.0, MAX_MASS, low_open=True, unit="mean-dot masses",
                            doc="mass of the heavy half of a bimodal board"),
        "mass_exponent": Param("float", 0.0, MAX_MASS_EXPONENT, optional=True, doc="p of the power mass model",
                               unset="none (mass_model 'power' needs it)"),
        "interval": Param("float", 0.0, MAX_INTERVAL, unit="s", doc="simulated time between two dots"),
        "settle": Param("float", 0.0, MAX_SETTLE, unit="s", doc="simulated time after the last dot",
                        rule=f"the whole run at most {MAX_STEPS:,} steps of engine.dt"),
        "max_tries": Param("int", 1, MAX_TRIES, doc="rejected candidates in a row before the board counts as full"),
    }

    def __post_init__(self) -> None:
        check_fields(self, self.PARAMS, "deposition.")
        if self.mass_model == "power" and self.mass_exponent is None:
            raise InputError(f"deposition.mass_exponent must be set ({self.PARAMS['mass_exponent'].bounds()}) for "
                             "mass_model 'power'")


def default_forces() -> tuple[dict, ...]:
    """The thesis's figure runs: van der Waals (thesis proxy) and thermal kicks, no drag or gravity."""
    return (VanDerWaals().to_dict(), ThermalKicks().to_dict())


def _checked_force(k: int, spec) -> Force:
    """``spec`` (a Force, taken as it is, or a ``to_dict()`` table, checked once as it is built) as a Force."""
    if isinstance(spec, Force):
        return spec
    if not isinstance(spec, dict):
        raise InputError(f"forces[{k}] must be a table (dict) with a 'type' key, got {spec!r}")
    try:
        return force_from_dict(dict(spec))
    except (TypeError, ValueError) as exc:
        raise InputError(f"forces[{k}]: {exc}") from None


@dataclass(frozen=True)
class Experiment:
    """One thesis-style run as plain data; `run_experiment` executes it.

    Parameters
    ----------
    name : str
        Label (non-empty).
    seed : int
        Root seed (>= 0). `run_experiment` splits it with
        ``numpy.random.SeedSequence(seed).spawn(2)``: one child for the
        simulation (collisions, thermal noise), one for the deposition.
    board : Board
        Size and walls.
    grating : float
        Width of the grating channel, px: a wall ``(0, g) - (width, g)`` confines
        the dots to ``0 < y < g`` (thesis ``6 d sqrt(3)/2 = 77.94`` px). 0 (or None) = none.
    deposition : Deposition
        How the dots arrive.
    restitution : qdots.Restitution
        Collision rule.
    forces : tuple of dict
        Forces as ``Force.to_dict()`` tables (Force instances are accepted and
        converted); stored in full, every parameter spelled out.
    engine : qdots.Chipmunk or qdots.Event
        The engine and its numerical knobs (time step, sub-steps, ...); default ``qdots.Chipmunk()``.
    """

    name: str = "experiment"
    seed: int = 154
    board: Board = field(default_factory=Board)
    grating: float = 0.0
    deposition: Deposition = field(default_factory=Deposition)
    restitution: Restitution = field(default_factory=Restitution)
    forces: tuple = field(default_factory=default_forces)
    engine: Settings = field(default_factory=Chipmunk)

    #: Declarations of the top-level fields: checks and file comments (`labrig.params`).
    PARAMS: ClassVar[dict[str, Param]] = {
        "name": Param("str", high=1000, doc="label of the run"),
        "seed": Param("int", 0, MAX_SEED, doc="root of the simulation and deposition random streams"),
        "grating": Param("float", 0.0, MAX_LENGTH, unit="px",
                         doc="width of the grating channel (a wall at y = grating keeps the dots in 0 < y < grating)",
                         rule="0 = no grating, else above deposition.mean_diameter and below board.height"),
    }

    def __post_init__(self) -> None:
        if self.grating is None:
            _set(self, "grating", 0.0)
        check_fields(self, self.PARAMS)
        for key, cls in (("board", Board), ("deposition", Deposition), ("restitution", Restitution),
                         ("engine", Settings)):
            if not isinstance(getattr(self, key), cls):
                what = "qdots.Chipmunk or qdots.Event" if key == "engine" else f"{cls.__module__}.{cls.__name__}"
                raise InputError(f"{key} must be a {what}, got {type(getattr(self, key)).__name__}")
        if isinstance(self.forces, (dict, str, Force)) or not hasattr(self.forces, "__iter__"):
            raise InputError(f"forces must be a sequence of force tables, got {self.forces!r}")
        forces = [_checked_force(k, f) for k, f in enumerate(self.forces)]
        _set(self, "forces", tuple(force.to_dict() for force in forces))
        self._check_geometry(forces)

    def __hash__(self) -> int:
        # The force tables are dicts: hash their types only (equal experiments still hash equal).
        return hash((self.name, self.seed, self.board, self.grating, self.deposition, self.restitution,
                     self.engine, tuple(spec["type"] for spec in self.forces)))

    def _check_geometry(self, forces: list[Force]) -> None:
        b, dep = self.board, self.deposition
        steps = (dep.n_dots * dep.interval + dep.settle) / self.engine.dt
        if steps > MAX_STEPS:
            raise InputError(f"deposition.n_dots x deposition.interval + deposition.settle = "
                             f"{dep.n_dots * dep.interval + dep.settle:g} s at engine.dt = {self.engine.dt:g} s is "
                             f"{steps:,.0f} steps, more than the {MAX_STEPS:,} a run may take")
        for k, force in enumerate(forces):
            try:
                force.check_run(self.engine.dt, math.ceil(steps))
                force.check_rule(self.restitution)
            except InputError as exc:
                raise InputError(f"forces[{k}]: {exc}") from None
        if dep.mean_diameter > min(b.width, b.height):
            raise InputError(f"deposition.mean_diameter ({dep.mean_diameter:g} px) must fit in the "
                             f"{b.width:g} x {b.height:g} px board")
        if self.grating:
            if not dep.mean_diameter + 2 * GAP < self.grating < b.height:
                raise InputError(f"grating must be 0 (none) or in (deposition.mean_diameter = "
                                 f"{dep.mean_diameter:g}, board.height = {b.height:g}) px, got {self.grating!r}")
            if dep.protocol == "centre":
                raise InputError("deposition.protocol 'centre' cannot be combined with a grating (use 'random')")
        if dep.protocol == "centre" and dep.n_dots:
            cx, cy = self.centre()
            room = min(cx, cy, b.width - cx, b.height - cy)
            reach = ring_radius(dep.n_dots - 1, dep.mean_diameter, dep.sigma) + dep.mean_diameter / 2
            if reach > room:
                raise InputError(f"deposition.n_dots = {dep.n_dots} needs a deposition ring reaching "
                                 f"{reach:.1f} px from the centre ({cx:g}, {cy:g}), but the board leaves {room:.1f} px")

    def centre(self) -> tuple[float, float]:
        """Centre of the ``"centre"`` protocol: the first CentreGravity's centre, else the board centre, px."""
        for spec in self.forces:
            if spec["type"] == "CentreGravity":
                return float(spec["centre"][0]), float(spec["centre"][1])
        return self.board.width / 2.0, self.board.height / 2.0

    def region(self) -> tuple[float, float, float, float]:
        """Rectangle ``(x0, y0, x1, y1)`` of the ``"random"`` protocol, px: the channel or the board."""
        return (0.0, 0.0, self.board.width, self.grating or self.board.height)

    def scene(self) -> Scene:
        """The empty board: box and grating wall (if any)."""
        segments = np.array([[0.0, self.grating, self.board.width, self.grating]]) if self.grating else None
        return Scene(box=(self.board.width, self.board.height), positions=np.zeros((0, 2)), radii=np.zeros(0),
                     segments=segments, closed=self.board.closed)

    def build_forces(self) -> list[Force]:
        """Fresh Force objects from `forces`."""
        return [force_from_dict(dict(spec)) for spec in self.forces]

    def replace(self, **changes) -> Experiment:
        """A copy with some fields changed, validated again."""
        return dataclasses.replace(self, **changes)

    def quick(self, factor: float = 0.1) -> Experiment:
        """A smaller, faster version of this experiment (for tests and notebooks).

        ``n_dots`` becomes ``max(1, round(n_dots * factor))`` and ``interval``
        and ``settle`` are multiplied by ``factor``. A free film's board shrinks
        by ``sqrt(factor)`` both ways (never below 4 mean diameters), keeping
        the dots per area. A grating channel keeps its width and shortens by
        ``sqrt(factor)`` only, so its dots get sparser by ``sqrt(factor)``: the
        full channel is filled beyond the random-packing jam (0.57 of its
        area) and only takes its dots because they aggregate in the 1 s
        between arrivals. A ``"centre"`` board keeps its size (the ring
        geometry sets it). CentreGravity centres move with the board.

        Parameters
        ----------
        factor : float
            In (0, 1]; 1 returns an equal experiment (renamed).
        """
        factor = real("factor", factor, 0.0, 1.0, low_open=True)
        dep, b = self.deposition, self.board
        n = max(1, round(dep.n_dots * factor)) if dep.n_dots else 0
        dep = dataclasses.replace(dep, n_dots=n, interval=dep.interval * factor, settle=dep.settle * factor)
        floor = 4.0 * dep.mean_diameter
        if dep.protocol == "centre":
            sx = sy = 1.0
        elif self.grating:
            sx, sy = max(math.sqrt(factor), min(1.0, floor / b.width)), 1.0
        else:
            sx = max(math.sqrt(factor), min(1.0, floor / b.width))
            sy = max(math.sqrt(factor), min(1.0, floor / b.height))
        forces = [dict(f, centre=[f["centre"][0] * sx, f["centre"][1] * sy]) if f["type"] == "CentreGravity" else f
                  for f in self.forces]
        return self.replace(name=f"{self.name} (quick x{factor:g})", deposition=dep, forces=tuple(forces),
                            board=dataclasses.replace(b, width=b.width * sx, height=b.height * sy))


def build_simulation(exp: Experiment) -> Simulation:
    """The empty board of ``exp`` as a `Simulation` (forces, engine settings and seed in place), before any dot."""
    if not isinstance(exp, Experiment):
        raise InputError(f"exp must be a qdots.experiment.Experiment, got {type(exp).__name__}")
    sim_seed, _ = np.random.SeedSequence(exp.seed).spawn(2)
    return Simulation(exp.scene(), exp.build_forces(), restitution=exp.restitution, seed=sim_seed, engine=exp.engine)


def populate(sim: Simulation, exp: Experiment, progress: bool = False) -> Simulation:
    """Deposit the dots of ``exp`` on ``sim`` (from `build_simulation`) and let them settle; returns ``sim``."""
    _, deposit_seed = np.random.SeedSequence(exp.seed).spawn(2)
    dep = exp.deposition
    sim.check_run(dep.n_dots * dep.interval + dep.settle)  # the whole deposition, before the first dot
    common: dict[str, Any] = dict(mean_diameter=dep.mean_diameter, sigma=dep.sigma, mass_model=dep.mass_model,
                                  heavy_mass=dep.heavy_mass, mass_exponent=dep.mass_exponent, interval=dep.interval,
                                  max_tries=dep.max_tries,
                                  rng=np.random.default_rng(deposit_seed), progress=progress)
    if dep.protocol == "centre":
        deposit_around_centre(sim, dep.n_dots, exp.centre(), **common)
    else:
        deposit(sim, dep.n_dots, region=exp.region(), **common)
    sim.run(dep.settle, progress=progress)
    return sim


def run_experiment(exp: Experiment, progress: bool = False, writers=()) -> Simulation:
    """Build the empty board, deposit the dots, let them settle; return the simulation.

    Parameters
    ----------
    exp : Experiment
    progress : bool
        Progress bars for the deposition (dots) and the settling (steps).
    writers : sequence of Writer
        Recorders (movie, trajectory) attached to the simulation (`Simulation.attach`, each with its
        own ``every``) before the first dot: they see the deposition and the settling as one run.

    Returns
    -------
    Simulation
        At time ``n_dots * interval + settle`` s (to whole steps). Equal
        experiments give bit-identical boards.
    """
    sim = build_simulation(exp)
    for writer in writers:
        sim.attach(writer)
    return populate(sim, exp, progress)

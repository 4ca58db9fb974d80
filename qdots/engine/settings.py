"""`EngineSettings`: the numerical knobs of a `qdots.Simulation` (none of them physics), validated and bounded."""

from __future__ import annotations

import dataclasses
from dataclasses import asdict, dataclass
from typing import ClassVar

from labrig.params import Param, check_fields
from labrig.validate import InputError

from ..geometry import MAX_SKIN
from ..scene import MAX_LENGTH
from ..units import THESIS_KICK_INTERVAL

#: Fraction of an overlap corrected per sub-step by default. Measured on a dense pack under
#: centre gravity at dt = 1 ms: 10 % leaves 0.60 % worst overlap (5.9 % at 10x gravity), 30 %
#: leaves 0.32 % (1.5 %) at the same cost; 50 % starts to jitter (rms speed x1.7 at 10x gravity).
OVERLAP_CORRECTION = 0.3
#: Time step range, s: the thesis's frame is 0.02 s; below 1e-7 s a second takes ten million steps.
DT_RANGE = (1e-7, 0.1)
#: The thesis's frame, s: its time step (the thermal kicks' interval too).
THESIS_FRAME = THESIS_KICK_INTERVAL
#: Most Chipmunk sub-steps per time step and solver iterations per sub-step.
MAX_SUBSTEPS = 1000
MAX_ITERATIONS = 1000
#: Range of `EngineSettings.overlap_tolerance`, radii.
TOLERANCE_RANGE = (1e-6, 1.0)
#: Largest collision slop, px.
MAX_SLOP = 100.0
#: Most cells of Chipmunk's spatial hash.
MAX_HASH_CELLS = 10_000_000
#: Smallest cell of Chipmunk's spatial hash, px: a dot of the thesis's 15 px then spans 150 x 150 cells (a smaller
#: cell puts each dot in more cells than the hash can index).
MIN_HASH_CELL = 0.1
#: Largest `EngineSettings.near_gap`, px (twice the largest van der Waals range).
MAX_NEAR_GAP = 2000.0
#: Longest interval between passes over the far van der Waals pairs, s.
MAX_FAR_INTERVAL = 1e4
#: The engines: Chipmunk's impulse solver, the thesis's event-driven hard discs.
ENGINES = ("chipmunk", "event")
#: Most collisions the event engine may be allowed in one frame.
MAX_EVENTS = 1_000_000_000
#: Where the Chipmunk engine resolves an impact (`EngineSettings.impacts`).
IMPACTS = ("contact", "overlap")
#: The event engine's default cap on a frame's collisions (`EngineSettings.max_events`).
FRAME_EVENTS = 1_000_000
#: The Java's cap (``maxIterations = 2500``): ``max_events = THESIS_EVENTS`` runs the thesis's loop as it was.
THESIS_EVENTS = 2500
#: Largest gap the event engine keeps between discs at contact, mean radii.
MAX_BUFFER = 1e-2


@dataclass(frozen=True)
class EngineSettings:
    """The numerical knobs of the engine, and which engine.

    Parameters
    ----------
    dt : float
        Time step, s, in `DT_RANGE`: the forces change the velocities once per step, at its start, as the
        thesis's frame did. The default is the thesis's frame, 20 ms (`THESIS_FRAME`), and with it the
        thesis's model: its van der Waals proxy is a velocity change per frame, ``min(a dt/2, sqrt(g a)/2)``,
        whose cap and whose impulses depend on the frame. A shorter step approaches the proxy's continuous
        limit (an acceleration ``a/2``) instead, a different model that binds dots of unequal mass more
        strongly: fig2-6's d^3 film at sigma 15 % kept one aggregate at 2.5 ms (interior fraction 0.74,
        mean speed 4 px/s) where the thesis's 20 ms frame breaks it up (0.44, 26 px/s; the event-driven
        engine 0.45, 27 px/s; seed 154). Contacts are resolved in sub-steps (``overlap_tolerance``)
        whatever the step.
    substeps : int
        Fewest Chipmunk steps per time step, in [1, `MAX_SUBSTEPS`]. More sub-steps resolve contacts
        more finely at proportional cost.
    overlap_tolerance : float, optional
        Largest overlap a contact may make before Chipmunk sees it, as a fraction of the smaller
        radius, in `TOLERANCE_RANGE`. Chipmunk finds a contact only once two discs overlap, so a
        dot closing at ``u`` px/s overlaps by up to ``u h`` in a sub-step ``h``: each step takes as
        many equal sub-steps as the fastest approach that can touch within it needs (at least
        ``substeps``, at most ``max_substeps``; `qdots.stepping`). None: always ``substeps``.
    max_substeps : int
        Most sub-steps a step may take for ``overlap_tolerance``, in [1, `MAX_SUBSTEPS`] (``substeps``
        when that is more). A bound on the cost of a step, reached only by very fast dots, and the
        run warns when a capped step leaves a dot moving more than `qdots.motion.SAFE_TRAVEL` radii
        per sub-step. Very light dots need many: those of a 1000:1 mass mixture under thermal kicks move
        ~600 px/s, a radius of 1.5 px in 2.5 ms (`qdots.hard_cases`).
    iterations : int
        Solver iterations per sub-step, in [1, `MAX_ITERATIONS`] (pymunk's default is 10). Two-body
        impacts are exact with any count; simultaneous impacts of three or more dots converge with
        more: an elastic gas of 100 dots lost up to 1.7e-3 of its energy over 2,000 impacts at 5,
        round-off at 10 and 30 (`tests/test_engine_collisions.py`); set 10 or more where energy
        must be conserved. 5 gives the thesis's films the packing metrics and overlaps of 10,
        ~1.1x faster (``python -m benchmarks --only qdots_knobs fig2_2_realtime``).
    impacts : {"contact", "overlap"}
        Where the Chipmunk engine resolves an impact. ``"contact"`` (default): where the discs met, as the
        thesis's model does: each impact's pair is moved to where the impact at contact leaves it
        (`qdots.engine.contacts`). ``"overlap"``: where Chipmunk finds it, the sub-step's overlap into the
        contact, which leaves every bounced pair ``(1 + e)`` times that overlap too close; with the thesis's
        van der Waals proxy that made films ~10 % hotter and, with masses ~ d^3, more fragmented
        (docs/engines.md): the earlier default.
    collision_slop : float
        Overlap Chipmunk tolerates without correcting, px, in [0, `MAX_SLOP`] (pymunk's default
        0.1 px is 1.3 % of a mean radius, ours 0.01 px).
    collision_bias : float, optional
        Fraction of an overlap left uncorrected after one second (pymunk's meaning), in [0, 1);
        None: correct `OVERLAP_CORRECTION` of the overlap per sub-step. The correction moves
        positions only (pseudo-velocities), not the velocities that carry energy.
    spatial_hash : (float, int), optional
        ``(cell size px, cell count)`` for Chipmunk's spatial hash; None: its bounding-box tree.
    threads : int
        Chipmunk solver threads, 1 or 2; it helps dense piles a little.
    pair_skin : float
        Verlet skin of the van der Waals pair list, px, in [0, `MAX_SKIN`] (`qdots.geometry.VerletPairs`):
        the list is rebuilt when a dot has moved half of it. Exact either way; a larger skin means fewer
        rebuilds and longer lists.
    near_gap : float
        Surface gap, px, in (0, `MAX_NEAR_GAP`], below which van der Waals pairs are pulled every step (wholly
        below ``near_gap / 2``, fading out above); the pull of farther ones (up to the force's range) comes
        every ``far_interval`` (`qdots.VanDerWaals`). Beyond the default 4 px the thesis proxy's pull is
        under 2.5 % of its pull at contact.
    far_interval : float, optional
        Seconds between the passes over the far van der Waals pairs when the step is shorter than the
        thesis's frame, in (0, `MAX_FAR_INTERVAL`]: each gives the far pairs' pull over the interval at
        once, at the start of the step that follows the interval's middle, where the dots were at the
        middle (multiple time stepping, in the impulse form of r-RESPA). None (default): every pair every
        step, as the thesis pulled every pair once per frame.
    tune_allocator : bool
        Raise glibc's allocator thresholds when the simulation is built (`qdots.engine.allocator`): speed
        only, never results.
    kind : {"chipmunk", "event"}
        The engine. ``"chipmunk"`` (default): Chipmunk's impulse solver in sub-steps planned for
        ``overlap_tolerance`` (`qdots.engine.ChipmunkEngine`); it reads every knob above. ``"event"``: the
        thesis's own algorithm, exact hard discs event by event within frames of ``dt`` at whose start the
        forces act (`qdots.engine.EventEngine`); it reads ``dt``, ``max_events``, ``buffer`` and the van der
        Waals pair list's ``pair_skin`` (every van der Waals pair is pulled every frame, as in the thesis).
    max_events : int
        Most collisions the event engine resolves in one frame, in [1, `MAX_EVENTS`]; a frame that reaches
        it leaves the rest of the frame unmoved, as the thesis's loop did, and the run counts it
        (`EventEngine.capped_frames`). Default 1,000,000 (`FRAME_EVENTS`), against the Java's 2,500
        (`THESIS_EVENTS`): a film's frames take ~200-300 collisions, but a cluster's inelastic collapse can
        take far more in one frame (195,311 on the fig2-2 film at sigma 0, seed 159, 0.2 s), and a capped
        frame keeps the velocities the unresolved collisions would have damped, so the next frames' kicks and
        pulls heat the film (at 2,500 that film's mean speed went from 14 to 128 px/s in 5 s and ended with
        82 single dots; at the default it stays at 12 px/s).
    buffer : float
        Gap the event engine keeps between discs at contact, in mean radii, in (0, `MAX_BUFFER`] (the
        thesis: a millionth of the mean radius added to every radius).
    """

    dt: float = THESIS_FRAME
    substeps: int = 1
    overlap_tolerance: float | None = 0.005
    max_substeps: int = 512
    iterations: int = 5
    impacts: str = "contact"
    collision_slop: float = 0.01
    collision_bias: float | None = None
    spatial_hash: tuple[float, int] | None = None
    threads: int = 1
    pair_skin: float = 6.0
    near_gap: float = 4.0
    far_interval: float | None = None
    tune_allocator: bool = True
    kind: str = "chipmunk"
    max_events: int = FRAME_EVENTS
    buffer: float = 1e-6

    #: Declarations of the fields: checks and file comments (`labrig.params`).
    PARAMS: ClassVar[dict[str, Param]] = {
        "dt": Param("float", *DT_RANGE, unit="s", doc="time step"),
        "substeps": Param("int", 1, MAX_SUBSTEPS, doc="fewest Chipmunk steps per time step"),
        "overlap_tolerance": Param("float", *TOLERANCE_RANGE, unit="radii", optional=True,
                                   doc="how far a dot may travel into a contact in one Chipmunk step",
                                   unset="always `substeps`"),
        "max_substeps": Param("int", 1, MAX_SUBSTEPS, doc="most Chipmunk steps per time step for overlap_tolerance"),
        "iterations": Param("int", 1, MAX_ITERATIONS, doc="solver iterations per sub-step"),
        "impacts": Param("str", choices=IMPACTS, doc="where Chipmunk resolves an impact: at contact or overlapped"),
        "collision_slop": Param("float", 0.0, MAX_SLOP, unit="px", doc="overlap left uncorrected"),
        "collision_bias": Param("float", 0.0, 1.0, high_open=True, optional=True,
                                doc="fraction of an overlap left after 1 s",
                                unset=f"{OVERLAP_CORRECTION:.0%} of an overlap corrected per sub-step"),
        "spatial_hash": Param("pair", optional=True, doc="Chipmunk's spatial hash", unset="Chipmunk's bounding-box tree",
                              parts=(Param("float", MIN_HASH_CELL, MAX_LENGTH, unit="px", doc="cell size"),
                                     Param("int", 1, MAX_HASH_CELLS, doc="count"))),
        "threads": Param("int", choices=(1, 2), doc="Chipmunk solver threads"),
        "pair_skin": Param("float", 0.0, MAX_SKIN, unit="px", doc="Verlet skin of the van der Waals pair list"),
        "near_gap": Param("float", 0.0, MAX_NEAR_GAP, low_open=True, unit="px",
                          doc="van der Waals pairs closer than this are pulled every step"),
        "far_interval": Param("float", 0.0, MAX_FAR_INTERVAL, low_open=True, unit="s", optional=True,
                              doc="time between passes over the farther van der Waals pairs",
                              unset="every pair every step"),
        "tune_allocator": Param("bool", doc="raise glibc's allocator thresholds (speed only)"),
        "kind": Param("str", choices=ENGINES, doc="the engine: Chipmunk's solver or the thesis's events"),
        "max_events": Param("int", 1, MAX_EVENTS, doc="most collisions the event engine resolves in a frame"),
        "buffer": Param("float", 0.0, MAX_BUFFER, low_open=True, unit="mean radii",
                        doc="gap the event engine keeps between discs at contact"),
    }

    def __post_init__(self) -> None:
        check_fields(self, self.PARAMS)

    @property
    def bias(self) -> float:
        """pymunk's collision_bias at ``substeps`` sub-steps per step (`bias_for`)."""
        return self.bias_for(self.dt / self.substeps)

    def bias_for(self, substep: float) -> float:
        """pymunk's collision_bias for a sub-step of ``substep`` s: given, or `OVERLAP_CORRECTION` per sub-step."""
        if self.collision_bias is not None:
            return float(self.collision_bias)
        return (1.0 - OVERLAP_CORRECTION) ** (1.0 / substep)

    def replace(self, **changes) -> "EngineSettings":
        """A copy with some settings changed, validated again."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict:
        """Plain-data form (JSON/TOML friendly)."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}

    @classmethod
    def from_dict(cls, data) -> "EngineSettings":
        """The settings of a `to_dict` table; `InputError` on an unknown key or a bad value."""
        if not isinstance(data, dict):
            raise InputError(f"engine settings must be a table, got {data!r}")
        names = [f.name for f in dataclasses.fields(cls)]
        unknown = [key for key in data if key not in names]
        if unknown:
            raise InputError(f"unknown engine setting {unknown[0]!r} (known: {', '.join(names)})")
        return cls(**data)

"""`Chipmunk`: the settings of the Chipmunk engine (pymunk's impulse solver in planned sub-steps), the default.

The engine itself is `qdots.engine.chipmunk_backend.ChipmunkBackend`, which `Chipmunk.build` makes. What each
knob costs and changes, as measured: docs/engines.md and docs/performance.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from labrig.params import Param

from ..limits import MAX_LENGTH
from .pair_scheme import PairScheme
from .settings import DT, THESIS_FRAME, TUNE_ALLOCATOR, Settings

#: Fraction of an overlap corrected per sub-step by default (`Chipmunk.collision_bias`): 30 % leaves half the
#: worst overlap of 10 % at the same cost; 50 % starts to jitter (docs/engines.md).
OVERLAP_CORRECTION = 0.3
#: Most Chipmunk sub-steps per time step and solver iterations per sub-step.
MAX_SUBSTEPS = 1000
MAX_ITERATIONS = 1000
#: Range of `Chipmunk.overlap_tolerance`, radii.
TOLERANCE_RANGE = (1e-6, 1.0)
#: Largest collision slop, px.
MAX_SLOP = 100.0
#: Most cells of Chipmunk's spatial hash.
MAX_HASH_CELLS = 10_000_000
#: Smallest cell of Chipmunk's spatial hash, px: a dot of the thesis's 15 px then spans 150 x 150 cells (a smaller
#: cell puts each dot in more cells than the hash can index).
MIN_HASH_CELL = 0.1
#: Where the Chipmunk engine resolves an impact (`Chipmunk.impacts`).
IMPACTS = ("contact", "overlap")


@dataclass(frozen=True)
class Chipmunk(Settings):
    """The Chipmunk engine and its numerical knobs (none of them physics).

    Chipmunk's impulse solver (pymunk) moves the dots in sub-steps planned so that no dot travels more than
    ``overlap_tolerance`` radii into a contact within one (`qdots.engine.chipmunk_step`), and the collision rule
    runs in Chipmunk's contact callbacks (`qdots.engine.contacts`).

    Parameters
    ----------
    dt : float
        Time step, s, in `qdots.engine.settings.DT_RANGE`: the forces change the velocities once per step, at its
        start, as the thesis's frame did. The default is the thesis's frame, 20 ms, and with it the thesis's model:
        its van der Waals proxy is a velocity change per frame whose cap and impulses depend on the frame. A
        shorter step approaches the proxy's continuous limit, a different model (docs/engines.md).
    substeps : int
        Fewest Chipmunk steps per time step, in [1, `MAX_SUBSTEPS`]. More sub-steps resolve contacts more finely
        at proportional cost.
    overlap_tolerance : float, optional
        Largest overlap a contact may make before Chipmunk sees it, as a fraction of the smaller radius, in
        `TOLERANCE_RANGE`. Chipmunk finds a contact only once two discs overlap, so a dot closing at ``u`` px/s
        overlaps by up to ``u h`` in a sub-step ``h``: each step takes as many equal sub-steps as the fastest
        approach that can touch within it needs (at least ``substeps``, at most ``max_substeps``). None: always
        ``substeps``.
    max_substeps : int
        Most sub-steps a step may take for ``overlap_tolerance``, in [1, `MAX_SUBSTEPS`] (``substeps`` when that
        is more): a bound on the cost of a step, reached only by very fast dots; the run warns when a capped
        step leaves a dot moving more than `qdots.motion.SAFE_TRAVEL` radii per sub-step.
    iterations : int
        Solver iterations per sub-step, in [1, `MAX_ITERATIONS`] (pymunk's default is 10). Two-body impacts are
        exact with any count; simultaneous impacts of three or more dots converge with more: set 10 or more
        where energy must be conserved (the default 5 gives the thesis's films the metrics of 10, faster).
    impacts : {"contact", "overlap"}
        Where an impact is resolved. ``"contact"`` (default): where the discs met, as the thesis's model does:
        each impact's pair is moved to where the impact at contact leaves it. ``"overlap"``: where Chipmunk finds
        it, the sub-step's overlap into the contact, which leaves every bounced pair ``(1 + e)`` times that
        overlap too close (the default until 0.3; it makes films hotter, docs/engines.md).
    collision_slop : float
        Overlap Chipmunk tolerates without correcting, px, in [0, `MAX_SLOP`] (pymunk's default 0.1 px is 1.3 %
        of a mean radius, ours 0.01 px).
    collision_bias : float, optional
        Fraction of an overlap left uncorrected after one second (pymunk's meaning), in [0, 1); None: correct
        `OVERLAP_CORRECTION` of the overlap per sub-step. The correction moves positions only (pseudo-velocities),
        not the velocities that carry energy.
    spatial_hash : (float, int), optional
        ``(cell size px, cell count)`` for Chipmunk's spatial hash; None: its bounding-box tree.
    threads : int
        Chipmunk solver threads, 1 or 2.
    pair_skin, near_gap, far_interval
        The pair forces' scheme in time (`pairs`, `qdots.engine.PairScheme`): the pair list's skin, px; the gap
        below which pairs are pulled every step, px; the seconds between passes over the far pairs (None,
        the default: every pair every step, as the thesis).
    tune_allocator : bool
        Raise glibc's allocator thresholds when the simulation is built (`qdots.engine.allocator`): speed only,
        never results.
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

    kind: ClassVar[str] = "chipmunk"
    PARAMS: ClassVar[dict[str, Param]] = {
        "dt": DT,
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
        **PairScheme.PARAMS,
        "tune_allocator": TUNE_ALLOCATOR,
    }
    SAVED: ClassVar[tuple[str, ...]] = ("dt", "substeps", "iterations", "collision_slop", "collision_bias",
                                        "spatial_hash", "threads")

    @property
    def pairs(self) -> PairScheme:
        """The pair forces' scheme: the pair list's skin and the multiple time stepping of the far pairs."""
        return PairScheme(self.pair_skin, self.near_gap, self.far_interval)

    @property
    def bias(self) -> float:
        """pymunk's collision_bias at ``substeps`` sub-steps per step (`bias_for`)."""
        return self.bias_for(self.dt / self.substeps)

    def bias_for(self, substep: float) -> float:
        """pymunk's collision_bias for a sub-step of ``substep`` s: given, or `OVERLAP_CORRECTION` per sub-step."""
        if self.collision_bias is not None:
            return float(self.collision_bias)
        return (1.0 - OVERLAP_CORRECTION) ** (1.0 / substep)

    def build(self, walls, restitution, key, positions, velocities, radii, masses):
        from .chipmunk_backend import ChipmunkBackend

        return ChipmunkBackend(self, walls, restitution, key, positions, velocities, radii, masses)

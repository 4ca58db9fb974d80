"""Hard cases of the engine: the scenes it must survive (stability, lost or escaped dots, overlap), and their check.

The same scenes are asserted by the test suite and timed by ``python -m benchmarks.qdots_hard_cases``;
this module builds them and checks a run of each (`check`). Each case is sampled every `SAMPLE` seconds of its run. A case passes
when every sample is finite, no dot left the box or crossed a wall segment (its side of every
grating line is unchanged), no dot is swallowed by another (centre distance below the larger
radius minus the smaller), and overlap stays within the documented tolerances:

* *settled* (the last 40 % of the samples): below `SETTLED_TOLERANCE` (5 % of the pair's mean
  radius; half the overlap at which a run warns, `qdots.simulation.OVERLAP_WARNING`);
* *transient* (any sample): below `qdots.simulation.OVERLAP_WARNING` (10 %) when the sub-steps
  adapt to the approach speeds (``overlap_tolerance``, the default). With fixed sub-steps
  (``overlap_tolerance=None``) Chipmunk, which sees a contact only once the discs overlap, can let
  an impact at normal speed v overlap by v dt / substeps before it is resolved, so the bound is
  10 % plus ``impact_speed * dt / substeps / r``; ``impact_speed`` is each case's bound on the
  normal approach speed, from its physics (stated where the case is built).

Overlap is (r_i + r_j - d) / ((r_i + r_j) / 2), as in `qdots.analysis.overlaps` (r: the mean
radius; `qdots.geometry.worst_overlap`); dot-wall overlap is (r - distance to the segment) / r
(`qdots.geometry.worst_wall_overlap`).

Cases marked *known failure* are limits measured here and documented, not hidden: the tests
expect them to fail (strict xfail), so a fix shows up as an unexpected pass. Two are kept: what
fixed sub-steps do, and a 1000:1 mass mixture under centre gravity (not a thesis scene) at the
default step, the thesis's 20 ms frame, which passes at 5 ms. Every other case passes at the
defaults; samples are taken at least one time step apart.

"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from labrig.validate import InputError, choice, count, real

from ..engine import Chipmunk
from ..forces import CentreGravity, Drag, Gravity, ThermalKicks, VanDerWaals
from ..geometry import DiscTree, nested_pairs, worst_overlap, worst_wall_overlap
from ..restitution import Restitution
from ..scene import MAX_DOTS, Scene, grating_segments
from ..simulation import OVERLAP_WARNING, Simulation
from ..units import thesis_kick_speed

#: Simulated time between samples, s.
SAMPLE = 0.05
#: Largest settled overlap a case may keep, in mean radii of the pair.
SETTLED_TOLERANCE = 0.05
#: Most samples of one case (each a pair search and a dot-wall distance table; the cases take 20-250).
MAX_SAMPLES = 100_000
#: Sites of `centre_pack`'s 25 px grid on its 600 px board: the most dots it places.
CENTRE_PACK_SITES = 23 * 23


@dataclass(frozen=True)
class HardCase:
    """A scene, its forces, collision rule and engine settings, how long to run it (s, sampled every ``sample``
    s: at most `MAX_SAMPLES` samples), and whether it is a known failure."""

    name: str
    build: Callable[[], tuple[Scene, list]]
    seconds: float
    impact_speed: float
    settings: dict = field(default_factory=dict)
    restitution: Restitution = field(default_factory=Restitution)
    slow: bool = False
    sample: float = SAMPLE
    known_failure: str = ""

    def __post_init__(self) -> None:
        real("seconds", self.seconds, 0.0, low_open=True, unit="s")
        real("sample", self.sample, 0.0, low_open=True, unit="s")
        samples = self.seconds / self.sample
        if samples > MAX_SAMPLES:
            raise InputError(f"sample = {self.sample:g} s takes {samples:.3g} samples of a {self.seconds:g} s run, "
                             f"more than the {MAX_SAMPLES:,} allowed")


def _channels(positions: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """For each dot, how many grating lines (horizontal segments) lie below its centre."""
    return (positions[:, 1][:, None] > segments[:, 1][None, :]).sum(axis=1)


def grating_corners(gravity: float) -> Callable:
    """Dots in three rows per 75 px grating channel, pushed into the channels' lower-left corners."""
    def build():
        box = (300.0, 300.0)
        positions = [(x, y0 + dy) for y0 in (0, 75, 150, 225) for x in np.arange(15.0, 290.0, 17.0)
                     for dy in (15.0, 35.0, 55.0)]
        scene = Scene(box=box, positions=positions, radii=np.full(len(positions), 7.0),
                            segments=grating_segments(box, 75.0))
        g = 750.0 * gravity
        return scene, [Gravity((-g, -g)), VanDerWaals(), ThermalKicks()]
    return build


def centre_pack(gravity: float, n: int = 400) -> Callable:
    """``n`` (at most `CENTRE_PACK_SITES`) polydisperse dots (radii N(7.5, 0.75)) pulled to the centre at
    ``gravity`` x 750 px/s^2."""
    n = count("n", n, 0, CENTRE_PACK_SITES)

    def build():
        rng = np.random.default_rng(0)
        grid = np.array([(x, y) for x in range(20, 585, 25) for y in range(20, 585, 25)], float)
        scene = Scene(box=(600.0, 600.0), positions=grid[rng.permutation(len(grid))[:n]],
                            radii=rng.normal(7.5, 0.75, n).clip(5, 9.5))
        return scene, [CentreGravity((300.0, 300.0), 750.0 * gravity), VanDerWaals(),
                       ThermalKicks(), Drag(1.0, 0.01)]
    return build


def mixture(masses: str, centre_gravity: float = 0.0) -> Callable:
    """60 dots of radius 15 px and 500 of 1.5 px (size ratio 10), vdW + kicks (+ centre gravity)."""
    choice("masses", masses, ("equal", "volume"))

    def build():
        rng = np.random.default_rng(0)
        positions, radii, placed = [], [], DiscTree(np.zeros((0, 2)), np.zeros(0))
        for p in rng.uniform(30, 570, (5000, 2)):
            r = 15.0 if len(positions) < 60 else 1.5
            if placed.clashing_partners(p, [r], 0.5)[0] < 0:  # at least 0.5 px from every dot placed
                positions.append(p)
                radii.append(r)
                placed = DiscTree(positions, radii)
            if len(positions) == 560:
                break
        radii = np.array(radii)
        m = {"equal": np.ones(len(radii)), "volume": (radii / 7.5) ** 3}[masses]
        scene = Scene(box=(600.0, 600.0), positions=positions, radii=radii, masses=m)
        forces = [VanDerWaals(), ThermalKicks()]
        if centre_gravity:
            forces += [CentreGravity((300.0, 300.0), 750.0 * centre_gravity), Drag(1.0, 0.01)]
        return scene, forces
    return build


def falling_gas() -> Callable:
    """400 dots at 100 px/s rms in a 420 px box under the thesis's gravity (the cases set the restitution)."""
    def build():
        rng = np.random.default_rng(1)
        ij = np.argwhere(np.ones((20, 20))).astype(float)
        scene = Scene(box=(420.0, 420.0), positions=20 + 19 * ij + rng.uniform(-1, 1, (400, 2)),
                      radii=np.full(400, 7.5), velocities=rng.normal(0, 100 / math.sqrt(2), (400, 2)))
        return scene, [Gravity()]
    return build


def head_on(multiple: float) -> Callable:
    """Two blocks of 200 dots (17 px lattice) flying at each other at ``multiple`` x the thesis kick speed."""
    def build():
        v0 = multiple * float(thesis_kick_speed(1.0))
        block = np.array([(100 + 17 * i, 60 + 17 * k) for i in range(10) for k in range(20)], float)
        positions = np.vstack([block, block + [200, 0]])  # facing rows 32 px apart
        velocities = np.vstack([np.tile([v0, 0.0], (200, 1)), np.tile([-v0, 0.0], (200, 1))])
        return Scene(box=(800.0, 450.0), positions=positions, radii=np.full(400, 7.5),
                           velocities=velocities), []
    return build


def loose_film(n: int) -> Scene:
    """``n`` dots (at most `qdots.scene.MAX_DOTS`) of 7.5 px on a jittered 17 px square lattice, thermal
    velocities (seeded)."""
    n = count("n", n, 0, MAX_DOTS)
    side = int(math.ceil(math.sqrt(n)))
    rng = np.random.default_rng(5)
    ij = np.argwhere(np.ones((side, side)))[:n].astype(float)
    return Scene(box=(17.0 * side + 40,) * 2, positions=20 + 17.0 * ij + rng.uniform(-0.9, 0.9, (n, 2)),
                 radii=np.full(n, 7.5), velocities=rng.normal(0, 10.0, (n, 2)))


def large_film() -> tuple[Scene, list]:
    """30,000 dots on a jittered 17 px lattice, thermal velocities, vdW + kicks + drag."""
    return loose_film(30000), [VanDerWaals(), ThermalKicks(), Drag()]


def fall_speed(acceleration: float, distance: float, quadratic_drag: float = 0.0) -> float:
    """Speed after falling ``distance`` px at ``acceleration`` px/s^2, capped by the terminal speed of the drag."""
    v = math.sqrt(2.0 * acceleration * distance)
    return min(v, math.sqrt(acceleration / quadratic_drag)) if quadratic_drag else v


KICK = float(thesis_kick_speed(1.0))
#: Impact speed bounds: a dot sliding the whole channel (300 px) into the corner; two dots meeting
#: head-on at the centre after falling up to 424 px (drag caps the speed); a gas dot at 3 sigma of
#: its 100 px/s rms speed after falling 420 px, met head-on; the blocks' closing speed.
CASES = [
    HardCase("grating corners, gravity x1 into the corners", grating_corners(1.0), 2.0,
             fall_speed(750 * math.sqrt(2), 300)),
    HardCase("grating corners, gravity x10 into the corners", grating_corners(10.0), 2.0,
             fall_speed(7500 * math.sqrt(2), 300)),
    HardCase("centre gravity x30", centre_pack(30.0), 2.0, 2 * fall_speed(22500, 424, 0.01), slow=True),
    HardCase("centre gravity x100, substeps 2", centre_pack(100.0), 1.5, 2 * fall_speed(75000, 424, 0.01),
             {"substeps": 2}, slow=True),
    HardCase("centre gravity x100, defaults", centre_pack(100.0), 2.0, 2 * fall_speed(75000, 424, 0.01), slow=True),
    HardCase("centre gravity x100, substeps 4", centre_pack(100.0), 1.0, 2 * fall_speed(75000, 424, 0.01),
             {"substeps": 4}, slow=True),
    HardCase("size ratio 10, equal masses, vdW film", mixture("equal"), 3.0, 50.0),
    HardCase("size ratio 10, masses ~ r^3, vdW film, substeps 4", mixture("volume"), 1.5, 50.0, {"substeps": 4}),
    HardCase("size ratio 10, masses ~ r^3, vdW film, defaults", mixture("volume"), 3.0, 50.0, slow=True),
    HardCase("size ratio 10, masses ~ r^3, centre gravity x1, dt 5 ms", mixture("volume", 1.0), 2.0,
             2 * fall_speed(750, 424, 0.01), {"dt": 5e-3}, slow=True),
    # A known failure until impacts were resolved at contact (transient overlap 24 %, settled 5.2 %: the 20 ms
    # frame's gravity reached the 1000x lighter dots as one velocity change that the iterative contact solve spread
    # through the heavy dots only in part); moving each impact's pair to contact holds it at 1.5 %.
    HardCase("size ratio 10, masses ~ r^3, centre gravity x1, defaults", mixture("volume", 1.0), 2.0,
             2 * fall_speed(750, 424, 0.01), slow=True),
    HardCase("elasticity 0.02, falling gas", falling_gas(), 2.5, 2 * math.hypot(300, fall_speed(750, 420)),
             restitution=Restitution(mean=0.02)),
    HardCase("elasticity 0.98, falling gas", falling_gas(), 2.5, 2 * math.hypot(300, fall_speed(750, 420)),
             restitution=Restitution(mean=0.98)),
    HardCase("head-on at 100x thermal speed (188 px/s)", head_on(100), 0.5, 200 * KICK, sample=0.002),
    HardCase("head-on at 1000x thermal speed (1,876 px/s), substeps 8", head_on(1000), 0.1, 2000 * KICK,
             {"substeps": 8}, sample=0.002),
    HardCase("head-on at 3000x thermal speed (5,628 px/s), defaults", head_on(3000), 0.1, 6000 * KICK, sample=0.002),
    HardCase("head-on at 3000x thermal speed (5,628 px/s), fixed sub-steps", head_on(3000), 0.1, 6000 * KICK,
             {"overlap_tolerance": None}, slow=True, sample=0.002,
             known_failure="no continuous collision detection: at a fixed sub-step a dot travels 113 px (15 r) per "
                           "20 ms step and passes through walls (measured); the run warns "
                           "(`qdots.simulation.SAFE_TRAVEL`). The default, sub-steps that adapt to approach speeds "
                           "(`overlap_tolerance`), passes"),
    HardCase("30,000 dots, vdW + kicks + drag, 10^3 steps", large_film, 1.0, 100.0, slow=True),
]


def check(case: HardCase) -> dict:
    """Run ``case``; everything the tests assert, with the wall time."""
    scene, forces = case.build()
    sim = Simulation(scene, forces, restitution=case.restitution, seed=1, **case.settings)
    segments = scene.segments
    assert segments is not None  # Scene.__post_init__ replaces the default None by an array
    walls, channels = scene.wall_segments(), _channels(scene.positions, segments)
    samples = max(1, round(case.seconds / max(case.sample, sim.dt)))  # each sample at least one step
    sim.check_run(samples * round(case.seconds / samples / sim.dt) * sim.dt)  # the whole case, as one run
    pair, wall, finite, lost, crossed, wall_time = [], [], True, False, False, 0.0
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", RuntimeWarning)
        for _ in range(samples):
            start = time.perf_counter()
            try:
                sim.run(case.seconds / samples)
            except FloatingPointError:
                finite = False
                break
            finally:
                wall_time += time.perf_counter() - start
            s = sim.state()
            swallowed = len(nested_pairs(s.positions, s.radii)[0]) > 0
            pair.append(worst_overlap(s.positions, s.radii)[0])
            wall.append(worst_wall_overlap(s.positions, s.radii, walls)[0])
            outside = (s.positions < 0).any() or (s.positions > np.array(s.box)).any()
            lost = lost or swallowed or bool(outside) or sim.n_dots != scene.n_dots
            crossed = crossed or not np.array_equal(_channels(s.positions, segments), channels)
    settled = slice(int(0.6 * samples), None)
    engine = sim.engine
    assert isinstance(engine, Chipmunk)  # no case's settings name another engine
    adaptive = engine.overlap_tolerance is not None
    step = 0.0 if adaptive else sim.dt / engine.substeps
    return {"case": case.name, "dots": sim.n_dots, "steps": sim.steps_taken, "wall_s": wall_time,
            "finite": finite, "lost": lost, "crossed": crossed,
            "warned": any("per sub-step" in str(w.message) for w in caught),
            "overlap": max(pair + wall, default=math.inf), "settled": max(pair[settled] + wall[settled], default=math.inf),
            "transient_tolerance": OVERLAP_WARNING + case.impact_speed * step / float(scene.radii.min()),
            "settled_tolerance": SETTLED_TOLERANCE}


def passed(result: dict) -> bool:
    return (result["finite"] and not result["lost"] and not result["crossed"]
            and result["settled"] < result["settled_tolerance"] and result["overlap"] < result["transient_tolerance"])



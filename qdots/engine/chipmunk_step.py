"""One time step of the Chipmunk engine (`qdots.engine.Chipmunk`): the force phase, the sub-step plan, Chipmunk's steps.

Order within a step of length ``dt`` (the thesis's: "acceleration, either from attraction or thermal
motion, is added only at the beginning of each time step as a change in velocity"):

1. Read every dot's position and velocity in one bulk call.
2. Let every force add its velocity change, evaluated where the dots are, and add it to the dots'
   velocities at once. A kick or a pull that drives a dot into a neighbour it touches is then an impact
   that Chipmunk resolves with the collision rule's restitution (`qdots.engine.contacts`). (Until 0.3 the
   change was handed to Chipmunk as a body force within the first sub-step, after its contacts had taken
   their velocities: every such kick or pull was absorbed, perfectly inelastically, which made the films of
   unequal masses colder and more cohesive than the thesis's model; the numbers: docs/engines.md.)
3. Plan the sub-steps (`substep_count`): Chipmunk sees a contact only once two discs overlap, so a
   dot closing on another (or on a wall) at speed ``u`` can overlap by up to ``u h`` in a sub-step
   ``h``. The step is split into the fewest equal sub-steps that keep that below
   ``overlap_tolerance`` times the smaller radius, for every pair that can touch within the step.
   Pairs already in contact count too (a contact solve that did not converge leaves an approach
   speed). A sub-step may grow at most `SUBSTEP_GROWTH` times from one step to the next, because
   Chipmunk re-applies the last sub-step's contact impulses scaled by the ratio of the sub-steps
   (after a fast impact at a short sub-step, a long one would inject energy).
4. Advance Chipmunk by the planned sub-steps.
"""

from __future__ import annotations

import math
from time import perf_counter

import numpy as np

from labrig.compiled import jit

from ..forces.base import StepContext
from ..geometry import VerletPairs, pair_separation
from ..restitution import Restitution
from .bodies import BodyArrays
from .chipmunk import Chipmunk
from .pymunk_adapter import advance, set_last_substep

#: Largest factor by which the sub-step may grow from one step to the next.
SUBSTEP_GROWTH = 2
#: Verlet skin of the pair list the plan reads, px.
PLAN_SKIN = 3.0


@jit
def fastest_speed(vx, vy):
    """The largest dot speed, px/s (inf when a velocity is not finite)."""
    fastest = 0.0
    for a in range(vx.size):
        s0 = vx[a] * vx[a] + vy[a] * vy[a]
        if not s0 < math.inf:  # NaN or inf: no sub-step plan can hold it
            return math.inf
        fastest = max(fastest, s0)
    return math.sqrt(fastest)


@jit
def closing_travel(x, y, vx, vy, i, j, radii, walls, dt, fastest):
    """The largest distance a dot can travel into a contact within ``dt``, in units of the smaller radius.

    A pair (or a dot and a wall segment) counts when it can touch within ``dt``: closing at speed
    ``u`` across a gap ``g`` with ``u dt > g``; its travel is ``u dt / r_min`` (every pair, contacts
    included, at the velocities the forces left).

    Parameters
    ----------
    x, y, vx, vy : ndarray, shape (N,)
        Positions (px) and velocities (px/s).
    i, j : ndarray of int, shape (P,)
        Candidate pairs: every pair that can touch within ``dt`` must be among them.
    radii : ndarray, shape (N,)
    walls : ndarray, shape (M, 4)
        Static segments ``(x0, y0, x1, y1)``, px.
    dt : float
        Step length, s.
    fastest : float
        `fastest_speed`, px/s: pairs farther apart than ``2 fastest dt`` and dots farther than
        ``fastest dt`` from a wall cannot touch within ``dt`` and are skipped.

    Returns
    -------
    float
        The largest travel, radii (0 when nothing can touch).
    """
    travel = 0.0
    close = 2.0 * fastest * dt  # no pair or wall farther apart than this can touch within dt
    for k in range(i.size):
        a = i[k]
        b = j[k]
        dx, dy, d2, contact = pair_separation(x, y, radii, a, b)
        if d2 >= (contact + close) ** 2 or d2 <= 0.0:
            continue
        d = math.sqrt(d2)
        gap = d - contact
        u = ((vx[a] - vx[b]) * dx + (vy[a] - vy[b]) * dy) / d
        if u * dt > gap:
            travel = max(travel, u * dt / min(radii[a], radii[b]))
    for w in range(walls.shape[0]):
        x0 = walls[w, 0]
        y0 = walls[w, 1]
        ex = walls[w, 2] - x0
        ey = walls[w, 3] - y0
        inv_length2 = 1.0 / (ex * ex + ey * ey)
        left = min(x0, x0 + ex) - 0.5 * close  # the segment's box, widened by the closing distance
        right = max(x0, x0 + ex) + 0.5 * close
        bottom = min(y0, y0 + ey) - 0.5 * close
        top = max(y0, y0 + ey) + 0.5 * close
        for a in range(x.size):
            r = radii[a]
            if x[a] + r <= left or x[a] - r >= right or y[a] + r <= bottom or y[a] - r >= top:
                continue  # too far from the segment to touch it within dt
            t = min(max(((x[a] - x0) * ex + (y[a] - y0) * ey) * inv_length2, 0.0), 1.0)
            nx = x[a] - x0 - t * ex
            ny = y[a] - y0 - t * ey
            d2 = nx * nx + ny * ny
            if d2 >= (radii[a] + 0.5 * close) ** 2 or d2 <= 0.0:
                continue
            d = math.sqrt(d2)
            gap = d - radii[a]
            u = -(vx[a] * nx + vy[a] * ny) / d
            if u * dt > gap:
                travel = max(travel, u * dt / radii[a])
    return travel


@jit
def prepare(rows, x, y, vx, vy, dv):
    """Positions and velocities from pymunk's bulk rows ``(x, y, vx, vy)``, and ``dv`` zeroed."""
    for a in range(x.size):
        x[a] = rows[a, 0]
        y[a] = rows[a, 1]
        vx[a] = rows[a, 2]
        vy[a] = rows[a, 3]
        dv[a, 0] = 0.0
        dv[a, 1] = 0.0


@jit
def add_velocity_change(vx, vy, dv):
    """``vx, vy += dv`` in place."""
    for a in range(vx.size):
        vx[a] += dv[a, 0]
        vy[a] += dv[a, 1]


def substep_count(travel: float, settings: Chipmunk, previous: int) -> int:
    """The sub-steps of the next step: enough for ``travel`` (radii) to stay within the tolerance.

    At least ``settings.substeps`` and ``previous / SUBSTEP_GROWTH``; at most ``settings.max_substeps`` (or
    ``settings.substeps`` when that is more), even when ``travel`` needs more.
    """
    tolerance = settings.overlap_tolerance
    assert tolerance is not None  # sub-steps are planned only with an overlap tolerance
    need = math.ceil(travel / tolerance) if travel > tolerance else 1
    most = max(settings.max_substeps, settings.substeps)
    return int(min(max(need, settings.substeps, math.ceil(previous / SUBSTEP_GROWTH)), most))


def plan_reach(fastest: float, dt: float, radius: float) -> float:
    """How far apart (surface to surface, px) the plan's pairs may be: ``radius`` times a power of two, at
    least the distance two dots at ``fastest`` px/s close in ``dt`` (so the pair list is rebuilt only
    when the fastest speed doubles)."""
    need = 2.0 * fastest * dt
    return radius * 2.0 ** max(0, math.ceil(math.log2(need / radius))) if need > radius else radius


class Stepper:
    """The per-step machinery of a simulation's dots: buffers, the plan's pair list, the force phase, and
    each force's per-run cache.

    Rebuilt whenever the space or the set of dots changes (it holds pymunk's body rows), which empties the
    forces' caches (`StepContext.cache`).

    Parameters
    ----------
    space : pymunk.Space
    bodies : list of pymunk.Body
        The dots, in the order of ``radii`` and ``masses``.
    radii, masses : ndarray, shape (N,)
    walls : ndarray, shape (M, 4)
        Static segments (box edges included when the board is closed), px.
    settings : qdots.engine.Chipmunk
        The engine's knobs (`settings` takes new ones between runs).
    record : qdots.engine.contacts.CollisionRecord, optional
        The collision callbacks' record, told each sub-step's length before Chipmunk steps.
    """

    def __init__(self, space, bodies, radii: np.ndarray, masses: np.ndarray, walls: np.ndarray, settings: Chipmunk,
                 record=None):
        self.settings = settings
        self.space = space
        self.record = record
        self.io = BodyArrays(space, bodies)
        n = len(bodies)
        self.radii, self.masses = radii, masses
        self.walls = np.ascontiguousarray(walls, dtype=float).reshape(-1, 4)
        self.x, self.y, self.vx, self.vy = (np.zeros(n) for _ in range(4))
        self.dv = np.zeros((n, 2))
        self._context = StepContext(time=0.0, dt=0.0, x=self.x, y=self.y, velocity=np.zeros((n, 2)), radii=radii,
                                    masses=masses, rng=None, dv=self.dv, pairs=settings.pairs, restitution=None,
                                    cache={})
        #: Each force's per-run cache, by its place in the forces' sequence (`forget_forces` empties them).
        self.caches: dict[int, dict] = {}
        #: Largest radius, px: the plan's pairs are those closer than twice it plus `reach`.
        self.largest = float(radii.max(initial=0.0))
        #: Smallest radius, px: no dot slower than ``overlap_tolerance * smallest / (2 dt)`` px/s can travel
        #: more than the tolerance into a contact within a step, so the plan needs no pairs then.
        self.smallest = float(radii.min()) if radii.size else 0.0
        #: Surfaces closer than this are in the plan's pair list, px (`plan_reach`).
        self.reach = self.largest
        self.pairs = VerletPairs(PLAN_SKIN)
        self.previous = 0  # sub-steps of the last step (0: none yet, no warm start to protect)
        #: Largest travel into a contact per sub-step (radii) in a step whose sub-steps hit
        #: ``max_substeps``, since the last `take_capped_travel`.
        self.capped_travel = 0.0
        self._bias_h: float | None = None

    @property
    def settings(self) -> Chipmunk:
        """The engine's knobs; assign new ones between runs."""
        return self._settings

    @settings.setter
    def settings(self, settings: Chipmunk) -> None:
        self._settings = settings
        self._pairs = settings.pairs

    def forget_forces(self) -> None:
        """Empty the forces' caches (the forces changed)."""
        self.caches = {}

    def step(self, forces, restitution: Restitution, time: float, rng: np.random.Generator, timings: dict) -> int:
        """Advance one time step of ``settings.dt`` from ``time``; returns the Chipmunk sub-steps taken.

        Adds the wall time of the force phase and of Chipmunk's steps to ``timings["forces"]`` and
        ``timings["pymunk"]``.
        """
        start = perf_counter()
        settings = self._settings
        dt = settings.dt
        adaptive = settings.overlap_tolerance is not None
        n = self.x.size
        k = settings.substeps
        if n and (forces or adaptive):
            rows = self.io.read_rows()
            if adaptive:  # the fewest sub-steps this step may take (the plan below may add more)
                k = max(k, math.ceil(self.previous / SUBSTEP_GROWTH))
            prepare(rows, self.x, self.y, self.vx, self.vy, self.dv)
            if forces:  # a velocity change at the step's start, where the dots are
                ctx = self._context
                ctx.time, ctx.dt, ctx.velocity, ctx.rng = time, dt, rows[:, 2:], rng
                ctx.pairs, ctx.restitution = self._pairs, restitution
                for index, force in enumerate(forces):
                    ctx.cache = self.caches.setdefault(index, {})
                    force.kick(ctx)
                self.io.add_velocities(self.dv, rows[:, 2:])
                add_velocity_change(self.vx, self.vy, self.dv)
            if adaptive:
                k = self._plan(settings)
        h = dt / k
        if h != self._bias_h:
            self.space.collision_bias = settings.bias_for(h)
            set_last_substep(self.space, h)
            if self.record is not None:
                self.record.substep = h
            self._bias_h = h
        middle = perf_counter()
        advance(self.space, h, k)
        self.previous = k
        timings["forces"] += middle - start
        timings["pymunk"] += perf_counter() - middle
        return k

    def _plan(self, settings: Chipmunk) -> int:
        """Sub-steps for the current velocities (the pair list follows the fastest dot)."""
        assert settings.overlap_tolerance is not None  # sub-steps are planned only with an overlap tolerance
        dt = settings.dt
        fastest = fastest_speed(self.vx, self.vy)
        if fastest == math.inf:  # no plan holds it; the simulation says what ran away
            raise FloatingPointError("a dot's velocity is not finite")
        if 2.0 * fastest * dt <= settings.overlap_tolerance * self.smallest:  # a still board: one sub-step will do
            return substep_count(0.0, settings, self.previous)
        reach = plan_reach(fastest, dt, self.largest)
        if reach > self.reach or reach < self.reach / 4 or not self.pairs.i.size:
            self.reach = reach
        self.pairs.update(self.x, self.y, 2.0 * self.largest + self.reach)
        travel = closing_travel(self.x, self.y, self.vx, self.vy, self.pairs.i, self.pairs.j, self.radii,
                                self.walls, dt, fastest)
        k = substep_count(travel, settings, self.previous)
        if travel / k > settings.overlap_tolerance:
            self.capped_travel = max(self.capped_travel, travel / k)
        return k

    def take_capped_travel(self) -> float:
        """`capped_travel`, reset to 0."""
        travel, self.capped_travel = self.capped_travel, 0.0
        return travel

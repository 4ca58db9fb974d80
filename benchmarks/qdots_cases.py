"""Test problems of the qdots engine with exact or converged answers, each timed as it runs.

Every case takes changes to the Chipmunk settings the benchmarks measure (`benchmarks.pinned.CHIPMUNK`: the thesis's
20 ms frame; `qdots.Chipmunk` keywords, the van der Waals pair list's ``pair_skin``, ``near_gap`` and
``far_interval`` among them) and returns a `Measured`: the error against the exact answer and the wall time per
simulated second of the same run.

* `restitution`: an oblique impact (70 px/s, 9 px offset) from 6-12 start offsets; exact answer:
  the event-driven impact at the exact contact time with the drawn restitution along the exact
  normal. Error: largest |v - v_exact| / |v_rel|.
* `gas_energy`: an elastic gas (restitution 1, no sticking, 50 % area fraction, rms speed 85 px/s);
  exact answer: energy conserved. Error: |E(T) - E(0)| / E(0), mean over 4 seeds with its standard
  error (the loss comes from rare contacts that last more than one step, so it varies ~10x
  between seeds).
* `vdw_pair`: two dots pulled together by the thesis's van der Waals proxy from an 8 px gap to
  0.8 of the frames before they come within 1 px; reference: the thesis's model of those frames (the pull a
  velocity change at each frame's start, straight lines between; `vdw_frames`, a loop of its own). Error:
  largest position difference, px. `vdw_far`: the same from a 20 px gap, a pair that stays beyond the
  engine's ``near_gap`` (its far pass alone, when ``far_interval`` is set).
* `dense_pack`: a polydisperse pack compressed by centre gravity (x1 or x10 the thesis's
  750 px/s^2) with vdW, kicks and drag, settled once at the pinned settings and then run at the given
  settings. Error: worst overlap (r_i + r_j - d) / mean radius of the pair (exact: 0).
* `list_error`: the dense pack and a loose thermal film, the van der Waals velocity change from the
  Verlet pair list against a brute-force pair search at the same instants (exact: equal).
* `split_error`: the same scenes, the van der Waals impulse each dot receives over 0.2 s (far pairs
  pulled once per ``far_interval``, near pairs every step) against every pair pulled at every step
  along the same trajectory (exact: equal).
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass

import numpy as np

import qdots
from qdots.analysis import overlaps
from qdots.diagnostics.hard_cases import loose_film
from qdots.forces import StepContext

from . import pinned

#: The collision rule of the elastic gas: elastic impacts and walls, no sticking.
ELASTIC = qdots.Restitution(mean=1.0, wall=1.0, sticking_speed=0.0)


@dataclass
class Measured:
    """Error against the exact answer and wall seconds per simulated second, from one run.

    ``error_se`` is the standard error of ``error`` when it is a mean over seeds (0: deterministic).
    """

    error: float
    cost: float
    error_se: float = 0.0


def engine(settings: dict) -> qdots.Chipmunk:
    """The pinned Chipmunk settings (`benchmarks.pinned.CHIPMUNK`) with ``settings`` changed."""
    return pinned.chipmunk(**settings)


def timed_run(sim: qdots.Simulation, seconds: float) -> float:
    start = time.perf_counter()
    sim.run(seconds)
    return time.perf_counter() - start


# ---------------------------------------------------------------- isolated oblique impact
def exact_impact(p: np.ndarray, v: np.ndarray, r_sum: float, eps: float, t_end: float) -> np.ndarray:
    """Velocities at ``t_end`` of two equal discs after one frictionless impact of restitution ``eps``."""
    dp, dv = p[1] - p[0], v[1] - v[0]
    a, b, c = dv @ dv, 2 * dp @ dv, dp @ dp - r_sum**2
    t_hit = (-b - math.sqrt(b * b - 4 * a * c)) / (2 * a)
    assert 0 < t_hit < t_end, "the dots must meet during the run"
    n = dp + dv * t_hit
    n /= np.linalg.norm(n)
    j = 0.5 * (1 + eps) * (dv @ n)  # equal masses: each dot's normal velocity changes by this much
    return np.array([v[0] + j * n, v[1] - j * n])


def restitution(settings: dict, quick: bool) -> Measured:
    seed, t_end = 4, 1.2
    worst, wall, simulated = 0.0, 0.0, 0.0
    for shift in np.linspace(0.0, 1.0, 6 if quick else 12):
        scene = qdots.Scene(box=(400, 200), positions=[[170 + shift, 100], [230, 109]], radii=[7.5, 7.5],
                            velocities=[[60.0, 0.0], [-10.0, 0.0]])
        sim = qdots.Simulation(scene, seed=seed, engine=engine(settings))
        exact = exact_impact(scene.positions, scene.velocities, 15.0, sim.collisions.next_elasticity(), t_end)
        wall += timed_run(sim, t_end)
        simulated += sim.time
        if sim.collisions.dot_dot != 1 or sim.collisions.dot_wall:
            raise RuntimeError("the oblique impact case must have exactly one impact and no wall contact")
        worst = max(worst, float(np.abs(sim.state().velocities - exact).max()) / 70.0)
    return Measured(worst, wall / simulated)


# ---------------------------------------------------------------- elastic gas
def elastic_gas(n: int, seed: int, area_fraction: float = 0.5, rms_speed: float = 85.0) -> qdots.Scene:
    """``n`` discs of 7.5 px on a jittered square lattice, Gaussian velocities (run them under `ELASTIC`)."""
    r = 7.5
    side = int(math.ceil(math.sqrt(n)))
    pitch = math.sqrt(math.pi * r * r / area_fraction)
    rng = np.random.default_rng(seed)
    ij = np.argwhere(np.ones((side, side)))[:n].astype(float)
    play = max(0.0, (pitch - 2 * r) / 2 - 0.01)
    positions = pitch * (ij + 0.5) + rng.uniform(-play, play, (n, 2))
    return qdots.Scene(box=(pitch * side, pitch * side), positions=positions, radii=np.full(n, r),
                       velocities=rng.normal(0.0, rms_speed / math.sqrt(2), (n, 2)))


def gas_energy(settings: dict, quick: bool) -> Measured:
    # energy is lost only in rare many-body impacts: 16 seeds resolve dt = 1 ms from 4 ms (4 did not)
    n, seconds, seeds = (300, 1.0, (0, 1)) if quick else (1000, 2.0, range(16))
    errors, wall = [], 0.0
    for seed in seeds:
        scene = elastic_gas(n, seed)
        e0 = 0.5 * float(np.sum(scene.velocities**2))
        sim = qdots.Simulation(scene, restitution=ELASTIC, seed=seed, engine=engine(settings))
        wall += timed_run(sim, seconds)
        errors.append(abs(sim.state().kinetic_energy() - e0) / e0)
    return Measured(float(np.mean(errors)), wall / (seconds * len(seeds)),
                    float(np.std(errors, ddof=1) / math.sqrt(len(errors))))


# ---------------------------------------------------------------- two-body van der Waals
def vdw_frames(gap0: float, dt: float, frames: int, mass: float = 1.0, r: float = 7.5) -> tuple[float, float, int]:
    """Positions (px, along x, from 0 and ``2 r + gap0``) of two dots of ``mass`` and radius ``r`` after ``frames``
    frames of ``dt`` s of the thesis's van der Waals proxy (default `qdots.VanDerWaals`): at each frame's start
    each dot's velocity changes by ``min(a dt / 2, sqrt(g a) / 2)`` toward the other, ``a = (R0 / (g - b))^7 / m``,
    for surface gaps ``min_gap <= g < max_gap``, then both move in straight lines. Also the first frame at whose
    start they are within 1 px (``frames`` if none). Written out here, apart from the engine (the reference)."""
    force = qdots.VanDerWaals()
    b = force.proxy_offset(qdots.Restitution().sticking_speed)
    x1, x2, v1, v2, touch = 0.0, 2 * r + gap0, 0.0, 0.0, frames
    for k in range(frames):
        gap = x2 - x1 - 2 * r
        if gap < 1.0:
            touch = min(touch, k)
        if force.min_gap <= gap < force.max_gap:
            a = (force.r0 / (gap - b)) ** 7 / mass
            dv = min(0.5 * a * dt, 0.5 * math.sqrt(gap * a))
            v1, v2 = v1 + dv, v2 - dv
        x1, x2 = x1 + v1 * dt, x2 + v2 * dt
    return x1, x2, touch


@functools.cache
def vdw_reference(gap0: float = 8.0, dt: float = 0.02) -> tuple[float, float, float]:
    """(t_end, x1, x2): the frames' positions at 0.8 of the frames before the pair comes within 1 px (`vdw_frames`)."""
    *_, touch = vdw_frames(gap0, dt, round(100.0 / dt))
    frames = max(1, round(0.8 * touch))
    x1, x2, _ = vdw_frames(gap0, dt, frames)
    return frames * dt, x1, x2


def vdw_pair(settings: dict, quick: bool, gap0: float = 8.0) -> Measured:
    settings_ = engine(settings)
    t_end, x1, x2 = vdw_reference(gap0, settings_.dt)
    scene = qdots.Scene(box=(200, 100), positions=[[80, 50], [95 + gap0, 50]], radii=[7.5, 7.5], closed=False)
    sim = qdots.Simulation(scene, [qdots.VanDerWaals()], seed=0, engine=settings_)
    wall = timed_run(sim, t_end)
    got = sim.state().positions[:, 0] - 80.0
    return Measured(max(abs(got[0] - x1), abs(got[1] - x2)), wall / t_end)


# ---------------------------------------------------------------- dense pack under centre gravity
def pack_forces(centre: float, gravity: float) -> list[qdots.Force]:
    return [qdots.CentreGravity((centre, centre), 750.0 * gravity), qdots.VanDerWaals(), qdots.ThermalKicks(),
            qdots.Drag(1.0, 0.01)]


@functools.cache
def settled_pack(gravity: float, quick: bool) -> qdots.Scene:
    """A polydisperse pack (radii N(7.5, 0.75) px) pulled together for 3 s (quick: 150 dots, 2 s) at the pinned
    settings."""
    n, side, settle = (150, 380, 2.0) if quick else (400, 600, 3.0)
    rng = np.random.default_rng(0)
    grid = np.array([(x, y) for x in range(20, side - 15, 25) for y in range(20, side - 15, 25)], float)
    grid = grid[rng.permutation(len(grid))[:n]]
    scene = qdots.Scene(box=(side, side), positions=grid, radii=rng.normal(7.5, 0.75, n).clip(5, 9.5))
    sim = qdots.Simulation(scene, pack_forces(side / 2, gravity), seed=1, engine=pinned.CHIPMUNK)
    sim.run(settle)
    return sim.current_scene()


def pack_simulation(settings: dict, gravity: float, quick: bool) -> qdots.Simulation:
    scene = settled_pack(gravity, quick)
    return qdots.Simulation(scene, pack_forces(scene.box[0] / 2, gravity), seed=2, engine=engine(settings))


def dense_pack(settings: dict, quick: bool, gravity: float) -> Measured:
    """Worst overlap over the last 0.5 s (quick 0.25 s) after 0.1 s to adapt to the settings."""
    sim = pack_simulation(settings, gravity, quick)
    sim.run(0.1)
    window, chunks = (0.25, 5) if quick else (0.5, 10)
    worst, wall = 0.0, 0.0
    for _ in range(chunks):
        wall += timed_run(sim, window / chunks)
        state = sim.state()
        if not np.isfinite(state.positions).all():
            return Measured(math.inf, wall / window)
        worst = max(worst, overlaps(state)[0])
    return Measured(worst, wall / window)


# ---------------------------------------------------------------- the vdW force against a plain pair search
def vdw_change(sim: qdots.Simulation, force: qdots.VanDerWaals, settings: qdots.Chipmunk,
               cache: dict) -> np.ndarray:
    """The velocity change ``force`` gives in the simulation's next step, from its present state, under the engine
    ``settings`` with the force's per-run ``cache`` (its pair lists)."""
    state = sim.state()
    ctx = StepContext(time=sim.time, dt=sim.dt, x=state.positions[:, 0].copy(), y=state.positions[:, 1].copy(),
                      velocity=state.velocities, radii=sim.radii, masses=sim.masses,
                      rng=np.random.default_rng(0), dv=np.zeros_like(state.velocities), pairs=settings.pairs,
                      restitution=sim.restitution, cache=cache)
    force.kick(ctx)
    return ctx.dv


def vdw_against(sim: qdots.Simulation, changes: dict, steps: int, summed: bool) -> float:
    """The simulation's vdW velocity changes against those of the same force under its engine settings with
    ``changes`` (e.g. ``{"pair_skin": 0.0}``), over ``steps``.

    ``summed=False``: the largest |dv - dv_other| / max |dv_other| of any one step; ``summed=True``:
    the same of the changes summed over the steps (the impulse each dot received).
    """
    force = next(f for f in sim.forces if isinstance(f, qdots.VanDerWaals))
    own, other = sim.force_cache(force), {}  # the run's own pair lists, and fresh ones for the other settings
    other_settings = sim.engine.replace(**changes)
    worst, totals = 0.0, 0.0
    for _ in range(steps):
        dv, dv_other = vdw_change(sim, force, sim.engine, own), vdw_change(sim, force, other_settings, other)
        if summed:
            totals = totals + np.stack([dv, dv_other])
        else:
            worst = max(worst, float(np.abs(dv - dv_other).max()) / (float(np.abs(dv_other).max()) or 1.0))
        sim.step()
    if summed:
        return float(np.abs(totals[0] - totals[1]).max()) / (float(np.abs(totals[1]).max()) or 1.0)
    return worst


def many_body_run(settings: dict, quick: bool, scene: str) -> tuple[qdots.Simulation, float]:
    """The pack (x10 gravity) run for 0.5 s or the loose film for 1 s (quick: less); (simulation, wall s per
    simulated s)."""
    if scene == "pack":
        sim = pack_simulation(settings, 10.0, quick)
        seconds = 0.25 if quick else 0.5
    else:
        sim = qdots.Simulation(loose_film(300 if quick else 2000),
                               [qdots.VanDerWaals(), qdots.ThermalKicks(), qdots.Drag()],
                               seed=3, engine=engine(settings))
        seconds = 0.3 if quick else 1.0
    return sim, timed_run(sim, seconds) / seconds


def list_error(settings: dict, quick: bool, scene: str) -> Measured:
    """Time a run of the pack (x10 gravity) or the loose film, then check the pair list on 10 more steps:
    the vdW change of every step against a brute-force pair search (skin 0) at the same instants."""
    sim, cost = many_body_run(settings, quick, scene)
    return Measured(vdw_against(sim, {"pair_skin": 0.0}, 10, summed=False), cost)


def split_error(settings: dict, quick: bool, scene: str) -> Measured:
    """Time a run of the pack (x10 gravity) or the loose film, then, over the next 0.2 s (a whole number of
    every far interval swept), the vdW impulse each dot received against that of every pair pulled at every
    step along the same trajectory."""
    sim, cost = many_body_run(settings, quick, scene)
    return Measured(vdw_against(sim, {"pair_skin": 0.0, "far_interval": None}, round(0.2 / sim.dt), summed=True),
                    cost)


#: name -> (title, error axis label, round-off floor of the error, measure(settings, quick))
CASES = {
    "restitution": ("isolated oblique impact", "|v - v_exact| / |v_rel|", 1e-12, restitution),
    "gas_energy": ("elastic gas, 50 % area fraction", "|dE| / E", 1e-12, gas_energy),
    "vdw_pair": ("two-body vdW vs the thesis's frames", "position error (px)", 1e-9, vdw_pair),
    "vdw_far": ("two-body vdW from a 20 px gap vs the thesis's frames", "position error (px)", 1e-9,
                functools.partial(vdw_pair, gap0=20.0)),
    "pack_g1": ("dense pack, centre gravity x1", "worst overlap / r", 1e-6,
                functools.partial(dense_pack, gravity=1.0)),
    "pack_g10": ("dense pack, centre gravity x10", "worst overlap / r", 1e-6,
                 functools.partial(dense_pack, gravity=10.0)),
    "list_pack": ("pair list vs brute force, dense pack x10", "max |dv error| / max |dv|", 1e-15,
                  functools.partial(list_error, scene="pack")),
    "list_film": ("pair list vs brute force, loose film", "max |dv error| / max |dv|", 1e-15,
                  functools.partial(list_error, scene="film")),
    "split_pack": ("vdW impulse over 0.2 s vs every pair every step, dense pack x10", "max |impulse error| / max",
                   1e-15, functools.partial(split_error, scene="pack")),
    "split_film": ("vdW impulse over 0.2 s vs every pair every step, loose film", "max |impulse error| / max",
                   1e-15, functools.partial(split_error, scene="film")),
}

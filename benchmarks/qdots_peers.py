"""qdots against LAMMPS on the same disc scene, and against a plain per-body Python loop of our forces.

**Peer.** N = 3,000 and 30,000 discs of 7.5 px, mass 1, at 40 % and 70 % area fraction in a closed
square box, Maxwell velocities at kT = 1.76 (one thesis kick rms speed), a Langevin thermostat
(gamma = 1/s) and restitution 0.8. qdots: Chipmunk's hard contacts with the thesis's per-impact
restitution N(0.8, 0.1) and `qdots.Langevin`, at the pinned settings (`benchmarks.pinned.CHIPMUNK`, the defaults of
0.3.0: the 20 ms frame, sub-steps planned so that no dot travels more than 0.005 radii into a contact) and at the
looser sub-step plans `MATCH_TOLERANCES`. LAMMPS (`benchmarks.lammps_scene`): soft linear springs with the damping
that gives e = 0.8, ``fix langevin`` with the same gamma and kT. Its stiffness is chosen so that a
head-on impact at 10 px/s (over 5x the rms relative speed) overlaps by 1 % of a radius, and its
time step is the usual contact time / 50; a second LAMMPS row runs at dt = 1 ms (contact time /
24). Both run on one core (LAMMPS as one MPI rank). Same simulated time for each; per row,
measured in the same run: ms/step, ms per simulated second, worst overlap over the run, kinetic
temperature against the target, and the restitution error of an isolated head-on impact at the
same settings (qdots: against the drawn value; LAMMPS: against 0.8).

**At equal overlap.** The two engines violate different things by default (qdots overlaps less
than LAMMPS at contact time / 50), so the headline also compares them at equal overlap: qdots
at the loosest of its sub-step plans whose worst overlap is at most LAMMPS's at contact time / 50.

**Vectorizing.** The thesis's forces (van der Waals + thermal kicks + drag) on a loose film, in
our vectorized form and as a per-body Python loop (`benchmarks.python_loop`), timed alternately
on the same board; error: the largest difference between their velocity changes from the same
state and generator, relative to the largest change.

Run: ``python -m benchmarks.qdots_peers [--quick] [--figures DIR]``
"""

from __future__ import annotations

import math
import time
from types import SimpleNamespace

import numpy as np

import qdots
from qdots.analysis import overlaps
from qdots.diagnostics.hard_cases import loose_film
from qdots.forces import StepContext

from . import lammps_scene, pinned
from .python_loop import LoopForces
from .report import Headline, Note, Table, cli
from .staleness import CHIPMUNK_ENGINE

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = (*CHIPMUNK_ENGINE,
                 "qdots/forces", "qdots/simulation.py", "benchmarks/lammps_scene.py", "benchmarks/python_loop.py",
                 "benchmarks/pinned.py")

RADIUS, KT, GAMMA, RESTITUTION = 7.5, 1.76, 1.0, 0.8
#: Area fractions of the scene: a thermal gas and a dense liquid (square-lattice start, so < pi/4).
AREA_FRACTIONS = (0.4, 0.7)
#: qdots sub-step plans looser than the pinned one (`qdots.Chipmunk.overlap_tolerance`, radii) for the comparison
#: at equal overlap.
MATCH_TOLERANCES = (0.01, 0.02, 0.05)
#: Label of qdots's rows.
OURS = "qdots (Chipmunk + vectorized Langevin)"
#: LAMMPS stiffness: a head-on impact at IMPACT_SPEED px/s overlaps by 1 % of a radius.
IMPACT_SPEED, OVERLAP = 10.0, 0.01 * RADIUS
KN = lammps_scene.stiffness_for(OVERLAP, IMPACT_SPEED, 0.5)
T_CONTACT = lammps_scene.contact_time(KN, 0.5, RESTITUTION)


def initial_board(n: int, fraction: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray, float]:
    """Jittered square lattice at area ``fraction``, Maxwell velocities at `KT`: positions, velocities, box side."""
    side = math.ceil(math.sqrt(n))
    pitch = math.sqrt(math.pi * RADIUS**2 / fraction)
    rng = np.random.default_rng(seed)
    ij = np.argwhere(np.ones((side, side)))[:n].astype(float)
    play = (pitch - 2 * RADIUS) / 2 - 0.01
    positions = pitch * (ij + 0.5) + rng.uniform(-play, play, (n, 2))
    return positions, rng.normal(0.0, math.sqrt(KT), (n, 2)), pitch * side


class Sampler:
    """Worst overlap and mean kinetic temperature over the samples of a run."""

    def __init__(self) -> None:
        self.worst, self.kT = 0.0, []

    def add(self, positions: np.ndarray, velocities: np.ndarray) -> None:
        self.worst = max(self.worst, overlaps(SimpleNamespace(positions=positions,
                                                              radii=np.full(len(positions), RADIUS)))[0])
        self.kT.append(float(np.mean(velocities**2)))  # m v^2 / 2 per degree of freedom, m = 1, 2 dof


def ours(n: int, fraction: float, seconds: float, tolerance: float | None = None, warmup: float = 0.2) -> dict:
    """qdots on the peer scene at the pinned settings, or with the sub-step plan's ``tolerance`` (radii)."""
    positions, velocities, box = initial_board(n, fraction)
    scene = qdots.Scene(box=(box, box), positions=positions, radii=np.full(n, RADIUS), velocities=velocities)
    settings = pinned.CHIPMUNK if tolerance is None else pinned.chipmunk(overlap_tolerance=tolerance)
    sim = qdots.Simulation(scene, [qdots.Langevin(GAMMA, KT)], restitution=qdots.Restitution(mean=RESTITUTION),
                           seed=1, engine=settings)
    sim.run(warmup)
    sampler, wall, chunks = Sampler(), 0.0, 10
    for _ in range(chunks):
        start = time.perf_counter()
        sim.run(seconds / chunks)
        wall += time.perf_counter() - start
        state = sim.state()
        sampler.add(state.positions, state.velocities)
    steps = round(seconds / sim.dt)
    label = OURS if tolerance is None else f"{OURS}, overlap tolerance {tolerance:g}"
    return {"engine": label, "N": n, "phi": fraction, "dt": sim.dt, "tolerance": settings.overlap_tolerance,
            "ms_step": 1e3 * wall / steps,
            "overlap": sampler.worst, "kT": float(np.mean(sampler.kT)), "restitution": our_restitution_error(settings)}


def our_restitution_error(settings, seed: int = 3) -> float:
    scene = qdots.Scene(box=(300, 200), positions=[[100, 100], [117, 100]], radii=[RADIUS, RADIUS],
                        velocities=[[IMPACT_SPEED / 2, 0.0], [-IMPACT_SPEED / 2, 0.0]])
    sim = qdots.Simulation(scene, restitution=qdots.Restitution(mean=RESTITUTION), seed=seed, engine=settings)
    drawn = sim.collisions.next_elasticity()
    v = sim.run(1.0).velocities
    return abs((v[1, 0] - v[0, 0]) / IMPACT_SPEED - drawn)


def lammps(make, n: int, fraction: float, seconds: float, dt: float, label: str, warmup: float = 0.2) -> dict:
    positions, velocities, box = initial_board(n, fraction)
    scene = lammps_scene.Scene(make, positions, velocities, RADIUS, box, KN, RESTITUTION, GAMMA, KT, dt)
    try:
        scene.run(round(warmup / dt))
        sampler, wall, chunks = Sampler(), 0.0, 10
        steps = max(chunks, round(seconds / dt / chunks) * chunks)
        for _ in range(chunks):
            wall += scene.run(steps // chunks)
            sampler.add(*scene.arrays())
    finally:
        scene.close()
    measured = lammps_scene.head_on_restitution(make, IMPACT_SPEED, KN, RESTITUTION, dt, RADIUS)
    return {"engine": label, "N": n, "phi": fraction, "dt": dt, "ms_step": 1e3 * wall / steps, "overlap": sampler.worst,
            "kT": float(np.mean(sampler.kT)), "restitution": abs(measured - RESTITUTION)}


def per_second(row: dict) -> float:
    """Wall s per simulated s of a row."""
    return row["ms_step"] / row["dt"] / 1e3


def equal_overlap(rows: list[dict], n: int, fraction: float) -> Headline:
    """LAMMPS (contact time / 50) against qdots at the loosest sub-step plan that overlaps no more than it."""
    scene = [r for r in rows if (r["N"], r["phi"]) == (n, fraction)]
    lmp = next(r for r in scene if r["engine"].startswith("LAMMPS"))
    within = [r for r in scene if r["engine"].startswith(OURS) and r["overlap"] <= lmp["overlap"]]
    what = f"qdots vs LAMMPS at equal overlap, {n:,} discs at {100 * fraction:.0f} % area"
    if not within:
        return Headline(what, "no qdots sub-step plan overlaps as little as LAMMPS", "")
    q = max(within, key=lambda r: r["tolerance"])
    return Headline(what, f"per simulated s {per_second(lmp) / per_second(q):.2f}x ours (qdots at overlap "
                          f"tolerance {q['tolerance']:g})",
                    f"worst overlap {100 * q['overlap']:.2f} % (qdots) vs {100 * lmp['overlap']:.2f} % of r "
                    f"(LAMMPS); kT {q['kT'] / KT:.3f} vs {lmp['kT'] / KT:.3f} of the target")


def peer_table(rows: list[dict]) -> Table:
    base = {(r["N"], r["phi"]): r for r in rows if r["engine"] == OURS}
    out = []
    for r in rows:
        q = base[r["N"], r["phi"]]
        out.append([r["engine"], r["N"], f"{100 * r['phi']:.0f} %", r["dt"] * 1e3, r["ms_step"], per_second(r),
                    f"{r['ms_step'] / q['ms_step']:.2f}", f"{per_second(r) / per_second(q):.2f}",
                    100 * r["overlap"], f"{r['restitution']:.1e}", f"{r['kT'] / KT:.3f}"])
    return Table("Same disc scene, one core each: cost against what each engine violates",
                 ["engine", "N", "area fraction", "dt (ms)", "ms/step", "wall s per simulated s", "per-step cost / qdots",
                  "per simulated s / qdots", "worst overlap (% r)", "restitution error (head-on, 10 px/s)",
                  "kT measured / target"], out)


# ---------------------------------------------------------------- vectorized against a Python loop
def loop_row(n: int, rounds: int) -> dict:
    scene = loose_film(n)
    # every vdW pair every step on both sides: the loop writes out that model (the far-pair split is
    # an approximation of its own, measured in qdots_knobs)
    forces = [qdots.VanDerWaals(contact="hold"), qdots.ThermalKicks(), qdots.Drag()]  # the model the loop writes
    vector = qdots.Simulation(scene, forces, seed=1, engine=pinned.CHIPMUNK)
    plain = qdots.Simulation(scene, [], seed=1, engine=pinned.CHIPMUNK)
    loop = LoopForces(plain.backend.space, *forces, plain.engine.pairs, plain.restitution)
    error = loop_error(plain, loop, forces)
    vector.step(5)  # first pair-list build
    vector.timings.update(forces=0.0, pymunk=0.0)
    loop_wall, steps = 0.0, 0
    for _ in range(rounds):
        vector.step(5)
        for _ in range(5):
            start = time.perf_counter()
            loop.apply(plain.time, plain.dt, plain.rng)
            loop_wall += time.perf_counter() - start
            plain.step()
        steps += 5
    return {"N": n, "vector_ms": 1e3 * vector.timings["forces"] / steps, "loop_ms": 1e3 * loop_wall / steps,
            "error": error}


def loop_error(sim: qdots.Simulation, loop: LoopForces, forces) -> float:
    """max |dv(loop) - dv(vectorized)| / max |dv| at a step with a thermal kick, same state and generator."""
    time_, dt = 0.02 - 0.5e-3, sim.dt  # (time, time + dt] holds the kick at 20 ms
    state = sim.state()
    if not np.array_equal(np.array([[b.position.x, b.position.y] for b in loop.bodies]), state.positions):
        raise RuntimeError("pymunk's body order differs from the simulation's")
    ctx = StepContext(time=time_, dt=dt, x=state.positions[:, 0].copy(), y=state.positions[:, 1].copy(),
                      velocity=state.velocities, radii=sim.radii, masses=sim.masses,
                      rng=np.random.default_rng(7), dv=np.zeros_like(state.velocities), pairs=sim.engine.pairs,
                      restitution=sim.restitution)
    for force in forces:
        ctx.cache = {}  # each force's own, fresh for this state
        force.kick(ctx)
    looped = np.array(loop.velocity_changes(time_, dt, np.random.default_rng(7)))
    return float(np.abs(looped - ctx.dv).max() / np.abs(ctx.dv).max())


def run(quick: bool) -> list:
    sizes = (3000,) if quick else (3000, 30000)
    results = []
    make = lammps_scene.load()
    rows = []
    for n in sizes:
        for fraction in AREA_FRACTIONS:
            seconds = 0.2 if quick else (1.0 if n <= 3000 else 0.3)
            rows.append(ours(n, fraction, seconds))
            if not isinstance(make, str):
                rows.append(lammps(make, n, fraction, seconds, T_CONTACT / 50,
                                   f"LAMMPS {make.version} granular, dt = t_c/50"))
                rows.append(lammps(make, n, fraction, seconds, 1e-3, f"LAMMPS {make.version} granular, dt = 1 ms"))
            rows += [ours(n, fraction, seconds, tolerance) for tolerance in MATCH_TOLERANCES]
    loops = [loop_row(n, 2 if quick else (4 if n <= 3000 else 1)) for n in sizes]
    q = rows[0]
    if isinstance(make, str):
        results.append(Headline(f"LAMMPS peer comparison ({sizes[0]:,} discs)", "skipped", make))
        results.append(Note(f"**LAMMPS rows skipped:** {make}."))
    else:
        lmp = rows[1]
        results.append(Headline(
            f"qdots vs LAMMPS granular, {q['N']:,} discs at {100 * q['phi']:.0f} % area, Langevin",
            f"per step {lmp['ms_step'] / q['ms_step']:.2f}x ours; per simulated s "
            f"{per_second(lmp) / per_second(q):.2f}x ours",
            f"worst overlap {100 * q['overlap']:.2f} % (qdots) vs {100 * lmp['overlap']:.2f} % of r (LAMMPS); "
            f"restitution {q['restitution']:.0e} vs {lmp['restitution']:.0e}"))
        results += [equal_overlap(rows, n, fraction) for n in sizes for fraction in AREA_FRACTIONS]
    big = loops[-1]
    results.append(Headline(f"vectorized forces vs per-body Python loop, {big['N']:,} dots",
                            f"{big['loop_ms'] / big['vector_ms']:.0f}x faster ({big['vector_ms']:.1f} vs "
                            f"{big['loop_ms']:.0f} ms/step)", f"max velocity-change difference {big['error']:.0e}"))
    results.append(peer_table(rows))
    results.append(Note(
        f"LAMMPS contact: kn = {KN:.0f} mass/s^2 (1 % overlap at a {IMPACT_SPEED:g} px/s head-on impact), contact "
        f"time t_c = {1e3 * T_CONTACT:.1f} ms. What each violates: LAMMPS contacts are soft by design: an impact at speed v "
        "overlaps by v sqrt(mu/kn), so halving the overlap takes a 4x stiffer spring and a 2x smaller step, and its "
        "restitution is exact only as dt -> 0; qdots resolves contacts as impulses, so an isolated impact has "
        "exactly the drawn restitution at any dt, and overlap is only what Chipmunk's position correction "
        "leaves under sustained pressure. qdots draws each impact's restitution from N(0.8, 0.1) (the thesis's "
        "rule) where LAMMPS uses 0.8 for all; both conserve momentum in contacts. `kT measured / target` checks "
        "the two thermostats: mean v_x^2 (m = 1) over 10 samples of the run, divided by kT."))
    results.append(Table("Forces (vdW + thermal kicks + drag) on a loose film, every vdW pair every step: vectorized against a per-body Python loop",
                         ["N", "vectorized ms/step", "Python loop ms/step", "speed-up",
                          "error: max |dv_loop - dv_vec| / max |dv|"],
                         [[r["N"], r["vector_ms"], r["loop_ms"], f"{r['loop_ms'] / r['vector_ms']:.0f}x",
                           f"{r['error']:.1e}"] for r in loops]))
    return results


def main(argv: list[str] | None = None) -> int:
    return cli(run, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    raise SystemExit(main())

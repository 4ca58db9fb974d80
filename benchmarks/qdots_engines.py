"""Both qdots engines on the same boards: time per simulated second beside overlap, and the event engine's throughput against its anchors.

The Chipmunk engine (soft contacts, sub-steps planned from the approach speeds) and the event engine (the
thesis's algorithm: exact hard discs, every collision of a frame in time order) run the same experiment
with the same forces, collision rule and seed; only how the dots collide differs. Both run the pinned settings
(`benchmarks.pinned`: the defaults of 0.3.0, the thesis's 20 ms frame).

* **Figure scenes**: the ``fig2-2`` preset at sigma 0 (equal masses) and at sigma 15 % with masses ~ d^3
  (the ``fig2-6`` setting), full size (300 dots, 600 x 600 px, one dot per second, 100 s settle), seed 154:
  wall time, simulated seconds per wall second, worst overlap, and the packing numbers at the end. One seed
  says nothing about agreement: that is `python -m reproduce` (its first section; the report runs 10 seeds per point).
* **Throughput** at 300, 3,000 and 30,000 dots (`THROUGHPUT`; quick: the two smaller), on three boards, both
  engines from the same start, timed alternately in `CHUNKS` chunks each (minimum and median over the chunks):
  the **free film** (dots of 15 px placed at random at the thesis's coverage, 300 per 600 x 600 px, and settled
  `SETTLE` s under the thesis's forces on the event engine: the clusters a deposited film has), the **dense pack**
  (a hexagonal pack at 15.2 px pitch, 0.2 px gaps, velocities N(0, 10) px/s), both under the thesis's forces
  (van der Waals pull and thermal kicks every 20 ms frame), and an **elastic gas** (50 % area fraction, rms speed
  85 px/s, no forces, restitution 1), the board the published hard-disc codes are measured on. Collisions per
  wall second count every collision (dot-dot and dot-wall; Chipmunk's: the impacts its collision callback saw)
  over the whole frame, the forces' phase included; the event engine's rate within its event loop alone is given
  beside it. The anchors: Isobe's algorithm (1999), 460 million collisions per CPU hour (1.3e5 per second) on
  2,500 discs; Smallenburg's (2022), one event per particle, neighbour lists and a calendar, 4-10x faster than
  the other codes it was set against on hard-sphere fluids; our goal, 1e6 collisions per second on one core at
  30,000 dots with the van der Waals frames on.

Run: ``python -m benchmarks.qdots_engines [--quick] [--figures DIR]``
"""

from __future__ import annotations

import dataclasses
import math
import time

import numpy as np

import qdots
from qdots.analysis import overlaps, packing_summary
from qdots.analysis.structure import clusters
from qdots.experiment import run_experiment
from qdots.placement import hexagonal_lattice, random_sequential
from qdots.presets import get_preset

from . import pinned
from .qdots_cases import ELASTIC, elastic_gas
from .report import Headline, Note, Table, cli

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = ("qdots/engine", "qdots/forces", "qdots/geometry", "qdots/simulation.py", "qdots/experiment.py",
                 "qdots/placement.py", "benchmarks/qdots_cases.py", "benchmarks/pinned.py")

#: The engines, the thesis's algorithm first.
ENGINES = ("event", "chipmunk")
#: Simulated seconds each engine is timed for, by dots (about the same wall time for each size).
THROUGHPUT = {300: 4.0, 3000: 1.0, 30000: 0.2}
#: Chunks each engine's timed run is cut into, timed alternately.
CHUNKS = 5
#: Simulated seconds the free film settles on the event engine before it is timed.
SETTLE = 20.0
#: The anchors: collisions per second per core.
ISOBE_1999 = 460e6 / 3600
GOAL = 1e6


def figure_scene(name: str, sigma: float, mass_model: str, quick: bool) -> dict:
    """The fig2-2 preset's film at ``sigma`` with ``mass_model``, seed 154, run by each engine."""
    base = next(exp for exp in get_preset("fig2-2", quick=0.1 if quick else False)
                if exp.deposition.sigma == sigma)
    out = {}
    for engine in ENGINES:
        exp = base.replace(seed=154, deposition=dataclasses.replace(base.deposition, mass_model=mass_model),
                           engine=pinned.PINNED[engine])
        start = time.perf_counter()
        sim = run_experiment(exp)
        wall = time.perf_counter() - start
        state = sim.state()
        summary = packing_summary(state)
        _, sizes = clusters(state)
        out[engine] = {"scene": name, "dots": state.n_dots, "simulated": state.time, "wall": wall,
                       "overlap": 100 * summary["max_overlap"], "interior": summary["interior_fraction"],
                       "aggregates": int(np.sum(sizes >= 5)), "speed": float(np.hypot(*state.velocities.T).mean()),
                       "collisions": sim.collisions.dot_dot}
    return out


def thesis_forces() -> list:
    """The thesis's forces: the van der Waals proxy and thermal kicks, every 20 ms frame."""
    return [qdots.VanDerWaals(), qdots.ThermalKicks()]


def free_film(n: int, seed: int = 0) -> qdots.Scene:
    """``n`` dots of 15 px at random at the thesis's coverage (300 per 600 x 600 px), settled `SETTLE` s under
    `thesis_forces` on the event engine from rest."""
    side = 600.0 * math.sqrt(n / 300.0)
    positions, radii = random_sequential(n, (side, side), 15.0, 0.0, rng=seed, margin=0.01)
    sim = qdots.Simulation(qdots.Scene(box=(side, side), positions=positions, radii=radii), thesis_forces(),
                           seed=seed, engine=pinned.EVENT)
    sim.run(SETTLE)
    return sim.current_scene()


def dense_pack(n: int, seed: int = 0, pitch: float = 15.2) -> qdots.Scene:
    """``n`` dots of 7.5 px on a hexagonal lattice of ``pitch`` px (0.2 px gaps), velocities N(0, 10) px/s."""
    m = int(math.ceil(math.sqrt(n)))
    points = hexagonal_lattice(m, pitch, origin=(20.0, 20.0))[:n]
    box = (float(points[:, 0].max()) + 20.0 + pitch, float(points[:, 1].max()) + 20.0 + pitch)
    return qdots.Scene(box=box, positions=points, radii=np.full(n, 7.5),
                       velocities=np.random.default_rng(seed).normal(0.0, 10.0, (n, 2)))


#: The throughput boards: name -> (scene of n dots, forces, collision rule).
BOARDS = {
    "free film": (free_film, thesis_forces, qdots.Restitution),
    "dense pack": (dense_pack, thesis_forces, qdots.Restitution),
    "elastic gas": (lambda n: elastic_gas(n, 0), list, lambda: ELASTIC),
}


def throughput(board: str, n: int, seconds: float) -> dict:
    """Both engines on ``board`` with ``n`` dots for ``seconds``, timed alternately in `CHUNKS` chunks."""
    make, forces, rule = BOARDS[board]
    scene = make(n)
    sims = {engine: qdots.Simulation(scene, forces(), restitution=rule(), seed=1, engine=pinned.PINNED[engine])
            for engine in ENGINES}
    chunks = {engine: [] for engine in ENGINES}
    worst = {engine: 0.0 for engine in ENGINES}
    for sim in sims.values():
        sim.step(2)  # compiled, caches built
    frames = max(1, round(seconds / CHUNKS / pinned.CHIPMUNK.dt))
    for _ in range(CHUNKS):
        for engine, sim in sims.items():
            impacts = sim.collisions.dot_dot + sim.collisions.dot_wall
            events = sim.backend.timings.get("events", math.nan)
            start = time.perf_counter()
            sim.step(frames)
            wall = time.perf_counter() - start
            done = sim.collisions.dot_dot + sim.collisions.dot_wall - impacts
            chunks[engine].append({"wall": wall, "simulated": frames * sim.dt, "collisions": done,
                                   "loop": sim.backend.timings.get("events", math.nan) - events})
            worst[engine] = max(worst[engine], overlaps(sim.state())[0])
    out = {}
    for engine, rows in chunks.items():
        speed = np.array([r["simulated"] / r["wall"] for r in rows])
        rate = np.array([r["collisions"] / r["wall"] for r in rows])
        loop = np.array([r["collisions"] / r["loop"] for r in rows])
        out[engine] = {"board": board, "dots": n, "engine": engine, "simulated": sum(r["simulated"] for r in rows),
                       "speed": (float(speed.max()), float(np.median(speed))),
                       "rate": (float(rate.max()), float(np.median(rate))),
                       "loop": (float(loop.max()), float(np.median(loop))) if engine == "event" else None,
                       "per_frame": sum(r["collisions"] for r in rows) / (CHUNKS * frames),
                       "overlap": 100 * worst[engine]}
    return out


def throughput_table(rows: list[dict]) -> Table:
    def pair(values, fmt):
        return f"{values[0]:{fmt}} / {values[1]:{fmt}}"

    return Table("Throughput, one core, both engines from the same board (best chunk / median chunk)",
                 ["board", "dots", "engine", "simulated s", "simulated s per wall s", "collisions per frame",
                  "collisions per wall s", "event loop alone: collisions per s", "worst overlap (% r)"],
                 [[r["board"], r["dots"], r["engine"], f"{r['simulated']:g}", pair(r["speed"], ".3g"),
                   f"{r['per_frame']:,.0f}", pair(r["rate"], ".3g"), pair(r["loop"], ".3g") if r["loop"] else "",
                   f"{r['overlap']:.3f}"] for r in rows],
                 note=f"Anchors: Isobe 1999, {ISOBE_1999:.2g} collisions per s (one CPU, 2,500 discs, a hard-disc gas); "
                      "Smallenburg 2022, 4-10x faster than the codes it was compared with; goal "
                      f"{GOAL:.0e} per s on one core at 30,000 dots with the van der Waals frames on. Our frames add "
                      "work the anchors do not have: at every frame's start the forces change every velocity "
                      "(kicks, the pull of every pair in range), so every dot's next event is found again, and "
                      "the collision candidates are searched again.")


def run(quick: bool) -> list:
    scenes = [figure_scene("fig2-2, sigma 0, equal masses", 0.0, "equal", quick),
              figure_scene("fig2-2, sigma 15 %, masses ~ d^3 (fig2-6)", 0.15, "volume", quick)]
    scene_table = Table("Figure scenes, seed 154" + (" (quick: boards scaled down 10x)" if quick else "")
                        + ": each engine from the same experiment",
                        ["scene", "engine", "dots", "wall (s)", "simulated s per wall s", "worst overlap (% r)",
                         "interior fraction", "aggregates (>= 5)", "mean speed (px/s)", "dot-dot collisions"])
    for scene in scenes:
        for engine, r in scene.items():
            scene_table.rows.append([r["scene"], engine, r["dots"], f"{r['wall']:.1f}",
                                     f"{r['simulated'] / r['wall']:.1f}", f"{r['overlap']:.3f}",
                                     f"{r['interior']:.3f}", r["aggregates"], f"{r['speed']:.1f}",
                                     f"{r['collisions']:,}"])
    sizes = {n: t for n, t in THROUGHPUT.items() if not quick or n <= 3000}
    rows = [r for board in BOARDS for n, seconds in sizes.items()
            for r in throughput(board, n, seconds).values()]
    first = scenes[0]
    big = max(sizes)
    at = {(r["board"], r["engine"]): r for r in rows if r["dots"] == big}
    film, pack, gas = (at[(b, "event")] for b in BOARDS)
    return [
        Headline("the two engines on fig2-2 (sigma 0, seed 154)",
                 f"event {first['event']['wall']:.1f} s, Chipmunk {first['chipmunk']['wall']:.1f} s per "
                 f"{first['event']['simulated']:.0f} s film",
                 f"worst overlap event {first['event']['overlap']:.4f} % r, Chipmunk "
                 f"{first['chipmunk']['overlap']:.3f} % r; interior fraction {first['event']['interior']:.3f} vs "
                 f"{first['chipmunk']['interior']:.3f} (one seed)"),
        Headline(f"event engine throughput, {big:,} dots, vdW frames on (goal {GOAL:.0e} collisions/s)",
                 f"dense pack {pack['rate'][1]:.3g}, free film {film['rate'][1]:.3g}, elastic gas {gas['rate'][1]:.3g} "
                 f"collisions per wall s (median chunk); simulated s per wall s: event "
                 f"{pack['speed'][1]:.3g} / {film['speed'][1]:.3g}, Chipmunk {at[('dense pack', 'chipmunk')]['speed'][1]:.3g}"
                 f" / {at[('free film', 'chipmunk')]['speed'][1]:.3g} (pack / film)",
                 f"anchors: Isobe 1999 {ISOBE_1999:.2g}/s; worst overlap event {pack['overlap']:.4f} % r, Chipmunk "
                 f"{at[('dense pack', 'chipmunk')]['overlap']:.3f} % r (pack)"),
        scene_table, throughput_table(rows),
        Note("The event engine keeps discs a buffer (1e-6 mean radii) apart, so its overlap is zero up to round-off; "
             "Chipmunk's soft contacts overlap by up to its sub-step plan's tolerance. Whether the two engines give "
             "the same films is measured over 10 seeds per point in docs/reproduction.md (first section)."),
    ]


def main(argv: list[str] | None = None) -> int:
    return cli(run, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    raise SystemExit(main())

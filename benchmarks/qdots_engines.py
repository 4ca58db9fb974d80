"""Both qdots engines on the same boards: time per simulated second beside overlap and the packing they give.

The Chipmunk engine (soft contacts, sub-steps planned from the approach speeds) and the event engine (the
thesis's algorithm: exact hard discs, every collision of a frame in time order) run the same experiment
with the same forces, collision rule and seed; only how the dots collide differs.

* **Figure scenes**: the ``fig2-2`` preset at sigma 0 (equal masses) and at sigma 15 % with masses ~ d^3
  (the ``fig2-6`` setting), full size (300 dots, 600 x 600 px, one dot per second, 100 s settle), seed 154:
  wall time, simulated seconds per wall second, worst overlap, and the packing numbers at the end. One seed
  says nothing about agreement: that is `python -m reproduce` (its first section; the report runs 10 seeds per point).
* **Large boards**: 3,000 and 30,000 dots (7.5 px, a jittered 17 px lattice, velocities N(0, 10) px/s) under
  the thesis's forces, run for 2 s (3,000) and 0.4 s (30,000) from the same start by both engines: wall per
  simulated second, worst overlap, collisions per frame, frames that reached the event cap (the default,
  1,000,000 collisions per frame).

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
from qdots.presets import get_preset

from .report import Headline, Note, Table, cli

#: The engines, the thesis's algorithm first.
ENGINES = ("event", "chipmunk")


def figure_scene(name: str, sigma: float, mass_model: str, quick: bool) -> dict:
    """The fig2-2 preset's film at ``sigma`` with ``mass_model``, seed 154, run by each engine."""
    base = next(exp for exp in get_preset("fig2-2", quick=0.1 if quick else False)
                if exp.deposition.sigma == sigma)
    out = {}
    for engine in ENGINES:
        exp = base.replace(seed=154, deposition=dataclasses.replace(base.deposition, mass_model=mass_model),
                           engine=base.engine.replace(kind=engine))
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


def large_board(n: int, seed: int = 0) -> qdots.Scene:
    side = int(math.ceil(math.sqrt(n)))
    rng = np.random.default_rng(seed)
    ij = np.argwhere(np.ones((side, side)))[:n].astype(float)
    return qdots.Scene(box=(17.0 * side + 40.0,) * 2, positions=20.0 + 17.0 * ij + rng.uniform(-0.9, 0.9, (n, 2)),
                       radii=np.full(n, 7.5), velocities=rng.normal(0.0, 10.0, (n, 2)))


def large(n: int, seconds: float) -> dict:
    """Both engines on the ``n``-dot board for ``seconds`` simulated."""
    scene = large_board(n)
    out = {}
    for engine in ENGINES:
        settings = qdots.engine.ENGINES[engine]()
        sim = qdots.Simulation(scene, [qdots.VanDerWaals(), qdots.ThermalKicks()], seed=1, engine=settings)
        sim.run(2 * sim.dt)  # compiled, caches built
        worst, start, frames = 0.0, time.perf_counter(), round(seconds / sim.dt)
        impacts = sim.collisions.dot_dot + sim.collisions.dot_wall
        for _ in range(10):
            sim.run(seconds / 10)
            state = sim.state()
            worst = max(worst, overlaps(state)[0])
        wall = time.perf_counter() - start
        out[engine] = {"dots": n, "simulated": seconds, "wall": wall, "overlap": 100 * worst,
                       "per_frame": (sim.collisions.dot_dot + sim.collisions.dot_wall - impacts) / frames,
                       "capped": sim.backend.diagnostics().get("capped_frames", 0),
                       "interior": packing_summary(sim.state())["interior_fraction"]}
    return out


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
    sizes = ((3000, 2.0),) if quick else ((3000, 2.0), (30000, 0.4))
    boards = [large(n, seconds) for n, seconds in sizes]
    board_table = Table("Large boards under the thesis's forces (vdW + kicks), from the same start",
                        ["dots", "engine", "simulated (s)", "wall s per simulated s", "worst overlap (% r)",
                         "collisions per 20 ms frame", "frames at the event cap", "interior fraction at the end"])
    for board in boards:
        for engine, r in board.items():
            board_table.rows.append([f"{r['dots']:,}", engine, f"{r['simulated']:g}",
                                     f"{r['wall'] / r['simulated']:.2f}", f"{r['overlap']:.3f}",
                                     f"{r['per_frame']:,.0f}", r["capped"], f"{r['interior']:.3f}"])
    first = scenes[0]
    n0 = boards[-1]
    return [
        Headline("the two engines on fig2-2 (sigma 0, seed 154)",
                 f"event {first['event']['wall']:.1f} s, Chipmunk {first['chipmunk']['wall']:.1f} s per "
                 f"{first['event']['simulated']:.0f} s film; at {next(iter(n0.values()))['dots']:,} dots "
                 f"event {n0['event']['wall'] / n0['event']['simulated']:.1f}, Chipmunk "
                 f"{n0['chipmunk']['wall'] / n0['chipmunk']['simulated']:.1f} wall s per simulated s",
                 f"worst overlap event {first['event']['overlap']:.4f} % r, Chipmunk "
                 f"{first['chipmunk']['overlap']:.3f} % r; interior fraction {first['event']['interior']:.3f} vs "
                 f"{first['chipmunk']['interior']:.3f} (one seed)"),
        scene_table, board_table,
        Note("The event engine keeps discs a buffer (1e-6 mean radii) apart, so its overlap is zero up to round-off; "
             "Chipmunk's soft contacts overlap by up to its sub-step plan's tolerance. Whether the two engines give "
             "the same films is measured over 10 seeds per point in docs/reproduction.md (first section)."),
    ]


def main(argv: list[str] | None = None) -> int:
    return cli(run, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    raise SystemExit(main())

"""Model only what a scene needs: the cost of each force when present, and nothing when absent.

One board (a jittered square lattice of 7.5 px dots at 17 px pitch, velocities N(0, 10) px/s,
closed box 100 px away) is run by several simulations side by side, each with one force (or none), from the
same start, all on the pinned Chipmunk settings (`benchmarks.pinned.CHIPMUNK`: the defaults of 0.3.0, the
thesis's 20 ms frame). They are stepped in turn, `CHUNK` steps at a time, so drifts in machine speed hit them
alike; each row gives the median ms/step over the chunks and its noise (half the interquartile
range), split into our force phase (bulk read, kicks, bulk write; `Simulation.timings`) and
Chipmunk's ``space.step``. The run is about a second of simulated time (`ROUNDS`): the gravity rows speed the
dots up as it goes, and with them the sub-steps a step takes.

The absent rows check that what is not modelled costs nothing, with an exact error: a
simulation with no forces at fixed sub-steps (``overlap_tolerance = None``) with impacts resolved where Chipmunk
finds them (``impacts = "overlap"``: nothing of ours in the contacts) against Chipmunk's ``space.step`` called
directly on the same settings, and an open board against a closed one (no dot reaches a wall in
the timed steps), must give bit-identical boards (error = largest position difference, 0
expected) at the same cost within noise. The default ``no forces`` row adapts its sub-steps to
the approach speeds (`qdots.engine.chipmunk_step`) and moves each impact's pair to where the impact at contact
leaves it (`qdots.engine.contacts`): it is not bare Chipmunk but a more accurate integration,
so it is reported with its sub-steps per step and its worst overlap beside the direct steps'.
``bulk I/O only`` is a force that adds nothing: what any force pays for reading and writing the
velocities.

Run: ``python -m benchmarks.qdots_model_cost [--quick] [--figures DIR]``
"""

from __future__ import annotations

import math
import time

import numpy as np

import qdots
from qdots.analysis import overlaps
from qdots.forces import Force, StepContext

from . import pinned
from .report import Headline, Note, Table, cli
from .staleness import CHIPMUNK_ENGINE

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = (*CHIPMUNK_ENGINE, "qdots/forces", "qdots/simulation.py", "benchmarks/pinned.py")

#: Steps per chunk, and chunks (rounds) timed, by (quick, dots): about 1 s simulated at 3,000 dots (quick 0.4 s),
#: 0.3 s at 30,000.
CHUNK = 2
ROUNDS = {(True, 3000): 10, (False, 3000): 25, (False, 30000): 8}


class NoForce(Force):
    """A force that adds nothing: isolates the bulk read/write every force pays for."""

    def kick(self, ctx: StepContext) -> None:
        pass


def board(n: int, seed: int = 0, margin: float = 100.0) -> qdots.Scene:
    """A jittered 17 px lattice ``margin`` px from the walls (no dot reaches them in the timed ~1 s)."""
    side = int(math.ceil(math.sqrt(n)))
    rng = np.random.default_rng(seed)
    ij = np.argwhere(np.ones((side, side)))[:n].astype(float)
    return qdots.Scene(box=(17.0 * side + 2 * margin,) * 2,
                       positions=margin + 17.0 * ij + rng.uniform(-0.9, 0.9, (n, 2)),
                       radii=np.full(n, 7.5), velocities=rng.normal(0.0, 10.0, (n, 2)))


#: The rows whose boards are compared, and the row each is compared with: the first and the last must be
#: bit-identical (nothing absent is modelled); the second shows how far the adaptive sub-steps move the board.
COMPARED = {"no forces, fixed sub-steps": "Chipmunk space.step called directly",
            "no forces": "Chipmunk space.step called directly",
            "no forces, open board (no walls)": "no forces"}


def variants(scene: qdots.Scene) -> list[tuple[str, qdots.Simulation, bool]]:
    """(label, simulation, step Chipmunk directly?) for every row."""
    w, h = scene.box
    rows = [("Chipmunk space.step called directly", [], True, scene),
            ("no forces, fixed sub-steps", [], False, scene),
            ("no forces", [], False, scene),
            ("no forces, open board (no walls)", [], False, scene.replace(closed=False)),
            ("bulk I/O only (a force that adds nothing)", [NoForce()], False, scene),
            ("Gravity", [qdots.Gravity()], False, scene),
            ("CentreGravity", [qdots.CentreGravity((w / 2, h / 2))], False, scene),
            ("Drag", [qdots.Drag()], False, scene),
            ("ThermalKicks", [qdots.ThermalKicks()], False, scene),
            ("Langevin", [qdots.Langevin()], False, scene),
            ("VanDerWaals", [qdots.VanDerWaals()], False, scene),
            ("VanDerWaals + ThermalKicks + Drag", [qdots.VanDerWaals(), qdots.ThermalKicks(), qdots.Drag()], False,
             scene)]
    bare = {"Chipmunk space.step called directly": {"impacts": "overlap"},
            "no forces, fixed sub-steps": {"overlap_tolerance": None, "impacts": "overlap"}}
    return [(label, qdots.Simulation(s, forces, seed=1, engine=pinned.chipmunk(**bare.get(label, {}))), raw)
            for label, forces, raw, s in rows]


def measure(n: int, rounds: int, chunk: int = CHUNK) -> list[dict]:
    sims = variants(board(n))
    total = {label: [] for label, _, _ in sims}
    split = {label: [] for label, _, _ in sims}
    worst = {label: 0.0 for label, _, _ in sims}  # worst overlap at the chunk ends, % of the radius
    for _label, sim, raw in sims:  # warm-up: first pair-list build, caches
        _advance(sim, raw, chunk)
        sim.timings.update(forces=0.0, pymunk=0.0)
    steps, substeps = {}, {}
    for label, sim, _ in sims:
        steps[label], substeps[label] = sim.steps_taken, sim.substeps_taken
    for _ in range(rounds):
        for label, sim, raw in sims:
            before = dict(sim.timings)
            start = time.perf_counter()
            _advance(sim, raw, chunk)
            total[label].append(1e3 * (time.perf_counter() - start) / chunk)
            split[label].append(1e3 * (sim.timings["forces"] - before["forces"]) / chunk)
            worst[label] = max(worst[label], 100.0 * overlaps(sim.state())[0])
    states = {label: sim.state() for label, sim, _ in sims}
    rows = []
    for label, sim, raw in sims:
        ms = np.array(total[label])
        q1, median, q3 = np.percentile(ms, [25, 50, 75])
        identical = ""
        if label in COMPARED:
            other = COMPARED[label]
            identical = f"{np.abs(states[label].positions - states[other].positions).max():.3g} vs {other}"
        per_step = 1.0 if raw else (sim.substeps_taken - substeps[label]) / (sim.steps_taken - steps[label])
        rows.append({"N": n, "label": label, "ms": float(median), "noise": float((q3 - q1) / 2),
                     "forces_ms": float(np.median(split[label])), "difference": identical,
                     "substeps": per_step, "overlap": worst[label], "wall_contacts": sim.collisions.dot_wall})
    return rows


def _advance(sim: qdots.Simulation, raw: bool, steps: int) -> None:
    if not raw:
        sim.step(steps)
        return
    for _ in range(steps):  # what Simulation.step does with no forces, minus its bookkeeping
        sim.backend.space.step(sim.dt)
    sim.steps_taken += steps
    sim.substeps_taken += steps


def table(rows: list[dict]) -> Table:
    baseline = {r["N"]: r["ms"] for r in rows if r["label"] == "no forces"}
    out = []
    for r in rows:
        added = r["ms"] - baseline[r["N"]]
        out.append([r["N"], r["label"], r["ms"], f"+- {r['noise']:.2f}", f"{added:+.2f}",
                    f"{r['forces_ms']:.4f}", f"{r['substeps']:.2f}", f"{r['overlap']:.3f}",
                    r["difference"], r["wall_contacts"]])
    return Table(f"ms per step (dt {1e3 * pinned.CHIPMUNK.dt:g} ms) of each force alone, from the same board",
                 ["N", "simulation", "ms/step (median)", "noise (IQR/2)", "vs no forces", "force phase ms/step",
                  "Chipmunk sub-steps per step", "worst overlap (% r)",
                  "error: max position difference (px)", "wall contacts"], out)


def run(quick: bool) -> list:
    sizes = (3000,) if quick else (3000, 30000)
    rows = []
    for n in sizes:
        rows += measure(n, rounds=ROUNDS[quick, n])
    n0 = sizes[0]
    by = {r["label"]: r for r in rows if r["N"] == n0}
    none, raw = by["no forces"], by["Chipmunk space.step called directly"]
    fixed, walls = by["no forces, fixed sub-steps"], by["no forces, open board (no walls)"]
    io = by["bulk I/O only (a force that adds nothing)"]
    return [
        Headline(f"absent forces and walls, {n0:,} dots",
                 f"no forces at fixed sub-steps {fixed['ms']:.2f} ms/step vs direct space.step {raw['ms']:.2f} "
                 f"(+- {raw['noise']:.2f}); adaptive {none['ms']:.2f} at {none['substeps']:.2f} sub-steps per step; "
                 f"no walls {walls['ms']:.2f}",
                 f"max position difference: fixed sub-steps {fixed['difference']}, no walls {walls['difference']}; "
                 f"worst overlap adaptive "
                 f"{none['overlap']:.2f} % r vs direct {raw['overlap']:.2f} %"),
        table(rows),
        Note(f"Each force's cost is its row minus `no forces`; at {n0:,} dots the bulk write of the body forces "
             f"that any force triggers costs {io['ms'] - none['ms']:.2f} ms/step, paid once however many forces "
             "there are (the adaptive sub-step plan reads the velocities with or without forces). "
             "Rows with different forces "
             "drift apart in configuration (gravity piles the dots up, vdW clusters them), so their Chipmunk time "
             "differs too; the force phase column is the forces' own work."),
    ]


def main(argv: list[str] | None = None) -> int:
    return cli(run, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    raise SystemExit(main())

"""The thesis's film runs (``fig2-2`` and ``fig2-3`` presets) as multiples of real time, against their errors.

The thesis's Java ran "in real time or nearly real time". This runs the sigma = 0 experiment of
the ``fig2-2`` preset (300 free dots, one every second, 100 s settle: 400 s simulated) and of the
``fig2-3`` preset (150 dots in a grating, 250 s) on both engines and at several Chipmunk settings (each a
change of the pinned settings, `benchmarks.pinned`: the defaults of 0.3.0, the thesis's 20 ms frame), on the
same seeds, and reports for each setting:

* wall time per run (the overlap sampling below excluded) and the real-time multiple
  (simulated s / wall s), and the speed-up against the default settings;
* Chipmunk sub-steps per time step (the sub-steps adapt to approach speeds, `qdots.engine.chipmunk_step`);
* the worst overlap (r_i + r_j - d) / mean radius, sampled every 20 ms of simulated time (the
  thesis's kick interval) and at the end: mean over seeds and the worst seed;
* the restitution error |measured - drawn| of an isolated head-on impact at the same settings;
* the packing metrics (interior fraction, mean neighbours of interior dots, local psi6) as the
  mean over seeds of the paired difference from the reference: the event engine, the thesis's own algorithm
  (exact hard discs, every collision of a frame in time order; the 20 ms frame is the model, so a shorter
  Chipmunk step is not a converged reference any more), with its standard
  error and the difference in standard errors. The reference and the default run on
  `DEFAULT_SEED_FACTOR` times as many seeds as the other settings: their comparison is the one a
  user relies on, and "within one standard error" holds for an unbiased setting only ~68 % of the
  time per metric whatever the seed count, so the seeds buy a smaller detectable bias, reported
  beside the seed-to-seed spread of each metric (what two seeds of the same setting differ by).

Runs go to a pool of worker processes (default: one per CPU), each run timed on its own; the
settings of a seed run next to each other, so drifts in machine speed hit them alike.

Run: ``python -m benchmarks.fig2_2_realtime [--seeds 8] [--workers 2] [--quick]`` (``--seeds``: seeds of the
other settings; the reference and the default run on twice as many).
"""

from __future__ import annotations

import argparse
import math
import os
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

import qdots
from qdots.analysis import overlaps, packing_summary
from qdots.analysis.structure import hexatic_order
from qdots.experiment import run_experiment
from qdots.presets import get_preset

from . import pinned
from .report import Headline, Note, Table

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = ("qdots/engine", "qdots/forces", "qdots/geometry", "qdots/simulation.py", "qdots/experiment.py",
                 "qdots/presets.py", "qdots/analysis", "benchmarks/pinned.py")

#: (label, engine settings): the first is the reference of the paired differences (the event engine), the
#: second the Chipmunk engine at the pinned settings (the defaults).
SETTINGS = [
    ("event engine (reference)", pinned.EVENT),
    ("Chipmunk (default)", pinned.CHIPMUNK),
    ("Chipmunk, overlap tolerance 0.01", pinned.chipmunk(overlap_tolerance=0.01)),
    ("Chipmunk, overlap tolerance 0.0025", pinned.chipmunk(overlap_tolerance=0.0025)),
    ("Chipmunk, 10 iterations", pinned.chipmunk(iterations=10)),
    ("Chipmunk, impacts overlapped (0.3's first fix undone)", pinned.chipmunk(impacts="overlap")),
    ("Chipmunk, far vdW pairs every 40 ms", pinned.chipmunk(far_interval=0.04)),
]
#: The presets whose sigma = 0 experiment is run.
PRESETS = ("fig2-2", "fig2-3")
#: packing metrics compared between settings: (key in a run's record, label)
METRICS = [("interior", "interior fraction"), ("neighbours", "mean neighbours"), ("psi6", "local psi6")]
FIRST_SEED = 1
#: The reference and the default run on this many times the other settings' seeds.
DEFAULT_SEED_FACTOR = 2
#: Simulated seconds between overlap samples.
SAMPLE_S = 0.02


class WorstOverlap:
    """A run writer that keeps the worst overlap seen (fraction of the mean radius) and its own wall time."""

    def __init__(self, every: int):
        self.every = every
        self.worst = 0.0
        self.wall = 0.0

    def write(self, state: qdots.State) -> None:
        start = time.perf_counter()
        self.worst = max(self.worst, overlaps(state)[0])
        self.wall += time.perf_counter() - start


def restitution_error(settings, seed: int = 3) -> float:
    """|measured - drawn| restitution of an isolated head-on impact at ``settings``."""
    scene = qdots.Scene(box=(400, 200), positions=[[170, 100], [230, 100]], radii=[7.5, 7.5],
                        velocities=[[40.0, 0.0], [-25.0, 0.0]])
    sim = qdots.Simulation(scene, seed=seed, engine=settings)
    before, drawn = sim.state(), sim.collisions.next_elasticity()
    after = sim.run(1.5)
    measured = -(after.velocities[1, 0] - after.velocities[0, 0]) / (before.velocities[1, 0] - before.velocities[0, 0])
    return abs(measured - drawn)


def measure(preset: str, settings, seed: int, quick: float | None) -> dict:
    """One run of the sigma = 0 experiment of ``preset`` on the engine ``settings`` with ``seed``."""
    exp = get_preset(preset, quick=quick or False)[0]
    exp = exp.replace(seed=seed, engine=settings)
    probe = WorstOverlap(every=max(1, round(SAMPLE_S / exp.engine.dt)))
    start = time.perf_counter()
    sim = run_experiment(exp, writers=[probe])
    wall = time.perf_counter() - start - probe.wall
    state = sim.state()
    summary = packing_summary(state)
    return {"seed": seed, "dots": state.n_dots, "simulated_s": state.time, "wall_s": wall,
            "substeps": sim.substeps_taken / sim.steps_taken,
            "collisions": sim.collisions.dot_dot + sim.collisions.dot_wall,
            "worst_overlap_pct": 100 * max(probe.worst, summary["max_overlap"]),
            "interior": summary["interior_fraction"], "neighbours": summary["mean_neighbours_interior"],
            "psi6": hexatic_order(state).local_order}


def paired_difference(values, reference) -> tuple[float, float]:
    """Mean and standard error of ``values - reference`` (paired by seed); nan SE for one seed."""
    diff = np.asarray(values, float) - np.asarray(reference, float)
    se = float(diff.std(ddof=1) / math.sqrt(len(diff))) if len(diff) > 1 else math.nan
    return float(diff.mean()), se


def run_settings(settings, seeds: dict[str, list[int]], quick: float | None,
                 workers: int) -> dict[tuple[str, str], list[dict]]:
    """Every (preset, setting, seed) run, grouped by (preset, setting label), each list in seed order.

    ``seeds`` maps each setting's label to its seeds; the runs of one seed are queued next to each other.
    """
    every_seed = sorted({seed for chosen in seeds.values() for seed in chosen})
    jobs = [(preset, label, changes, seed) for preset in PRESETS for seed in every_seed
            for label, changes in settings if seed in seeds[label]]
    args = [(preset, changes, seed, quick) for preset, _, changes, seed in jobs]
    if workers > 1:
        with ProcessPoolExecutor(workers) as pool:
            done = list(pool.map(measure, *zip(*args)))
    else:
        done = [measure(*a) for a in args]
    runs: dict[tuple[str, str], list[dict]] = {}
    for (preset, label, _, _), record in zip(jobs, done):
        runs.setdefault((preset, label), []).append(record)
    return runs


def shared_seeds(records: list[dict], others: list[dict]) -> tuple[list[dict], list[dict]]:
    """The records of ``records`` and of ``others`` whose seeds both have, in seed order."""
    seeds = {r["seed"] for r in records} & {r["seed"] for r in others}
    return tuple(sorted((r for r in rs if r["seed"] in seeds), key=lambda r: r["seed"]) for rs in (records, others))


def metric_differences(records: list[dict], reference: list[dict]) -> list[tuple[float, float]]:
    """(mean, SE) of the paired difference from ``reference`` of each of `METRICS`, over the shared seeds."""
    mine, theirs = shared_seeds(records, reference)
    return [paired_difference([r[key] for r in mine], [r[key] for r in theirs]) for key, _ in METRICS]


def tables(runs: dict, settings, preset: str, workers: int) -> list:
    reference, default = runs[(preset, settings[0][0])], runs[(preset, settings[1][0])]
    first = reference[0]
    speed_rows, metric_rows = [], []
    for label, changes in settings:
        rs = runs[(preset, label)]
        wall = float(np.mean([r["wall_s"] for r in rs]))
        default_wall = float(np.mean([r["wall_s"] for r in shared_seeds(default, rs)[0]]))
        worst = [r["worst_overlap_pct"] for r in rs]
        speed_rows.append([label, len(rs), changes.kind, float(np.mean([r["substeps"] for r in rs])), wall,
                           first["simulated_s"] / wall, default_wall / wall, float(np.mean(worst)),
                           float(np.max(worst)), restitution_error(changes),
                           float(np.mean([r["collisions"] / r["wall_s"] for r in rs]))])
        row = [label, len(rs)]
        if rs is reference:
            for key, _ in METRICS:
                row += [f"{np.mean([r[key] for r in rs]):.3f}", "(reference)"]
            metric_rows.append(row + [""])
            continue
        ratios = []
        for (key, _), (diff, se) in zip(METRICS, metric_differences(rs, reference)):
            ratios.append(abs(diff) / se if se > 0 else (0.0 if diff == 0 else math.inf))
            row += [f"{np.mean([r[key] for r in rs]):.3f}", f"{diff:+.3f} +- {se:.3f} ({ratios[-1]:.1f} SE)"]
        metric_rows.append(row + [max(ratios)])
    spread = ["seed-to-seed SD, reference", len(reference)]
    for key, _ in METRICS:
        spread += [f"{np.std([r[key] for r in reference], ddof=1):.3f}" if len(reference) > 1 else "", ""]
    metric_rows.append(spread + [""])
    speed = Table(f"{preset}, sigma = 0 ({first['dots']} dots, {first['simulated_s']:.0f} s simulated), "
                  f"{workers} run(s) at a time: time and overlap by setting",
                  ["setting", "seeds", "engine", "sub-steps per step", "wall per run (s)", "x real time",
                   "speed-up vs default (same seeds)", "worst overlap, mean (% r)",
                   "worst overlap, worst seed (% r)", "restitution error", "collisions per wall s"], speed_rows)
    metrics = Table(f"{preset}, the same runs: packing metrics, mean over the seeds, and the paired difference "
                    f"from {settings[0][0]} over the seeds both ran (mean +- SE, and |mean| in SEs); last column: "
                    f"the largest |difference| in SEs (an unbiased setting exceeds 1 for ~32 % of metrics, 2 for "
                    f"~5 %); last row: how much two seeds of the reference differ",
                    ["setting", "seeds"] + [c for _, name in METRICS for c in (name, "difference")]
                    + ["largest |difference| / SE"], metric_rows)
    return [speed, metrics]


def run(quick: bool, seeds: int | None = None, workers: int | None = None) -> list:
    """Both presets at `SETTINGS` over 8 seeds, the reference and the default over `DEFAULT_SEED_FACTOR`
    times as many (quick: the 0.1-scaled presets, 3 settings, 2 seeds and 4)."""
    settings = SETTINGS[:3] if quick else SETTINGS
    count = seeds or (2 if quick else 8)
    chosen = {label: list(range(FIRST_SEED, FIRST_SEED + count * (DEFAULT_SEED_FACTOR if k < 2 else 1)))
              for k, (label, _) in enumerate(settings)}
    workers = workers or (1 if quick else min(2, os.cpu_count() or 1))
    runs = run_settings(settings, chosen, 0.1 if quick else None, workers)
    results = []
    for preset in PRESETS:
        reference, default = runs[(preset, settings[0][0])], runs[(preset, settings[1][0])]
        wall = float(np.mean([r["wall_s"] for r in default]))
        event_wall = float(np.mean([r["wall_s"] for r in reference]))
        first = default[0]
        differences = ", ".join(f"{name} {diff:+.3f} +- {se:.3f}" for (_, name), (diff, se)
                                in zip(METRICS, metric_differences(default, reference)))
        results.append(Headline(
            f"{preset} preset, sigma 0 ({first['dots']} dots, {first['simulated_s']:.0f} s simulated), Chipmunk "
            f"(default) and event engine, {len(default)} seeds",
            f"Chipmunk {first['simulated_s'] / wall:.1f}x real time ({wall:.0f} s per run), event engine "
            f"{first['simulated_s'] / event_wall:.1f}x ({event_wall:.0f} s)",
            f"worst overlap {np.mean([r['worst_overlap_pct'] for r in default]):.2f} % of r (mean over seeds, "
            f"sampled every {SAMPLE_S * 1e3:.0f} ms); against the event engine: {differences}"))
    results.append(Note("Each setting runs the same seeds (the reference and the default twice as many); "
                        "speed-ups are ratios of mean wall times over the seeds both settings ran (overlap "
                        "sampling excluded). Packing differences are paired by seed against the event engine, the "
                        "thesis's algorithm at the same 20 ms frame (a seed gives both engines the same deposition "
                        "and kicks; the collisions then part the films, so the pairing takes out the deposition's "
                        "share of the spread only). The event engine has one sub-step per frame and no overlap; "
                        "its restitution error is that of its exact impact. `collisions per wall s` counts the "
                        "impacts each engine resolved (the event engine's dot-dot and dot-wall events, Chipmunk's "
                        "impacts seen by its pre-solve callback)."))
    for preset in PRESETS:
        results += tables(runs, settings, preset, workers)
    return results


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=None, help="seeds per setting (default 8; quick 2); the reference and the default run twice as many")
    parser.add_argument("--workers", type=int, default=None, help="runs at a time (default: one per CPU, max 2)")
    parser.add_argument("--quick", action="store_true", help="the 0.1-scaled presets, 3 settings, 2 seeds (4 for the reference and the default)")
    args = parser.parse_args(argv)
    from .report import print_results
    print_results(run(args.quick, args.seeds, args.workers))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

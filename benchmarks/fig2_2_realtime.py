"""The thesis's film runs (``fig2-2`` and ``fig2-3`` presets) as multiples of real time, against their errors.

The thesis's Java ran "in real time or nearly real time". This runs the sigma = 0 experiment of
the ``fig2-2`` preset (300 free dots, one every second, 100 s settle: 400 s simulated) and of the
``fig2-3`` preset (150 dots in a grating, 250 s) at several engine settings on the same seeds,
and reports for each setting:

* wall time per run (the overlap sampling below excluded) and the real-time multiple
  (simulated s / wall s), and the speed-up against the default settings;
* Chipmunk sub-steps per time step (the sub-steps adapt to approach speeds, `qdots.stepping`);
* the worst overlap (r_i + r_j - d) / mean radius, sampled every 20 ms of simulated time (the
  thesis's kick interval) and at the end: mean over seeds and the worst seed;
* the restitution error |measured - drawn| of an isolated head-on impact at the same settings;
* the packing metrics (interior fraction, mean neighbours of interior dots, local psi6) as the
  mean over seeds of the paired difference from the converged reference (the first setting,
  dt = 0.25 ms at 10 solver iterations, every van der Waals pair every step), with its standard
  error, and whether each is within one standard error.

Runs go to a pool of worker processes (default: one per CPU), each run timed on its own; the
settings of a seed run next to each other, so drifts in machine speed hit them alike.

Run: ``python -m benchmarks.fig2_2_realtime [--seeds 8] [--workers 2] [--quick]``
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

from .qdots_cases import VDW_KNOBS
from .report import Headline, Note, Table

#: (label, settings changed from the preset's: engine settings, and the van der Waals force's `VDW_KNOBS`);
#: the first is the converged reference of the paired differences, the second the default.
SETTINGS = [
    ("0.25 ms (reference)", {"dt": 2.5e-4, "iterations": 10, "far_interval": None}),
    ("2.5 ms (default)", {}),
    ("5 ms", {"dt": 5e-3}),
    ("1.25 ms", {"dt": 1.25e-3}),
    ("2.5 ms, vdW every step", {"far_interval": None}),
    ("2.5 ms, 10 iterations", {"iterations": 10}),
    ("2.5 ms, overlap tolerance 0.01", {"overlap_tolerance": 0.01}),
    ("1 ms, fixed sub-steps", {"dt": 1e-3, "overlap_tolerance": None, "iterations": 10, "far_interval": None}),
]
#: The presets whose sigma = 0 experiment is run.
PRESETS = ("fig2-2", "fig2-3")
#: packing metrics compared between settings: (key in a run's record, label)
METRICS = [("interior", "interior fraction"), ("neighbours", "mean neighbours"), ("psi6", "local psi6")]
FIRST_SEED = 1
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


def restitution_error(settings: qdots.EngineSettings, seed: int = 3) -> float:
    """|measured - drawn| restitution of an isolated head-on impact at ``settings``."""
    scene = qdots.Scene(box=(400, 200), positions=[[170, 100], [230, 100]], radii=[7.5, 7.5],
                        velocities=[[40.0, 0.0], [-25.0, 0.0]])
    sim = qdots.Simulation(scene, seed=seed, engine=settings)
    before, drawn = sim.state(), sim.collisions.next_elasticity()
    after = sim.run(1.5)
    measured = -(after.velocities[1, 0] - after.velocities[0, 0]) / (before.velocities[1, 0] - before.velocities[0, 0])
    return abs(measured - drawn)


def engine_changes(changes: dict) -> dict:
    """The engine settings among ``changes`` (the rest are the van der Waals force's)."""
    return {k: v for k, v in changes.items() if k not in VDW_KNOBS}


def measure(preset: str, changes: dict, seed: int, quick: float | None) -> dict:
    """One run of the sigma = 0 experiment of ``preset`` with the ``changes`` and ``seed``."""
    exp = get_preset(preset, quick=quick or False)[0]
    vdw = {k: v for k, v in changes.items() if k in VDW_KNOBS}
    forces = tuple({**f, **vdw} if f["type"] == "VanDerWaals" else f for f in exp.forces)
    exp = exp.replace(seed=seed, engine=exp.engine.replace(**engine_changes(changes)), forces=forces)
    probe = WorstOverlap(every=max(1, round(SAMPLE_S / exp.engine.dt)))
    start = time.perf_counter()
    sim = run_experiment(exp, writers=[probe])
    wall = time.perf_counter() - start - probe.wall
    state = sim.state()
    summary = packing_summary(state)
    return {"seed": seed, "dots": state.n_dots, "simulated_s": state.time, "wall_s": wall,
            "substeps": sim.substeps_taken / sim.steps_taken,
            "worst_overlap_pct": 100 * max(probe.worst, summary["max_overlap"]),
            "interior": summary["interior_fraction"], "neighbours": summary["mean_neighbours_interior"],
            "psi6": hexatic_order(state).local_order}


def paired_difference(values, reference) -> tuple[float, float]:
    """Mean and standard error of ``values - reference`` (paired by seed); nan SE for one seed."""
    diff = np.asarray(values, float) - np.asarray(reference, float)
    se = float(diff.std(ddof=1) / math.sqrt(len(diff))) if len(diff) > 1 else math.nan
    return float(diff.mean()), se


def run_settings(settings, seeds, quick: float | None, workers: int) -> dict[tuple[str, str], list[dict]]:
    """Every (preset, setting, seed) run, grouped by (preset, setting label), each list in seed order."""
    jobs = [(preset, label, changes, seed) for preset in PRESETS for seed in seeds for label, changes in settings]
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


def tables(runs: dict, settings, preset: str, workers: int) -> list:
    reference, default = runs[(preset, settings[0][0])], runs[(preset, settings[1][0])]
    default_wall = float(np.mean([r["wall_s"] for r in default]))
    first, n_seeds = reference[0], len(reference)
    speed_rows, metric_rows = [], []
    for label, changes in settings:
        rs = runs[(preset, label)]
        wall = float(np.mean([r["wall_s"] for r in rs]))
        worst = [r["worst_overlap_pct"] for r in rs]
        engine = qdots.EngineSettings(**engine_changes(changes))
        speed_rows.append([label, 1e3 * engine.dt, float(np.mean([r["substeps"] for r in rs])), wall,
                           first["simulated_s"] / wall, default_wall / wall, float(np.mean(worst)),
                           float(np.max(worst)), restitution_error(engine)])
        row, within = [label], True
        for key, _ in METRICS:
            mean = float(np.mean([r[key] for r in rs]))
            if rs is reference:
                row += [f"{mean:.3f}", "(reference)"]
                continue
            diff, se = paired_difference([r[key] for r in rs], [r[key] for r in reference])
            within &= abs(diff) <= se
            row += [f"{mean:.3f}", f"{diff:+.3f} +- {se:.3f}"]
        metric_rows.append(row + ["" if rs is reference else ("yes" if within else "no")])
    speed = Table(f"{preset}, sigma = 0 ({first['dots']} dots, {first['simulated_s']:.0f} s simulated), {n_seeds} "
                  f"seeds, {workers} run(s) at a time: time and overlap by setting",
                  ["setting", "dt (ms)", "Chipmunk sub-steps per step", "wall per run (s)", "x real time",
                   "speed-up vs default", "worst overlap, mean (% r)", "worst overlap, worst seed (% r)",
                   "restitution error"], speed_rows)
    metrics = Table(f"{preset}, the same runs: packing metrics, mean over {n_seeds} seeds, and the paired difference "
                    f"from {settings[0][0]} (mean +- SE); last column: every difference within one SE",
                    ["setting"] + [c for _, name in METRICS for c in (name, "difference")] + ["within 1 SE"],
                    metric_rows)
    return [speed, metrics]


def run(quick: bool, seeds: int | None = None, workers: int | None = None) -> list:
    """Both presets at `SETTINGS` over 8 seeds (quick: the 0.1-scaled presets, 3 settings, 2 seeds)."""
    settings = SETTINGS[:3] if quick else SETTINGS
    seeds = range(FIRST_SEED, FIRST_SEED + (seeds or (2 if quick else 8)))
    workers = workers or (1 if quick else min(2, os.cpu_count() or 1))
    runs = run_settings(settings, seeds, 0.1 if quick else None, workers)
    results = []
    for preset in PRESETS:
        default = runs[(preset, settings[1][0])]
        wall = float(np.mean([r["wall_s"] for r in default]))
        first = default[0]
        results.append(Headline(
            f"{preset} preset, sigma 0 ({first['dots']} dots, {first['simulated_s']:.0f} s simulated), default "
            f"settings, {len(default)} seeds",
            f"{first['simulated_s'] / wall:.1f}x real time ({wall:.0f} s per run)",
            f"worst overlap {np.mean([r['worst_overlap_pct'] for r in default]):.2f} % of r (mean over seeds, "
            f"sampled every {SAMPLE_S * 1e3:.0f} ms)"))
    results.append(Note("Each setting runs the same seeds; speed-ups are ratios of mean wall times (overlap "
                        "sampling excluded). Packing differences are paired by seed against the converged "
                        "reference: dt = 0.25 ms, 10 solver iterations, every van der Waals pair pulled every "
                        "step; `1 ms, fixed sub-steps` (10 iterations, vdW every step) is the step of 0.2 on this "
                        "engine (0.2 also handed the forces to Chipmunk differently, see `qdots.stepping`)."))
    for preset in PRESETS:
        results += tables(runs, settings, preset, workers)
    return results


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=None, help="seeds per setting (default 8; quick 2)")
    parser.add_argument("--workers", type=int, default=None, help="runs at a time (default: one per CPU, max 2)")
    parser.add_argument("--quick", action="store_true", help="the 0.1-scaled presets, 3 settings, 2 seeds")
    args = parser.parse_args(argv)
    from .report import print_results
    print_results(run(args.quick, args.seeds, args.workers))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

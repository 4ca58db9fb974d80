"""The ``fig2-2`` preset (300 free dots, 400 s simulated) as a multiple of real time, against its errors.

The thesis's Java ran "in real time or nearly real time". This runs the sigma = 0 experiment
of the ``fig2-2`` preset (300 dots, one every second, 100 s settle) at several engine settings
(time step ``dt`` and Chipmunk sub-steps) on the same seeds, and reports for each setting:

* wall time per run and the real-time multiple (simulated s / wall s), and the speed-up
  against the default settings (ratio of mean wall times);
* the worst overlap (r_i + r_j - d) / mean radius, sampled every simulated second and at the
  end (mean over seeds and the worst seed);
* the restitution error |measured - drawn| of an isolated head-on impact at the same settings;
* the packing metrics (interior fraction, mean neighbours of interior dots, local psi6) as the
  mean over seeds of the paired difference from the reference setting (the smallest Chipmunk
  step), with its standard error.

Runs go to a pool of worker processes (default: one per CPU), each run timed on its own; the
settings of a seed run next to each other, so drifts in machine speed hit them alike.

Run: ``python -m benchmarks.fig2_2_realtime [--seeds 8] [--workers 2] [--quick F]``
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

from .report import Headline, Note, Table

#: (label, dt s, Chipmunk sub-steps); the first is the reference of the paired differences.
SETTINGS = [("1 ms / 1 (default)", 1e-3, 1), ("1.5 ms / 1", 1.5e-3, 1), ("2 ms / 1", 2e-3, 1), ("3 ms / 1", 3e-3, 1),
            ("4 ms / 2", 4e-3, 2)]
#: packing metrics compared between settings: (key in a run's record, label)
METRICS = [("interior", "interior fraction"), ("neighbours", "mean neighbours"), ("psi6", "local psi6")]
FIRST_SEED = 1


class WorstOverlap:
    """A run writer that keeps the worst overlap seen (fraction of the mean radius)."""

    def __init__(self, every: int):
        self.every = every
        self.worst = 0.0

    def write(self, state: qdots.State) -> None:
        self.worst = max(self.worst, overlaps(state)[0])


def restitution_error(settings: qdots.EngineSettings, seed: int = 3) -> float:
    """|measured - drawn| restitution of an isolated head-on impact at ``settings``."""
    scene = qdots.Scene(box=(400, 200), positions=[[170, 100], [230, 100]], radii=[7.5, 7.5],
                        velocities=[[40.0, 0.0], [-25.0, 0.0]])
    sim = qdots.Simulation(scene, seed=seed, **settings.to_dict())
    before = sim.state()
    after = sim.run(1.5)
    measured = -(after.velocities[1, 0] - after.velocities[0, 0]) / (before.velocities[1, 0] - before.velocities[0, 0])
    drawn = qdots.Restitution().draw(np.random.default_rng(seed), approach_speed=np.inf)
    return abs(measured - drawn)


def measure(dt: float, substeps: int, seed: int, quick: float | None) -> dict:
    """One run of the sigma = 0 fig2-2 experiment at ``dt`` / ``substeps`` and ``seed``."""
    exp = get_preset("fig2-2", quick=quick or False)[0]
    settings = exp.engine.replace(dt=dt, substeps=substeps, spatial_hash=None)
    exp = exp.replace(seed=seed, engine=settings)
    probe = WorstOverlap(every=max(1, round(1.0 / dt)))
    start = time.perf_counter()
    sim = run_experiment(exp, writers=[probe])
    wall = time.perf_counter() - start
    state = sim.state()
    summary = packing_summary(state)
    return {"dt": dt, "substeps": substeps, "seed": seed, "dots": state.n_dots, "simulated_s": state.time,
            "wall_s": wall, "worst_overlap_pct": 100 * max(probe.worst, summary["max_overlap"]),
            "interior": summary["interior_fraction"], "neighbours": summary["mean_neighbours_interior"],
            "psi6": hexatic_order(state).local_order}


def paired_difference(values, reference) -> tuple[float, float]:
    """Mean and standard error of ``values - reference`` (paired by seed); nan SE for one seed."""
    diff = np.asarray(values, float) - np.asarray(reference, float)
    se = float(diff.std(ddof=1) / math.sqrt(len(diff))) if len(diff) > 1 else math.nan
    return float(diff.mean()), se


def run_settings(settings, seeds, quick: float | None, workers: int) -> dict[str, list[dict]]:
    """Every (setting, seed) run, grouped by setting label, each list in seed order."""
    jobs = [(label, dt, sub, seed) for seed in seeds for label, dt, sub in settings]
    if workers > 1:
        with ProcessPoolExecutor(workers) as pool:
            done = list(pool.map(measure, *zip(*[(dt, sub, seed, quick) for _, dt, sub, seed in jobs])))
    else:
        done = [measure(dt, sub, seed, quick) for _, dt, sub, seed in jobs]
    runs: dict[str, list[dict]] = {label: [] for label, _, _ in settings}
    for (label, *_), record in zip(jobs, done):
        runs[label].append(record)
    return runs


def tables(runs: dict[str, list[dict]], settings, workers: int) -> list:
    reference = runs[settings[0][0]]
    base_wall = float(np.mean([r["wall_s"] for r in reference]))
    first = reference[0]
    n_seeds = len(reference)
    speed_rows, metric_rows = [], []
    for label, dt, sub in settings:
        rs = runs[label]
        wall = float(np.mean([r["wall_s"] for r in rs]))
        worst = [r["worst_overlap_pct"] for r in rs]
        speed_rows.append([label, 1e3 * dt / sub, wall, first["simulated_s"] / wall, base_wall / wall,
                           float(np.mean(worst)), float(np.max(worst)),
                           restitution_error(qdots.EngineSettings(dt=dt, substeps=sub))])
        row = [label]
        within = True
        for key, _ in METRICS:
            mean = float(np.mean([r[key] for r in rs]))
            if rs is reference:
                row += [f"{mean:.3f}", "(reference)"]
                continue
            diff, se = paired_difference([r[key] for r in rs], [r[key] for r in reference])
            within &= abs(diff) <= se
            row += [f"{mean:.3f}", f"{diff:+.3f} +- {se:.3f}"]
        metric_rows.append(row + ["" if rs is reference else ("yes" if within else "no")])
    speed = Table(f"fig2-2, sigma = 0 ({first['dots']} dots, {first['simulated_s']:.0f} s simulated), {n_seeds} seeds, "
                  f"{workers} run(s) at a time: time and overlap by setting; goal: 4x the default's speed with the "
                  f"worst overlap < 1 % of r",
                  ["dt / sub-steps", "Chipmunk step (ms)", "wall per run (s)", "x real time", "speed-up",
                   "worst overlap, mean (% r)", "worst overlap, worst seed (% r)", "restitution error"], speed_rows)
    metrics = Table(f"The same runs: packing metrics, mean over {n_seeds} seeds, and the paired difference from "
                    f"{settings[0][0]} (mean +- SE); last column: every difference within one SE",
                    ["dt / sub-steps"] + [c for _, name in METRICS for c in (name, "difference")]
                    + ["within 1 SE"], metric_rows)
    return [speed, metrics]


def run(quick: bool, seeds: int | None = None, workers: int | None = None) -> list:
    """The full preset at `SETTINGS` over 8 seeds (quick: the 0.1-scaled preset, 2 settings, 2 seeds)."""
    settings = SETTINGS[:2] if quick else SETTINGS
    seeds = range(FIRST_SEED, FIRST_SEED + (seeds or (2 if quick else 8)))
    workers = workers or (1 if quick else min(2, os.cpu_count() or 1))
    runs = run_settings(settings, seeds, 0.1 if quick else None, workers)
    results = tables(runs, settings, workers)
    default = runs[settings[0][0]]
    wall = float(np.mean([r["wall_s"] for r in default]))
    first = default[0]
    return [Headline(f"fig2-2 preset ({first['dots']} dots, {first['simulated_s']:.0f} s simulated, dt 1 ms), "
                     f"{len(default)} seeds",
                     f"{first['simulated_s'] / wall:.1f}x real time ({wall:.0f} s per run)",
                     f"worst overlap {np.mean([r['worst_overlap_pct'] for r in default]):.2f} % of r (mean over "
                     f"seeds)"),
            Note("Larger steps: the speed-up is the ratio of mean wall times to the default's on the same seeds; "
                 "the packing differences are paired by seed against the default (dt 1 ms, which the "
                 "`qdots_knobs` section compares with 0.25 ms on the scaled preset)."),
            *results]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=None, help="seeds per setting (default 8; quick 2)")
    parser.add_argument("--workers", type=int, default=None, help="runs at a time (default: one per CPU, max 2)")
    parser.add_argument("--quick", action="store_true", help="the 0.1-scaled preset, 2 settings, 2 seeds")
    args = parser.parse_args(argv)
    from .report import print_results
    print_results(run(args.quick, args.seeds, args.workers))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""Sweep throughput: 2 local workers (and a 2-worker Dask LocalCluster) against one process.

The sweep: the Fig 2-2 preset on the pinned Chipmunk settings (`benchmarks.pinned.CHIPMUNK`) scaled by ``--quick``
(0.3: 90 dots, 27 s of deposition, 30 s to settle; 5-6 s of wall time per run on an idle core here), at sigma 0 and 0.15, ``--seeds`` seeds
each. Each executor runs the whole sweep into a fresh directory; sequential and 2-worker runs
alternate ``--repeats`` times (the machine is shared: timings vary 20-40 %). Goal: >= 1.8x with
2 workers.

``worker busy`` is the time spent inside runs over workers x sweep wall time: what is missing is
the executor's own overhead (process start, pickling, records, the table) and idle workers.
``CPU share`` is the runs' CPU time over their wall time: below 100 %, other processes on the
machine took the cores (the speedup then measures them, not the executor).
``error`` is the largest difference between that run's table and the first sequential table over
every cell but ``wall_s`` (0 means identical: numbers bit for bit, text equal; a text mismatch
would show as inf). Identical tables are the reproducibility promise: a run depends only on its
parameters, not on the executor, the worker count or the order in which runs finish.

Run: ``python -m benchmarks.sweeps [--quick 0.3] [--seeds 2] [--repeats 2] [--no-dask]``
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import tempfile
import time
from dataclasses import dataclass

from labrig.sweeps import Sweep, run_sweep
from qdots.cli.sweep import ExperimentRunner, experiment_to_dict
from qdots.presets import PRESETS

from . import pinned
from .staleness import CHIPMUNK_ENGINE

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = (*CHIPMUNK_ENGINE,
                 "labrig/sweeps", "qdots/cli/sweep.py", "qdots/forces", "qdots/experiment.py", "benchmarks/pinned.py")

#: Columns that measure the machine, not the run: left out of the table comparison.
TIMINGS = ("wall_s", "cpu_s")


@dataclass(frozen=True)
class CpuTimedRunner(ExperimentRunner):
    """`ExperimentRunner` whose row also has the run's CPU time, ``cpu_s``."""

    def __call__(self, params, state_path=None):
        start = time.process_time()
        row = super().__call__(params, state_path)
        return {**row, "cpu_s": time.process_time() - start}


def table_error(rows, reference) -> float:
    """Largest |difference| between two tables' cells (`TIMINGS` excepted); inf if they differ otherwise."""
    if len(rows) != len(reference) or any(list(a) != list(b) for a, b in zip(rows, reference)):
        return math.inf
    worst = 0.0
    for a, b in zip(rows, reference):
        for key in a:
            x, y = a[key], b[key]
            if key in TIMINGS or x == y:
                continue
            numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (x, y))
            if numeric and math.isnan(x) and math.isnan(y):
                continue
            worst = max(worst, abs(x - y) if numeric else math.inf)
    return worst


def timed(sweep: Sweep, runner, **executor) -> tuple[float, list, float]:
    """Wall time and table of the sweep run into a fresh directory, and the 1-minute load average before it."""
    load = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as out:
        start = time.perf_counter()
        result = run_sweep(sweep, runner, out, progress=False, **executor)
        wall = time.perf_counter() - start
    if result.failed:
        raise RuntimeError(f"{result.failed} runs failed: {[r['error'] for r in result.rows if r['error']]}")
    return wall, result.rows, load


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", type=float, default=0.3, help="Experiment.quick factor of each run (0.3)")
    parser.add_argument("--seeds", type=int, default=2, help="seeds per sigma (2: 4 runs)")
    parser.add_argument("--repeats", type=int, default=2, help="sequential / 2-worker alternations (2)")
    parser.add_argument("--no-dask", action="store_true", help="skip the Dask LocalCluster row")
    args = parser.parse_args(argv)
    sweep = Sweep(base=experiment_to_dict(PRESETS["fig2-2"][0].replace(engine=pinned.CHIPMUNK)),
                  axes={"deposition.sigma": [0.0, 0.15]},
                  seeds=args.seeds)
    runner = CpuTimedRunner(quick=args.quick)
    print(f"python {platform.python_version()}, {os.cpu_count()} cores, {len(sweep)} runs of the Fig 2-2 preset "
          f"at quick {args.quick:g}\n")
    results = []  # (executor, workers, wall, rows, load)
    for _ in range(args.repeats):
        for name, workers in (("sequential", 1), ("local processes", 2)):
            results.append((name, workers, *timed(sweep, runner, workers=workers)))
    if not args.no_dask:
        try:
            from distributed import LocalCluster
        except ImportError:
            print("(no dask.distributed: pip install 'nanodisorder[sweep]' for the Dask row)\n")
        else:
            with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
                results.append(("dask LocalCluster", 2, *timed(sweep, runner, scheduler=cluster.scheduler_address)))
    reference = results[0][3]
    sequential = [wall for name, _, wall, _, _ in results if name == "sequential"]
    base = sum(sequential) / len(sequential)
    run_walls = [row["wall_s"] for row in reference]
    print(f"one run: {min(run_walls):.1f} to {max(run_walls):.1f} s (sequential, first repeat)\n")
    print("| executor | workers | sweep wall (s) | runs/min | speedup vs mean sequential | worker busy | CPU share "
          "| error (max table diff) | load before |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name, workers, wall, rows, load in results:
        inside = sum(row["wall_s"] for row in rows)
        busy, share = inside / (workers * wall), sum(row["cpu_s"] for row in rows) / inside
        print(f"| {name} | {workers} | {wall:.1f} | {60 * len(rows) / wall:.1f} | {base / wall:.2f}x | {busy:.0%} "
              f"| {share:.0%} | {table_error(rows, reference):.3g} | {load:.1f} |")
    pairs = [results[k][2] / results[k + 1][2] for k in range(0, 2 * args.repeats, 2)]
    best = max(pairs)
    print(f"\n2 workers vs sequential, same repeat: {', '.join(f'{p:.2f}x' for p in pairs)}; "
          f"goal >= 1.8x: {'met' if best >= 1.8 else 'NOT met'} (best {best:.2f}x)")
    print("worker busy: time inside runs / (workers x sweep wall); CPU share: CPU time / wall time of the runs "
          "(below 100 % other processes took the cores); load before: 1-minute load average")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

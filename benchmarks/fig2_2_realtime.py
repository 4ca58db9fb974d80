"""The ``fig2-2`` preset (300 free dots, 400 s simulated) as a multiple of real time, with its errors.

The thesis's Java ran "in real time or nearly real time". For each time step dt
this runs the sigma = 0 experiment of the ``fig2-2`` preset (300 dots, one every
second, 100 s settle) and reports, measured in the same run:

* wall time and the real-time multiple (simulated s / wall s),
* the worst overlap (r_i + r_j - d) / mean radius, sampled every 5 s of the run,
* the restitution error |measured - drawn| of an isolated head-on impact at the
  same settings (exact answer: the drawn eps),
* the packing result (interior fraction, mean neighbours of interior dots).

Run: ``python -m benchmarks.fig2_2_realtime [--dts 0.001 0.002] [--quick F]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import qdots
from qdots.analysis import overlaps, packing_summary
from qdots.experiment import run_experiment
from qdots.presets import get_preset

from .report import Headline, Table


class WorstOverlap:
    """A run writer that keeps the worst overlap seen."""

    def __init__(self, every: int):
        self.every = every
        self.worst = 0.0

    def write(self, state: qdots.State) -> None:
        self.worst = max(self.worst, overlaps(state)[0])


def restitution_error(settings: qdots.EngineSettings, seed: int = 3) -> float:
    scene = qdots.Scene(box=(400, 200), positions=[[170, 100], [230, 100]], radii=[7.5, 7.5],
                        velocities=[[40.0, 0.0], [-25.0, 0.0]])
    sim = qdots.Simulation(scene, seed=seed, **settings.to_dict())
    before = sim.state()
    after = sim.run(1.5)
    measured = -(after.velocities[1, 0] - after.velocities[0, 0]) / (before.velocities[1, 0] - before.velocities[0, 0])
    drawn = qdots.Restitution().draw(np.random.default_rng(seed), approach_speed=np.inf)
    return abs(measured - drawn)


def measure(dt: float, quick: float | None) -> dict:
    exp = get_preset("fig2-2", quick=quick or False)[0]
    exp = exp.replace(engine=qdots.EngineSettings(**{**exp.engine.to_dict(), "dt": dt, "spatial_hash": None}))
    probe = WorstOverlap(every=max(1, round(5.0 / dt)))
    start = time.perf_counter()
    sim = run_experiment(exp, writers=[probe])
    wall = time.perf_counter() - start
    state = sim.state()
    summary = packing_summary(state)
    return {
        "dt_ms": dt * 1e3,
        "simulated_s": state.time,
        "wall_s": wall,
        "x_real_time": state.time / wall,
        "worst_overlap_pct": 100 * max(probe.worst, summary["max_overlap"]),
        "restitution_error": restitution_error(exp.engine),
        "interior": summary["interior_fraction"],
        "dots": state.n_dots,
        "neighbours": summary["mean_neighbours_interior"],
    }


def table(rows: list[dict]) -> Table:
    return Table("fig2-2, sigma = 0, default settings except dt; goal >= 100x real time",
                 ["dt (ms)", "dots", "simulated (s)", "wall (s)", "x real time", "worst overlap (% r)",
                  "restitution error", "interior fraction", "mean neighbours"],
                 [[r["dt_ms"], r["dots"], round(r["simulated_s"]), r["wall_s"], r["x_real_time"],
                   r["worst_overlap_pct"], r["restitution_error"], r["interior"], r["neighbours"]] for r in rows])


def run(quick: bool) -> list:
    """The full preset at dt 1 and 2 ms (quick: the 0.1-scaled preset at 1 ms)."""
    rows = [measure(dt, 0.1 if quick else None) for dt in ((1e-3,) if quick else (1e-3, 2e-3))]
    first = rows[0]
    return [Headline(f"fig2-2 preset ({first['dots']} dots, {first['simulated_s']:.0f} s simulated, dt 1 ms)",
                     f"{first['x_real_time']:.0f}x real time",
                     f"worst overlap {first['worst_overlap_pct']:.2f} % of r, restitution error "
                     f"{first['restitution_error']:.0e}"),
            table(rows)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dts", type=float, nargs="+", default=[1e-3, 2e-3])
    parser.add_argument("--quick", type=float, default=None, help="scale the preset down (e.g. 0.1)")
    args = parser.parse_args(argv)
    rows = [measure(dt, args.quick) for dt in args.dts]
    print(table(rows).markdown())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""The event engine's choices where the thesis's listing is silent, and how far each alternative moves the films.

The OCR'd listing lacks the call site of ``updateVelocityAttraction`` (is a pair pulled once, or once from
each side?), and its collision loop's cap and buffer are numbers whose effect is not stated. Each choice is
set against its alternative on the two films that tell the mass models apart, full size, 5 seeds each
(154-158): the ``fig2-2`` film at sigma 0 with equal masses and at sigma 15 % with masses ~ d^3.

* **pull once per unordered pair** (ours: each pair's velocity change ``min(a dt/2, sqrt(g a)/2)`` given once
  to each dot, as Eq 2.3's pair force acts) against **once per ordered pair** (a loop over every dot and
  each of its neighbours, updating both: every pair pulled twice);
* **max_events = 1,000,000** (ours: a frame's collisions resolved, a cluster's inelastic collapse included)
  against the Java's ``maxIterations = 2500``;
* **buffer 1e-6 mean radii** (the Java's ``epsilonSpace = 1e-6``, px in the Java, where a mean radius is
  7.5 px) against 1e-3.

Run: ``python -m benchmarks.qdots_event_choices [--quick] [--figures DIR]`` (about 10 minutes on 2 cores;
``--quick``: boards scaled down 10x, 2 seeds).
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

import qdots
from qdots.analysis import packing_summary
from qdots.analysis.structure import clusters
from qdots.experiment import build_simulation, populate
from qdots.presets import get_preset

from . import pinned
from .report import Headline, Note, Table, cli

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = ("qdots/engine", "qdots/forces", "qdots/simulation.py", "qdots/experiment.py", "benchmarks/pinned.py")


class PullTwice(qdots.VanDerWaals):
    """The thesis's proxy applied once per ordered pair: every pair's velocity change given twice."""

    def kick(self, ctx) -> None:
        super().kick(ctx)
        super().kick(ctx)


#: Each variant: (label, engine settings changed, whether the pull is given twice).
VARIANTS = (("ours: once per pair, cap 1e6, buffer 1e-6", {}, False),
            ("pull once per ordered pair (twice)", {}, True),
            ("the Java's event cap, 2,500", {"max_events": 2500}, False),
            ("buffer 1e-3 mean radii", {"buffer": 1e-3}, False))
#: The films: (label, sigma, mass model).
FILMS = (("sigma 0, equal masses", 0.0, "equal"), ("sigma 15 %, masses ~ d^3", 0.15, "volume"))
MEASURES = (("interior", "interior fraction", 3), ("aggregates", "aggregates (>= 5)", 1),
            ("largest", "largest share", 2), ("speed", "mean speed (px/s)", 1))


def one_run(args) -> dict:
    film, variant, seed, quick = args
    _, sigma, mass_model = next(f for f in FILMS if f[0] == film)
    _, changes, twice = next(v for v in VARIANTS if v[0] == variant)
    base = next(exp for exp in get_preset("fig2-2", quick=0.1 if quick else False) if exp.deposition.sigma == sigma)
    exp = base.replace(seed=seed, deposition=dataclasses.replace(base.deposition, mass_model=mass_model),
                       engine=pinned.event(**changes))
    start = time.perf_counter()
    sim = build_simulation(exp)
    if twice:
        sim.forces = [PullTwice(**{k: v for k, v in f.to_dict().items() if k != "type"})
                      if isinstance(f, qdots.VanDerWaals) else f for f in sim.forces]
    populate(sim, exp)
    state = sim.state()
    summary = packing_summary(state)
    _, sizes = clusters(state)
    return {"film": film, "variant": variant, "seed": seed, "wall": time.perf_counter() - start,
            "interior": summary["interior_fraction"], "aggregates": float(np.sum(sizes >= 5)),
            "largest": float(sizes[0] / sizes.sum()), "speed": float(np.hypot(*state.velocities.T).mean()),
            "capped": sim.backend.diagnostics()["capped_frames"], "events": sim.backend.diagnostics()["events"]}


def mean_se(values) -> tuple[float, float]:
    values = np.asarray(values, float)
    return float(values.mean()), float(values.std(ddof=1) / math.sqrt(values.size)) if values.size > 1 else math.nan


def run(quick: bool) -> list:
    seeds = (154, 155) if quick else tuple(range(154, 159))
    jobs = [(film[0], variant[0], seed, quick) for film in FILMS for variant in VARIANTS for seed in seeds]
    with ProcessPoolExecutor(max_workers=min(2, os.cpu_count() or 1)) as pool:
        rows = list(pool.map(one_run, jobs))
    table = Table(f"Event engine, full-size fig2-2 films{' (quick: 10x smaller)' if quick else ''}: mean +- standard "
                  f"error over seeds {seeds[0]}-{seeds[-1]}; shift = (variant - ours) / combined SE",
                  ["film", "variant", *(label for _, label, _ in MEASURES), "largest shift (SE)",
                   "frames at the cap", "wall per run (s)"])
    shifts = {}
    for film, _, _ in FILMS:
        ours = [r for r in rows if r["film"] == film and r["variant"] == VARIANTS[0][0]]
        for variant, _, _ in VARIANTS:
            mine = [r for r in rows if r["film"] == film and r["variant"] == variant]
            cells, worst = [], 0.0
            for key, _, digits in MEASURES:
                m, se = mean_se([r[key] for r in mine])
                m0, se0 = mean_se([r[key] for r in ours])
                cells.append(f"{m:.{digits}f} +- {se:.{digits}f}")
                combined = math.hypot(se, se0)
                if variant != VARIANTS[0][0] and combined > 0:
                    worst = max(worst, abs(m - m0) / combined)
            shifts[(film, variant)] = worst
            table.rows.append([film, variant, *cells, "" if variant == VARIANTS[0][0] else f"{worst:.1f}",
                               sum(r["capped"] for r in mine), f"{np.mean([r['wall'] for r in mine]):.1f}"])
    moved = [f"{variant} on {film} ({shift:.1f} SE)" for (film, variant), shift in shifts.items() if shift > 2]
    return [
        Headline("event engine: the listing's open choices",
                 f"{len(rows)} full films" if not quick else f"{len(rows)} quick films",
                 "alternatives that move a metric by more than 2 combined SE: " + (", ".join(moved) or "none")),
        table,
        Note("A shift above 2 SE means the choice matters for the figures; our choice rests on the thesis's text: "
             "Eq 2.3 is a pair force (equal and opposite, once per pair), and the Java's epsilonSpace is 1e-6; step 5 "
             "caps the loop at a number of iterations (the Java's 2,500), which we raise so that a frame's "
             "collisions are resolved (qdots.Event.max_events says what the Java's cap does to a film)."),
    ]


def main(argv: list[str] | None = None) -> int:
    return cli(run, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    raise SystemExit(main())

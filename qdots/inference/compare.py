"""``qdots compare``: the simulation that matches a measured film, run, and set beside it.

`matching_experiment` builds the thesis's deposition (random arrival one dot per second, 100 s to
settle, van der Waals attraction and thermal kicks, masses ~ d^3) with the film's measured size
spread and coverage: ``n_dots`` dots of mean diameter 15 px (the thesis's) on a square board whose
side gives the film's coverage, ``L = sqrt(n pi d^2 (1 + sigma^2) / (4 coverage))``. One board px
is then ``mean diameter (nm) / 15`` nm: the stated scale of the simulated film. `compare_film` runs
it for several seeds and measures every film as the image was measured (`film_metrics`, the film
LQE), so the table gives the image's value beside the simulation's mean +- standard error. It returns a
`Comparison` and writes nothing: `qdots.micrograph.overlay` draws it, `qdots.cli.files` writes
``qdots compare``'s files. The seeds can run in parallel processes (``workers``): each process runs its seed and saves
the simulation (`qdots.io.checkpoint`), which is loaded back here, so the films, the table and every file written
are the same as one process gives (saving a loaded simulation writes the same bytes).
"""

from __future__ import annotations

import math
import os
import tempfile
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from labrig.validate import InputError, choice, count

from ..analysis.lqe import film_lqe
from ..engine import ENGINES
from ..experiment import Board, Deposition, Experiment, default_forces, run_experiment
from ..micrograph.choices import MAX_COMPARE_DOTS, MAX_SEEDS, MAX_WORKERS
from ..micrograph.film import film_metrics
from ..micrograph.measure import MeasuredFilm, lqe_draws
from ..presets import MEAN_DIAMETER, THESIS_SEED

#: Metrics of the comparison table: (key, label, digits).
METRICS = (("coverage", "coverage", 3), ("size_spread", "size spread sigma", 3),
           ("interior_fraction", "interior fraction (>= 5 neighbours)", 3), ("mean_neighbours", "mean neighbours", 2),
           ("psi6_local", "psi6 local", 3), ("psi6_global", "psi6 global", 3), ("aggregates", "aggregates (>= 5 dots)", 1),
           ("largest_share", "largest cluster (share)", 3), ("single_dots", "single dots (per 100 dots)", 1),
           ("gr_peak_diameters", "g(r) first peak (mean diameters)", 2), ("lqe", "film LQE", 3))
#: Metrics the simulation is given (not predictions): the board is built to match them.
MATCHED = ("coverage", "size_spread")
#: Largest coverage a simulated board is asked to take (random deposition jams near 0.55-0.6).
MAX_COVERAGE = 0.55
#: Largest size spread a simulated deposition is given.
MAX_SPREAD = 0.5
#: The caps of the matched metrics, and why (`table_rows` says when one applied).
CAPS = {"coverage": (MAX_COVERAGE, "a random deposition jams near 0.55-0.6"),
        "size_spread": (MAX_SPREAD, "the largest spread a deposition is given")}


@dataclass(frozen=True)
class Comparison:
    """A measured film and the simulations of it.

    Attributes
    ----------
    film : MeasuredFilm
    experiment : Experiment
        The experiment run (its seed the first one's).
    nm_per_board_px : float
        nm per px of the simulated board.
    simulations : list of qdots.Simulation
        The run of each seed (``qdots.io.checkpoint.save`` writes them resumable).
    states : list of qdots.State
        The final board of each seed.
    runs : list of dict
        The metrics of each seed's film.
    table : list of dict
        One row per metric: ``metric``, ``label``, ``image``, ``simulation`` (mean), ``standard_error``,
        ``seeds``, ``matched`` (the simulation was built to match it: coverage and size spread).
    """

    film: MeasuredFilm
    experiment: Experiment
    nm_per_board_px: float
    simulations: list
    states: list
    runs: list
    table: list


def matching_experiment(film: MeasuredFilm, n_dots: int = 300, engine: str = "chipmunk", seed: int = THESIS_SEED,
                        name: str | None = None) -> tuple[Experiment, float]:
    """The thesis's deposition with the film's size spread and coverage, and nm per board px (see the module)."""

    n_dots = count("dots", n_dots, 2, MAX_COMPARE_DOTS)
    engine = choice("engine", engine, tuple(ENGINES))
    s = film.summary
    sigma = float(s["size_spread"])
    coverage = float(s["coverage"])
    if not (math.isfinite(sigma) and math.isfinite(coverage) and coverage > 0):
        raise InputError(f"the film has no measured size spread or coverage (sigma {sigma}, coverage {coverage}): "
                         "too few whole dots to simulate it")
    sigma = min(max(sigma, 0.0), MAX_SPREAD)
    asked = min(coverage, MAX_COVERAGE)
    side = math.sqrt(n_dots * math.pi * MEAN_DIAMETER**2 * (1.0 + sigma**2) / (4.0 * asked))
    deposition = Deposition(protocol="random", n_dots=n_dots, mean_diameter=MEAN_DIAMETER, sigma=sigma,
                            mass_model="volume", interval=1.0, settle=100.0)
    exp = Experiment(name=name or f"film of {film.image.source}", seed=seed, board=Board(side, side, True),
                     deposition=deposition, forces=default_forces())
    exp = exp.replace(engine=exp.engine.replace(kind=engine))
    scale = s["mean_diameter_nm"] / MEAN_DIAMETER if math.isfinite(s["nm_per_px"]) else math.nan
    return exp, scale


def simulated_metrics(state) -> dict:
    """`film_metrics` of a simulated board, with its coverage (disc area over board area) and film LQE."""

    out = film_metrics(state)
    out["coverage"] = float(np.sum(np.pi * np.asarray(state.radii) ** 2) / (state.box[0] * state.box[1]))
    out["lqe"] = film_lqe(state, draws=lqe_draws(state.n_dots), seed=0).mean
    return out


def per_hundred(metrics: dict) -> dict:
    """``single_dots`` as dots per 100 dots (films of different sizes compare)."""
    return {**metrics, "single_dots": 100.0 * metrics["single_dots"] / max(metrics["dots"], 1)}


def default_workers(seeds: int) -> int:
    """One process per core this process may use, at most one per seed."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, min(seeds, cores, MAX_WORKERS))


def seed_film(exp: Experiment, folder: str) -> tuple[str, dict]:
    """Run ``exp`` (in a worker process), save its simulation into ``folder``; the file and the film's metrics."""
    from ..io import checkpoint

    sim = run_experiment(exp)
    path = checkpoint.save(sim, Path(folder) / f"seed-{exp.seed}.npz")
    return str(path), per_hundred(simulated_metrics(sim.state()))


def run_seeds(exp: Experiment, seeds: int, workers: int, progress: bool) -> list[tuple]:
    """``(simulation, state, metrics)`` of ``exp`` at its seed and the ``seeds - 1`` after it, in seed order: in this
    process, or in ``workers`` processes (each simulation loaded back from the file its process saved)."""
    experiments = [exp.replace(seed=exp.seed + k) for k in range(seeds)]
    if workers <= 1 or seeds == 1:
        out = []
        for one in experiments:
            sim = run_experiment(one, progress=progress)
            state = sim.state()
            out.append((sim, state, per_hundred(simulated_metrics(state))))
        return out
    from labrig.sweeps.backends import exit_with_parent

    from ..io.checkpoint import load

    with tempfile.TemporaryDirectory(prefix="qdots-compare-") as folder:
        with ProcessPoolExecutor(max_workers=min(workers, seeds), initializer=exit_with_parent,
                                 initargs=(os.getpid(),)) as pool:
            done = list(pool.map(seed_film, experiments, [folder] * seeds))
        sims = [load(path) for path, _ in done]
    return [(sim, sim.state(), metrics) for sim, (_, metrics) in zip(sims, done)]


def compare_film(film: MeasuredFilm, seeds: int = 3, n_dots: int = 300, engine: str = "chipmunk",
                 progress: bool = False, name: str | None = None, workers: int = 1) -> Comparison:
    """Run `matching_experiment` for ``seeds`` seeds (the thesis's 154, 155, ...) and tabulate image against
    simulation (mean +- standard error over the seeds); ``workers`` > 1 runs the seeds in that many processes
    (the same result; progress is shown only in one process)."""
    seeds = count("seeds", seeds, 1, MAX_SEEDS)
    workers = count("workers", workers, 1, MAX_WORKERS)
    exp, scale = matching_experiment(film, n_dots, engine, name=name)
    sims, states, runs = (list(column) for column in zip(*run_seeds(exp, seeds, workers, progress)))
    image = per_hundred(film.summary)
    table = []
    for key, label, _ in METRICS:
        values = np.array([run[key] for run in runs], dtype=float)
        finite = values[np.isfinite(values)]
        mean = float(finite.mean()) if finite.size else math.nan
        se = float(finite.std(ddof=1) / math.sqrt(finite.size)) if finite.size > 1 else math.nan
        table.append({"metric": key, "label": label, "image": float(image.get(key, math.nan)), "simulation": mean,
                      "standard_error": se, "seeds": int(finite.size), "matched": key in MATCHED})
    return Comparison(film, exp, scale, sims, states, runs, table)


def table_rows(comparison: Comparison) -> list[tuple[str, str]]:
    """(label, text) rows: image value, simulation mean +- SE."""
    digits = {key: d for key, _, d in METRICS}
    rows = []
    for row in comparison.table:
        d = digits[row["metric"]]
        se = f" +- {row['standard_error']:.{d}f}" if math.isfinite(row["standard_error"]) else ""
        given = "   (set to match)" if row["matched"] else ""
        cap, why = CAPS.get(row["metric"], (math.inf, ""))
        if row["matched"] and row["image"] > cap:
            given = f"   (set to match, capped at {cap:g}: {why})"
        rows.append((row["label"], f"image {row['image']:.{d}f}   simulation {row['simulation']:.{d}f}{se}{given}"))
    return rows

"""qdots infer: a first inference on a fresh install, the calibration of its intervals and of its mass-model
probabilities on held-out synthetic micrographs, how the posterior narrows with the observations, and the films'
speed-up on a Dask LocalCluster.

* **A first inference** (`qdots.inference.infer.infer_image` at its defaults: the 3,000 training films of 150 dots
  shipped with the package, 3 networks, 24 films in the predictive check, 2 local workers) on the shared TEM
  micrograph, with a new library folder (no training film runs; the networks train, the calibrations are fitted),
  then again (the posterior loads). The library is kept in the system's temporary folder
  (``qdots-infer-library``) for notebook 06, which loads it.
* **Calibration**: ``FILMS`` held-out films (`qdots.inference.calibration`: drawn from the prior over its whole
  range, none in the training, nor among the library films that calibrated the intervals), drawn as micrographs,
  measured, and the posterior's 90 % intervals counted against the truth, per parameter; beside it the same from
  each film's board (no picture), and the networks' own intervals before their calibration. The mass models:
  the confusion table (true model against the most probable) and the reliability of the probabilities.
* **Observations**: ``TEST_GROUPS`` held-out depositions (replicate groups from 1,000 on: not those shipped for
  the joint calibration), 8 films each; the joint posterior of the first m films' boards, m = 1, 2, 4, 8: the
  intervals' coverage and width, and the mass model's accuracy, against the dots in view.
* **Dask**: ``DASK_FILMS`` films on a LocalCluster of 1 and of 2 worker processes (one thread each), after one
  warm-up film per worker (the compiled kernels load).

Run: ``python -m benchmarks.qdots_infer [--quick]``. For a release, ``python -m benchmarks.qdots_infer --ship DIR``
builds the training and replicate films in ``DIR`` (about 50 + 10 minutes on 2 cores) and writes the tables
shipped with the package (`qdots.inference.library.SHIPPED`, `SHIPPED_REPLICATES`).
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from qdots.inference.calibration import (
    calibration_films,
    coverage_table,
    model_choice_by_condition,
    model_choice_tables,
)
from qdots.inference.conformal import describe_factor
from qdots.inference.forward import FILM_DOTS, MASS_MODELS, PARAMETERS
from qdots.inference.infer import infer_image
from qdots.inference.library import (
    REPLICATE_COPIES,
    REPLICATE_GROUPS,
    SHIPPED,
    SHIPPED_REPLICATES,
    build_library,
    build_replicates,
    prior_point,
    replicate_groups,
    run_points,
    shipped_replicates,
    write_shipped,
)
from qdots.inference.posterior import credible_intervals, load_or_train
from qdots.micrograph.choices import LIBRARY_FILMS

from .report import Headline, Note, Table, machine_info, machine_line, print_results

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = ("qdots/inference", "qdots/micrograph", "qdots/engine", "qdots/forces", "qdots/experiment.py",
                 "qdots/deposition.py", "qdots/analysis")

TEM = Path(__file__).resolve().parents[2] / "shared" / "data" / "micrographs" / "nanoparticle_film_tem.png"
#: Held-out films of the calibration, and films of the Dask measurement (full, quick).
FILMS, QUICK_FILMS = 200, 6
#: Held-out replicate groups of the observations' table (from group 1,000 on), and their copies (full, quick).
TEST_GROUPS, QUICK_TEST_GROUPS, TEST_FIRST = 40, 3, 1000
DASK_FILMS, QUICK_DASK_FILMS = 24, 4


def library_folder(quick: bool) -> Path:
    """Where the benchmark keeps its library (the full one is notebook 06's)."""
    return Path(tempfile.gettempdir()) / ("qdots-infer-library-quick" if quick else "qdots-infer-library")


def held_out_folder(quick: bool) -> Path:
    """Where the benchmark keeps its held-out films (simulated once, kept across runs: they depend only on the
    prior and the simulator)."""
    return Path(tempfile.gettempdir()) / ("qdots-infer-held-out-quick" if quick else "qdots-infer-held-out")


def one_inference(quick: bool) -> tuple[list, Any]:
    """Cold and warm inference on the shared micrograph: the timing rows and the warm result."""
    folder = library_folder(quick)
    shutil.rmtree(folder, ignore_errors=True)
    options: dict[str, Any] = dict(films=60, n_dots=30, check_films=4, ensemble=1) if quick else {}
    rows = []
    for label in ("first: a new library folder (the shipped films; the networks train)",
                  "again (nothing runs, the posterior loads)"):
        start = time.perf_counter()
        result = infer_image(TEM, folder, workers=2, progress=not quick, **options)
        wall = time.perf_counter() - start
        t = result.timings
        rows.append([label, f"{wall:.0f}", f"{t['measure']:.1f}", f"{t['library']:.0f}", t["library_films_run"],
                     f"{t['train']:.0f}", f"{t['sample']:.1f}", f"{t['check']:.0f}"])
    return rows, result


def dask_speedup(films: int, n_dots: int) -> list:
    """Wall seconds of ``films`` films of ``n_dots`` dots on LocalClusters of 1 and 2 workers."""
    from distributed import Client, LocalCluster

    points = [prior_point(10_000 + k, "calibration", n_dots) for k in range(films)]
    out = []
    for workers in (1, 2):
        with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
                Client(cluster) as client, tempfile.TemporaryDirectory() as folder:
            warm = [dict(prior_point(20_000 + k, "calibration"), n_dots=12) for k in range(workers)]
            run_points(warm, Path(folder) / "warm", scheduler=client, progress=False)
            start = time.perf_counter()
            rows = run_points(points, Path(folder) / "films", scheduler=client, progress=False)
            out.append((workers, time.perf_counter() - start, sum(r["status"] == "ok" for r in rows)))
    return out


def pct(share: float, se: float | None = None) -> str:
    """A share as a percentage, with its standard error when given."""
    return f"{100 * share:.0f} %" + ("" if se is None else f" +- {100 * se:.0f}")


def calibration_tables(posterior, films: list, wall: float, left_out: list) -> tuple[list, list]:
    """The coverage table and the mass models' confusion and reliability tables of the held-out films, and where
    the picture tells the mass models apart."""
    cal = coverage_table(films)
    coverage = Table(f"Calibration: share of {len(films)} held-out films (drawn over the whole prior: coverage "
                     "0.05-0.7, sigma 0.03-0.25) whose 90 % interval holds the truth (binomial SE beside it; the "
                     "goal 85-95 %)",
                     ["parameter", "from the micrograph", "mean width (share of prior)", "from the board",
                      "mean width (board)", "networks' own, from the micrograph", "their width", "spread"],
                     [[r["label"], pct(r["coverage_image"], r["coverage_image_se"]), pct(r["width_image"]),
                       pct(r["coverage_board"], r["coverage_board_se"]), pct(r["width_board"]),
                       pct(r["coverage_image_raw"], r["coverage_image_raw_se"]), pct(r["width_image_raw"]),
                       describe_factor(factor)]
                      for r, factor in zip(cal, posterior.calibration.factors)])
    coverage.note = (f"{wall:.0f} s for the films, their micrographs and their posteriors. Left out: {len(left_out)} "
                     f"of {len(films) + len(left_out)}" + "".join(
                         f"; coverage {p['coverage']:.2f}, sigma {p['sigma']:.2f}: {why[:160]}" for p, why in left_out))
    out = [coverage]
    for source in ("image", "board"):
        reliability, confusion = model_choice_tables(films, source)
        right = np.trace(confusion) / max(1, confusion.sum())
        out.append(Table(f"Mass model from the {'micrograph' if source == 'image' else 'board'}: true model (rows) "
                         f"against the most probable (columns), {confusion.sum()} films; right {pct(right)} "
                         "(a third by chance)", ["true model", *(m.key for m in MASS_MODELS)],
                         [[m.label, *map(str, row)] for m, row in zip(MASS_MODELS, confusion)]))
        out.append(Table(f"Are its probabilities honest? ({'micrograph' if source == 'image' else 'board'}): the "
                         "most probable model's probability, binned, against how often it was the true one",
                         ["probability", "films", "mean probability given", "share right"],
                         [[f"{r['low']:.1f}-{r['high']:.1f}", r["films"],
                           "" if not r["films"] else f"{r['stated']:.2f}",
                           "" if not r["films"] else f"{r['right']:.2f}"] for r in reliability]))
    out.append(Table("Where a micrograph tells the mass models apart: the most probable model right, and the mean "
                     "probability of the true one (a third by chance), by the film's size spread and coverage",
                     ["size spread sigma", "coverage", "films", "right", "mean P(true model)"],
                     [[f"{r['sigma'][0]:.2f}-{r['sigma'][1]:.2f}", f"{r['coverage'][0]:.2f}-{r['coverage'][1]:.2f}",
                       r["films"], "" if not r["films"] else pct(r["right"]),
                       "" if not r["films"] else f"{r['p_true']:.2f}"] for r in model_choice_by_condition(films)]))
    return out, cal


def observations_table(posterior, folder: Path, groups: int, n_dots: int, counts=(1, 2, 4, 8)) -> Table:
    """The joint posterior of 1, 2, 4 and 8 films of held-out depositions (their boards): coverage and width of the
    90 % intervals, and the mass model's accuracy, against the dots in view."""
    rows = build_replicates(folder, groups, max(counts), workers=2, progress=False, n_dots=n_dots, first=TEST_FIRST)
    sets = replicate_groups(rows)
    dots = float(np.mean([r["complete_dots"] for r in rows if r.get("status") == "ok" and r.get("complete_dots")]))
    table: list = []
    for m in counts:
        chosen = [g for g in sets if len(g[2]) >= m]
        hits, widths, right, given = [], [], [], []
        for k, (theta, model, x) in enumerate(chosen):
            draws, _ = posterior.sample_joint(x[:m], 2000, seed=k)
            intervals = credible_intervals(draws)
            hits.append([i["low"] <= t <= i["high"] for i, t in zip(intervals, theta)])
            widths.append([i["width_share"] for i in intervals])
            chance = posterior.model_probabilities(x[:m])
            right.append(int(np.argmax(chance) == model))
            given.append(float(chance[model]))
        hits_a, widths_a = np.array(hits, dtype=float), np.array(widths)
        table.append([m, f"{m * dots:.0f}", len(chosen),
                      *(f"{pct(h)} / {pct(w)}" for h, w in zip(hits_a.mean(axis=0), widths_a.mean(axis=0))),
                      pct(float(np.mean(right))), f"{np.mean(given):.2f}"])
    return Table(f"Several observations of one deposition ({len(sets)} held-out depositions, their films' boards): "
                 "90 % interval coverage / mean width (share of the prior) per parameter, and the mass model",
                 ["observations", "dots in view", "sets", *(p.label for p in PARAMETERS), "mass model right",
                  "mean P(true model)"], table)


def run(quick: bool) -> list:
    from qdots.micrograph.choices import INFER_EXTRA, missing_infer_extra

    if missing_infer_extra():
        return [Note(f"Not run: {INFER_EXTRA}.")]
    timing_rows, result = one_inference(quick)
    timing = Table("A first inference on the shared micrograph (2 local workers)",
                   ["run", "wall s", "measure s", "library s", "films run", "training s", "sampling s",
                    "predictive check s"], timing_rows)
    intervals = Table("What it infers on the shared micrograph (sigma {sigma:.3f}, coverage {coverage:.3f}; "
                      .format(**result.conditions) + f"{result.dots} measured dots, {result.observations} "
                      f"observation{'s' if result.observations > 1 else ''}: {result.calibrated_as})",
                      ["parameter", "median", "90 % interval", "share of the prior"],
                      [[r["label"], f"{r['median']:.3g}", f"[{r['low']:.3g}, {r['high']:.3g}]",
                        f"{100 * r['width_share']:.0f} %"] for r in result.intervals]
                      + [[m["label"], f"probability {m['probability']:.2f}", "", ""] for m in result.mass_models])
    check = Table("Its posterior-predictive check (* conditioned on)", ["measure", "micrograph", "predicted median",
                                                                        "predicted 90 %", "inside"],
                  [[r["label"] + (" *" if r["used"] else ""), f"{r['image']:.3g}", f"{r['median']:.3g}",
                    f"[{r['low']:.3g}, {r['high']:.3g}]", "yes" if r["inside"] else "NO"] for r in result.check])
    folder = library_folder(quick)
    n_dots = 30 if quick else FILM_DOTS
    lib = build_library(folder, 60 if quick else LIBRARY_FILMS, workers=2, progress=False, n_dots=n_dots)
    posterior, _ = load_or_train(folder, lib.theta, lib.models, lib.x, lib.ids, ensemble=1 if quick else 3,
                                 replicates=replicate_groups(shipped_replicates(n_dots)))
    start = time.perf_counter()
    left_out: list = []
    held_out = held_out_folder(quick)
    films = calibration_films(posterior, QUICK_FILMS if quick else FILMS, held_out / "films", n_dots=n_dots,
                              workers=2, progress=not quick, left_out=left_out)
    calibration, cal = calibration_tables(posterior, films, time.perf_counter() - start, left_out)
    observations = observations_table(posterior, held_out / "replicates",
                                      QUICK_TEST_GROUPS if quick else TEST_GROUPS, n_dots)
    dask_films = QUICK_DASK_FILMS if quick else DASK_FILMS
    (_, one, ok1), (_, two, ok2) = dask_speedup(dask_films, n_dots)
    dask = Table(f"The films on a Dask LocalCluster ({dask_films} films of {n_dots} dots)",
                 ["workers", "wall s", "films done", "speed-up"],
                 [[1, f"{one:.1f}", ok1, "1"], [2, f"{two:.1f}", ok2, f"{one / two:.2f}"]])
    cold, warm = float(timing_rows[0][1]), float(timing_rows[1][1])
    return [Headline("qdots infer: a first inference on the shared micrograph (fresh install, then again), "
                     "calibration", f"{cold / 60:.1f} min first, {warm:.0f} s again",
                     "90 % intervals hold the truth in " + ", ".join(
                         f"{r['parameter']} {100 * r['coverage_image']:.0f} %" for r in cal)),
            timing, intervals, check, *calibration, observations, dask,
            Note("Parameters: " + "; ".join(f"{p.label}: prior [{p.low:g}, {p.high:g}], thesis {p.thesis:g}"
                                            for p in PARAMETERS) + "; mass models: "
                 + ", ".join(m.label for m in MASS_MODELS) + ", a third each."),
            Note(f"Truths of the held-out films span the prior: {np.round(np.ptp([[f.point[p.key] for p in PARAMETERS] for f in films], axis=0), 2).tolist()} "
                 "(range per parameter).")]


def ship(folder: Path) -> list:
    """Build the training and replicate films in ``folder`` and write the tables shipped with the package."""
    start = time.perf_counter()
    lib = build_library(folder, LIBRARY_FILMS, workers=2, progress=True)
    written = [write_shipped(lib.rows, SHIPPED[FILM_DOTS])]
    replicates = build_replicates(folder / "replicates", REPLICATE_GROUPS, REPLICATE_COPIES, workers=2, progress=True)
    written.append(write_shipped(replicates, SHIPPED_REPLICATES[FILM_DOTS]))
    return [Note(f"Shipped {len(lib.rows)} training films ({len(lib.ids)} usable) and {len(replicates)} replicate "
                 f"films in {time.perf_counter() - start:.0f} s: " + ", ".join(str(p) for p in written))]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the small version run by the test suite")
    parser.add_argument("--ship", type=Path, default=None, metavar="DIR",
                        help="build the films in DIR and write the tables shipped with the package (a release)")
    args = parser.parse_args(argv)
    print(machine_line(machine_info()) + "\n")
    print_results(ship(args.ship) if args.ship is not None else run(args.quick))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())

"""qdots infer: one inference on the shared micrograph cold and with the library built, the calibration of its
credible intervals on held-out synthetic micrographs, and the films' speed-up on a Dask LocalCluster.

* **One inference** (`qdots.inference.infer.infer_image` at its defaults: 1,000 training films of 150 dots,
  3 networks, 24 films in the predictive check, 2 local workers) on the shared TEM micrograph, with a new
  library (cold: every film runs, the networks train), then again with the library built (nothing runs,
  the posterior loads). The library is kept in the system's temporary folder (``qdots-infer-library``) for
  notebook 06, which loads it.
* **Calibration**: ``FILMS`` held-out films (`qdots.inference.calibration`: drawn from the prior, none in the
  training, nor among the library films that calibrated the intervals), drawn as micrographs, measured, and the
  posterior's 90 % intervals counted against the truth, per parameter; beside it the same from each film's
  board (no picture), and the networks' own intervals before their calibration.
* **Dask**: ``DASK_FILMS`` films on a LocalCluster of 1 and of 2 worker processes (one thread each), after one
  warm-up film per worker (the compiled kernels load).

Run: ``python -m benchmarks.qdots_infer [--quick]``
"""

from __future__ import annotations

import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from qdots.inference.calibration import calibration_films, coverage_table
from qdots.inference.conformal import describe_factor
from qdots.inference.forward import PARAMETERS
from qdots.inference.infer import infer_image
from qdots.inference.library import build_library, prior_point, run_points
from qdots.inference.posterior import load_or_train

from .report import Headline, Note, Table, cli

#: The code this benchmark measures (besides itself): a commit to it after a run marks the run's section as
#: older than its code (`benchmarks.staleness`).
MEASURED_CODE = ("qdots/micrograph", "qdots/engine", "qdots/forces", "qdots/experiment.py", "qdots/deposition.py",
                 "qdots/analysis")

TEM = Path(__file__).resolve().parents[2] / "shared" / "data" / "micrographs" / "nanoparticle_film_tem.png"
#: Held-out films of the calibration, and films of the Dask measurement (full, quick).
FILMS, QUICK_FILMS = 40, 6
DASK_FILMS, QUICK_DASK_FILMS = 24, 4


def library_folder(quick: bool) -> Path:
    """Where the benchmark keeps its library (the full one is notebook 06's)."""
    return Path(tempfile.gettempdir()) / ("qdots-infer-library-quick" if quick else "qdots-infer-library")


def one_inference(quick: bool) -> tuple[list, object]:
    """Cold and warm inference on the shared micrograph: the timing rows and the warm result."""
    folder = library_folder(quick)
    shutil.rmtree(folder, ignore_errors=True)
    options = dict(films=60, n_dots=30, check_films=4, ensemble=1) if quick else {}
    rows = []
    for label in ("cold: new library (films run, networks trained)", "library built (nothing runs, posterior loads)"):
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


def run(quick: bool) -> list:
    from qdots.micrograph.choices import INFER_EXTRA, missing_infer_extra

    if missing_infer_extra():
        return [Note(f"Not run: {INFER_EXTRA}.")]
    timing_rows, result = one_inference(quick)
    timing = Table("One inference on the shared micrograph (2 local workers)",
                   ["run", "wall s", "measure s", "library s", "films run", "training s", "sampling s",
                    "predictive check s"], timing_rows)
    intervals = Table("What it infers on the shared micrograph (sigma {sigma:.3f}, coverage {coverage:.3f})"
                      .format(**result.conditions), ["parameter", "median", "90 % interval", "share of the prior"],
                      [[r["label"], f"{r['median']:.3g}", f"[{r['low']:.3g}, {r['high']:.3g}]",
                        f"{100 * r['width_share']:.0f} %"] for r in result.intervals])
    check = Table("Its posterior-predictive check (* conditioned on)", ["measure", "micrograph", "predicted median",
                                                                        "predicted 90 %", "inside"],
                  [[r["label"] + (" *" if r["used"] else ""), f"{r['image']:.3g}", f"{r['median']:.3g}",
                    f"[{r['low']:.3g}, {r['high']:.3g}]", "yes" if r["inside"] else "NO"] for r in result.check])
    folder = library_folder(quick)
    n_dots = 30 if quick else 150
    lib = build_library(folder, 60 if quick else 1000, workers=2, progress=False, n_dots=n_dots)
    posterior, _ = load_or_train(folder, lib.theta, lib.x, lib.ids, ensemble=1 if quick else 3)
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as held_out:
        films = calibration_films(posterior, QUICK_FILMS if quick else FILMS, held_out, n_dots=n_dots, workers=2,
                                  progress=not quick)
    calibration_wall = time.perf_counter() - start
    cal = coverage_table(films)
    calibration = Table(f"Calibration: share of {len(films)} held-out films whose 90 % interval holds the truth "
                        "(binomial SE beside it; the goal 80-97 % for an identifiable parameter)",
                        ["parameter", "from the micrograph", "mean width (share of prior)", "from the board",
                         "mean width (board)", "networks' own, from the micrograph", "their width",
                         "spread"],
                        [[r["label"], f"{100 * r['coverage_image']:.0f} % +- {100 * r['coverage_image_se']:.0f}",
                          f"{100 * r['width_image']:.0f} %",
                          f"{100 * r['coverage_board']:.0f} % +- {100 * r['coverage_board_se']:.0f}",
                          f"{100 * r['width_board']:.0f} %",
                          f"{100 * r['coverage_image_raw']:.0f} % +- {100 * r['coverage_image_raw_se']:.0f}",
                          f"{100 * r['width_image_raw']:.0f} %", describe_factor(factor)]
                         for r, factor in zip(cal, posterior.calibration.factors)])
    calibration.note = f"{calibration_wall:.0f} s for the films, their micrographs and their posteriors."
    dask_films = QUICK_DASK_FILMS if quick else DASK_FILMS
    (_, one, ok1), (_, two, ok2) = dask_speedup(dask_films, n_dots)
    dask = Table(f"The films on a Dask LocalCluster ({dask_films} films of {n_dots} dots)",
                 ["workers", "wall s", "films done", "speed-up"],
                 [[1, f"{one:.1f}", ok1, "1"], [2, f"{two:.1f}", ok2, f"{one / two:.2f}"]])
    cold, warm = float(timing_rows[0][1]), float(timing_rows[1][1])
    return [Headline("qdots infer on the shared micrograph (cold, library built), calibration",
                     f"{cold / 60:.1f} min cold, {warm:.0f} s with the library built",
                     "90 % intervals hold the truth in " + ", ".join(
                         f"{r['parameter']} {100 * r['coverage_image']:.0f} %" for r in cal)),
            timing, intervals, check, calibration, dask,
            Note("Parameters: " + "; ".join(f"{p.label}: prior [{p.low:g}, {p.high:g}], thesis {p.thesis:g}"
                                            for p in PARAMETERS) + "."),
            Note(f"Truths of the held-out films span the prior: {np.round(np.ptp([[f.point[p.key] for p in PARAMETERS] for f in films], axis=0), 2).tolist()} "
                 "(range per parameter).")]


def main(argv: list[str] | None = None) -> int:
    return cli(run, __doc__.splitlines()[0], argv)


if __name__ == "__main__":
    raise SystemExit(main())

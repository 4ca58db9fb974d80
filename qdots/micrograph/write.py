"""The files of ``qdots measure`` and ``qdots compare``: a measured film, or its comparison, written as one set.

The analysis is `qdots.micrograph.measure.measure_image` and `qdots.micrograph.compare.compare_film` (they
return their results and write nothing); these functions run them and write the results into a run folder
(`labrig.files.OutputSet`: all files or none), as the command line does.
"""

from __future__ import annotations

import os
from pathlib import Path

from labrig.files import OutputSet, slug, write_csv
from labrig.validate import count

from ..io import checkpoint
from ..io.experiment_file import save_experiment
from .compare import MAX_COMPARE_DOTS, MAX_SEEDS, MAX_WORKERS, Comparison, compare_film, default_workers
from .measure import MeasuredFilm, measure_image, state_metadata
from .overlay import save_overlay, save_side_by_side


def write_measurement(film: MeasuredFilm, files: OutputSet, stem: str) -> None:
    """Stage ``STEM.npz`` (the board, a qdots state file), ``STEM_detections.png`` and ``STEM_summary.csv``."""
    checkpoint.save_board(film.state, files.stage(f"{stem}.npz"), state_metadata(film))
    save_overlay(film, files.stage(f"{stem}_detections.png"))
    write_csv(files.stage(f"{stem}_summary.csv"), [film.summary])


def measure(path: str | os.PathLike, out: str | os.PathLike | None = None, *, name: str | None = None,
            nm_per_px=None, scale_bar: str | None = None, polarity: str = "auto", profile: str = "auto",
            page: int = 0, lqe: bool = True) -> MeasuredFilm:
    """`measure_image`, then write ``NAME.npz``, ``NAME_detections.png`` and ``NAME_summary.csv`` into ``out``
    (default: beside the image) as one set. ``NAME`` defaults to the image's stem. Nothing is written when the
    image is refused or holds no dot."""
    path = Path(path)
    film = measure_image(path, nm_per_px=nm_per_px, scale_bar=scale_bar, polarity=polarity, profile=profile,
                         page=page, lqe=lqe)
    stem = slug(name if name is not None else path.stem)
    out = path.parent if out is None else Path(out)
    with OutputSet(out, stem) as files:
        write_measurement(film, files, stem)
    return film


def compare(path: str | os.PathLike, out: str | os.PathLike | None = None, *, name: str | None = None,
            nm_per_px=None, scale_bar: str | None = None, polarity: str = "auto", profile: str = "auto",
            page: int = 0, seeds: int = 3, n_dots: int = 300, engine: str = "chipmunk",
            progress: bool = False, workers: int | None = None) -> Comparison:
    """Measure an image, simulate it, and write as one set into ``out`` (default beside the image):
    the measurement's files (`qdots.micrograph.measure.measure`), ``NAME_compare.toml`` (the experiment run,
    to edit and run again with ``qdots run``), ``NAME_compare.png`` (side by side), ``NAME_compare.csv``
    (the table) and ``NAME_sim-SEED.npz`` (each simulated board). The seeds run in ``workers`` processes (default:
    one per core, at most one per seed; `qdots.micrograph.compare.compare_film`)."""
    path = Path(path)
    stem = slug(name if name is not None else path.stem)
    count("seeds", seeds, 1, MAX_SEEDS)
    count("dots", n_dots, 2, MAX_COMPARE_DOTS)
    workers = default_workers(seeds) if workers is None else count("workers", workers, 1, MAX_WORKERS)
    film = measure_image(path, nm_per_px=nm_per_px, scale_bar=scale_bar, polarity=polarity, profile=profile,
                         page=page)
    comparison = compare_film(film, seeds=seeds, n_dots=n_dots, engine=engine, progress=progress and workers == 1,
                              name=stem, workers=workers)
    out = path.parent if out is None else Path(out)
    with OutputSet(out, f"{stem}_compare") as files:
        write_measurement(film, files, stem)
        save_experiment(comparison.experiment, files.stage(f"{stem}_compare.toml"))
        for k, sim in enumerate(comparison.simulations):
            checkpoint.save(sim, files.stage(f"{stem}_sim-{comparison.experiment.seed + k}.npz"),
                            {"simulated_film_of": film.image.source, "nm_per_board_px": comparison.nm_per_board_px})
        save_side_by_side(comparison, files.stage(f"{stem}_compare.png"))
        write_csv(files.stage(f"{stem}_compare.csv"), comparison.table)
    return comparison

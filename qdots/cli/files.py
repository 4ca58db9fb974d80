"""The files of ``qdots measure``, ``qdots compare`` and ``qdots infer``: a measured film, its comparison or its
inference, written as one set.

The analysis is `qdots.micrograph.measure.measure_image`, `qdots.inference.compare.compare_film` and
`qdots.inference.infer.infer_image` (they return their results and write nothing); these functions run them and write the results into a run folder
(`labrig.outputset.OutputSet`: all files or none), as the command line does.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

from labrig.files import slug, write_csv
from labrig.outputset import OutputSet
from labrig.validate import count

from ..io import checkpoint
from ..io.experiment_file import save_experiment
from ..micrograph.admit import NotAFilm
from ..micrograph.choices import MAX_COMPARE_DOTS, MAX_SEEDS, MAX_WORKERS
from ..micrograph.measure import MeasuredFilm, measure_image, state_metadata
from ..micrograph.overlay import save_overlay

if TYPE_CHECKING:
    from ..inference.compare import Comparison


def write_measurement(film: MeasuredFilm, files: OutputSet, stem: str) -> None:
    """Stage ``STEM.npz`` (the board, a qdots state file), ``STEM_detections.png`` and ``STEM_summary.csv``."""
    checkpoint.save_board(film.state, files.stage(f"{stem}.npz"), state_metadata(film))
    save_overlay(film, files.stage(f"{stem}_detections.png"))
    write_csv(files.stage(f"{stem}_summary.csv"), [film.summary])


def measure(path: str | os.PathLike, out: str | os.PathLike | None = None, *, name: str | None = None,
            nm_per_px=None, scale_bar: str | None = None, polarity: str = "auto", profile: str = "auto",
            page: int = 0, lqe: bool = True, force: bool = False, progress: bool | str = False) -> MeasuredFilm:
    """`measure_image`, then write ``NAME.npz``, ``NAME_detections.png`` and ``NAME_summary.csv`` into ``out``
    (default: beside the image) as one set. ``NAME`` defaults to the image's stem. A picture that is not a film of
    round particles (`qdots.micrograph.admit.NotAFilm`, unless ``force``) writes only the overlay of what was found,
    ``NAME-refused/NAME_refused.png`` (an earlier measurement of ``NAME`` is left as it was), and the error says
    where; an image that cannot be read or holds no dot writes nothing."""
    path = Path(path)
    stem = slug(name if name is not None else path.stem)
    out = path.parent if out is None else Path(out)
    try:
        film = measure_image(path, nm_per_px=nm_per_px, scale_bar=scale_bar, polarity=polarity, profile=profile,
                             page=page, lqe=lqe, force=force, progress=progress)
    except NotAFilm as refusal:
        if refusal.found is None:
            raise
        with OutputSet(out, f"{stem}-refused") as files:
            picture = files.stage(f"{stem}_refused.png")
            save_overlay(refusal.found, picture, refused=refusal.reasons)
        shown = out / f"{stem}-refused" / picture.name
        raise NotAFilm(f"{refusal}; what was found: {shown}; --force measures it anyway", refusal.reasons,
                       refusal.found) from None
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
    one per core, at most one per seed; `qdots.inference.compare.compare_film`)."""
    from ..inference.compare import compare_film, default_workers
    from ..inference.plots import save_side_by_side

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


def infer(path: str | os.PathLike, out: str | os.PathLike | None = None, *, library: str | os.PathLike,
          name: str | None = None, nm_per_px=None, scale_bar: str | None = None, polarity: str = "auto",
          profile: str = "auto", page: int = 0, also=(), **options):
    """`qdots.inference.infer.infer_image` (of ``path`` and the pictures ``also`` of the same sample), then write
    as one set into ``out`` (default beside the image), folder ``NAME_infer``: the measurement's files,
    ``NAME_posterior.csv`` (the draws), ``NAME_intervals.csv`` (median and 90 % interval per parameter),
    ``NAME_mass_models.csv`` (each mass model's probability), ``NAME_check.csv`` (each measure: micrograph, best
    film, predicted band), ``NAME_corner.png``, ``NAME_best.png`` (the micrograph beside the best-fitting film,
    both measure tables), ``NAME_check.png`` (the predictive check) and ``NAME_best-film.npz`` (that film's
    board). ``options`` are `qdots.inference.infer.infer_film`'s keywords. The library is kept in ``library``."""
    from labrig.figures import save_figure

    from ..inference.forward import MASS_KEY, parameter_keys
    from ..inference.infer import infer_image
    from ..inference.plots import best_film_figure, check_figure, corner_figure

    path = Path(path)
    stem = slug(name if name is not None else path.stem)
    result = infer_image([path, *also] if also else path, library, nm_per_px=nm_per_px, scale_bar=scale_bar,
                         polarity=polarity, profile=profile, page=page, **options)
    out = path.parent if out is None else Path(out)
    with OutputSet(out, f"{stem}_infer") as files:
        write_measurement(result.film, files, stem)
        write_csv(files.stage(f"{stem}_posterior.csv"),
                  [dict(zip(parameter_keys(), (float(v) for v in row))) for row in result.samples])
        write_csv(files.stage(f"{stem}_intervals.csv"), result.intervals)
        write_csv(files.stage(f"{stem}_mass_models.csv"), result.mass_models)
        best = result.best
        write_csv(files.stage(f"{stem}_check.csv"),
                  [{**row, "best_film": best.get(row["measure"])} for row in result.check])
        save_figure(corner_figure(result), files.stage(f"{stem}_corner.png"), dpi=110)
        save_figure(best_film_figure(result), files.stage(f"{stem}_best.png"), dpi=100)
        save_figure(check_figure(result), files.stage(f"{stem}_check.png"), dpi=100)
        checkpoint.save_board(best["state"], files.stage(f"{stem}_best-film.npz"),
                              {"best_film_of": result.film.image.source,
                               "point": {k: best[k] for k in (*parameter_keys(), MASS_KEY, "sigma", "coverage", "n_dots",
                                                               "seed")}})
    return result

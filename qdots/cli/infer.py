"""``qdots infer``: its arguments beyond the image's, and what it prints (the command itself is in `qdots.cli.main`)."""

from __future__ import annotations

import argparse
import os
import shutil
import sys
from pathlib import Path

from labrig.cli import int_in, print_table
from labrig.validate import MAX_SEED, InputError


def add_arguments(p) -> None:
    """The library, the films and where they run."""
    from ..micrograph.choices import (
        CHECK_FILMS,
        FILM_DOTS,
        LIBRARY_FILMS,
        MAX_CHECK_FILMS,
        MAX_FILM_DOTS,
        MAX_LIBRARY_FILMS,
        MAX_SAMPLES,
        MIN_TRAINING_FILMS,
        SAMPLES,
    )

    p.add_argument("--also", nargs="+", type=Path, default=[], metavar="IMAGE",
                   help="more micrographs of the same sample, read with the same scale options: independent "
                        "observations of the same deposition, which narrow the posterior")
    p.add_argument("--library", type=Path, default=Path("qdots-infer-library"), metavar="DIR",
                   help="the library of simulated films, kept and reused by later images (default "
                        "./qdots-infer-library)")
    p.add_argument("--films", type=int_in(MIN_TRAINING_FILMS, MAX_LIBRARY_FILMS), default=LIBRARY_FILMS,
                   help=f"training films (default {LIBRARY_FILMS}, which the package ships for films of {FILM_DOTS} "
                        "dots: none runs; the library runs only those it lacks)")
    p.add_argument("--check-films", type=int_in(1, MAX_CHECK_FILMS), default=CHECK_FILMS,
                   help=f"films of the posterior-predictive check (default {CHECK_FILMS})")
    p.add_argument("--samples", type=int_in(100, MAX_SAMPLES), default=SAMPLES,
                   help=f"posterior draws (default {SAMPLES})")
    p.add_argument("--dots", type=int_in(10, MAX_FILM_DOTS), default=FILM_DOTS,
                   help=f"dots of each simulated film (default {FILM_DOTS}; one size per library)")
    where = p.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int_in(1, 256), default=None,
                       help="local worker processes (default: every core)")
    where.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="run the films on this Dask cluster (tcp://host:8786) instead")
    p.add_argument("--seed", type=int_in(0, MAX_SEED), default=0, help="seed of the training and the draws")


def check_extra() -> None:
    """`InputError` saying how to install the infer extra when torch or sbi is missing (nothing is imported)."""
    from ..micrograph.choices import INFER_EXTRA, missing_infer_extra

    if missing_infer_extra():
        raise InputError(INFER_EXTRA)


def run(args: argparse.Namespace, stem: str) -> int:
    """Infer, write the files, print the intervals, the check and the timings."""
    from ..inference.infer import check_rows, interval_rows
    from .files import infer

    new_library = not args.library.exists()
    try:
        result = infer(args.image, args.out, library=args.library, name=args.name, nm_per_px=args.nm_per_px,
                       scale_bar=args.scale_bar, polarity=args.polarity, profile=args.profile, page=args.page,
                       also=args.also, films=args.films, check_films=args.check_films, samples=args.samples, n_dots=args.dots,
                       workers=args.workers, scheduler=args.scheduler, seed=args.seed, progress=True)
    except KeyboardInterrupt:
        if new_library and not any(args.library.glob("*/runs/*.json")):  # nothing finished: leave nothing behind
            shutil.rmtree(args.library, ignore_errors=True)
        elif args.library.is_dir():
            print(f"the library {str(args.library)!r} keeps the films that finished: the next qdots infer with it "
                  "runs only the others (delete the folder to start over)", file=sys.stderr)
        raise
    c = result.conditions
    seen = (f"{result.pictures} pictures" if result.pictures > 1 else str(args.image)) + \
        f" ({result.dots} measured dots, {result.observations} observation{'s' if result.observations > 1 else ''})"
    print_table(f"{seen}: sigma {c['sigma']:.3f}, coverage {c['coverage']:.3f}; posterior median and 90 % "
                f"credible interval ({result.films} training films):", interval_rows(result))
    print_table("posterior-predictive check (* the measures the posterior is conditioned on):", check_rows(result))
    t = result.timings
    training = "0 s (loaded)" if t["posterior_loaded"] else f"{t['train']:.0f} s"
    print(f"time: measure {t['measure']:.0f} s, library {t['library']:.0f} s ({t['library_films_run']} films run, "
          f"{t['library_films_failed']} left out), training {training}, check {t['check']:.0f} s")
    print(f"wrote {args.out / f'{stem}_infer'}{os.sep}: {stem}_intervals.csv, {stem}_mass_models.csv, "
          f"{stem}_posterior.csv, {stem}_check.csv, {stem}_corner.png, {stem}_best.png, {stem}_check.png, "
          f"{stem}_best-film.npz and the measurement's files")
    return 0

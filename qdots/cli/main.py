"""The ``qdots`` command line.

``qdots demo`` runs a small deposition-like board (dots placed at random,
then van der Waals attraction and thermal kicks) and writes a picture, a
movie and a one-row CSV summary. Each subcommand is a `labrig.cli.Command`
in `COMMANDS`: its ``_<name>_arguments`` function adds its arguments when it
is the command chosen, and its ``_run_<name>`` function (whose docstring is
the command's description) runs it; `main` dispatches and turns bad input
into a one-line error. Nothing here imports the simulators before a command
runs, so ``qdots --help`` and argument errors answer at once.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from pathlib import Path

from labrig.cli import Command, command_line, float_in, fraction, int_in, param_help, param_type
from labrig.sweeps.command import plot_command, sweep_command
from labrig.validate import MAX_SEED

from ..limits import SIGMA
from ..presets import NAMES as PRESET_NAMES  # the names only: the presets are made when first used

#: Demo board, px, and mean dot diameter, px (the thesis's diameter on a quarter of its board).
DEMO_BOX = (300.0, 300.0)
DEMO_DIAMETER = 15.0
#: Simulated time between movie frames, s.
DEMO_FRAME_INTERVAL = 0.2
#: Most dots the demo board takes (a 300 x 300 px board holds about 460 close-packed 15 px dots).
DEMO_MAX_DOTS = 460


#: What `qdots resume` writes, in its --help and the README.
RESUME_RULE = (
    "A resume never changes its input: it writes the continuation as a new folder beside the state's own "
    "(run NAME/NAME.npz resumed to T s: NAME-tTs/, with NAME-tTs.npz, .png, its summary.csv row and, with "
    "--movie / --gsd, a movie or trajectory of the continuation), and prints its name. --out DIR writes that "
    "folder into DIR instead. --in-place replaces the run's own folder instead, all at once when the "
    "continuation has finished; an earlier NAME.mp4 or NAME.gsd is then kept as NAME.until-Ts.mp4 (.gsd), "
    "T the time in s of the state resumed from (it shows the run up to T s), and a line says so. A folder "
    "that another run is writing is refused.")


def _demo_arguments(p) -> None:
    p.add_argument("--out", type=Path, default=Path("qdots-demo"), metavar="DIR",
                   help="output directory, created if missing (default ./qdots-demo)")
    p.add_argument("--seed", type=int_in(0, MAX_SEED), default=1, help="random seed (default 1)")
    p.add_argument("--dots", type=int_in(1, DEMO_MAX_DOTS), default=150, metavar="N", help="number of dots (default 150)")
    p.add_argument("--seconds", type=float_in(0.0, math.inf, low_open=True), default=20.0, metavar="T",
                   help="simulated time, s (default 20)")
    p.add_argument("--sigma", type=param_type(SIGMA), default=0.05, metavar="F", help=param_help(SIGMA, 0.05))
    p.add_argument("--no-movie", action="store_true", help="skip demo.mp4 (faster)")


def _add_outputs(p, out_default: str | None) -> None:
    if out_default is not None:
        p.add_argument("--out", type=Path, default=Path(out_default), metavar="DIR",
                       help=f"output directory, created if missing (default ./{out_default})")
    p.add_argument("--movie", action="store_true", help="also write an MP4 (one frame per 0.5 s simulated)")
    p.add_argument("--gsd", action="store_true", help="also write a GSD trajectory (needs the gsd package)")


def _add_engine(p) -> None:
    from ..engine import ENGINES  # the engines' settings only: no simulator code

    p.add_argument("--engine", choices=list(ENGINES), default=None,
                   help="override the file's [engine] kind: chipmunk (pymunk, the default) or event (the thesis's "
                        "event-driven exact hard discs)")


def _with_engine(exp, engine: str | None):
    """``exp`` run by the engine ``engine`` (None: as it says)."""
    return exp if engine is None else exp.replace(engine=exp.engine.replace(kind=engine))


def _add_state(p) -> None:
    """The argument of a subcommand that reads a state file (``STATE.npz``)."""
    p.add_argument("state", type=Path, metavar="STATE.npz", help="state file")


def _run_arguments(p) -> None:
    p.add_argument("experiment", type=Path, metavar="EXPERIMENT.toml", help="experiment file")
    _add_outputs(p, "qdots-run")
    _add_engine(p)
    p.add_argument("--seed", type=int_in(0, MAX_SEED), default=None, help="override the file's seed")
    p.add_argument("--quick", type=fraction, default=None,
                   metavar="F", help="scale the run down by F (fewer dots, shorter times) for a first look")


def _preset_arguments(p) -> None:
    p.add_argument("name", choices=list(PRESET_NAMES), metavar="NAME", help=f"one of: {', '.join(PRESET_NAMES)}")
    _add_outputs(p, "qdots-preset")
    _add_engine(p)
    p.add_argument("--quick", type=fraction, default=None,
                   metavar="F", help="scale the runs down by F (e.g. 0.1) for a first look")
    p.add_argument("--save", type=Path, default=None, metavar="DIR",
                   help="only write the preset's experiment files (TOML) into DIR, do not run")


def _resume_arguments(p) -> None:
    _add_state(p)
    p.add_argument("--seconds", type=float_in(0.0, math.inf, low_open=True), required=True, metavar="T",
                   help="simulated time to add, s")
    _add_outputs(p, None)
    where = p.add_mutually_exclusive_group()
    where.add_argument("--out", type=Path, default=None, metavar="DIR",
                       help="write the continuation's folder here (default: beside STATE's own folder)")
    where.add_argument("--in-place", action="store_true",
                       help="replace STATE's own run folder with the continuation instead (all at once, when it "
                            "has finished)")


def _render_arguments(p) -> None:
    _add_state(p)
    p.add_argument("--out", type=Path, default=None, metavar="FILE.png",
                   help="default: STATE with .png, which replaces the run's own picture of that state "
                        "(the same drawing; the command says so)")


def _analyze_arguments(p) -> None:
    from ..limits import MAX_DRAWS, MAX_FORSTER_PX, MAX_FORSTER_RADII

    _add_state(p)
    p.add_argument("--json", action="store_true", help="print one JSON object instead of the table")
    p.add_argument("--plot", nargs="?", type=Path, const=True, default=None, metavar="FILE.png",
                   help="also write the figure (default: STATE with _analysis.png)")
    p.add_argument("--rule", choices=["text", "code"], default="text",
                   help="neighbours: surface gap < one mean radius (text, default) or d <= r_i + 2 r_j (code)")
    radius = p.add_mutually_exclusive_group()
    radius.add_argument("--forster-radius", type=float_in(0.0, MAX_FORSTER_PX, low_open=True, high_open=False),
                        default=None, metavar="PX", help="Förster radius, px (default: the mean diameter)")
    radius.add_argument("--forster-radii", type=float_in(0.0, MAX_FORSTER_RADII, low_open=True), default=None,
                        metavar="R",
                        help="Förster radius in mean dot radii, as the thesis's Fig 2-5 c (2 = the default)")
    p.add_argument("--traps", type=float_in(0.0, 1.0, high_open=False), default=1 / 3, metavar="F",
                   help="fraction of trap dots (default 1/3)")
    p.add_argument("--draws", type=int_in(1, MAX_DRAWS), default=8, help="trap draws to average (default 8)")
    p.add_argument("--seed", type=int_in(0, MAX_SEED), default=0, help="seed of the trap draws (default 0)")


def _add_image_options(p, out_default: str) -> None:
    """The arguments of the commands that read a micrograph (``measure``, ``compare``), their files going to
    ``./out_default`` by default."""
    from ..micrograph.choices import MAX_NM_PER_PX, MIN_NM_PER_PX, POLARITIES, PROFILES

    p.add_argument("image", type=Path, metavar="IMAGE",
                   help="micrograph: .tif/.tiff, .png, .jpg, .bmp, .gif, or .dm3/.dm4/.emd/.ser (qdots[microscope])")
    p.add_argument("--out", type=Path, default=Path(out_default), metavar="DIR",
                   help=f"output directory, created if missing (default ./{out_default})")
    p.add_argument("--name", default=None, help="stem of the files written (default: IMAGE's stem)")
    scale = p.add_mutually_exclusive_group()
    scale.add_argument("--nm-per-px", type=float_in(MIN_NM_PER_PX, MAX_NM_PER_PX, high_open=False), default=None,
                       metavar="S", help="scale, nm per pixel, when the file's metadata has none")
    scale.add_argument("--scale-bar", default=None, metavar="LENGTH",
                       help="length of the scale bar drawn on the image, such as 200nm or 0.5um: the scale is read "
                            "off the bar (the command says what it found)")
    p.add_argument("--polarity", choices=POLARITIES, default="auto",
                   help="dots darker (dark) or lighter (light) than the background; auto decides and says how")
    p.add_argument("--invert", action="store_const", const="light", dest="polarity",
                   help="the dots are lighter than the background (same as --polarity light)")
    p.add_argument("--profile", choices=list(PROFILES), default="auto",
                   help="the dots' contrast profile: sphere (projected), disc (flat), or auto (fitted when the "
                        "dots show enough background around them, else sphere)")
    p.add_argument("--page", type=int_in(0, 100_000), default=0, help="page of a multi-page file (default 0)")


def _measure_arguments(p) -> None:
    _add_image_options(p, "qdots-measure")
    p.add_argument("--no-lqe", action="store_true", help="skip the film LQE (the slowest part on large films)")
    p.add_argument("--force", action="store_true",
                   help="measure a picture that does not look like a film of round particles anyway (the table "
                        "says why it would have been refused)")


def _compare_arguments(p) -> None:
    from ..engine import ENGINES
    from ..micrograph.choices import MAX_COMPARE_DOTS, MAX_SEEDS, MAX_WORKERS

    _add_image_options(p, "qdots-compare")
    p.add_argument("--seeds", type=int_in(1, MAX_SEEDS), default=3, help="simulated films (default 3)")
    p.add_argument("--dots", type=int_in(2, MAX_COMPARE_DOTS), default=300,
                   help="dots of each simulated film (default 300, the thesis's)")
    p.add_argument("--engine", choices=list(ENGINES), default="chipmunk", help="engine of the simulation")
    p.add_argument("--workers", type=int_in(1, MAX_WORKERS), default=None,
                   help="processes the seeds run in (default: one per core, at most one per seed)")


def _infer_arguments(p) -> None:
    from .infer import add_arguments

    _add_image_options(p, "qdots-infer")
    add_arguments(p)


def _run_infer(args: argparse.Namespace) -> int:
    """Measure a micrograph (as qdots measure), then infer the deposition parameters that made the film
    (thermal kicks against the van der Waals pull, the mass exponent, the restitution, the drag) by
    neural posterior estimation on a library of simulated films at its size spread and coverage: the
    posterior draws, 90 % credible intervals, a corner plot, the best-fitting film beside the micrograph
    and a posterior-predictive check. Needs the infer extra (torch, sbi)."""
    from .infer import check_extra, run

    check_extra()
    check_image_arguments(args)
    return run(args, film_stem(args))


def _run_measure(args: argparse.Namespace) -> int:
    """Read a micrograph, find every dot (touching ones included) with sub-pixel centres and fitted
    diameters, and write a state file (for qdots analyze and render), an overlay picture and a
    summary table of the thesis's metrics: coverage, size and spread, interior fraction,
    neighbours, psi6, aggregates, g(r) and the film LQE. Dots cut by the image edge are measured and
    flagged; the neighbourhood metrics use only dots whose neighbourhood is inside the picture."""
    check_image_arguments(args)
    from labrig.cli import print_table

    from ..micrograph.measure import summary_rows
    from .files import measure

    film = measure(args.image, args.out, name=args.name, nm_per_px=args.nm_per_px, scale_bar=args.scale_bar,
                   polarity=args.polarity, profile=args.profile, page=args.page, lqe=not args.no_lqe,
                   force=args.force, progress=True if sys.stderr.isatty() else "lines")
    print_table(f"{args.image}:", summary_rows(film.summary))
    stem = film_stem(args)
    print(f"wrote {args.out / stem}{os.sep}: {stem}.npz, {stem}_detections.png, {stem}_summary.csv")
    return 0


def check_image_arguments(args: argparse.Namespace) -> None:
    """Refuse at once, before the measurement is imported: a picture that is not there, cannot be opened or has a
    suffix qdots does not read; a ``--name`` that leaves no file name; an ``--out`` that a file is in the way of."""
    from labrig.files import existing_file, writable_directory
    from labrig.validate import InputError

    from ..micrograph.choices import unknown_suffix

    existing_file(args.image, "micrograph")
    reason = unknown_suffix(args.image.name)
    if reason is not None:
        raise InputError(reason)
    if args.name is not None and not any(char.isascii() and char.isalnum() for char in args.name):
        raise InputError(f"--name {args.name!r} leaves no file name: give letters, digits, '.', '_' or '-'")
    writable_directory(args.out)


def film_stem(args: argparse.Namespace) -> str:
    from labrig.files import slug

    return slug(args.name if args.name is not None else args.image.stem)


def _run_compare(args: argparse.Namespace) -> int:
    """Measure a micrograph (as qdots measure), build the thesis's deposition with the film's size
    spread and coverage (masses ~ d^3, 15 px mean diameter, the board sized for the coverage), run it
    for several seeds, and write the side-by-side figure, the table of every metric (image against
    simulation mean +- SE) and the experiment file it ran (edit it and run it with qdots run)."""
    check_image_arguments(args)
    from labrig.cli import print_table

    from ..inference.compare import table_rows
    from .files import compare

    comparison = compare(args.image, args.out, name=args.name, nm_per_px=args.nm_per_px, scale_bar=args.scale_bar,
                         polarity=args.polarity, profile=args.profile, page=args.page, seeds=args.seeds,
                         n_dots=args.dots, engine=args.engine, progress=True, workers=args.workers)
    exp = comparison.experiment
    print_table(f"{args.image} against {len(comparison.states)} simulated films ({exp.deposition.n_dots} dots, "
                f"{exp.board.width:.0f} x {exp.board.height:.0f} px, {comparison.nm_per_board_px:.3g} nm per px, "
                f"{exp.engine.kind} engine):", table_rows(comparison))
    stem = film_stem(args)
    print(f"wrote {args.out / f'{stem}_compare'}{os.sep}: {stem}_compare.png, {stem}_compare.csv, {stem}_compare.toml "
          f"and the boards ({stem}.npz, {stem}_sim-SEED.npz)")
    return 0


def _load_sweep(path: Path):
    from .sweep import load_sweep

    return load_sweep(path)


def _sweep_runner(quick: float | None):
    from .sweep import ExperimentRunner

    return ExperimentRunner(quick)


def _run_analyze(args: argparse.Namespace) -> int:
    """Measure a state file: interior dots, neighbours, spacing, psi6, clusters, Voronoi coordination,
    and the film's luminescence quantum efficiency (exact, averaged over random trap draws)."""
    from .commands import analyze

    plot = args.state.with_name(f"{args.state.stem}_analysis.png") if args.plot is True else args.plot
    analyze(args.state, rule=args.rule, forster_radius=args.forster_radius, forster_radii=args.forster_radii,
            trap_fraction=args.traps,
            draws=args.draws, seed=args.seed, as_json=args.json, plot=plot)
    return 0


def _run_scene(args: argparse.Namespace) -> int:
    """Run an experiment file (see `qdots preset NAME --save DIR` for examples): deposit, settle, then
    write the final state (.npz, resumable), a picture, a summary row and optionally a movie."""
    from ..io.experiment_file import load_experiment
    from .commands import run_experiments

    exp = load_experiment(args.experiment)
    if args.seed is not None:
        exp = exp.replace(seed=args.seed)
    if args.quick is not None:
        exp = exp.quick(args.quick)
    exp = _with_engine(exp, args.engine)
    run_experiments([exp], args.out, movie=args.movie, gsd=args.gsd, source=args.experiment)
    return 0


def _run_preset(args: argparse.Namespace) -> int:
    from labrig.files import slug

    from ..io.experiment_file import save_experiment
    from ..presets import get_preset
    from .commands import run_experiments

    experiments = [_with_engine(exp, args.engine)
                   for exp in get_preset(args.name, quick=False if args.quick is None else args.quick)]
    if args.save is not None:
        args.save.mkdir(parents=True, exist_ok=True)
        for exp in experiments:
            path = args.save / f"{slug(exp.name)}.toml"
            save_experiment(exp, path)
            print(path)
        return 0
    run_experiments(experiments, args.out, movie=args.movie, gsd=args.gsd)
    return 0


def _run_resume(args: argparse.Namespace) -> int:
    """Load a state file written by run/preset/resume and continue it; the continuation is
    bit-identical to never having stopped."""
    from .commands import resume

    resume(args.state, args.seconds, args.out, movie=args.movie, gsd=args.gsd, in_place=args.in_place)
    return 0


def _run_render(args: argparse.Namespace) -> int:
    """Draw a state file: dots coloured by size, walls, time stamp."""
    from .commands import render

    render(args.state, args.out)
    return 0




def _run_demo(args: argparse.Namespace) -> int:
    """Place dots at random on a 300 x 300 px board (mean diameter 15 px), let them attract (van der
    Waals) and jiggle (thermal kicks), and write the final picture, a movie and a summary."""
    import numpy as np

    import qdots
    from labrig.cli import print_table
    from labrig.files import write_csv
    from labrig.outputset import OutputSet

    from ..analysis.packing import packing_summary
    from ..placement import random_sequential
    from ..render import MovieWriter, save_png
    from .commands import OVERLAP_COLUMN, nominal_diameters, run_title, say_replaced

    out: Path = args.out
    movie = None
    # Independent streams for placement and dynamics, both from the one seed (a board too full is an error
    # before the output directory is made).
    place_seed, sim_seed = np.random.SeedSequence(args.seed).spawn(2)
    positions, radii = random_sequential(args.dots, DEMO_BOX, DEMO_DIAMETER, args.sigma,
                                         rng=np.random.default_rng(place_seed))
    scene = qdots.Scene(box=DEMO_BOX, positions=positions, radii=radii)
    sim = qdots.Simulation(scene, [qdots.VanDerWaals(), qdots.ThermalKicks()], seed=sim_seed)
    title = run_title({"name": "qdots demo", "dots": args.dots, "sigma": args.sigma, "mass_model": "equal",
                       "engine": sim.engine.kind, "seed": args.seed})
    start = time.perf_counter()
    with OutputSet(out, "demo") as files:  # locks the set before the run
        if args.no_movie:
            files.drop("demo.mp4")
        else:
            movie = sim.attach(files.adopt(MovieWriter(files.stage("demo.mp4"),
                                                       every=max(1, round(DEMO_FRAME_INTERVAL / sim.dt)), title=title,
                                                       diameters=nominal_diameters(DEMO_DIAMETER, args.sigma))))
        state = sim.run(args.seconds, progress=True)
        wall = time.perf_counter() - start
        movie_wall = movie.wall_seconds if movie is not None else 0.0
        save_png(state, files.stage("demo.png"), title=title,
                 colour_range=nominal_diameters(DEMO_DIAMETER, args.sigma))
        summary = packing_summary(state)
        steps_per_s = sim.steps_taken / max(wall - movie_wall, 1e-9)
        row = {
            "seed": args.seed, "dots": args.dots, "sigma": args.sigma, "box_px": f"{DEMO_BOX[0]:g}x{DEMO_BOX[1]:g}",
            "mean_diameter_px": DEMO_DIAMETER, "simulated_s": state.time, "dt_s": sim.dt,
            "steps": sim.steps_taken, "wall_s": round(wall, 3), "movie_wall_s": round(movie_wall, 3),
            "steps_per_s": round(steps_per_s, 1), "interior_fraction": summary["interior_fraction"],
            "mean_neighbours_interior": summary["mean_neighbours_interior"],
            OVERLAP_COLUMN: 100 * summary["max_overlap"], "kinetic_energy": summary["kinetic_energy"],
        }
        write_csv(files.stage("summary.csv"), [row])
    say_replaced(files, hints=False)
    movie_note = f" (movie {movie_wall:.1f} s, {movie.frames} frames)" if movie is not None else ""
    print_table(f"qdots demo: {args.dots} dots on a {DEMO_BOX[0]:g} x {DEMO_BOX[1]:g} px board, "
                f"sigma {args.sigma:g}, seed {args.seed}", [
        ("dots", f"{summary['n_dots']}"),
        ("simulated time", f"{state.time:.2f} s ({sim.steps_taken} steps of {sim.dt:g} s)"),
        ("wall time", f"{wall:.1f} s{movie_note}"),
        ("steps/s", f"{steps_per_s:,.0f} (simulation only)"),
        ("interior fraction", f"{summary['interior_fraction']:.3f}"),
        ("mean neighbours (interior)", f"{summary['mean_neighbours_interior']:.2f}"),
        ("max overlap", f"{100 * summary['max_overlap']:.3f} % of radius"),
        ("kinetic energy", f"{summary['kinetic_energy']:.4g} mass px^2/s^2"),
        ("files", f"{files.path}{os.sep}: " + ", ".join(path.name for path in files.written)),
    ])
    return 0


#: The subcommands, in the order `--help` lists them.
COMMANDS = [
    Command("demo", "run a small demo board and write the folder demo/: demo.png, demo.mp4, summary.csv",
            _run_demo, _demo_arguments),
    Command("run", "run the experiment described by a TOML experiment file", _run_scene, _run_arguments),
    Command("preset", "run one of the thesis's experiments", _run_preset, _preset_arguments,
            description="Run the experiments that reproduce a thesis figure: " + ", ".join(PRESET_NAMES) + "."),
    Command("resume", "continue a saved run", _run_resume, _resume_arguments,
            description=f"{_run_resume.__doc__} {RESUME_RULE}"),
    Command("render", "draw a saved state as PNG", _run_render, _render_arguments),
    Command("analyze", "packing table and LQE of a saved state", _run_analyze, _analyze_arguments),
    Command("measure", "find the dots of a micrograph and measure the film", _run_measure, _measure_arguments),
    Command("compare", "measure a micrograph and simulate the film beside it", _run_compare, _compare_arguments),
    Command("infer", "infer the deposition parameters of a micrograph's film, with credible intervals", _run_infer,
            _infer_arguments),
    sweep_command("qdots", "qdots experiments", _load_sweep, _sweep_runner,
                  "scale every run down by F (fewer dots, shorter times) for a first look"),
    plot_command("qdots"),
]
build_parser, main = command_line("qdots", "Quantum-dot monolayer packing simulator (pymunk).", COMMANDS)


if __name__ == "__main__":
    sys.exit(main())

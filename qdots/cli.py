"""The ``qdots`` command line.

``qdots demo`` runs a small deposition-like board (dots placed at random,
then van der Waals attraction and thermal kicks) and writes a picture, a
movie and a one-row CSV summary. Each subcommand is a ``_add_<name>``
function that registers its parser and sets ``func`` to the function that
runs it; `main` dispatches and turns bad input into a one-line error.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import sys
import time
from pathlib import Path
from typing import Sequence

import numpy as np

#: Demo board, px, and mean dot diameter, px (the thesis's diameter on a quarter of its board).
DEMO_BOX = (300.0, 300.0)
DEMO_DIAMETER = 15.0
#: Simulated time between movie frames, s.
DEMO_FRAME_INTERVAL = 0.2


class _UsageError(Exception):
    """A command-line argument was rejected by argparse."""


class _Parser(argparse.ArgumentParser):
    def error(self, message: str):  # argparse would print the usage and exit
        raise _UsageError(f"{message} (see '{self.prog} --help')")


def _int_at_least(low: int):
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be an integer >= {low}, got {value}")
        return value
    return parse


def _float_in(low: float, high: float, low_open: bool = False, high_open: bool = True):
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
        ok = math.isfinite(value) and (value > low if low_open else value >= low) and \
            (value < high if high_open else value <= high)
        if not ok:
            interval = f"{'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"
            raise argparse.ArgumentTypeError(f"must be in {interval}, got {text}")
        return value
    return parse


def _add_demo(subparsers) -> None:
    p = subparsers.add_parser(
        "demo", help="run a small demo board and write demo.png, demo.mp4, summary.csv",
        description="Place dots at random on a 300 x 300 px board (mean diameter 15 px), let them "
                    "attract (van der Waals) and jiggle (thermal kicks), and write the final "
                    "picture, a movie and a summary.",
    )
    p.add_argument("--out", type=Path, default=Path("qdots-demo"), metavar="DIR",
                   help="output directory, created if missing (default ./qdots-demo)")
    p.add_argument("--seed", type=_int_at_least(0), default=1, help="random seed (default 1)")
    p.add_argument("--dots", type=_int_at_least(1), default=150, metavar="N",
                   help="number of dots (default 150)")
    p.add_argument("--seconds", type=_float_in(0.0, math.inf, low_open=True), default=20.0, metavar="T",
                   help="simulated time, s (default 20)")
    p.add_argument("--sigma", type=_float_in(0.0, 1.0), default=0.05, metavar="F",
                   help="diameter spread as a fraction of the mean (default 0.05)")
    p.add_argument("--no-movie", action="store_true", help="skip demo.mp4 (faster)")
    p.set_defaults(func=_run_demo)


def build_parser() -> argparse.ArgumentParser:
    """The ``qdots`` argument parser, one subparser per command."""
    parser = _Parser(prog="qdots", description="Quantum-dot monolayer packing simulator (pymunk).")
    from . import __version__

    parser.add_argument("--version", action="version", version=f"qdots {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    _add_demo(subparsers)
    return parser


def _atomic_csv(path: Path, row: dict) -> None:
    from .atomic import atomic_path

    text = io.StringIO()
    writer = csv.DictWriter(text, fieldnames=list(row), lineterminator="\n")
    writer.writeheader()
    writer.writerow(row)
    with atomic_path(path) as tmp:
        tmp.write_text(text.getvalue())


def _table(rows: Sequence[tuple[str, str]]) -> str:
    width = max(len(key) for key, _ in rows)
    return "\n".join(f"  {key:<{width}}  {value}" for key, value in rows)


def _run_demo(args: argparse.Namespace) -> int:
    import qdots
    from .analysis import packing_summary
    from .placement import random_sequential
    from .render import MovieWriter, save_png

    out: Path = args.out
    # Independent streams for placement and dynamics, both from the one seed.
    place_seed, sim_seed = np.random.SeedSequence(args.seed).spawn(2)
    positions, radii = random_sequential(args.dots, DEMO_BOX, DEMO_DIAMETER, args.sigma,
                                         rng=np.random.default_rng(place_seed))
    scene = qdots.Scene(box=DEMO_BOX, positions=positions, radii=radii)
    out.mkdir(parents=True, exist_ok=True)
    sim = qdots.Simulation(scene, [qdots.VanDerWaals(), qdots.ThermalKicks()], seed=sim_seed)
    files = []
    movie = None
    start = time.perf_counter()
    if args.no_movie:
        state = sim.run(args.seconds, progress=True)
    else:
        every = max(1, round(DEMO_FRAME_INTERVAL / sim.dt))
        with MovieWriter(out / "demo.mp4", every=every) as movie:
            state = sim.run(args.seconds, progress=True, writers=[movie])
        files.append(out / "demo.mp4")
    wall = time.perf_counter() - start
    movie_wall = movie.wall_seconds if movie is not None else 0.0
    files.insert(0, save_png(state, out / "demo.png"))
    summary = packing_summary(state)
    steps_per_s = sim.steps_taken / max(wall - movie_wall, 1e-9)
    row = {
        "seed": args.seed, "dots": args.dots, "sigma": args.sigma, "box_px": f"{DEMO_BOX[0]:g}x{DEMO_BOX[1]:g}",
        "mean_diameter_px": DEMO_DIAMETER, "simulated_s": state.time, "dt_s": sim.dt,
        "steps": sim.steps_taken, "wall_s": round(wall, 3), "movie_wall_s": round(movie_wall, 3),
        "steps_per_s": round(steps_per_s, 1), "interior_fraction": summary["interior_fraction"],
        "mean_neighbours_interior": summary["mean_neighbours_interior"],
        "max_overlap": summary["max_overlap"], "kinetic_energy": summary["kinetic_energy"],
    }
    _atomic_csv(out / "summary.csv", row)
    files.append(out / "summary.csv")
    movie_note = f" (movie {movie_wall:.1f} s, {movie.frames} frames)" if movie is not None else ""
    print(f"qdots demo: {args.dots} dots on a {DEMO_BOX[0]:g} x {DEMO_BOX[1]:g} px board, "
          f"sigma {args.sigma:g}, seed {args.seed}")
    print(_table([
        ("dots", f"{summary['n_dots']}"),
        ("simulated time", f"{state.time:.2f} s ({sim.steps_taken} steps of {sim.dt:g} s)"),
        ("wall time", f"{wall:.1f} s{movie_note}"),
        ("steps/s", f"{steps_per_s:,.0f} (simulation only)"),
        ("interior fraction", f"{summary['interior_fraction']:.3f}"),
        ("mean neighbours (interior)", f"{summary['mean_neighbours_interior']:.2f}"),
        ("max overlap", f"{100 * summary['max_overlap']:.3f} % of radius"),
        ("kinetic energy", f"{summary['kinetic_energy']:.4g} mass px^2/s^2"),
        ("files", ", ".join(str(f) for f in files)),
    ]))
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run the ``qdots`` command line; returns the exit status.

    0 on success, 2 on bad input (a one-line ``qdots: error: ...`` on stderr).
    """
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
        return int(args.func(args))
    except SystemExit as exc:  # --help and --version
        return exc.code if isinstance(exc.code, int) else 0
    except (_UsageError, ValueError, OSError) as exc:
        print(f"qdots: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("qdots: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
